//! What each node's piece does not show of its surface: the area of the triangles below the node,
//! the mean and variance of their heights above the piece's plane (area-weighted, exact for
//! triangles), how far their normals agree (the normal coherence, `stopping.rs`), and how their
//! normals turn across the piece (the normal field). A coarse pair integrates the penalty over its
//! pieces (`crate::slab`); these moments say where the surfaces the pieces simplify lie about them
//! and which way they face where a region lies. Derived from the leaves' triangles in one pass,
//! so they are not saved with a hierarchy.

use haptic_core::{Mat3, Real, Vec3};
use nalgebra::{Matrix2, Matrix3x2, Vector2};

use crate::geometry::plane_basis;

use super::build::{Node, ROUNDOFF_REL};

/// Per node: area (m²) and the heights' mean (m) and variance (m²) about its piece's plane.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SurfaceMoments {
    /// Surface area of the triangles below the node (m²).
    pub area_m2: Real,
    /// Area-weighted mean height of those triangles above the piece's plane, along its normal
    /// (m); 0 for a leaf.
    pub height_mean_m: Real,
    /// Area-weighted variance of the heights (m²); 0 for a leaf.
    pub height_var_m2: Real,
    /// The surface's area over the piece's, at most 1: the convex piece of a patch that is not
    /// convex spreads over its neighbours' (their prisms overlap by its excess), so a region
    /// over it counts for this share of its area. 1 for a leaf.
    pub cover: Real,
    /// The normal coherence `|Σ aᵢ nᵢ| / Σ aᵢ` of the triangles below the node: 1 for a flat
    /// patch (and a leaf), toward 0 where their faces cancel (`stopping.rs`).
    pub coherence: Real,
    /// The tangent of the angle whose cosine is the coherence, `√(1 − c²) / c`: how far aside
    /// the triangles' prisms lean from the piece's, per unit of height (0 for a flat patch,
    /// [`MAX_SPREAD_TAN`] where the normals cancel). The budgeted rule stops at a piece only
    /// where that lean over the penalty's reach, `δ` times it, fits the threshold with its
    /// deviation (`stopping.rs`).
    pub spread_tan: Real,
}

/// The largest [`SurfaceMoments::spread_tan`]: normals that cancel (a closed shell) lean every
/// way.
pub(crate) const MAX_SPREAD_TAN: Real = 1e6;

/// [`SurfaceMoments::spread_tan`] of the coherence `c`.
pub(crate) fn spread_tan(c: Real) -> Real {
    let c = c.clamp(0.0, 1.0);
    if c * MAX_SPREAD_TAN <= 1.0 {
        MAX_SPREAD_TAN
    } else {
        (1.0 - c * c).sqrt() / c
    }
}

/// Per node: how the surface's normal turns across its piece, kept apart from
/// [`SurfaceMoments`] because only a pair that writes a region reads it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct NormalField {
    /// The area-weighted centroid of the triangles below the node (mesh frame, m).
    pub centroid: Vec3,
    /// The least-squares linear field of the triangles' normals over the piece's plane,
    /// `n(x) ≈ n_piece + G (u·(x − centroid), w·(x − centroid))` (`(u, w)` its
    /// [`plane_basis`]), area-weighted; 1/m. Zero for a flat patch and a leaf.
    pub gradient: Matrix3x2<Real>,
}

impl NormalField {
    /// The unit normal of the surface below the piece of normal `piece_normal` at `x` (mesh
    /// frame), from the linear normal field: where a region covers part of a curved piece, its
    /// force is along the surface's normal there, not along the piece's mean. The piece's normal
    /// where the field gives no direction on the piece's side (turned by a right angle or more,
    /// or not finite).
    #[inline]
    pub fn normal_at(&self, piece_normal: &Vec3, x: &Vec3) -> Vec3 {
        let (u, w) = plane_basis(piece_normal);
        let d = x - self.centroid;
        let n = piece_normal + self.gradient * Vector2::new(u.dot(&d), w.dot(&d));
        let along = n.dot(piece_normal);
        if along > 0.0 && along.is_finite() {
            n / n.norm()
        } else {
            *piece_normal
        }
    }
}

