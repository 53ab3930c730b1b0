//! Preprocessing: one hierarchy per mesh that is both a bounding-volume hierarchy and a
//! level-of-detail hierarchy (after Otaduy & Lin 2003, adapted; see `docs/decisions.md`).
//!
//! The tree is binary, built top-down by splitting the triangles at the median centroid along the
//! longest axis; every leaf holds one triangle. Every node carries
//! - a bounding sphere and a bounding slab (a plane with a half-thickness) of the triangles below
//!   it, both in the mesh frame and both conservative (used for culling);
//! - its simplified convex piece: a planar convex polygon of at most
//!   [`MAX_PIECE_VERTICES`](super::MAX_PIECE_VERTICES) vertices in the slab's mid-plane (a leaf's
//!   piece is its triangle);
//! - the piece's surface deviation `s`: an upper bound on the two-sided Hausdorff distance
//!   between the piece and the node's triangles.

use std::time::Instant;

use haptic_core::{Real, Vec3};

use super::MAX_PIECE_VERTICES;
use crate::geometry::{point_polygon_distance, triangle_normal};
use crate::mesh::TriMesh;

/// Marks "no right child" (a leaf).
pub(crate) const LEAF: u32 = u32::MAX;

/// One node of the hierarchy (mesh frame, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Node {
    /// Centre of the bounding sphere.
    pub center: Vec3,
    /// Radius of the bounding sphere.
    pub radius: Real,
    /// Unit normal of the bounding slab and of the piece's plane.
    pub normal: Vec3,
    /// A point of the slab's mid-plane (the piece's plane).
    pub plane_point: Vec3,
    /// Half-thickness of the slab: every point below the node is within this of the mid-plane.
    pub half_thickness: Real,
    /// Surface deviation `s` of the piece (m); infinite when the node has no usable piece.
    pub deviation: Real,
    /// Index of the right child, or [`LEAF`]; the left child is the next node.
    pub right: u32,
    /// For a leaf: index of its triangle in the source mesh.
    pub triangle: u32,
    /// First vertex of the piece in [`Hierarchy::piece`].
    pub piece_start: u32,
    /// Number of vertices of the piece (0 when there is none).
    pub piece_len: u32,
}

impl Node {
    /// Whether the node is a leaf (one triangle).
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.right == LEAF
    }
}

/// The hierarchy of one mesh: a bounding-volume hierarchy whose nodes also carry simplified convex
/// pieces and their surface deviation (the contact levels of detail).
#[derive(Debug, Clone)]
pub struct Hierarchy {
    pub(crate) nodes: Vec<Node>,
    pub(crate) piece: Vec<Vec3>,
    radius_about_origin_m: Real,
    triangle_count: usize,
    height: usize,
    build_s: Real,
}

/// A small convex polygon in a node's plane (2-D, fixed capacity, CCW).
#[derive(Debug, Clone, Copy)]
struct Poly2 {
    pts: [[Real; 2]; POLY2_CAP],
    len: usize,
}

/// Capacity of [`Poly2`]: a hexagon clipped by two hexagons' half-planes stays far below it.
const POLY2_CAP: usize = 24;

impl Default for Poly2 {
    fn default() -> Self {
        Self {
            pts: [[0.0; 2]; POLY2_CAP],
            len: 0,
        }
    }
}

impl Poly2 {
    fn from_slice(p: &[[Real; 2]]) -> Self {
        let mut out = Self::default();
        for v in p {
            out.push(*v);
        }
        out
    }

    fn push(&mut self, p: [Real; 2]) {
        if self.len < POLY2_CAP {
            self.pts[self.len] = p;
            self.len += 1;
        }
    }

    fn as_slice(&self) -> &[[Real; 2]] {
        &self.pts[..self.len]
    }

    fn signed_area(&self) -> Real {
        let mut a = 0.0;
        for i in 0..self.len {
            let (p, q) = (self.pts[i], self.pts[(i + 1) % self.len]);
            a += p[0] * q[1] - p[1] * q[0];
        }
        0.5 * a
    }

