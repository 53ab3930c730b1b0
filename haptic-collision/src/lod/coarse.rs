//! What a stopped coarse pair reports: the contacts of two simplified pieces, standing for those
//! of the triangle pairs below them (`docs/formulation.md` §7).
//!
//! A coarse pair is judged by samples spread over the tool piece, each against the obstacle
//! piece (its distance, as a triangle pair reports it), and by where the pieces cross. The walk
//! only records the pairs it stops at ([`CoarsePair`]); [`emit_coarse_pairs`] then takes them
//! tool node by tool node, so that a sample near several obstacle pieces shares its area among
//! them by gap (as a triangle's contacts do, `crate::area`), and writes **one contact per pair
//! and side of the obstacle piece**: the weighted sums of its samples (`Σ w`, `Σ w p`, `Σ w d`,
//! `Σ w n`, with `w = a (d + δ)`, the clustering's weights), plus one touching contact where the
//! pieces cross. A clustering that takes whole pairs gets the same centroid, weight and depth as
//! from the samples themselves (`haptic-cluster`, eqs. 28–32), so the paper's "one contact per
//! pair of convex pieces" costs nothing the force reads, while a query writes, validates and
//! compacts a contact per pair instead of one per sample (up to 37).

use haptic_core::{ContactSet, NO_FEATURE, Real, Vec3, gap_weight_m};

use super::build::{Hierarchy, plane_basis};
use super::query::{Frames, Nearest, place_piece};
use super::{LodError, MAX_PIECE_VERTICES};
use crate::compact::AREA_FLOOR_M2;
use crate::geometry::{PairContact, closest_point_on_polygon_2d, crossing_witness};

/// Subdivisions of each fan triangle's edges in [`fan_samples`].
pub(super) const SAMPLE_LEVEL: usize = 3;

/// Most sample points of a coarse pair (`1 + m · L (L + 1) / 2` for a piece of `m` vertices).
pub(super) const MAX_SAMPLES: usize = sample_count(MAX_PIECE_VERTICES, SAMPLE_LEVEL);

/// The level of [`fan_samples`] for a piece of `m` vertices: [`SAMPLE_LEVEL`], lowered (down to
/// 1, the centroid and the vertices) so that there are at most `budget` points, the number of
/// triangle pairs the coarse pair stands for.
#[inline]
pub(super) fn sample_level(m: usize, budget: u32) -> usize {
    let mut level = SAMPLE_LEVEL;
    while level > 1 && sample_count(m, level) > budget as usize {
        level -= 1;
    }
    level
}

/// How many points [`fan_samples`] places on a piece of `m` vertices at `level`.
#[inline]
pub(super) const fn sample_count(m: usize, level: usize) -> usize {
    1 + m * level * (level + 1) / 2
}

/// The sample points of a tool piece and the fraction of its area each stands for: the centroid
/// and a regular grid on each triangle of the fan from the centroid (the points shared by two
/// fan triangles taken once), of level `level` (1 to [`SAMPLE_LEVEL`], from [`sample_level`]).
/// Returns their number, `1 + m · level (level + 1) / 2` for a piece of `m` vertices.
///
/// A point of fan triangle `i` stands for that triangle's area over its points, a point on the
/// edge two fan triangles share for the mean of theirs, the centroid for the mean fan triangle;
/// the fractions add up to 1. Equal shares would over-weigh the narrow fan triangles of an
/// irregular piece, which get as many points as the wide ones.
#[inline]
pub(super) fn fan_samples(
    a: &[Vec3],
    pts: &mut [Vec3; MAX_SAMPLES],
    wts: &mut [Real; MAX_SAMPLES],
    level: usize,
) -> usize {
    let m = a.len();
    let centroid = a.iter().sum::<Vec3>() / m as Real;
    let level = level.clamp(1, SAMPLE_LEVEL);
    let next = |i: usize| a[if i + 1 == m { 0 } else { i + 1 }];
    let mut fan = [0.0; MAX_PIECE_VERTICES];
    for (i, f) in fan[..m].iter_mut().enumerate() {
        *f = 0.5 * (a[i] - centroid).cross(&(next(i) - centroid)).norm();
    }
    pts[0] = centroid;
    wts[0] = fan[..m].iter().sum::<Real>() / m as Real;
    let mut count = 1;
    let step = 1.0 / level as Real;
    for i in 0..m {
        let (v, prev) = (a[i], fan[if i == 0 { m - 1 } else { i - 1 }]);
        // Row `r` lies on the segment from `centroid + r (v − c)/L` towards the next vertex; its
        // first point is on the edge shared with the previous fan triangle, its last point
        // belongs to the next fan triangle.
        for r in 1..=level {
            let start = centroid + (v - centroid) * (r as Real * step);
            for k in 0..r {
                pts[count] = start + (next(i) - v) * (k as Real * step);
                wts[count] = if k == 0 {
                    0.5 * (prev + fan[i])
                } else {
                    fan[i]
                };
                count += 1;
            }
        }
    }
    let sum: Real = wts[..count].iter().sum();
    if sum > 0.0 && sum.is_finite() {
        wts[..count].iter_mut().for_each(|w| *w /= sum);
    } else {
        // A degenerate piece (no area): equal shares.
        wts[..count].fill(1.0 / count as Real);
    }
    count
}

