//! How the build divides a node's triangles between its two children.
//!
//! Two candidates, scored by how flat their children are (the larger of the two children's
//! thicknesses along their own area-weighted normals, which bounds how far a planar piece can be
//! from them):
//! - **by position**: the median centroid along the longest axis of the centroids' box, which
//!   halves the node's extent and so, on a smooth surface, quarters its thickness; the two
//!   halves of a quad (`quads.rs`) share their quad's centroid and are never cut apart;
//! - **by orientation**: the triangles sorted along the direction in which their normals spread
//!   most, cut at the widest gap of that order, when that gap is a crease (every normal on one
//!   side at least [`CREASE_ANGLE_RAD`] from every normal on the other): a box's sides, a
//!   thread's two flanks, a peg's wall and its end.
//!
//! The cut along a crease is taken when its children are less than half as thick as the
//! position split's. On creased, CAD-like parts each face then gets nodes of its own high in
//! the tree, whose pieces are exact (deviation 0 on a planar face), so the walk stops there
//! instead of descending to the triangles; on smooth, organic surfaces there are few creases
//! and the tree is mostly the position split's. Both candidates are balanced enough
//! ([`MIN_SHARE`]) for the tree's depth to stay logarithmic in practice.

use haptic_core::{Mat3, Real, Vec3};

use super::build::ROUNDOFF_REL;
use super::quads;

/// A cut by orientation must leave at least `1 / MIN_SHARE` of the node's triangles on each
/// side, so that the tree's depth stays logarithmic in practice.
pub(super) const MIN_SHARE: usize = 16;

/// A cut by orientation is a crease only where every normal on one side is at least this far
/// in angle from every normal on the other: 30°, the usual feature angle of CAD and mesh tools
/// (smooth shading and feature-edge extraction). Finer turns of the normals are a curved
/// surface's, which the position split flattens better.
pub(super) const CREASE_ANGLE_RAD: Real = std::f64::consts::PI / 6.0;

/// The orientation split is taken only when its children are thinner than this fraction of the
/// position split's.
pub(super) const ORIENTATION_GAIN: Real = 0.5;

/// What the split reads of each triangle (by source index).
pub(super) struct Triangles<'a> {
    /// The three corners.
    pub corners: &'a [[Vec3; 3]],
    /// Where the split by position places each: its centroid, or its quad's
    /// ([`quads::positions`]).
    pub positions: &'a [Vec3],
    /// Each one's quad partner, or [`quads::NONE`].
    pub partner: &'a [u32],
    /// `(b − a) × (c − a)`: along the normal, twice the area long.
    pub area_normals: &'a [Vec3],
}