    fn reverse(&mut self) {
        self.pts[..self.len].reverse();
    }

    /// The part on the left of the directed line `a → b` (closed half-plane).
    fn clip(&self, a: &[Real; 2], b: &[Real; 2]) -> Self {
        let side = |p: &[Real; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let mut out = Self::default();
        for i in 0..self.len {
            let (p, q) = (self.pts[i], self.pts[(i + 1) % self.len]);
            let (sp, sq) = (side(&p), side(&q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp > 0.0 && sq < 0.0) || (sp < 0.0 && sq > 0.0) {
                let t = sp / (sp - sq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
        out
    }
}

/// Scratch buffers reused while building.
#[derive(Default)]
struct Scratch {
    pts: Vec<[Real; 2]>,
    heights: Vec<Real>,
    hull: Vec<[Real; 2]>,
}

impl Hierarchy {
    /// Builds the hierarchy of `mesh` (mesh frame).
    pub fn build(mesh: &TriMesh) -> Self {
        let start = Instant::now();
        let tris: Vec<[Vec3; 3]> = (0..mesh.triangles().len())
            .map(|t| mesh.triangle(t))
            .collect();
        let n = tris.len();
        let centroids: Vec<Vec3> = tris.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let mut perm: Vec<u32> = (0..n as u32).collect();
        let mut nodes: Vec<Node> = Vec::with_capacity(2 * n);
        let mut ranges: Vec<(u32, u32)> = Vec::with_capacity(2 * n);
        // Topology, in depth-first pre-order: children come after their parent.
        let mut todo: Vec<(u32, u32, Option<usize>, usize)> = vec![(0, n as u32, None, 1)];
        let mut height = 0;
        while let Some((lo, hi, parent, level)) = todo.pop() {
            height = height.max(level);
            let index = nodes.len();
            if let Some(p) = parent {
                nodes[p].right = index as u32;
            }
            nodes.push(Node {
                center: Vec3::zeros(),
                radius: 0.0,
                normal: Vec3::z(),
                plane_point: Vec3::zeros(),
                half_thickness: 0.0,
                deviation: 0.0,
                right: LEAF,
                triangle: perm[lo as usize],
                piece_start: 0,
                piece_len: 0,
            });
            ranges.push((lo, hi));
            if hi - lo > 1 {
                let slice = &mut perm[lo as usize..hi as usize];
                let (mut bmin, mut bmax) =
                    (Vec3::repeat(Real::INFINITY), Vec3::repeat(-Real::INFINITY));
                for &t in slice.iter() {
                    bmin = bmin.inf(&centroids[t as usize]);
                    bmax = bmax.sup(&centroids[t as usize]);
                }
                let axis = (bmax - bmin).imax();
                let mid = slice.len() / 2;
                slice.select_nth_unstable_by(mid, |&a, &b| {
                    centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
                });
                let m = lo + mid as u32;
                // Right is processed after left (stack): push right first, remember the parent.
                todo.push((m, hi, Some(index), level + 1));
                todo.push((lo, m, None, level + 1));
            }
        }
        let mut piece: Vec<Vec3> = Vec::with_capacity(nodes.len() * 4);
        let mut scratch = Scratch::default();
        // Pieces bottom-up: a parent's deviation bound uses its children's pieces.
        let mut piece_at: Vec<(u32, u32)> = vec![(0, 0); nodes.len()];
        let mut local: Vec<Vec3> = Vec::with_capacity(MAX_PIECE_VERTICES);
        for index in (0..nodes.len()).rev() {
            let (lo, hi) = ranges[index];
            let node_tris = &perm[lo as usize..hi as usize];
            local.clear();
            let mut node = nodes[index];
            if node.is_leaf() {
                let t = &tris[node.triangle as usize];
                fill_bounds(&mut node, node_tris, &tris);
                node.normal = triangle_normal(t).unwrap_or_else(Vec3::z);
                node.plane_point = t[0];
                node.half_thickness = 0.0;
                node.deviation = 0.0;
                local.extend_from_slice(t);
            } else {
                fill_bounds(&mut node, node_tris, &tris);
                let children = [index + 1, node.right as usize];
                let child_info: [(Node, &[Vec3]); 2] = children.map(|c| {
                    let (s, l) = piece_at[c];
                    (nodes[c], &piece[s as usize..(s + l) as usize])
                });
                fill_piece(
                    &mut node,
                    node_tris,
                    &tris,
                    &child_info,
                    &mut scratch,
                    &mut local,
                );
            }
            piece_at[index] = (piece.len() as u32, local.len() as u32);
            node.piece_start = piece.len() as u32;
            node.piece_len = local.len() as u32;
            piece.extend_from_slice(&local);
            nodes[index] = node;
        }
        let radius_about_origin_m = mesh
            .vertices()
            .iter()
            .map(|v| v.norm())
            .fold(0.0, Real::max);
        Self {
            nodes,
            piece,
            radius_about_origin_m,
            triangle_count: n,
            height,
            build_s: start.elapsed().as_secs_f64(),
        }
    }

    /// Number of nodes (`2 n − 1` for `n` triangles).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Radius (m) of the sphere about the mesh frame's origin that encloses the mesh.
    pub fn radius_about_origin_m(&self) -> Real {
        self.radius_about_origin_m
    }

    /// Levels of the tree (1 for a single triangle).
    pub fn height(&self) -> usize {
        self.height
    }

    /// Wall-clock time the build took (s).
    pub fn build_s(&self) -> Real {
        self.build_s
    }

    /// Heap memory held by the hierarchy (bytes).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.piece.capacity() * std::mem::size_of::<Vec3>()
    }

    /// The piece of node `i` (vertices CCW about the node normal).
    #[inline]
    pub(crate) fn piece_of(&self, node: &Node) -> &[Vec3] {
        &self.piece[node.piece_start as usize..(node.piece_start + node.piece_len) as usize]
    }
}

/// Bounding sphere (centre of the corners' box, radius to the farthest corner).
fn fill_bounds(node: &mut Node, node_tris: &[u32], tris: &[[Vec3; 3]]) {
    let (mut bmin, mut bmax) = (Vec3::repeat(Real::INFINITY), Vec3::repeat(-Real::INFINITY));
    for &t in node_tris {
        for v in &tris[t as usize] {
            bmin = bmin.inf(v);
            bmax = bmax.sup(v);
        }
    }
    let c = (bmin + bmax) * 0.5;
    let mut r2: Real = 0.0;
    for &t in node_tris {
        for v in &tris[t as usize] {
            r2 = r2.max((v - c).norm_squared());
        }
    }
    node.center = c;
    // A hair of slack so that rounding in the distance tests never culls a touching pair.
    node.radius = r2.sqrt() * (1.0 + 1e-12);
}

/// Two unit vectors `u, w` with `u × w = n`.
fn plane_basis(n: &Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.6 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let u = n.cross(&helper).normalize();
    let w = n.cross(&u);
    (u, w)
}

/// 2-D convex hull (Andrew's monotone chain), counter-clockwise, without collinear points.
fn convex_hull_2d(pts: &mut [[Real; 2]], hull: &mut Vec<[Real; 2]>) {
    hull.clear();
    pts.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: &[Real; 2], a: &[Real; 2], b: &[Real; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    for p in pts.iter() {
        while hull.len() >= 2 && cross(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(*p);
    }
    let lower = hull.len() + 1;
    for p in pts.iter().rev().skip(1) {
        while hull.len() >= lower && cross(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(*p);
    }
    hull.pop();
}

/// Reduces a convex polygon to at most `max` vertices by repeatedly dropping the vertex whose
/// removal loses the least area (the result is inside the original polygon).
fn reduce_polygon(hull: &mut Vec<[Real; 2]>, max: usize) {
    while hull.len() > max {
        let m = hull.len();
        let mut best = 0;
        let mut best_area = Real::INFINITY;
        for i in 0..m {
            let a = hull[(i + m - 1) % m];
            let b = hull[i];
            let c = hull[(i + 1) % m];
            let area = ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs();
            if area < best_area {
                best_area = area;
                best = i;
            }
        }
        hull.remove(best);
    }
}

/// Distance from a 2-D point to a convex CCW polygon (0 inside).
pub(crate) fn dist_to_polygon_2d(p: [Real; 2], poly: &[[Real; 2]]) -> Real {
    let m = poly.len();
    let mut inside = true;
    let mut best2 = Real::INFINITY;
    for i in 0..m {
        let a = poly[i];
        let b = poly[(i + 1) % m];
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let (px, py) = (p[0] - a[0], p[1] - a[1]);
        if ex * py - ey * px < 0.0 {
            inside = false;
        }
        let len2 = ex * ex + ey * ey;
        let t = if len2 > 0.0 {
            ((px * ex + py * ey) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (dx, dy) = (px - t * ex, py - t * ey);
        best2 = best2.min(dx * dx + dy * dy);
    }
    if inside { 0.0 } else { best2.sqrt() }
}

/// Plane, slab, piece and deviation of an inner node.
fn fill_piece(
    node: &mut Node,
    node_tris: &[u32],
    tris: &[[Vec3; 3]],
    children: &[(Node, &[Vec3]); 2],
    scratch: &mut Scratch,
    local: &mut Vec<Vec3>,
) {
    // Area-weighted mean normal; fall back to the thinnest axis of the box.
    let mut nsum = Vec3::zeros();
    let mut asum = 0.0;
    for &t in node_tris {
        let [a, b, c] = tris[t as usize];
        let cr = (b - a).cross(&(c - a));
        asum += cr.norm();
        nsum += cr;
    }
    let n = if nsum.norm() > 1e-9 * asum && nsum.norm() > 0.0 {
        nsum.normalize()
    } else {
        let (mut bmin, mut bmax) = (Vec3::repeat(Real::INFINITY), Vec3::repeat(-Real::INFINITY));
        for &t in node_tris {
            for v in &tris[t as usize] {
                bmin = bmin.inf(v);
                bmax = bmax.sup(v);
            }
        }
        let mut axis = Vec3::zeros();
        axis[(bmax - bmin).imin()] = 1.0;
        axis
    };
    let (u, w) = plane_basis(&n);
    let o = node.center;
    scratch.pts.clear();
    scratch.heights.clear();
    let (mut hmin, mut hmax) = (Real::INFINITY, Real::NEG_INFINITY);
    for &t in node_tris {
        for v in &tris[t as usize] {
            let d = v - o;
            let h = n.dot(&d);
            hmin = hmin.min(h);
            hmax = hmax.max(h);
            scratch.heights.push(h);
            scratch.pts.push([u.dot(&d), w.dot(&d)]);
        }
    }
    let hmid = 0.5 * (hmin + hmax);
    node.normal = n;
    node.plane_point = o + n * hmid;
    node.half_thickness = 0.5 * (hmax - hmin) * (1.0 + 1e-12) + 1e-15 * node.radius;
    // Rigorous fallback: piece and surface both lie within √2 r and r of the sphere centre.
    let cap = (1.0 + std::f64::consts::SQRT_2) * node.radius;

    let mut sorted = std::mem::take(&mut scratch.pts);
    let mut hull = std::mem::take(&mut scratch.hull);
    // Keep the unsorted projections for the deviation below.
    let unsorted = sorted.clone();
    convex_hull_2d(&mut sorted, &mut hull);
    scratch.pts = sorted;
    if hull.len() < 3 {
        node.deviation = Real::INFINITY;
        scratch.hull = hull;
        return;
    }
    reduce_polygon(&mut hull, MAX_PIECE_VERTICES);
    local.extend(hull.iter().map(|p| node.plane_point + u * p[0] + w * p[1]));

    // Surface → piece: distance to a convex set is convex, so the corners bound every point of
    // the triangles.
    let mut s_out: Real = 0.0;
    for (p, h) in unsorted.iter().zip(scratch.heights.iter()) {
        let dh = h - hmid;
        let d2 = dist_to_polygon_2d(*p, &hull);
        s_out = s_out.max((dh * dh + d2 * d2).sqrt());
    }
    // Piece → surface. For q on the piece and either child c, dist(q, S) <= dist(q, piece_c) + s_c
    // and dist(q, S) <= |q − centre_c| + r_c. Each of these four terms is convex in q, so on a
    // convex region its maximum is at a vertex, and min over terms of (max over the vertices)
    // bounds the surface distance on the region. The polygon is cut into convex regions along the
    // children's pieces projected on its plane: the parts above each child piece (where that
    // child's term is about the height gap) and the uncovered rest.
    let terms = |p: &[Real; 2]| -> [Real; 4] {
        let q = node.plane_point + u * p[0] + w * p[1];
        let mut t = [Real::INFINITY; 4];
        for (k, (c, poly)) in children.iter().enumerate() {
            t[2 * k] = (q - c.center).norm() + c.radius;
            if c.deviation.is_finite() && !poly.is_empty() {
                t[2 * k + 1] = point_polygon_distance(&q, poly, &c.normal) + c.deviation;
            }
        }
        t
    };
    let region_bound = |r: &Poly2| -> Real {
        if r.len == 0 {
            return 0.0;
        }
        let mut worst = [Real::NEG_INFINITY; 4];
        for p in r.as_slice() {
            let t = terms(p);
            for k in 0..4 {
                worst[k] = worst[k].max(t[k]);
            }
        }
        worst.iter().copied().fold(Real::INFINITY, Real::min)
    };
    let to2 = |v: &Vec3| -> [Real; 2] {
        let d = v - o;
        [u.dot(&d), w.dot(&d)]
    };
    let q_poly = Poly2::from_slice(&hull);
    let projected: [Option<Poly2>; 2] = [0, 1].map(|k| {
        let (c, poly) = &children[k];
        if !c.deviation.is_finite() || poly.len() < 3 {
            return None;
        }
        let mut p = Poly2::default();
        for v in poly.iter() {
            p.push(to2(v));
        }
        let area = p.signed_area();
        if area.abs() <= 1e-12 * node.radius * node.radius {
            return None;
        }
        if area < 0.0 {
            p.reverse();
        }
        Some(p)
    });
    let mut s_in: Real = 0.0;
    // Above each child piece.
    for a in projected.iter().flatten() {
        let mut r = q_poly;
        for i in 0..a.len {
            r = r.clip(&a.pts[i], &a.pts[(i + 1) % a.len]);
        }
        s_in = s_in.max(region_bound(&r));
    }
    // The rest: Q minus A, minus B, as disjoint convex pieces.
    let mut rest: Vec<Poly2> = vec![q_poly];
    for a in projected.iter().flatten() {
        let mut next = Vec::with_capacity(rest.len() * a.len);
        for piece in &rest {
            let mut inside = *piece;
            for i in 0..a.len {
                let (p0, p1) = (a.pts[i], a.pts[(i + 1) % a.len]);
                let outside = inside.clip(&p1, &p0);
                if outside.len >= 3 {
                    next.push(outside);
                }
                inside = inside.clip(&p0, &p1);
                if inside.len < 3 {
                    break;
                }
            }
        }
        rest = next;
    }
    for r in &rest {
        s_in = s_in.max(region_bound(r));
    }
    node.deviation = s_out.max(s_in).min(cap);
    scratch.hull = hull;
}