/// The obstacle piece in the frame of its plane (`u, w` in the plane, `n` its normal), for the
/// distances of many points to it.
pub(super) struct PlanarPiece {
    origin: Vec3,
    u: Vec3,
    w: Vec3,
    n: Vec3,
    verts: [[Real; 2]; MAX_PIECE_VERTICES],
    len: usize,
}

impl PlanarPiece {
    pub(super) fn new(b: &[Vec3], nb: &Vec3) -> Self {
        let (u, w) = plane_basis(nb);
        let origin = b[0];
        let mut verts = [[0.0; 2]; MAX_PIECE_VERTICES];
        for (dst, v) in verts.iter_mut().zip(b) {
            let d = v - origin;
            *dst = [u.dot(&d), w.dot(&d)];
        }
        Self {
            origin,
            u,
            w,
            n: *nb,
            verts,
            len: b.len(),
        }
    }

    /// The closest point of the piece to `x`, and the distance, when it is at most `delta`.
    #[inline]
    pub(super) fn closest_within(&self, x: &Vec3, delta: Real) -> Option<(Vec3, Real)> {
        let d = x - self.origin;
        let h = self.n.dot(&d);
        if h.abs() > delta {
            return None;
        }
        let p = [self.u.dot(&d), self.w.dot(&d)];
        let c = closest_point_on_polygon_2d(p, &self.verts[..self.len]);
        let dist = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + h * h).sqrt();
        (dist <= delta).then(|| (self.origin + self.u * c[0] + self.w * c[1], dist))
    }
}

/// A pair of nodes at which the walk stopped above the leaves, for [`emit_coarse_pairs`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct CoarsePair {
    /// Tool node.
    pub ia: u32,
    /// Level of the tool piece's samples ([`sample_level`]).
    pub level: u32,
    /// Index of the obstacle (in the back-end's order).
    pub obstacle: u32,
    /// Obstacle node.
    pub ib: u32,
    /// A lower bound on the pieces' distance (their plane gaps).
    pub gap_m: Real,
}

/// One sample against one obstacle piece: the sample and its closest point (obstacle frame) and
/// the distance, infinite when beyond `δ`.
#[derive(Debug, Clone, Copy)]
struct Hit {
    /// The sample (obstacle frame).
    x: Vec3,
    closest: Vec3,
    distance: Real,
}

/// How coarse pairs are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CoarseOutput {
    /// One contact per pair and side of the obstacle piece (and one where the pieces cross).
    Regions,
    /// One contact per sample within `δ`: what the regions sum up, kept to test them against.
    #[cfg_attr(not(test), allow(dead_code))]
    Samples,
}

/// Scratch of [`emit_coarse_pairs`], reused between queries.
#[derive(Debug, Clone, Default)]
pub(crate) struct CoarseScratch {
    /// The stopped coarse pairs of the whole query (all obstacles).
    pub pairs: Vec<CoarsePair>,
    /// Per pair of the current tool node: its crossing point, if the pieces cross.
    crossing: Vec<Option<Vec3>>,
    /// Per pair × sample of the current tool node and level.
    hits: Vec<Hit>,
}

impl CoarseScratch {
    /// Room held (elements), for the tests that check a warm query allocates nothing.
    pub fn capacity(&self) -> usize {
        self.pairs.capacity() + self.crossing.capacity() + self.hits.capacity()
    }

