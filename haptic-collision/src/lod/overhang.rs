//! Where a node's piece overhangs the surface it stands for: per edge of the piece, the width of
//! the band along it outside which the piece is covered.
//!
//! A node's piece is the convex hull of its triangles flattened onto its plane (`build.rs`), so
//! where its surface is not convex in that plane (an annulus's inner arc, a jagged patch of a
//! tessellation) the piece spreads beyond it. Its cover `k` (`SurfaceMoments::cover`) says how
//! much, not where: a region over the piece counts `k` of its area, and where the region lies
//! mostly over the uncovered part its weight is off by far more than `w (1 − k)` (the cow resting
//! on a bowl's rim, its feet over the bowl's opening: `docs/experiments/
//! lod-accuracy-and-speed-probes.md`, probes 39 and 40).
//!
//! The build measures where, for a planar piece (its surface's normals agree: a flat face of a
//! part, a washer, a gear's side): for edge `i` of the piece (from corner `i` to corner `i + 1`),
//! a width `tᵢ` such that every point of the piece farther than `tᵢ` from every edge — the inner
//! polygon `P' = {x : fᵢ(x) > tᵢ ∀ i}`, `fᵢ` the distance inward from edge `i` — lies under the
//! surface, and the area `Uᵢ` of the band `{fᵢ ≤ tᵢ}` that no triangle lies over. The outline of
//! a planar surface is its boundary (the edges whose triangle across is not the node's, or not
//! there); the widths are raised until no boundary edge enters `P'` (each end to the band of its
//! nearest edge of the piece, then each edge that still crosses pushed out whole by the band
//! that needs the least widening), and then while a point of `P'` lies under no triangle (`P'`
//! in a hole of the surface, or between two parts of it), past that point. The uncovered part of
//! the piece then lies within `tᵢ` of edge `i` for some `i`, and the query bounds a region's
//! weight over it by the bands it reaches (`slab::pair_region_beside`, `refine.rs`).
//!
//! A curved piece is not measured (its widths and areas are infinite, and the query does not
//! read them): its deviation from its surface is mostly in height, which the regions' spread
//! terms count, and its cover is a ratio of areas rather than a share of the piece. Measured on
//! curved pieces too, the jaws' pieces of 8 to 512 triangles had bands a quarter to a half of
//! their extent wide (a tessellation's jagged outline, at a triangle's scale), and counting them
//! took a quarter more time a jaws query for no change in its error (probe 40).

use haptic_core::{Real, Vec3};

use super::MAX_PIECE_VERTICES;
use super::build::ROUNDOFF_REL;
use crate::mesh::TriMesh;

/// Marks "no triangle across this edge" in [`Across`].
const NONE: u32 = u32::MAX;

/// Most rounds of widening a band past a point of the inner polygon that lies under no
/// triangle (in a hole of the surface, or in a gap between its parts); beyond them the piece is
/// taken as overhanging anywhere (infinite widths).
const MAX_ROUNDS: usize = 64;

/// For each triangle of a mesh and each of its edges (edge `k` from corner `k` to corner
/// `k + 1`): the triangle across it, or none where the edge is the mesh's boundary or is shared
/// by more than two triangles.
#[derive(Debug, Clone)]
pub(super) struct Across(Vec<[u32; 3]>);

impl Across {
    /// The triangles across the edges of `mesh`'s triangles (shared vertex indices: STL corners
    /// are welded where exactly equal, `mesh/load.rs`).
    pub fn of(mesh: &TriMesh) -> Self {
        let tris = mesh.triangles();
        let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * tris.len());
        for (t, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let key = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
                edges.push((key, (t as u32) * 3 + k as u32));
            }
        }
        edges.sort_unstable();
        let mut across = vec![[NONE; 3]; tris.len()];
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j].0 == edges[i].0 {
                j += 1;
            }
            if j - i == 2 {
                let (e0, e1) = (edges[i].1, edges[i + 1].1);
                across[(e0 / 3) as usize][(e0 % 3) as usize] = e1 / 3;
                across[(e1 / 3) as usize][(e1 % 3) as usize] = e0 / 3;
            }
            i = j;
        }
        Self(across)
    }
}