/// The moments and normal fields of every node. The children of node `i` (`i + 1` and `right`)
/// come after it, so one pass from the end sums their raw moments (`∫dA`, `∫x dA`, `∫x xᵀ dA`,
/// `∫n dA`, `∫n xᵀ dA`); a leaf's piece is its triangle.
pub(crate) fn surface_moments(
    nodes: &[Node],
    piece: &[Vec3],
) -> (Vec<SurfaceMoments>, Vec<NormalField>) {
    // Raw moments about the first leaf's first vertex, so that they stay small for a patch far
    // from the mesh's origin.
    let origin = piece.first().copied().unwrap_or_else(Vec3::zeros);
    let mut raw = vec![(0.0, Vec3::zeros(), Mat3::zeros()); nodes.len()];
    // ∫n dA: the vector area.
    let mut vector_area = vec![Vec3::zeros(); nodes.len()];
    // ∫n xᵀ dA, for the normal field.
    let mut normal_moment = vec![Mat3::zeros(); nodes.len()];
    let mut out = vec![SurfaceMoments::default(); nodes.len()];
    let mut fields = vec![NormalField::default(); nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = &nodes[i];
        raw[i] = if n.is_leaf() {
            let s = n.piece_start as usize;
            match piece.get(s..s + n.piece_len as usize) {
                Some([a, b, c]) => {
                    let (a, b, c) = (a - origin, b - origin, c - origin);
                    vector_area[i] = 0.5 * (b - a).cross(&(c - a));
                    let area = vector_area[i].norm();
                    let sum = a + b + c;
                    normal_moment[i] = vector_area[i] * (sum / 3.0).transpose();
                    // ∫x xᵀ over a triangle: A/12 (Σ vᵢ vᵢᵀ + (Σ vᵢ)(Σ vᵢ)ᵀ).
                    let second = (a * a.transpose()
                        + b * b.transpose()
                        + c * c.transpose()
                        + sum * sum.transpose())
                        * (area / 12.0);
                    (area, sum * (area / 3.0), second)
                }
                _ => (0.0, Vec3::zeros(), Mat3::zeros()),
            }
        } else {
            let zero = (0.0, Vec3::zeros(), Mat3::zeros());
            let l = raw.get(i + 1).copied().unwrap_or(zero);
            let r = raw.get(n.right as usize).copied().unwrap_or(zero);
            let va = |j: usize| vector_area.get(j).copied().unwrap_or_else(Vec3::zeros);
            vector_area[i] = va(i + 1) + va(n.right as usize);
            let nm = |j: usize| normal_moment.get(j).copied().unwrap_or_else(Mat3::zeros);
            normal_moment[i] = nm(i + 1) + nm(n.right as usize);
            (l.0 + r.0, l.1 + r.1, l.2 + r.2)
        };
        let (area, first, second) = raw[i];
        let mut m = SurfaceMoments {
            area_m2: area,
            cover: 1.0,
            // A planar surface's normals agree to roundoff: within `ROUNDOFF_REL` of 1, it is 1
            // (the query reads the overhang of planar pieces only, `Hierarchy::overhang_of`).
            coherence: if area > 0.0 {
                let c = vector_area[i].norm() / area;
                if c >= 1.0 - ROUNDOFF_REL { 1.0 } else { c }
            } else {
                1.0
            },
            ..SurfaceMoments::default()
        };
        m.spread_tan = spread_tan(m.coherence);
        if !n.is_leaf() && area > 0.0 && n.normal.iter().all(|x| x.is_finite()) {
            // h = n·x − c with c = n·p₀: ∫h = n·∫x − A c; ∫h² = nᵀ(∫x xᵀ)n − 2c n·∫x + A c².
            let c = n.normal.dot(&(n.plane_point - origin));
            let nf = n.normal.dot(&first);
            let mean = nf / area - c;
            let second_h = n.normal.dot(&(second * n.normal)) / area - 2.0 * c * nf / area + c * c;
            m.height_mean_m = mean;
            m.height_var_m2 = (second_h - mean * mean).max(0.0);
            let xbar = first / area;
            fields[i].centroid = xbar + origin;
            fields[i].gradient = normal_gradient(
                &n.normal,
                &(second - first * xbar.transpose()),
                &(normal_moment[i] - vector_area[i] * xbar.transpose()),
            );
            let s = n.piece_start as usize;
            if let Some(p) = piece.get(s..s + n.piece_len as usize) {
                let piece_area = polygon_area(p);
                if piece_area > area * (1.0 + ROUNDOFF_REL) {
                    m.cover = area / piece_area;
                }
            }
        }
        out[i] = m;
    }
    (out, fields)
}