    /// Heap memory held (bytes).
    pub fn memory_bytes(&self) -> usize {
        self.pairs.capacity() * std::mem::size_of::<CoarsePair>()
            + self.crossing.capacity() * std::mem::size_of::<Option<Vec3>>()
            + self.hits.capacity() * std::mem::size_of::<Hit>()
    }
}

/// The weighted sums of the samples of one pair on one side of the obstacle piece.
#[derive(Debug, Clone, Copy)]
struct Region {
    /// `Σ a g` (area × gap, the clustering's weight).
    w: Real,
    /// The same sums with areas floored at [`AREA_FLOOR_M2`], for the means.
    wf: Real,
    p: Vec3,
    n: Vec3,
    d: Real,
    /// Normal of the nearest sample (the fallback when the normals cancel).
    nearest_n: Vec3,
    nearest: Real,
}

impl Region {
    const EMPTY: Self = Self {
        w: 0.0,
        wf: 0.0,
        p: Vec3::new(0.0, 0.0, 0.0),
        n: Vec3::new(0.0, 0.0, 0.0),
        d: 0.0,
        nearest_n: Vec3::new(0.0, 0.0, 1.0),
        nearest: Real::INFINITY,
    };

    #[inline]
    fn add(&mut self, x: &Vec3, n: &Vec3, d: Real, area_m2: Real, g: Real) {
        let wf = area_m2.max(AREA_FLOOR_M2) * g;
        self.w += area_m2 * g;
        self.wf += wf;
        self.p += x * wf;
        self.n += n * wf;
        self.d += d * wf;
        if -d < self.nearest {
            self.nearest = -d;
            self.nearest_n = *n;
        }
    }

    /// The region as one contact (obstacle frame) and its area: depth, point and normal the
    /// weighted means, area `Σ w / (d + δ)` so that its weight is `Σ w`.
    fn contact(&self, delta_m: Real) -> (PairContact, Real) {
        let p_a = self.p / self.wf;
        let d = (self.d / self.wf).clamp(-delta_m, -self.nearest);
        let n = self
            .n
            .try_normalize(1e-9 * self.wf)
            .unwrap_or(self.nearest_n);
        let pc = PairContact {
            p_a,
            p_b: p_a - n * d,
            n,
            depth: d,
            distance: -d,
        };
        (pc, self.w / gap_weight_m(d, delta_m))
    }
}