impl Triangles<'_> {
    /// Thickness (m) of `tris` along their area-weighted mean normal; infinite when that normal
    /// is undefined (the triangles' normals cancel).
    fn thickness(&self, tris: &[u32]) -> Real {
        let (mut sum, mut len) = (Vec3::zeros(), 0.0);
        for &t in tris {
            let an = &self.area_normals[t as usize];
            sum += an;
            len += an.norm();
        }
        let norm = sum.norm();
        if !(norm > 1e-9 * len && norm > 0.0) {
            return Real::INFINITY;
        }
        let n = sum / norm;
        let (mut lo, mut hi) = (Real::INFINITY, Real::NEG_INFINITY);
        for &t in tris {
            for v in &self.corners[t as usize] {
                let h = n.dot(v);
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        hi - lo
    }

    /// The larger thickness of the two parts of `tris` cut at `m`.
    fn score(&self, tris: &[u32], m: usize) -> Real {
        self.thickness(&tris[..m]).max(self.thickness(&tris[m..]))
    }

    /// Reorders `tris` (at least two) into the median split by position; returns the cut,
    /// which keeps a quad's two halves on one side when there are more than two triangles.
    fn by_position(&self, tris: &mut [u32]) -> usize {
        let (mut lo, mut hi) = (Vec3::repeat(Real::INFINITY), Vec3::repeat(-Real::INFINITY));
        for &t in tris.iter() {
            lo = lo.inf(&self.positions[t as usize]);
            hi = hi.sup(&self.positions[t as usize]);
        }
        // The longest axis; of axes equally long within roundoff (a square plate), the first,
        // rather than whichever rounded longer.
        let extent = hi - lo;
        let longest = extent.max();
        let axis = (0..3)
            .find(|&k| extent[k] >= longest * (1.0 - ROUNDOFF_REL))
            .unwrap_or(0);
        let mid = tris.len() / 2;
        // Ordered by position, then by quad (its smaller index), then by index: a quad's two
        // halves are neighbours in the order.
        let quad = |t: u32| t.min(self.partner[t as usize]);
        tris.select_nth_unstable_by(mid, |&a, &b| {
            self.positions[a as usize][axis]
                .total_cmp(&self.positions[b as usize][axis])
                .then(quad(a).cmp(&quad(b)))
                .then(a.cmp(&b))
        });
        // `tris[mid]` is the first of the right part; its partner, when it comes before it,
        // is the last of the left part (a quad's halves are never parted above this node, by
        // either split): take `tris[mid]` to the left too.
        let t = tris[mid];
        let p = self.partner[t as usize];
        debug_assert!(p == quads::NONE || tris.contains(&p), "a quad parted above");
        if tris.len() > 2 && p < t {
            mid + 1
        } else {
            mid
        }
    }

    /// Reorders `tris` along the normals' direction of largest spread and returns the cut at
    /// the widest gap leaving at least `len / MIN_SHARE` triangles on each side; `None` when
    /// the normals do not spread (a flat node) or have no gap.
    fn by_orientation(&self, tris: &mut [u32], keys: &mut Vec<(Real, u32)>) -> Option<usize> {
        let (mut mean, mut weight) = (Vec3::zeros(), 0.0);
        for &t in tris.iter() {
            let an = &self.area_normals[t as usize];
            mean += an;
            weight += an.norm();
        }
        if weight.is_nan() || weight <= 0.0 {
            return None;
        }
        mean /= weight;
        let mut spread = Mat3::zeros();
        for &t in tris.iter() {
            let an = &self.area_normals[t as usize];
            let w = an.norm();
            if w > 0.0 {
                let d = an / w - mean;
                spread += d * d.transpose() * w;
            }
        }
        // Normals within about 0.1° of one another: nothing to separate.
        let trace = spread.trace();
        if trace.is_nan() || trace <= 1e-6 * weight {
            return None;
        }
        let eigen = spread.symmetric_eigen();
        let u: Vec3 = eigen
            .eigenvectors
            .column(eigen.eigenvalues.imax())
            .into_owned();
        keys.clear();
        keys.extend(tris.iter().map(|&t| {
            let an = &self.area_normals[t as usize];
            let w = an.norm();
            (if w > 0.0 { u.dot(an) / w } else { 0.0 }, t)
        }));
        keys.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let min = (tris.len() / MIN_SHARE).max(1);
        let (mut cut, mut widest) = (None, 0.0);
        for m in min..=tris.len() - min {
            let gap = keys[m].0 - keys[m - 1].0;
            if gap > widest {
                (cut, widest) = (Some(m), gap);
            }
        }
        let cut = cut?;
        // Normals `g` apart along `u` are at least `2 asin(g / 2)` apart in angle.
        if widest < 2.0 * (0.5 * CREASE_ANGLE_RAD).sin() {
            return None;
        }
        for (dst, &(_, t)) in tris.iter_mut().zip(keys.iter()) {
            *dst = t;
        }
        Some(cut)
    }

    /// Reorders `tris` (at least two) into the two children's and returns the cut: the left
    /// child is `tris[..cut]`, the right `tris[cut..]`, both non-empty.
    pub(super) fn split(&self, tris: &mut [u32], scratch: &mut SplitScratch) -> usize {
        let mid = self.by_position(tris);
        if tris.len() < 4 {
            return mid;
        }
        let by_position = self.score(tris, mid);
        if by_position == 0.0 {
            return mid;
        }
        scratch.order.clear();
        scratch.order.extend_from_slice(tris);
        match self.by_orientation(&mut scratch.order, &mut scratch.keys) {
            Some(cut) if self.score(&scratch.order, cut) < ORIENTATION_GAIN * by_position => {
                tris.copy_from_slice(&scratch.order);
                cut
            }
            _ => mid,
        }
    }
}

/// What the split reads of a mesh's triangles, owned (the hierarchy's build and tests borrow it
/// as [`Triangles`]).
#[derive(Debug, Clone)]
pub(super) struct TriangleData {
    /// The three corners of each triangle.
    pub corners: Vec<[Vec3; 3]>,
    /// Where the split by position places each (see [`Triangles::positions`]).
    pub positions: Vec<Vec3>,
    /// Each one's quad partner, or [`quads::NONE`].
    pub partner: Vec<u32>,
    /// `(b − a) × (c − a)` of each.
    pub area_normals: Vec<Vec3>,
}

impl TriangleData {
    /// The triangles of `mesh`, by source index.
    pub(super) fn of(mesh: &crate::mesh::TriMesh) -> Self {
        let corners: Vec<[Vec3; 3]> = (0..mesh.triangles().len())
            .map(|t| mesh.triangle(t))
            .collect();
        let centroids: Vec<Vec3> = corners.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let area_normals: Vec<Vec3> = corners
            .iter()
            .map(|t| (t[1] - t[0]).cross(&(t[2] - t[0])))
            .collect();
        let partner = quads::partners(mesh.triangles(), &corners, &area_normals);
        let positions = quads::positions(&centroids, &area_normals, &partner);
        Self {
            corners,
            positions,
            partner,
            area_normals,
        }
    }

    /// The borrowed view the split reads.
    pub(super) fn view(&self) -> Triangles<'_> {
        Triangles {
            corners: &self.corners,
            positions: &self.positions,
            partner: &self.partner,
            area_normals: &self.area_normals,
        }
    }
}