/// Where a piece overhangs its surface along one of its edges.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Overhang {
    /// The width of the band along the edge outside which the piece lies under its surface
    /// (m; 0 or more, infinite where the piece may overhang anywhere).
    pub width_m: Real,
    /// The area of the band that no surface lies over (m²).
    pub area_m2: Real,
}

/// Scratch buffers reused between nodes.
#[derive(Debug, Default)]
pub(super) struct OverhangScratch {
    /// The outline's edges, flattened onto the piece's plane.
    segments: Vec<[[Real; 2]; 2]>,
}

/// What [`overhang_widths`] reads of a node.
pub(super) struct NodeSurface<'a> {
    /// The node's triangles (source indices).
    pub triangles: &'a [u32],
    /// By triangle (source index): its place in the order the nodes' ranges read.
    pub rank: &'a [u32],
    /// The node's range of places in that order: a triangle is the node's where its place is
    /// in it.
    pub range: (u32, u32),
    /// The in-plane basis `u`, `w` of the piece's 2-D corners.
    pub basis: (Vec3, Vec3),
    /// The origin of the 2-D coordinates.
    pub origin: Vec3,
}

/// The widths `tᵢ` (m) of the bands along the edges of the piece `hull` (2-D, counter-clockwise,
/// at least three corners; edge `i` from corner `i`) outside which the piece lies under the
/// node's surface (module docs), into `out[..hull.len()]`, and each band's uncovered area (m²)
/// into `uncovered[..hull.len()]`; every one infinite where the widths do not settle.
pub(super) fn overhang_widths(
    hull: &[[Real; 2]],
    node: &NodeSurface<'_>,
    tris: &[[Vec3; 3]],
    across: &Across,
    scratch: &mut OverhangScratch,
    out: &mut [Real; MAX_PIECE_VERTICES],
    uncovered: &mut [Real; MAX_PIECE_VERTICES],
) {
    let m = hull.len().min(MAX_PIECE_VERTICES);
    out.fill(0.0);
    uncovered.fill(0.0);
    if m < 3 {
        out.fill(Real::INFINITY);
        uncovered.fill(Real::INFINITY);
        return;
    }
    let (u, w) = node.basis;
    let flat = |p: &Vec3| {
        let d = p - node.origin;
        [u.dot(&d), w.dot(&d)]
    };
    // The inward unit normals of the edges and their offsets: `fᵢ(x) = nᵢ · x − cᵢ`.
    let mut walls = [[0.0; 3]; MAX_PIECE_VERTICES];
    let mut size: Real = 0.0;
    for (i, wall) in walls.iter_mut().enumerate().take(m) {
        let (p, q) = (hull[i], hull[(i + 1) % m]);
        let e = [q[0] - p[0], q[1] - p[1]];
        let len = (e[0] * e[0] + e[1] * e[1]).sqrt();
        size = size.max(len);
        *wall = if len > 0.0 {
            let normal = [-e[1] / len, e[0] / len];
            [normal[0], normal[1], normal[0] * p[0] + normal[1] * p[1]]
        } else {
            // A corner given twice bounds nothing: infinitely far from every point, it is never
            // the nearest edge nor cuts the inner polygon.
            [0.0, 0.0, Real::NEG_INFINITY]
        };
    }
    let f = |i: usize, x: &[Real; 2]| value(&walls[i], x);
    let tolerance = ROUNDOFF_REL * size;

    // The outline: the surface's boundary edges.
    scratch.segments.clear();
    for &t in node.triangles {
        let tri = &tris[t as usize];
        for (k, &other) in across.0[t as usize].iter().enumerate() {
            if other == NONE || !(node.range.0..node.range.1).contains(&node.rank[other as usize]) {
                scratch
                    .segments
                    .push([flat(&tri[k]), flat(&tri[(k + 1) % 3])]);
            }
        }
    }

    // Each end of an outline edge to the band of its nearest edge of the piece.
    let nearest = |x: &[Real; 2], t: &[Real; MAX_PIECE_VERTICES]| {
        (0..m)
            .map(|i| (f(i, x) - t[i], i))
            .fold((Real::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
    };
    for s in &scratch.segments {
        for x in s {
            let (depth, i) = nearest(x, out);
            if depth > 0.0 {
                out[i] += depth;
            }
        }
    }
    // Then each outline edge that still enters the inner polygon is pushed out of it whole, by
    // the band that needs the least widening to take it (the inner polygon only shrinks, so the
    // edges already pushed out stay out: one pass).
    for s in &scratch.segments {
        if let Some((a, b)) = part_inside(s, m, &f, out, tolerance) {
            let (raise, i) = (0..m)
                .map(|i| (f(i, &a).max(f(i, &b)) - out[i], i))
                .fold((Real::INFINITY, 0), |x, y| if y.0 < x.0 { y } else { x });
            out[i] += raise.max(tolerance);
        }
    }
    // No outline edge enters the inner polygon now, so it lies wholly under the surface or
    // wholly off it (in a hole of the surface, or a gap between its parts): one of its points
    // tells which. Off it, the band nearest that point is widened past it, and again.
    let mut settled = false;
    for _ in 0..MAX_ROUNDS {
        let Some(x) = inner_point(&hull[..m], &walls[..m], out) else {
            settled = true;
            break;
        };
        let under = node.triangles.iter().any(|&t| {
            let [a, b, c] = &tris[t as usize];
            in_triangle(&x, &flat(a), &flat(b), &flat(c))
        });
        if under {
            settled = true;
            break;
        }
        let (depth, i) = nearest(&x, out);
        out[i] += depth.max(tolerance);
    }
    if !settled {
        out.fill(Real::INFINITY);
        uncovered.fill(Real::INFINITY);
        return;
    }
    for t in &mut out[..m] {
        if *t <= tolerance {
            *t = 0.0;
        }
    }
    // The uncovered area of each band: its area in the piece less that of the triangles in it
    // (a planar surface does not lie over itself).
    for i in 0..m {
        let t = out[i];
        if t <= 0.0 {
            continue;
        }
        let mut planes = [[0.0; 3]; 1 + MAX_PIECE_VERTICES];
        planes[0] = [-walls[i][0], -walls[i][1], -walls[i][2] - t];
        planes[1..=m].copy_from_slice(&walls[..m]);
        let band_m2 = clipped_area(&hull[..m], &planes[..1]);
        let mut covered_m2 = 0.0;
        for &tri in node.triangles {
            let corners = tris[tri as usize].map(|p| flat(&p));
            if corners.iter().all(|c| f(i, c) >= t) {
                continue;
            }
            covered_m2 += clipped_area(&corners, &planes[..=m]);
        }
        uncovered[i] = (band_m2 - covered_m2).max(0.0);
    }
}

/// The part of segment `s` inside the open inner polygon `{fᵢ > tᵢ + tolerance}`, as its two
/// ends, if it has one.
fn part_inside(
    s: &[[Real; 2]; 2],
    m: usize,
    f: &impl Fn(usize, &[Real; 2]) -> Real,
    t: &[Real; MAX_PIECE_VERTICES],
    tolerance: Real,
) -> Option<([Real; 2], [Real; 2])> {
    let (mut lo, mut hi): (Real, Real) = (0.0, 1.0);
    for i in 0..m {
        let (a, b) = (
            f(i, &s[0]) - t[i] - tolerance,
            f(i, &s[1]) - t[i] - tolerance,
        );
        if a <= 0.0 && b <= 0.0 {
            return None;
        }
        // Inside where a + (b − a) λ > 0.
        if a <= 0.0 {
            lo = lo.max(-a / (b - a));
        } else if b <= 0.0 {
            hi = hi.min(a / (a - b));
        }
        if lo >= hi {
            return None;
        }
    }
    let at = |l: Real| {
        [
            s[0][0] + (s[1][0] - s[0][0]) * l,
            s[0][1] + (s[1][1] - s[0][1]) * l,
        ]
    };
    Some((at(lo), at(hi)))
}

/// `n · x − c` for the half-plane `[nx, ny, c]`: at least 0 on its side.
#[inline]
fn value(plane: &[Real; 3], x: &[Real; 2]) -> Real {
    plane[0] * x[0] + plane[1] * x[1] - plane[2]
}

/// Most corners of a polygon [`clip`] gives: a triangle or a piece, one more per plane.
const MAX_CLIPPED: usize = 2 * MAX_PIECE_VERTICES + 4;

/// A convex polygon of at most [`MAX_CLIPPED`] corners (2-D).
type Polygon = ([[Real; 2]; MAX_CLIPPED], usize);

/// The convex polygon `poly` where every half-plane of `planes` ([`value`]) is at least 0 (a
/// plane that leaves every corner inside cuts nothing and copies nothing).
fn clip(poly: &[[Real; 2]], planes: &[[Real; 3]]) -> Polygon {
    let mut first = [[0.0; 2]; MAX_CLIPPED];
    let mut second = [[0.0; 2]; MAX_CLIPPED];
    let mut k = poly.len().min(MAX_CLIPPED);
    first[..k].copy_from_slice(&poly[..k]);
    let (mut cur, mut next) = (&mut first, &mut second);
    for plane in planes {
        let mut values = [0.0; MAX_CLIPPED];
        let mut all_in = true;
        for (v, p) in values.iter_mut().zip(&cur[..k]) {
            *v = value(plane, p);
            all_in &= *v >= 0.0;
        }
        if all_in {
            continue;
        }
        let mut len = 0;
        for j in 0..k {
            let (p, q) = (cur[j], cur[(j + 1) % k]);
            let (vp, vq) = (values[j], values[(j + 1) % k]);
            if vp >= 0.0 && len < MAX_CLIPPED {
                next[len] = p;
                len += 1;
            }
            if (vp >= 0.0) != (vq >= 0.0) && len < MAX_CLIPPED {
                let l = vp / (vp - vq);
                next[len] = [p[0] + (q[0] - p[0]) * l, p[1] + (q[1] - p[1]) * l];
                len += 1;
            }
        }
        std::mem::swap(&mut cur, &mut next);
        k = len;
        if k < 3 {
            return (*cur, 0);
        }
    }
    (*cur, k)
}

/// The area (m²) of the convex polygon `poly` where every half-plane of `planes` is at least 0.
fn clipped_area(poly: &[[Real; 2]], planes: &[[Real; 3]]) -> Real {
    let (corners, k) = clip(poly, planes);
    let twice: Real = (0..k)
        .map(|j| {
            let (p, q) = (corners[j], corners[(j + 1) % k]);
            p[0] * q[1] - p[1] * q[0]
        })
        .sum();
    0.5 * twice.abs()
}

/// A point inside the inner polygon `{x ∈ hull : fᵢ(x) ≥ tᵢ}` (the mean of its corners, `fᵢ`
/// the distance from wall `i`, [`value`]), if it has an area.
fn inner_point(
    hull: &[[Real; 2]],
    walls: &[[Real; 3]],
    t: &[Real; MAX_PIECE_VERTICES],
) -> Option<[Real; 2]> {
    let mut planes = [[0.0; 3]; MAX_PIECE_VERTICES];
    let mut count = 0;
    for (wall, &t) in walls.iter().zip(t) {
        if t > 0.0 {
            planes[count] = [wall[0], wall[1], wall[2] + t];
            count += 1;
        }
    }
    let (corners, k) = clip(hull, &planes[..count]);
    if k < 3 {
        return None;
    }
    let n = k as Real;
    let c = corners[..k]
        .iter()
        .fold([0.0, 0.0], |c, p| [c[0] + p[0] / n, c[1] + p[1] / n]);
    // An area, not a sliver of roundoff.
    walls
        .iter()
        .zip(t)
        .all(|(wall, &t)| value(wall, &c) > t)
        .then_some(c)
}

/// Whether `x` lies in the 2-D triangle `abc` (either orientation; on its edges counts).
fn in_triangle(x: &[Real; 2], a: &[Real; 2], b: &[Real; 2], c: &[Real; 2]) -> bool {
    let cross = |o: &[Real; 2], p: &[Real; 2]| {
        (p[0] - o[0]) * (x[1] - o[1]) - (p[1] - o[1]) * (x[0] - o[0])
    };
    let (d0, d1, d2) = (cross(a, b), cross(b, c), cross(c, a));
    (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)
}

#[cfg(test)]
mod tests;