/// Writes the contacts of the query's stopped coarse pairs (`scratch.pairs`, emptied), taken tool
/// node by tool node (see the module docs):
/// - where a pair's pieces cross, one contact at a point of their intersection, touching
///   (depth 0), with the normal `−n_b` (out of the tool, into the obstacle). Triangle pairs that
///   cross report small separating-axis depths; the pieces' own separating-axis depth measures
///   how two large polygons cross and is not bounded by the size of the triangles below them;
/// - samples spread over the tool piece ([`fan_samples`], at the pair's level), each with what a
///   triangle pair reports, its distance to the obstacle piece: `depth = −distance`, `n` along
///   the closest-point direction, on whichever side of the obstacle piece it lies (a triangle
///   below the obstacle's surface by `h` is `h` away from every triangle it is paired with),
///   kept when within `δ`.
///
/// Areas: the tool node's area (below it) is shared among its samples by their weights from
/// [`fan_samples`], one sample's equal share going to each crossing; a sample within `δ` of
/// several obstacle pieces (of the same level) shares its area among them by gap, and the
/// crossings of one tool node share theirs. With [`CoarseOutput::Regions`] each pair's samples
/// on each side of its obstacle piece become one contact ([`Region`]).
///
/// `nearest[o]` notes the distances written against obstacle `o` (0 where pieces cross; a
/// region's mean distance) and found (the nearest sample), and the pairs that do not cross are
/// pushed onto `apart` as `(gap, obstacle, ia, ib)`, so that
/// [`super::query::closest_approaches`] finds the exact closest approach wherever it could be
/// closer than what was written.
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
#[allow(clippy::too_many_arguments)]
pub(crate) fn emit_coarse_pairs(
    tool: &Hierarchy,
    obstacles: &[(Hierarchy, haptic_core::Pose)],
    frames: &[Frames],
    delta_m: Real,
    output: CoarseOutput,
    scratch: &mut CoarseScratch,
    nearest: &mut [Nearest],
    apart: &mut Vec<(Real, u32, u32, u32)>,
    out: &mut ContactSet,
) -> Result<(), LodError> {
    let CoarseScratch {
        pairs,
        crossing,
        hits,
    } = scratch;
    // Grouped by tool node, level and obstacle; the order within a group is the walk's, so the
    // output is deterministic.
    pairs.sort_unstable_by_key(|p| {
        (u64::from(p.ia) << 32) | (u64::from(p.level) << 30) | u64::from(p.obstacle)
    });
    let mut buf = [Vec3::zeros(); MAX_PIECE_VERTICES];
    let mut pts = [Vec3::zeros(); MAX_SAMPLES];
    let mut wts = [0.0; MAX_SAMPLES];
    let mut gap_sums = [0.0; MAX_SAMPLES];
    for node in pairs.chunk_by(|p, q| p.ia == q.ia) {
        let ia = node[0].ia;
        let a = &tool.nodes[ia as usize];
        let area_m2 = tool.area_of(ia);
        // Where each pair's pieces cross; the crossings of the node share one sample's share
        // each, equally (their gaps are all δ).
        crossing.clear();
        let (mut placed_for, mut len, mut na) = (u32::MAX, 0, Vec3::zeros());
        for p in node {
            if placed_for != p.obstacle {
                (len, na) = place_piece(tool, a, &frames[p.obstacle as usize], &mut buf);
                placed_for = p.obstacle;
            }
            let (obs, _) = &obstacles[p.obstacle as usize];
            let b = &obs.nodes[p.ib as usize];
            crossing.push(crossing_witness(
                &buf[..len],
                &na,
                obs.piece_of(b),
                &b.normal,
            ));
        }
        let crossings = crossing.iter().filter(|c| c.is_some()).count().max(1) as Real;
        // Each level's pairs sample the same points; `hits` holds them, pair by pair.
        let mut lstart = 0;
        for group in node.chunk_by(|p, q| p.level == q.level) {
            let level = group[0].level;
            hits.clear();
            let mut count = 0;
            placed_for = u32::MAX;
            for p in group {
                if placed_for != p.obstacle {
                    let (len, _) = place_piece(tool, a, &frames[p.obstacle as usize], &mut buf);
                    count = fan_samples(&buf[..len], &mut pts, &mut wts, level as usize);
                    placed_for = p.obstacle;
                }
                let (obs, _) = &obstacles[p.obstacle as usize];
                let b = &obs.nodes[p.ib as usize];
                let piece = PlanarPiece::new(obs.piece_of(b), &b.normal);
                for x in &pts[..count] {
                    let mut hit = Hit {
                        x: *x,
                        closest: *x,
                        distance: Real::INFINITY,
                    };
                    if let Some((c, _)) = piece.closest_within(x, delta_m) {
                        // Distance from the 3-D points themselves (see where the normal is
                        // taken, below).
                        let len = (c - x).norm();
                        if len > 0.0 && len.is_finite() {
                            hit.closest = c;
                            hit.distance = len;
                        }
                    }
                    hits.push(hit);
                }
            }
            // Per sample, the sum of its gaps over the pieces it is within δ of.
            gap_sums[..count].fill(0.0);
            for (i, h) in hits.iter().enumerate() {
                if h.distance.is_finite() {
                    gap_sums[i % count] += gap_weight_m(-h.distance, delta_m);
                }
            }
            for (j, p) in group.iter().enumerate() {
                let f = &frames[p.obstacle as usize];
                let (obs, _) = &obstacles[p.obstacle as usize];
                let b = &obs.nodes[p.ib as usize];
                let cross = crossing[lstart + j];
                // The crossing takes one sample's share; the samples the rest, by their weights.
                let share = area_m2 / (count + usize::from(cross.is_some())) as Real;
                let sampled_m2 = area_m2 - if cross.is_some() { share } else { 0.0 };
                let mut near = Real::INFINITY;
                if let Some(x) = cross {
                    let touching = PairContact {
                        p_a: x,
                        p_b: x,
                        n: -b.normal,
                        depth: 0.0,
                        distance: 0.0,
                    };
                    f.emit(&touching, NO_FEATURE, NO_FEATURE, share / crossings, out)?;
                    nearest[p.obstacle as usize].written(0.0);
                    near = 0.0;
                }
                let origin = obs.piece_of(b)[0];
                let mut sides = [Region::EMPTY; 2];
                for (k, hit) in hits[j * count..(j + 1) * count].iter().enumerate() {
                    if !hit.distance.is_finite() {
                        continue;
                    }
                    let d = -hit.distance;
                    // The normal and the distance from the same 3-D points: the planar frame's
                    // distance can differ from `|c − x|` by rounding, and at a few ulps from the
                    // piece that made a normal of norm √5 (gears in mesh, whose flat faces are
                    // coarse pieces even at threshold 0).
                    let n = (hit.closest - hit.x) / hit.distance;
                    let g = gap_weight_m(d, delta_m);
                    let a_k = sampled_m2 * wts[k] * (g / gap_sums[k]).min(1.0);
                    near = near.min(hit.distance);
                    match output {
                        CoarseOutput::Samples => {
                            nearest[p.obstacle as usize].written(hit.distance);
                            let sample = PairContact {
                                p_a: hit.x,
                                p_b: hit.closest,
                                n,
                                depth: d,
                                distance: hit.distance,
                            };
                            f.emit(&sample, NO_FEATURE, NO_FEATURE, a_k, out)?;
                        }
                        CoarseOutput::Regions => {
                            nearest[p.obstacle as usize].found(hit.distance, p.ia, p.ib);
                            let side = usize::from(b.normal.dot(&(hit.x - origin)) < 0.0);
                            sides[side].add(&hit.x, &n, d, a_k, g);
                        }
                    }
                }
                for r in sides.iter().filter(|r| r.wf > 0.0) {
                    let (pc, area) = r.contact(delta_m);
                    f.emit(&pc, NO_FEATURE, NO_FEATURE, area, out)?;
                    nearest[p.obstacle as usize].written(pc.distance);
                }
                if near > 0.0 {
                    apart.push((p.gap_m, p.obstacle, p.ia, p.ib));
                }
            }
            lstart += group.len();
        }
    }
    pairs.clear();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::closest_point_on_polygon;
    use crate::lod::LodBackend;
    use crate::lod::testmesh::mesh;
    use haptic_core::{CollisionBackend, Pose, QueryParams};
    use proptest::prelude::*;

    /// The contacts of one coarse pair: tool piece `a` over obstacle piece `b` (each a convex
    /// polygon, meshed as a fan), at a threshold that stops the walk at the root pair.
    fn coarse_pair_contacts(
        a: &[Vec3],
        b: &[Vec3],
        delta: Real,
        output: CoarseOutput,
        out: &mut ContactSet,
    ) -> Result<(), LodError> {
        let fan = |p: &[Vec3]| {
            let tris = (1..p.len() as u32 - 1).map(|i| [0, i, i + 1]).collect();
            mesh(p.to_vec(), tris)
        };
        let mut lod =
            LodBackend::new(&fan(a), &[(fan(b), Pose::identity())])?.with_max_contacts(None);
        if output == CoarseOutput::Samples {
            lod = lod.with_coarse_samples();
        }
        lod.query(&Pose::identity(), &QueryParams::new(delta, 1.0)?, out)
            .map(|_| ())
    }

    /// A convex polygon of `m` vertices on an ellipse in the plane through `o` with normal `n`,
    /// counter-clockwise about `n`.
    fn polygon(m: usize, o: Vec3, n: Vec3, r: (Real, Real), phase: Real) -> Vec<Vec3> {
        let (u, w) = plane_basis(&n);
        (0..m)
            .map(|k| {
                let t = phase + k as Real / m as Real * std::f64::consts::TAU;
                o + u * (r.0 * t.cos()) + w * (r.1 * t.sin())
            })
            .collect()
    }

    fn arb_vec() -> impl Strategy<Value = Vec3> {
        prop::array::uniform3(-1.0..1.0f64).prop_map(Vec3::from)
    }

    proptest! {
        /// Samples a few ulps off a tilted obstacle piece give contacts with unit normals, and
        /// `p_a − p_b = depth · n` (the query failed on these before the normal and the
        /// distance were taken from the same 3-D points).
        #[test]
        fn coarse_samples_near_a_piece_give_valid_contacts(
            n in arb_vec().prop_filter("non-zero", |n| n.norm() > 0.1),
            o in arb_vec(),
            phase in 0.0..6.3f64,
            ulps in 0i64..6,
        ) {
            let n = n.normalize();
            let b = polygon(4, o, n, (0.02, 0.015), phase);
            // The tool piece: the obstacle's, lifted by a few ulps along its normal.
            let lift = n * (ulps as Real * Real::EPSILON * o.norm().max(1.0));
            let a: Vec<Vec3> = polygon(4, o + lift, n, (0.01, 0.008), phase + 0.3)
                .into_iter()
                .rev()
                .collect();
            let mut out = ContactSet::new();
            let r = coarse_pair_contacts(&a, &b, 1e-3, CoarseOutput::Samples, &mut out);
            prop_assert!(r.is_ok(), "{r:?}");
            let r = coarse_pair_contacts(&a, &b, 1e-3, CoarseOutput::Regions, &mut out);
            prop_assert!(r.is_ok(), "{r:?}");
            for c in out.iter() {
                prop_assert!((c.n.norm() - 1.0).abs() < 1e-9);
                prop_assert!((c.p_a - c.p_b - c.n * c.depth_m).norm() < 1e-15);
            }
        }

        /// The planar-frame distance agrees with the general point–polygon routine.
        #[test]
        fn planar_piece_matches_point_polygon(
            m in 3usize..=MAX_PIECE_VERTICES,
            o in arb_vec(),
            n in arb_vec().prop_filter("non-zero", |n| n.norm() > 0.1),
            r in (0.05..1.0f64, 0.05..1.0f64),
            phase in 0.0..6.3f64,
            x in arb_vec(),
        ) {
            let n = n.normalize();
            let b = polygon(m, o, n, r, phase);
            let piece = PlanarPiece::new(&b, &n);
            let c = closest_point_on_polygon(&x, &b, &n);
            let d = (c - x).norm();
            match piece.closest_within(&x, 10.0) {
                Some((c2, d2)) => {
                    prop_assert!((d - d2).abs() < 1e-12 && (c - c2).norm() < 1e-12);
                }
                None => prop_assert!(false, "a point 10 m in reach was not reported"),
            }
            // Beyond δ nothing is reported.
            prop_assert!(piece.closest_within(&x, 0.99 * d).is_none());
        }

        /// The samples lie in the piece, the centroid first, each once.
        #[test]
        fn fan_samples_cover_the_piece_once(
            m in 3usize..=MAX_PIECE_VERTICES,
            n in arb_vec().prop_filter("non-zero", |n| n.norm() > 0.1),
            phase in 0.0..6.3f64,
        ) {
            let n = n.normalize();
            let a = polygon(m, Vec3::zeros(), n, (0.3, 0.2), phase);
            let mut pts = [Vec3::zeros(); MAX_SAMPLES];
            let mut wts = [0.0; MAX_SAMPLES];
            let count = fan_samples(&a, &mut pts, &mut wts, sample_level(m, u32::MAX));
            prop_assert_eq!(count, 1 + m * SAMPLE_LEVEL * (SAMPLE_LEVEL + 1) / 2);
            prop_assert!(pts[0].norm() < 1e-12);
            for (i, p) in pts[..count].iter().enumerate() {
                prop_assert!((closest_point_on_polygon(p, &a, &n) - p).norm() < 1e-12);
                for q in &pts[..i] {
                    prop_assert!((p - q).norm() > 1e-6);
                }
            }
            for v in &a {
                prop_assert!(pts[..count].iter().any(|p| (p - v).norm() < 1e-12));
            }
            // The weights add up to 1, each positive.
            prop_assert!((wts[..count].iter().sum::<Real>() - 1.0).abs() < 1e-12);
            prop_assert!(wts[..count].iter().all(|&w| w > 0.0));
            // A budget lowers the level, down to the centroid and the vertices.
            prop_assert_eq!(sample_level(m, (1 + 3 * m) as u32), 2);
            prop_assert_eq!(fan_samples(&a, &mut pts, &mut wts, 2), 1 + 3 * m);
            prop_assert_eq!(sample_level(m, 3 * m as u32), 1);
            prop_assert_eq!(sample_level(m, 0), 1);
            prop_assert_eq!(fan_samples(&a, &mut pts, &mut wts, 1), 1 + m);
        }
    }
}