/// Buffers [`Triangles::split`] reuses from node to node.
#[derive(Debug, Default)]
pub(super) struct SplitScratch {
    order: Vec<u32>,
    keys: Vec<(Real, u32)>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::testmesh;

    /// Every triangle's index, in order.
    fn all(t: &TriangleData) -> Vec<u32> {
        (0..t.corners.len() as u32).collect()
    }

    /// A box is cut along its creases: the first cut leaves both children thinner than the
    /// box (a cut by position leaves each half as thick as the box along some normal).
    #[test]
    fn a_box_is_cut_along_its_creases() {
        let mesh = testmesh::cuboid(Vec3::new(0.03, 0.02, 0.01));
        let owned = TriangleData::of(&mesh);
        let tris = owned.view();
        let mut all = all(&owned);
        let mut scratch = SplitScratch::default();
        let cut = tris.split(&mut all, &mut scratch);
        assert!(0 < cut && cut < all.len());
        // Each part lies on fewer faces' planes than the whole: its thickness dropped.
        assert!(tris.score(&all, cut) < tris.thickness(&all));
    }

    /// Two faces meeting at a right angle, one twice as long as the other: the cut is the
    /// crease (each child flat), where the median by position would cut the long face.
    #[test]
    fn an_l_shape_is_cut_at_its_crease() {
        let (k, step) = (4u32, 0.01);
        let mut vertices = Vec::new();
        let mut faces = Vec::new();
        // Floor: x in [0, 2k] steps, y in [0, k]; wall: x = 0, z in [0, k].
        let mut grid = |nu: u32, nv: u32, at: &dyn Fn(u32, u32) -> Vec3| {
            let base = vertices.len() as u32;
            for i in 0..=nu {
                for j in 0..=nv {
                    vertices.push(at(i, j));
                }
            }
            let v = |i: u32, j: u32| base + i * (nv + 1) + j;
            for i in 0..nu {
                for j in 0..nv {
                    faces.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                    faces.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
                }
            }
        };
        grid(2 * k, k, &|i, j| {
            Vec3::new(i as Real * step, j as Real * step, 0.0)
        });
        grid(k, k, &|i, j| {
            Vec3::new(0.0, j as Real * step, i as Real * step)
        });
        let floor = (2 * k * k * 2) as usize;
        let mesh = testmesh::mesh(vertices, faces);
        let owned = TriangleData::of(&mesh);
        let tris = owned.view();
        let mut all = all(&owned);
        let cut = tris.split(&mut all, &mut SplitScratch::default());
        assert_eq!(tris.score(&all, cut), 0.0, "both children flat");
        let one_face = |part: &[u32]| {
            part.iter().all(|&t| (t as usize) < floor)
                || part.iter().all(|&t| (t as usize) >= floor)
        };
        assert!(
            one_face(&all[..cut]) && one_face(&all[cut..]),
            "the cut is the crease"
        );
    }

    /// A patch of 4 × 4 quads, its vertex `(i, j)` at `at(i, j)`; triangle `t` is in the column
    /// `t / 8` (constant `i`).
    fn patch(at: impl Fn(Real, Real) -> Vec3) -> crate::mesh::TriMesh {
        let mut vertices = Vec::new();
        let mut faces = Vec::new();
        for i in 0..5 {
            for j in 0..5 {
                vertices.push(at(i as Real, j as Real));
            }
        }
        for i in 0..4u32 {
            for j in 0..4u32 {
                let v = |a: u32, b: u32| a * 5 + b;
                faces.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                faces.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        testmesh::mesh(vertices, faces)
    }

    /// A flat patch is cut by position (its normals do not spread), into halves.
    #[test]
    fn a_flat_patch_is_cut_by_position() {
        let mesh = patch(|i, j| Vec3::new(i * 0.01, j * 0.01, 0.0));
        let owned = TriangleData::of(&mesh);
        let tris = owned.view();
        let mut all = all(&owned);
        assert_eq!(tris.split(&mut all, &mut SplitScratch::default()), 16);
    }

    /// A square patch has two longest axes; the cut by position takes the first (x) in any
    /// units, rather than whichever one its coordinates rounded longer.
    #[test]
    fn a_square_patch_is_cut_across_x_in_any_units() {
        for scale in [1.0, 1e-3, 0.1, 0.3, 10.0, 7.3, 1e3] {
            // Turned a little about z, so that x and y round differently.
            let mesh = patch(|i, j| {
                let (x, y) = (i * 0.01 * scale, j * 0.01 * scale);
                Vec3::new(x - 1e-3 * y, y + 1e-3 * x, 0.0)
            });
            let owned = TriangleData::of(&mesh);
            let tris = owned.view();
            let mut all = all(&owned);
            let cut = tris.split(&mut all, &mut SplitScratch::default());
            // Two columns on each side.
            let mut left: Vec<u32> = all[..cut].iter().map(|t| t / 8).collect();
            left.sort_unstable();
            left.dedup();
            assert_eq!(left, [0, 1], "scale {scale}");
        }
    }
}
