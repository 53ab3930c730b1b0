//! Exact geometric primitives shared by the multiresolution back-end ([`crate::lod`]) and the
//! brute-force reference ([`crate::reference`]).
//!
//! Everything works on planar convex polygons given as counter-clockwise vertex lists (seen from
//! the side their unit normal points to); a triangle is a polygon of three vertices. The
//! triangle–triangle query ([`triangle_pair`]) is the exact leaf test of the hierarchy, and the
//! same routine on polygons of up to [`crate::lod::MAX_PIECE_VERTICES`] vertices gives the contacts
//! of the simplified convex pieces.
//!
//! Depth of an intersecting pair (our definition): the penetration depth of the two convex sets,
//! i.e. the length of the shortest translation that separates them, found by the separating-axis
//! theorem over every candidate axis (both normals, all edge–edge cross products, and each normal
//! crossed with the other polygon's edges, which covers coplanar pairs). The minimum over a
//! superset of the facet normals of the Minkowski difference is exactly the penetration depth.

use haptic_core::{Real, Vec3};

/// Closest point to `p` on the segment `[a, b]`, and its parameter in `[0, 1]`.
#[inline]
pub fn closest_point_on_segment(p: &Vec3, a: &Vec3, b: &Vec3) -> (Vec3, Real) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 <= 0.0 {
        return (*a, 0.0);
    }
    let t = ((p - a).dot(&ab) / len2).clamp(0.0, 1.0);
    (a + ab * t, t)
}