/// The least-squares gradient `G` (3 × 2, 1/m) of the normals over the plane of `normal`, from the
/// centred moments `∫(x − x̄)(x − x̄)ᵀ dA` (`cov_xx`) and `∫(n − n̄)(x − x̄)ᵀ dA` (`cov_nx`):
/// `G = M C⁻¹` with `M = cov_nx S`, `C = Sᵀ cov_xx S`, `S = [u w]`. `C` is regularised by 10⁻⁹ of
/// its trace, so that a strip of triangles in a row (no spread across it) gets the gradient along
/// it and none across; zero where there is no spread at all.
fn normal_gradient(normal: &Vec3, cov_xx: &Mat3, cov_nx: &Mat3) -> Matrix3x2<Real> {
    let (u, w) = plane_basis(normal);
    let s = Matrix3x2::from_columns(&[u, w]);
    let c = s.transpose() * cov_xx * s;
    let c = c + Matrix2::identity() * (1e-9 * c.trace());
    match c.try_inverse() {
        Some(inv) if c.trace() > 0.0 => {
            let g = cov_nx * s * inv;
            if g.iter().all(|x| x.is_finite()) {
                g
            } else {
                Matrix3x2::zeros()
            }
        }
        _ => Matrix3x2::zeros(),
    }
}