/// Closest points between the segments `[p1, q1]` and `[p2, q2]` (Ericson, *Real-Time Collision
/// Detection*, 5.1.9). Degenerate (zero-length) segments are handled as points.
#[inline]
pub fn closest_points_segments(p1: &Vec3, q1: &Vec3, p2: &Vec3, q2: &Vec3) -> (Vec3, Vec3) {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let tiny = Real::MIN_POSITIVE;
    let (s, t);
    if a <= tiny && e <= tiny {
        return (*p1, *p2);
    }
    if a <= tiny {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= tiny {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    (p1 + d1 * s, p2 + d2 * t)
}

/// Unit normal of the triangle `(a, b, c)` (counter-clockwise), or `None` if degenerate.
#[inline]
pub fn triangle_normal(tri: &[Vec3; 3]) -> Option<Vec3> {
    let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    let len = n.norm();
    (len > 0.0 && len.is_finite()).then(|| n / len)
}

/// Whether the projection of `p` on the plane of the convex polygon `poly` (unit normal `n`, CCW)
/// lies inside the polygon (boundary included).
#[inline]
fn inside_prism(p: &Vec3, poly: &[Vec3], n: &Vec3) -> bool {
    let m = poly.len();
    for i in 0..m {
        let a = &poly[i];
        let b = &poly[(i + 1) % m];
        if (b - a).cross(&(p - a)).dot(n) < 0.0 {
            return false;
        }
    }
    true
}

/// Closest point to `p` on the planar convex polygon `poly` (unit normal `n`, CCW).
pub fn closest_point_on_polygon(p: &Vec3, poly: &[Vec3], n: &Vec3) -> Vec3 {
    // One pass: `p` projects inside unless it lies outside some edge, and then the closest point
    // (unique, the polygon being convex) lies on an edge that `p` is outside of, so only those
    // edges are searched.
    let m = poly.len();
    let mut inside = true;
    let mut best = poly[0];
    let mut best_d2 = Real::INFINITY;
    for i in 0..m {
        let a = &poly[i];
        let b = &poly[if i + 1 == m { 0 } else { i + 1 }];
        let ab = b - a;
        let ap = p - a;
        if ab.cross(&ap).dot(n) < 0.0 {
            inside = false;
            let len2 = ab.norm_squared();
            let c = if len2 <= 0.0 {
                *a
            } else {
                a + ab * (ap.dot(&ab) / len2).clamp(0.0, 1.0)
            };
            let d2 = (c - p).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = c;
            }
        }
    }
    if inside {
        return p - n * n.dot(&(p - poly[0]));
    }
    best
}

/// Closest point to the 2-D point `p` on the convex counter-clockwise polygon `poly` (`p` itself
/// when inside): the 2-D form of [`closest_point_on_polygon`], with the same one-pass search.
#[inline]
pub fn closest_point_on_polygon_2d(p: [Real; 2], poly: &[[Real; 2]]) -> [Real; 2] {
    let m = poly.len();
    let mut inside = true;
    let (mut best, mut best_d2) = (p, Real::INFINITY);
    for (i, a) in poly.iter().enumerate() {
        let b = &poly[if i + 1 == m { 0 } else { i + 1 }];
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let (px, py) = (p[0] - a[0], p[1] - a[1]);
        if ex * py - ey * px < 0.0 {
            inside = false;
            let len2 = ex * ex + ey * ey;
            let t = if len2 > 0.0 {
                ((px * ex + py * ey) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let c = [a[0] + t * ex, a[1] + t * ey];
            let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
            if d2 < best_d2 {
                best_d2 = d2;
                best = c;
            }
        }
    }
    if inside { p } else { best }
}

/// Closest point to `p` on the triangle `tri` (any orientation; degenerate triangles are handled
/// through their edges).
pub fn closest_point_on_triangle(p: &Vec3, tri: &[Vec3; 3]) -> Vec3 {
    match triangle_normal(tri) {
        Some(n) => closest_point_on_polygon(p, tri, &n),
        None => {
            let mut best = tri[0];
            let mut best_d2 = Real::INFINITY;
            for i in 0..3 {
                let (c, _) = closest_point_on_segment(p, &tri[i], &tri[(i + 1) % 3]);
                let d2 = (c - p).norm_squared();
                if d2 < best_d2 {
                    best_d2 = d2;
                    best = c;
                }
            }
            best
        }
    }
}

/// Where the segment `[p, q]` crosses the planar convex polygon `poly` (unit normal `n`, CCW), if
/// it does. A segment lying in the polygon's plane is not reported (coplanar contact is found by
/// the distance tests).
#[inline]
pub fn segment_crosses_polygon(p: &Vec3, q: &Vec3, poly: &[Vec3], n: &Vec3) -> Option<Vec3> {
    let hp = n.dot(&(p - poly[0]));
    let hq = n.dot(&(q - poly[0]));
    if (hp > 0.0 && hq > 0.0) || (hp < 0.0 && hq < 0.0) || hp == hq {
        return None;
    }
    let t = hp / (hp - hq);
    let x = p + (q - p) * t;
    inside_prism(&x, poly, n).then_some(x)
}

/// Result of the exact query between two convex polygons `a` (tool side) and `b` (obstacle side).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairContact {
    /// Point on (or, when intersecting, half the depth beyond) `a`.
    pub p_a: Vec3,
    /// Point on (or, when intersecting, half the depth beyond) `b`.
    pub p_b: Vec3,
    /// Unit normal pointing out of `a`, towards `b`.
    pub n: Vec3,
    /// Penetration depth (m): the separating-axis penetration depth when the two intersect,
    /// minus the distance when apart. Always `p_a - p_b = depth · n`.
    pub depth: Real,
    /// Euclidean distance between the two sets (0 when they intersect or touch).
    pub distance: Real,
}

/// Separating-axis penetration depth of two intersecting convex polygons, and the axis (unit,
/// pointing from `a` towards `b`) along which translating `b` by the depth separates them.
pub fn sat_penetration(a: &[Vec3], na: &Vec3, b: &[Vec3], nb: &Vec3) -> (Real, Vec3) {
    let mut best = Real::INFINITY;
    let mut best_axis = *nb;
    // Scale of the edges, to reject near-parallel cross products.
    let mut test = |u: Vec3| {
        let len = u.norm();
        if len.is_nan() || len <= 0.0 {
            return;
        }
        let u = u / len;
        let (mut a0, mut a1) = (Real::INFINITY, Real::NEG_INFINITY);
        for v in a {
            let s = u.dot(v);
            a0 = a0.min(s);
            a1 = a1.max(s);
        }
        let (mut b0, mut b1) = (Real::INFINITY, Real::NEG_INFINITY);
        for v in b {
            let s = u.dot(v);
            b0 = b0.min(s);
            b1 = b1.max(s);
        }
        let plus = a1 - b0; // move b along +u
        let minus = b1 - a0; // move b along -u
        let (o, axis) = if plus <= minus {
            (plus, u)
        } else {
            (minus, -u)
        };
        if o < best {
            best = o;
            best_axis = axis;
        }
    };
    test(*na);
    test(*nb);
    let (ma, mb) = (a.len(), b.len());
    for i in 0..ma {
        let e = a[(i + 1) % ma] - a[i];
        let el = e.norm();
        test(na.cross(&e));
        for j in 0..mb {
            let f = b[(j + 1) % mb] - b[j];
            let c = e.cross(&f);
            // Near-parallel edges: the cross product is noise, skip it.
            if c.norm() > 1e-9 * el * f.norm() {
                test(c);
            }
        }
    }
    for j in 0..mb {
        let f = b[(j + 1) % mb] - b[j];
        test(nb.cross(&f));
    }
    (best.max(0.0), best_axis)
}

/// A point common to two planar convex polygons, if they cross: the mean of the points where an
/// edge of one passes through the other (the middle of the intersection segment for transversal
/// polygons). Polygons that only touch in a common plane are not reported.
#[inline]
pub fn crossing_witness(a: &[Vec3], na: &Vec3, b: &[Vec3], nb: &Vec3) -> Option<Vec3> {
    let mut cross_sum = Vec3::zeros();
    let mut crossings = 0u32;
    let (ma, mb) = (a.len(), b.len());
    for i in 0..ma {
        if let Some(x) = segment_crosses_polygon(&a[i], &a[(i + 1) % ma], b, nb) {
            cross_sum += x;
            crossings += 1;
        }
    }
    for j in 0..mb {
        if let Some(x) = segment_crosses_polygon(&b[j], &b[(j + 1) % mb], a, na) {
            cross_sum += x;
            crossings += 1;
        }
    }
    (crossings > 0).then(|| cross_sum / crossings as Real)
}

/// Exact closest points / penetration between two planar convex polygons (`a` with unit normal
/// `na`, `b` with `nb`, both CCW about their normals).
pub fn convex_polygon_pair(a: &[Vec3], na: &Vec3, b: &[Vec3], nb: &Vec3) -> PairContact {
    let witness = if let Some(x) = crossing_witness(a, na, b, nb) {
        Some(x)
    } else {
        let (pa, pb) = closest_points_below(a, na, b, nb, Real::INFINITY).unwrap_or((a[0], b[0]));
        if let Some(pc) = apart(pa, pb) {
            return pc;
        }
        // A zero or non-finite distance falls through to the touching case.
        Some((pa + pb) * 0.5)
    };
    let w = witness.unwrap_or(a[0]);
    let (depth, n) = sat_penetration(a, na, b, nb);
    PairContact {
        p_a: w + n * (0.5 * depth),
        p_b: w - n * (0.5 * depth),
        n,
        depth,
        distance: 0.0,
    }
}

/// The closest points `(on a, on b)` of two planar convex polygons that do not cross (`a` with
/// unit normal `na`, `b` with `nb`), where they are nearer than `limit_m` (m): the nearest of
/// the vertex–polygon and edge–edge candidates, each skipped where a lower bound (its plane
/// distance, or the balls about the two edges) is already no nearer than the best so far, so
/// that a limit only saves work. `None` where no candidate is nearer than the limit. Polygons
/// either of which lies wholly on one side of the other's plane, at a positive distance from
/// it, do not cross; [`apart`] makes the pair result.
pub fn closest_points_below(
    a: &[Vec3],
    na: &Vec3,
    b: &[Vec3],
    nb: &Vec3,
    limit_m: Real,
) -> Option<(Vec3, Vec3)> {
    let (ma, mb) = (a.len(), b.len());
    let mut best_d2 = limit_m * limit_m;
    let mut closest = None;
    if let Some((v, c)) = nearest_vertex(a, b, nb, &mut best_d2) {
        closest = Some((v, c));
    }
    if let Some((v, c)) = nearest_vertex(b, a, na, &mut best_d2) {
        closest = Some((c, v));
    }
    for i in 0..ma {
        let (a0, a1) = (&a[i], &a[(i + 1) % ma]);
        let mid_a = (a0 + a1) * 0.5;
        let half_a = 0.5 * (a1 - a0).norm();
        for j in 0..mb {
            let (b0, b1) = (&b[j], &b[(j + 1) % mb]);
            // Cheap lower bound: the edges lie in balls about their midpoints.
            let lower = (mid_a - (b0 + b1) * 0.5).norm() - half_a - 0.5 * (b1 - b0).norm();
            if lower > 0.0 && lower * lower >= best_d2 {
                continue;
            }
            let (c1, c2) = closest_points_segments(a0, a1, b0, b1);
            let d2 = (c2 - c1).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                closest = Some((c1, c2));
            }
        }
    }
    closest
}

/// The vertex of `from` nearest the polygon `onto` (unit normal `n`) and its closest point
/// there, where nearer than `√best_d2`, which it then lowers; each vertex skipped where its
/// plane distance, a lower bound, is already no nearer.
fn nearest_vertex(
    from: &[Vec3],
    onto: &[Vec3],
    n: &Vec3,
    best_d2: &mut Real,
) -> Option<(Vec3, Vec3)> {
    let mut found = None;
    for v in from {
        let h = n.dot(&(v - onto[0]));
        if h * h >= *best_d2 {
            continue;
        }
        let c = closest_point_on_polygon(v, onto, n);
        let d2 = (c - v).norm_squared();
        if d2 < *best_d2 {
            *best_d2 = d2;
            found = Some((*v, c));
        }
    }
    found
}

/// The pair result of polygons apart with the closest points `pa` (on the first) and `pb`:
/// distance and normal from their difference; `None` where that is zero or not finite.
pub fn apart(pa: Vec3, pb: Vec3) -> Option<PairContact> {
    let gap = pb - pa;
    let dist = gap.norm();
    (dist > 0.0 && dist.is_finite()).then(|| PairContact {
        p_a: pa,
        p_b: pb,
        n: gap / dist,
        depth: -dist,
        distance: dist,
    })
}

/// Exact query between two triangles (tool triangle `a`, obstacle triangle `b`) with their unit
/// normals; see [`convex_polygon_pair`] for the result and the depth definition.
#[inline]
pub fn triangle_pair(a: &[Vec3; 3], na: &Vec3, b: &[Vec3; 3], nb: &Vec3) -> PairContact {
    convex_polygon_pair(a, na, b, nb)
}

/// Distance from `p` to the planar convex polygon `poly` (unit normal `n`, CCW).
#[inline]
pub fn point_polygon_distance(p: &Vec3, poly: &[Vec3], n: &Vec3) -> Real {
    (closest_point_on_polygon(p, poly, n) - p).norm()
}

/// Two unit vectors `u, w` with `u × w = n`, the same for the same `n` in every build: the
/// hierarchy's normal fields are stored in this basis (`lod/moments.rs`), so it must not change
/// without the hierarchy file's format version. See [`any_plane_basis`] for a faster one.
pub(crate) fn plane_basis(n: &Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.6 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let u = n.cross(&helper).normalize();
    let w = n.cross(&u);
    (u, w)
}

/// Two unit vectors `u, w` with `u × w = n` for a unit `n`, without a square root or a branch
/// on the axes: Duff et al., "Building an orthonormal basis, revisited" (JCGT 6(1), 2017). For
/// what does not depend on the basis (a polygon's clip and integrals in its plane, `slab.rs`);
/// quantities stored in a basis use [`plane_basis`].
#[inline]
pub(crate) fn any_plane_basis(n: &Vec3) -> (Vec3, Vec3) {
    let sign = 1.0_f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Both bases are orthonormal and right-handed about any unit normal, the poles and
        /// the axes included.
        #[test]
        fn both_plane_bases_are_right_handed_and_orthonormal(
            x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64, axis in 0usize..7,
        ) {
            let n = match axis {
                0 => Vec3::new(0.0, 0.0, 1.0),
                1 => Vec3::new(0.0, 0.0, -1.0),
                2 => Vec3::new(1.0, 0.0, 0.0),
                3 => Vec3::new(0.0, -1.0, 0.0),
                4 => Vec3::new(1e-12, 0.0, -1.0).normalize(),
                _ => Vec3::new(x, y, z),
            };
            prop_assume!(n.norm() > 1e-3);
            let n = n.normalize();
            for (u, w) in [plane_basis(&n), any_plane_basis(&n)] {
                prop_assert!((u.norm() - 1.0).abs() < 1e-12 && (w.norm() - 1.0).abs() < 1e-12);
                prop_assert!(u.dot(&w).abs() < 1e-12 && u.dot(&n).abs() < 1e-12);
                prop_assert!((u.cross(&w) - n).norm() < 1e-12);
            }
        }
    }

    fn tri(a: [Real; 3], b: [Real; 3], c: [Real; 3]) -> [Vec3; 3] {
        [Vec3::from(a), Vec3::from(b), Vec3::from(c)]
    }

    /// Dense sampling of a triangle (barycentric grid).
    fn samples(t: &[Vec3; 3], k: usize) -> Vec<Vec3> {
        let mut out = Vec::new();
        for i in 0..=k {
            for j in 0..=(k - i) {
                let (u, v) = (i as Real / k as Real, j as Real / k as Real);
                out.push(t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v);
            }
        }
        out
    }

    fn arb_point() -> impl Strategy<Value = Vec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    fn arb_tri() -> impl Strategy<Value = [Vec3; 3]> {
        (arb_point(), arb_point(), arb_point())
            .prop_filter("non-degenerate", |(a, b, c)| {
                (b - a).cross(&(c - a)).norm() > 1e-3
            })
            .prop_map(|(a, b, c)| [a, b, c])
    }

    #[test]
    fn segment_closest_points_known_cases() {
        // Crossing segments.
        let (c1, c2) = closest_points_segments(
            &Vec3::new(-1.0, 0.0, 0.0),
            &Vec3::new(1.0, 0.0, 0.0),
            &Vec3::new(0.0, -1.0, 1.0),
            &Vec3::new(0.0, 1.0, 1.0),
        );
        assert!((c1 - Vec3::zeros()).norm() < 1e-15);
        assert!((c2 - Vec3::new(0.0, 0.0, 1.0)).norm() < 1e-15);
        // Parallel segments, overlapping in projection.
        let (c1, c2) = closest_points_segments(
            &Vec3::new(0.0, 0.0, 0.0),
            &Vec3::new(2.0, 0.0, 0.0),
            &Vec3::new(1.0, 1.0, 0.0),
            &Vec3::new(3.0, 1.0, 0.0),
        );
        assert!(((c1 - c2).norm() - 1.0).abs() < 1e-15);
        // A point against a segment.
        let p = Vec3::new(0.5, 2.0, 0.0);
        let (c1, c2) = closest_points_segments(&p, &p, &Vec3::zeros(), &Vec3::x());
        assert_eq!(c1, p);
        assert!((c2 - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn separated_triangles_distance_and_normal() {
        let a = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let b = tri([0.0, 0.0, 0.5], [0.0, 1.0, 0.5], [1.0, 0.0, 0.5]);
        let na = triangle_normal(&a).unwrap();
        let nb = triangle_normal(&b).unwrap();
        let c = triangle_pair(&a, &na, &b, &nb);
        assert!((c.distance - 0.5).abs() < 1e-15);
        assert!((c.depth + 0.5).abs() < 1e-15);
        assert!((c.n - Vec3::z()).norm() < 1e-12);
        assert!((c.p_a - c.p_b - c.n * c.depth).norm() < 1e-15);
    }

    #[test]
    fn crossing_witness_lies_in_both_or_is_absent() {
        let a = tri([-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]);
        let na = triangle_normal(&a).unwrap();
        // A vertical triangle through the middle of `a`.
        let b = tri([0.0, -0.5, -1.0], [0.0, 0.5, -1.0], [0.0, 0.0, 1.0]);
        let nb = triangle_normal(&b).unwrap();
        let x = crossing_witness(&a, &na, &b, &nb).expect("they cross");
        assert!(x.z.abs() < 1e-12 && x.x.abs() < 1e-12, "{x:?}");
        assert!(closest_point_on_triangle(&x, &a).metric_distance(&x) < 1e-12);
        assert!(closest_point_on_triangle(&x, &b).metric_distance(&x) < 1e-12);
        // Lifted above `a`: no crossing.
        let lifted = b.map(|v| v + Vec3::new(0.0, 0.0, 1.5));
        assert!(crossing_witness(&a, &na, &lifted, &nb).is_none());
    }

    #[test]
    fn crossing_triangles_have_sat_depth() {
        // a lies in z = 0; b is vertical and pokes 0.1 below z = 0 through a's interior.
        let a = tri([-1.0, -1.0, 0.0], [2.0, -1.0, 0.0], [-1.0, 2.0, 0.0]);
        let b = tri([0.0, -0.2, -0.1], [0.0, 0.2, -0.1], [0.0, 0.0, 1.0]);
        let na = triangle_normal(&a).unwrap();
        let nb = triangle_normal(&b).unwrap();
        let c = triangle_pair(&a, &na, &b, &nb);
        assert_eq!(c.distance, 0.0);
        // Shortest separation: push b up by 0.1 (out of a, along +z).
        assert!((c.depth - 0.1).abs() < 1e-12, "{c:?}");
        assert!((c.n - Vec3::z()).norm() < 1e-12);
        assert!((c.p_a - c.p_b - c.n * c.depth).norm() < 1e-14);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        #[test]
        fn point_triangle_is_closest(t in arb_tri(), p in arb_point()) {
            let c = closest_point_on_triangle(&p, &t);
            let d = (c - p).norm();
            for s in samples(&t, 12) {
                prop_assert!(d <= (s - p).norm() + 1e-12);
            }
            // c is on the triangle: distance from c to the triangle is 0.
            let back = closest_point_on_triangle(&c, &t);
            prop_assert!((back - c).norm() < 1e-12);
        }

        #[test]
        fn triangle_pair_distance_is_minimal(a in arb_tri(), b in arb_tri()) {
            let na = triangle_normal(&a).unwrap();
            let nb = triangle_normal(&b).unwrap();
            let c = triangle_pair(&a, &na, &b, &nb);
            prop_assert!((c.n.norm() - 1.0).abs() < 1e-9);
            prop_assert!((c.p_a - c.p_b - c.n * c.depth).norm() < 1e-12);
            if c.distance > 0.0 {
                // Witness points lie on the triangles and realise the distance.
                prop_assert!((closest_point_on_triangle(&c.p_a, &a) - c.p_a).norm() < 1e-12);
                prop_assert!((closest_point_on_triangle(&c.p_b, &b) - c.p_b).norm() < 1e-12);
                let sa = samples(&a, 10);
                for s in &sa {
                    let q = closest_point_on_triangle(s, &b);
                    prop_assert!(c.distance <= (q - s).norm() + 1e-12);
                }
            } else {
                // Intersecting: translating b by depth along n separates (up to rounding).
                let shift = c.n * (c.depth + 1e-9);
                let moved = [b[0] + shift, b[1] + shift, b[2] + shift];
                let after = triangle_pair(&a, &na, &moved, &nb);
                prop_assert!(after.distance > 0.0, "{c:?} {after:?}");
                prop_assert!(c.depth >= 0.0);
            }
        }

        /// Below a limit, the bounded search finds the same closest points as the whole pair
        /// where the triangles are apart, and nothing where they are no nearer than the limit.
        #[test]
        fn the_bounded_search_is_the_pair_below_its_limit(
            a in arb_tri(),
            b in arb_tri(),
            limit in 0.0..3.0f64,
        ) {
            let na = triangle_normal(&a).unwrap();
            let nb = triangle_normal(&b).unwrap();
            let c = triangle_pair(&a, &na, &b, &nb);
            prop_assume!(c.distance > 0.0);
            let below = closest_points_below(&a, &na, &b, &nb, limit).and_then(|(p, q)| apart(p, q));
            if c.distance < limit {
                prop_assert_eq!(below, Some(c));
            } else {
                prop_assert!(below.is_none(), "{below:?} at {} against {limit}", c.distance);
            }
        }

        #[test]
        fn sat_depth_is_the_shortest_separation(
            a in arb_tri(),
            b0 in arb_tri(),
            (u, v) in (0.0..0.5f64, 0.0..0.5f64),
            dir in arb_point(),
        ) {
            // Place b so that its centroid lies on a point of a: the two intersect.
            let on_a = a[0] + (a[1] - a[0]) * u + (a[2] - a[0]) * v;
            let shift0 = on_a - (b0[0] + b0[1] + b0[2]) / 3.0;
            let b = [b0[0] + shift0, b0[1] + shift0, b0[2] + shift0];
            let na = triangle_normal(&a).unwrap();
            let nb = triangle_normal(&b).unwrap();
            let c = triangle_pair(&a, &na, &b, &nb);
            prop_assert_eq!(c.distance, 0.0);
            prop_assume!(dir.norm() > 1e-3);
            // No translation of b shorter than the depth separates the triangles.
            let u = dir.normalize();
            let shift = u * (c.depth * (1.0 - 1e-6) - 1e-12).max(0.0);
            let moved = [b[0] + shift, b[1] + shift, b[2] + shift];
            let after = triangle_pair(&a, &na, &moved, &nb);
            prop_assert!(after.distance < 1e-9, "{c:?} {after:?}");
        }
    }
}