/// Area of a planar convex polygon (m²).
fn polygon_area(p: &[Vec3]) -> Real {
    let mut s = Vec3::zeros();
    for k in 1..p.len().saturating_sub(1) {
        s += (p[k] - p[0]).cross(&(p[k + 1] - p[0]));
    }
    0.5 * s.norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::Hierarchy;
    use crate::lod::testmesh::{icosphere_raw, mesh};

    /// The spread's tangent is that of the angle whose cosine is the coherence: 0 for a flat
    /// patch (every leaf), 1 at 45°, the cap where the normals cancel (a whole sphere).
    #[test]
    fn the_spread_is_the_tangent_of_the_coherence_angle() {
        assert_eq!(spread_tan(1.0), 0.0);
        assert!((spread_tan(std::f64::consts::FRAC_1_SQRT_2) - 1.0).abs() < 1e-12);
        assert!((spread_tan(0.5) - 3f64.sqrt()).abs() < 1e-12);
        assert_eq!(spread_tan(0.0), MAX_SPREAD_TAN);
        assert_eq!(spread_tan(-0.5), MAX_SPREAD_TAN);
        let (v, t) = icosphere_raw(3);
        let h = Hierarchy::build(&mesh(v, t));
        for (i, n) in h.nodes.iter().enumerate() {
            let m = &h.moments[i];
            if n.is_leaf() {
                assert_eq!(m.spread_tan, 0.0);
            } else {
                let expected = (1.0 - m.coherence.powi(2)).sqrt() / m.coherence;
                assert!(
                    (m.spread_tan - expected.min(MAX_SPREAD_TAN)).abs() <= 1e-9 * expected.max(1.0)
                );
            }
        }
        // The root (the whole sphere) cancels.
        assert!(h.moments[0].spread_tan > 1e3);
    }

    /// On a sphere, whose normal is `x / r` everywhere, the normal field of every node that
    /// covers a cap of at least 16 triangles (their normals within about 37° of their mean:
    /// coherence ≥ 0.9) gives the triangles' normals at their centroids at least five times
    /// closer than the piece's own normal does. (Below a few triangles, what is left is the
    /// facets' own scatter about the sphere's normal, which no smooth field follows.)
    #[test]
    fn the_normal_field_follows_a_sphere() {
        let (v, t) = icosphere_raw(4);
        let r = 0.05;
        let centre = Vec3::new(0.3, -0.2, 0.1);
        let m = mesh(v.iter().map(|p| centre + p * r).collect(), t);
        let h = Hierarchy::build(&m);
        let (moments, fields) = surface_moments(&h.nodes, &h.piece);
        let angle = |a: &Vec3, b: &Vec3| a.dot(b).clamp(-1.0, 1.0).acos();
        let mut caps = 0;
        for (i, node) in h.nodes.iter().enumerate() {
            if node.is_leaf() || moments[i].coherence < 0.9 {
                continue;
            }
            let (mut with_field, mut piece_only, mut count) = (0.0, 0.0, 0);
            let mut stack = vec![i];
            while let Some(j) = stack.pop() {
                let nj = &h.nodes[j];
                if !nj.is_leaf() {
                    stack.push(j + 1);
                    stack.push(nj.right as usize);
                    continue;
                }
                let tri = m.triangle(nj.triangle as usize);
                let x = (tri[0] + tri[1] + tri[2]) / 3.0;
                let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0])).normalize();
                with_field += angle(&fields[i].normal_at(&node.normal, &x), &n);
                piece_only += angle(&node.normal, &n);
                count += 1;
            }
            if count < 16 {
                continue;
            }
            assert!(
                with_field <= 0.2 * piece_only,
                "node {i} (coherence {}): mean angle {with_field} with the field, {piece_only} without",
                moments[i].coherence
            );
            caps += 1;
        }
        assert!(caps > 100, "{caps} caps");
    }

    /// Against the moments summed triangle by triangle (each by a three-point rule exact for
    /// quadratics) for every node of a bumpy mesh.
    #[test]
    fn moments_match_the_triangles_below_each_node() {
        let mut verts = Vec::new();
        let k = 12;
        for i in 0..=k {
            for j in 0..=k {
                let (x, y) = (i as Real * 0.01, j as Real * 0.01);
                verts.push(Vec3::new(
                    x,
                    y,
                    0.002 * (40.0 * x).sin() * (30.0 * y).cos() + 0.3,
                ));
            }
        }
        let mut tris = Vec::new();
        for i in 0..k {
            for j in 0..k {
                let v = |a: usize, b: usize| (a * (k + 1) + b) as u32;
                tris.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                tris.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        let m = mesh(verts, tris);
        let h = Hierarchy::build(&m);
        let (moments, fields) = surface_moments(&h.nodes, &h.piece);
        for (i, node) in h.nodes.iter().enumerate() {
            let mut tris_below = Vec::new();
            let mut stack = vec![i];
            while let Some(j) = stack.pop() {
                let nj = &h.nodes[j];
                if nj.is_leaf() {
                    tris_below.push(m.triangle(nj.triangle as usize));
                } else {
                    stack.push(j + 1);
                    stack.push(nj.right as usize);
                }
            }
            let height = |x: &Vec3| node.normal.dot(&(x - node.plane_point));
            let (mut a, mut s1, mut s2) = (0.0, 0.0, 0.0);
            let mut vector_area = Vec3::zeros();
            let mut first = Vec3::zeros();
            for t in &tris_below {
                let area = 0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm();
                first += (t[0] + t[1] + t[2]) * (area / 3.0);
                vector_area += 0.5 * (t[1] - t[0]).cross(&(t[2] - t[0]));
                // Edge midpoints: exact for quadratics.
                for (p, q) in [(0, 1), (1, 2), (2, 0)] {
                    let hm = height(&((t[p] + t[q]) * 0.5));
                    s1 += area / 3.0 * hm;
                    s2 += area / 3.0 * hm * hm;
                }
                a += area;
            }
            let got = moments[i];
            assert!((got.area_m2 - a).abs() <= 1e-12 * a);
            // Within roundoff of 1, a planar surface's: 1.
            let coherence = vector_area.norm() / a;
            let coherence = if coherence >= 1.0 - ROUNDOFF_REL {
                1.0
            } else {
                coherence
            };
            assert!(
                (got.coherence - coherence).abs() < 1e-12,
                "node {i}: coherence {} vs {coherence}",
                got.coherence
            );
            assert!(got.coherence <= 1.0);
            if node.is_leaf() {
                assert_eq!((got.height_mean_m, got.height_var_m2), (0.0, 0.0));
                assert_eq!(fields[i].gradient, Matrix3x2::zeros());
                continue;
            }
            assert!((fields[i].centroid - first / a).norm() < 1e-12, "node {i}");
            let (mean, var) = (s1 / a, s2 / a - (s1 / a).powi(2));
            assert!(
                (got.height_mean_m - mean).abs() < 1e-12,
                "node {i}: {got:?} vs {mean}"
            );
            assert!(
                (got.height_var_m2 - var).abs() < 1e-12,
                "node {i}: {got:?} vs {var}"
            );
            // Every height lies within the deviation of the piece's plane.
            assert!(got.height_mean_m.abs() <= node.deviation + 1e-12);
            assert!(got.height_var_m2.sqrt() <= node.deviation + 1e-12);
        }
    }
}
