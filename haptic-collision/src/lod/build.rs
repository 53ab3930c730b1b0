//! Preprocessing: one hierarchy per mesh that is both a bounding-volume hierarchy and a
//! level-of-detail hierarchy (after Otaduy & Lin 2003, adapted; see `docs/decisions.md`).
//!
//! The tree is binary, built top-down by splitting the triangles at the median centroid along the
//! longest axis, or along a crease of the surface where that leaves flatter children
//! (`split.rs`); every leaf holds one triangle. Every node carries
//! - a bounding sphere and a bounding slab (a plane with a half-thickness) of the triangles below
//!   it, both in the mesh frame and both conservative (used for culling);
//! - its simplified convex piece: a planar convex polygon of at most
//!   [`MAX_PIECE_VERTICES`](super::MAX_PIECE_VERTICES) vertices in the slab's mid-plane (a leaf's
//!   piece is its triangle);
//! - the piece's surface deviation `s`: an upper bound on the two-sided Hausdorff distance
//!   between the piece and the node's triangles.

use std::time::Instant;

use haptic_core::{Real, Vec3};
use rayon::prelude::*;

use super::MAX_PIECE_VERTICES;
use super::moments::{SurfaceMoments, surface_moments};
use super::split::Triangles;
use super::topology::{PARALLEL_TOPOLOGY_MIN, Place, blank_node, topology};
use crate::geometry::{
    closest_point_on_polygon_2d, plane_basis, point_polygon_distance, triangle_normal,
};
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
    /// Number of triangles below the node (1 for a leaf).
    pub triangles: u32,
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
    /// Area and height moments of the surface below each node, by node index (derived from
    /// the leaves' triangles, so not saved with the hierarchy).
    pub(crate) moments: Vec<SurfaceMoments>,
    radius_about_origin_m: Real,
    triangle_count: usize,
    height: usize,
    build_s: Real,
}

/// A small convex polygon in a node's plane (2-D, fixed capacity, CCW).
#[derive(Debug, Clone, Copy)]
struct Poly2<const CAP: usize = POLY2_CAP> {
    pts: [[Real; 2]; CAP],
    len: usize,
}

/// Capacity of [`Poly2`]: a hexagon clipped by two hexagons' half-planes stays far below it.
pub(crate) const POLY2_CAP: usize = 24;

impl<const CAP: usize> Default for Poly2<CAP> {
    fn default() -> Self {
        Self {
            pts: [[0.0; 2]; CAP],
            len: 0,
        }
    }
}

impl<const CAP: usize> Poly2<CAP> {
    fn push(&mut self, p: [Real; 2]) {
        if self.len < CAP {
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
            let (p, q) = (
                self.pts[i],
                self.pts[if i + 1 == self.len { 0 } else { i + 1 }],
            );
            a += p[0] * q[1] - p[1] * q[0];
        }
        0.5 * a
    }

    fn reverse(&mut self) {
        self.pts[..self.len].reverse();
    }

    /// Whether `other` lies entirely outside one of this polygon's edges (then they do not
    /// overlap).
    fn beside<const N: usize>(&self, other: &Poly2<N>) -> bool {
        let n = self.len;
        (0..n).any(|i| {
            let (a, b) = (self.pts[i], self.pts[if i + 1 == n { 0 } else { i + 1 }]);
            other
                .as_slice()
                .iter()
                .all(|p| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) < 0.0)
        })
    }

    /// Makes `self` a copy of `other` (its points only).
    fn assign(&mut self, other: &Self) {
        self.pts[..other.len].copy_from_slice(other.as_slice());
        self.len = other.len;
    }

    /// Writes into `out` the part of `self` on the left of the directed line `a → b` (closed
    /// half-plane).
    fn clip_into(&self, a: &[Real; 2], b: &[Real; 2], out: &mut Self) {
        let side = |p: &[Real; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        out.len = 0;
        let n = self.len;
        if n == 0 {
            return;
        }
        let mut p = self.pts[0];
        let mut sp = side(&p);
        for i in 0..n {
            let q = self.pts[if i + 1 == n { 0 } else { i + 1 }];
            let sq = side(&q);
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp > 0.0 && sq < 0.0) || (sp < 0.0 && sq > 0.0) {
                let t = sp / (sp - sq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
            (p, sp) = (q, sq);
        }
    }
}

/// Scratch of [`final_deviation`]: the candidates, the walk's stack, the candidates' gaps.
type DeviationScratch = (Vec<usize>, Vec<usize>, Vec<(Real, usize, usize)>);

/// Scratch buffers reused while building.
#[derive(Default)]
struct Scratch {
    pts: Vec<[Real; 2]>,
    /// Corners in the node's plane frame `(u, w, height)`, each vertex once.
    corners: Vec<[Real; 3]>,
    hull: Vec<[Real; 2]>,
    /// By mesh vertex: the last node whose corners took it (`u32::MAX` for none yet).
    taken_by: Vec<u32>,
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
        let area_normals: Vec<Vec3> = tris
            .iter()
            .map(|t| (t[1] - t[0]).cross(&(t[2] - t[0])))
            .collect();
        let triangles = Triangles {
            corners: &tris,
            centroids: &centroids,
            area_normals: &area_normals,
        };
        let mut perm: Vec<u32> = (0..n as u32).collect();
        // Topology, in depth-first pre-order: children come after their parent.
        let mut nodes = vec![blank_node(0, 0); 2 * n - 1];
        let mut ranges: Vec<(u32, u32)> = vec![(0, 0); 2 * n - 1];
        let at = Place {
            lo: 0,
            base: 0,
            level: 1,
        };
        let height = topology(
            &triangles,
            &mut perm,
            &mut nodes,
            &mut ranges,
            at,
            PARALLEL_TOPOLOGY_MIN,
        );
        // Pass 1 (any order, in parallel): bounds, plane, slab, piece and the surface → piece
        // deviation.
        type Piece = ([Vec3; MAX_PIECE_VERTICES], usize);
        let pass1: Vec<(Node, Piece)> = (0..nodes.len())
            .into_par_iter()
            .map_init(
                || (Scratch::default(), Vec::with_capacity(MAX_PIECE_VERTICES)),
                |(scratch, local): &mut (Scratch, Vec<Vec3>), index| {
                    let (lo, hi) = ranges[index];
                    let node_tris = &perm[lo as usize..hi as usize];
                    local.clear();
                    let mut node = nodes[index];
                    fill_bounds(&mut node, node_tris, &tris);
                    if node.is_leaf() {
                        let t = &tris[node.triangle as usize];
                        node.normal = triangle_normal(t).unwrap_or_else(Vec3::z);
                        node.plane_point = t[0];
                        node.half_thickness = 0.0;
                        node.deviation = 0.0;
                        local.extend_from_slice(t);
                    } else {
                        let stamp = index as u32;
                        fill_piece(&mut node, node_tris, &tris, mesh, stamp, scratch, local);
                    }
                    let mut verts = [Vec3::zeros(); MAX_PIECE_VERTICES];
                    verts[..local.len()].copy_from_slice(local);
                    (node, (verts, local.len()))
                },
            )
            .collect();
        let (mut nodes, pieces): (Vec<Node>, Vec<Piece>) = pass1.into_iter().unzip();
        // Pass 2, smallest subtrees first: the piece → surface side of the deviation, bounded
        // through the pieces of smaller nearby nodes (whose deviations are then final). Nodes of
        // equal size never use each other, so each size is done in parallel.
        let count = |i: usize| ranges[i].1 - ranges[i].0;
        let mut order: Vec<usize> = (0..nodes.len()).filter(|&i| !nodes[i].is_leaf()).collect();
        order.sort_by_key(|&i| count(i));
        let mut first = 0;
        while first < order.len() {
            let size = count(order[first]);
            let end = first + order[first..].partition_point(|&i| count(i) == size);
            let done: Vec<(usize, Real)> = order[first..end]
                .par_iter()
                .map_init(
                    || (Vec::new(), Vec::new(), Vec::new()),
                    |(cands, walk, gaps): &mut DeviationScratch, &index| {
                        (
                            index,
                            final_deviation(index, &nodes, &pieces, &count, cands, walk, gaps),
                        )
                    },
                )
                .collect();
            for (index, deviation) in done {
                nodes[index].deviation = deviation;
            }
            first = end;
        }
        let mut piece: Vec<Vec3> = Vec::with_capacity(pieces.iter().map(|p| p.1).sum());
        for (node, (verts, len)) in nodes.iter_mut().zip(&pieces) {
            node.piece_start = piece.len() as u32;
            node.piece_len = *len as u32;
            piece.extend_from_slice(&verts[..*len]);
        }
        let radius_about_origin_m = mesh
            .vertices()
            .iter()
            .map(|v| v.norm())
            .fold(0.0, Real::max);
        let moments = surface_moments(&nodes, &piece);
        Self {
            nodes,
            piece,
            moments,
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

    /// A hierarchy from its parts (read back from a file; see `cache.rs`), `build_s` the time
    /// it took to get.
    pub(crate) fn from_parts(
        nodes: Vec<Node>,
        piece: Vec<Vec3>,
        radius_about_origin_m: Real,
        triangle_count: usize,
        height: usize,
        build_s: Real,
    ) -> Self {
        let moments = surface_moments(&nodes, &piece);
        Self {
            nodes,
            piece,
            moments,
            radius_about_origin_m,
            triangle_count,
            height,
            build_s,
        }
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
            + self.moments.capacity() * std::mem::size_of::<SurfaceMoments>()
    }

    /// Area and height moments of the surface below node `i`.
    #[inline]
    pub(crate) fn moments_of(&self, i: u32) -> &SurfaceMoments {
        &self.moments[i as usize]
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

/// Plane, slab, piece and deviation of an inner node.
fn fill_piece(
    node: &mut Node,
    node_tris: &[u32],
    tris: &[[Vec3; 3]],
    mesh: &TriMesh,
    stamp: u32,
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
    scratch.corners.clear();
    let (mut hmin, mut hmax) = (Real::INFINITY, Real::NEG_INFINITY);
    let vertices = mesh.vertices();
    if scratch.taken_by.len() != vertices.len() {
        scratch.taken_by.clear();
        scratch.taken_by.resize(vertices.len(), u32::MAX);
    }
    for &t in node_tris {
        // A vertex is a corner of several triangles: keep it once.
        for &k in &mesh.triangles()[t as usize] {
            if std::mem::replace(&mut scratch.taken_by[k as usize], stamp) == stamp {
                continue;
            }
            let d = vertices[k as usize] - o;
            let h = n.dot(&d);
            hmin = hmin.min(h);
            hmax = hmax.max(h);
            scratch.corners.push([u.dot(&d), w.dot(&d), h]);
        }
    }
    let hmid = 0.5 * (hmin + hmax);
    node.normal = n;
    node.plane_point = o + n * hmid;
    node.half_thickness = 0.5 * (hmax - hmin) * (1.0 + 1e-12) + 1e-15 * node.radius;
    // Rigorous fallback: piece and surface both lie within √2 r and r of the sphere centre.
    let cap = (1.0 + std::f64::consts::SQRT_2) * node.radius;

    let mut pts = std::mem::take(&mut scratch.pts);
    let mut hull = std::mem::take(&mut scratch.hull);
    pts.clear();
    pts.extend(scratch.corners.iter().map(|c| [c[0], c[1]]));
    convex_hull_2d(&mut pts, &mut hull);
    scratch.pts = pts;
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
    for c in &scratch.corners {
        let dh = c[2] - hmid;
        let p = [c[0], c[1]];
        let q = closest_point_on_polygon_2d(p, &hull);
        let d2 = (p[0] - q[0]).hypot(p[1] - q[1]);
        s_out = s_out.max((dh * dh + d2 * d2).sqrt());
    }
    node.deviation = s_out.min(cap);
    scratch.hull = hull;
}

/// The final (two-sided) deviation of inner node `index`: its surface → piece part, already in
/// `nodes`, and the piece → surface part bounded through nearby smaller nodes.
fn final_deviation(
    index: usize,
    nodes: &[Node],
    pieces: &[([Vec3; MAX_PIECE_VERTICES], usize)],
    count: &(dyn Fn(usize) -> u32 + Sync),
    cands: &mut Vec<usize>,
    walk: &mut Vec<usize>,
    gaps: &mut Vec<(Real, usize, usize)>,
) -> Real {
    let node = nodes[index];
    if !node.deviation.is_finite() {
        return node.deviation;
    }
    cands.clear();
    walk.clear();
    walk.push(0);
    while let Some(m) = walk.pop() {
        let nm = &nodes[m];
        let reach = nm.radius + node.radius;
        if (nm.center - node.center).norm_squared() > reach * reach {
            continue;
        }
        if count(m) < count(index) {
            cands.push(m);
        } else if !nm.is_leaf() {
            walk.push(m + 1);
            walk.push(nm.right as usize);
        }
    }
    if cands.len() > MAX_CANDIDATES {
        // The nearest ones (any subset keeps the bound rigorous, only looser), nearest first,
        // ties in walk order.
        let gap = |m: usize| (nodes[m].center - node.center).norm() - nodes[m].radius;
        gaps.clear();
        gaps.extend(cands.iter().enumerate().map(|(k, &m)| (gap(m), k, m)));
        let by_gap = |a: &(Real, usize, usize), b: &(Real, usize, usize)| {
            a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
        };
        gaps.select_nth_unstable_by(MAX_CANDIDATES - 1, by_gap);
        gaps[..MAX_CANDIDATES].sort_unstable_by(by_gap);
        cands.clear();
        cands.extend(gaps[..MAX_CANDIDATES].iter().map(|g| g.2));
    }
    let s_in = piece_to_surface(&node, &pieces[index], cands, nodes, pieces);
    let cap = (1.0 + std::f64::consts::SQRT_2) * node.radius;
    s_in.min(cap)
}

/// Most neighbouring nodes used to bound a piece's distance to the surface.
pub(crate) const MAX_CANDIDATES: usize = 10;

/// Most convex regions tracked while cutting a piece along its neighbours' pieces.
pub(crate) const MAX_REGIONS: usize = 32;

/// Upper bound on `sup_{q ∈ piece} dist(q, S)`, `S` the whole mesh surface, or `node.deviation`
/// (the surface → piece part) when that is larger: the larger of the two is the two-sided
/// deviation, so a region whose bound is already below `node.deviation` needs no tighter one.
///
/// For any node `m`, `dist(q, S) <= dist(q, piece_m) + s_m` (its two-sided deviation) and
/// `dist(q, S) <= |q − centre_m| + r_m`. Both are convex in `q`, so over a convex region their
/// maximum is at a vertex. The piece (in 2-D, in its plane) is cut along the projections of the
/// candidates' pieces, best-aligned first: each region above candidate `m` is bounded with `m`'s
/// term, and what no candidate covers with the smallest of all terms' vertex maxima. A region
/// whose vertices the next candidate's term already bounds by the running maximum is dropped
/// before it is cut (nothing in it can raise the maximum).
fn piece_to_surface(
    node: &Node,
    own: &([Vec3; MAX_PIECE_VERTICES], usize),
    cands: &[usize],
    nodes: &[Node],
    pieces: &[([Vec3; MAX_PIECE_VERTICES], usize)],
) -> Real {
    let n = node.normal;
    let (u, w) = plane_basis(&n);
    let o = node.plane_point;
    let to2 = |v: &Vec3| -> [Real; 2] {
        let d = v - o;
        [u.dot(&d), w.dot(&d)]
    };
    let to3 = |p: &[Real; 2]| o + u * p[0] + w * p[1];
    // `term(m, q, limit)`: the smaller of m's two bounds at q when it is below `limit`, else some
    // value at least `limit`. The polygon distance (the costly part) is skipped when its lower
    // bound, the distance to m's plane, already reaches the sphere bound or `limit`: the result
    // is then the same as with it.
    let term = |m: usize, q: &Vec3, limit: Real| -> Real {
        let nm = &nodes[m];
        let t = (q - nm.center).norm() + nm.radius;
        let (verts, len) = &pieces[m];
        if nm.deviation.is_finite() && *len >= 3 {
            let plane = nm.normal.dot(&(q - verts[0])).abs() + nm.deviation;
            if plane < t.min(limit) {
                return t.min(point_polygon_distance(q, &verts[..*len], &nm.normal) + nm.deviation);
            }
        }
        t
    };
    let mut q_poly = Poly2::<POLY2_CAP>::default();
    for v in &own.0[..own.1] {
        q_poly.push(to2(v));
    }
    // Candidates with a usable projected piece, best first (closest to this plane).
    let mut usable: Vec<(Real, usize, Poly2<MAX_PIECE_VERTICES>)> = Vec::with_capacity(cands.len());
    for &m in cands {
        let nm = &nodes[m];
        let (verts, len) = &pieces[m];
        if !nm.deviation.is_finite() || *len < 3 {
            continue;
        }
        let mut p = Poly2::<MAX_PIECE_VERTICES>::default();
        let mut off: Real = 0.0;
        for v in &verts[..*len] {
            p.push(to2(v));
            off = off.max(n.dot(&(v - o)).abs());
        }
        let area = p.signed_area();
        if area.abs() <= 1e-12 * node.radius * node.radius {
            continue;
        }
        if area < 0.0 {
            p.reverse();
        }
        usable.push((off + nm.deviation, m, p));
    }
    usable.sort_by(|a, b| a.0.total_cmp(&b.0));
    // min over candidates of (max over the region's vertices of the candidate's term), below
    // `start`; any value at most `enough` once one is found (the caller takes the max with it).
    let best_term = |verts: &[[Real; 2]], start: Real, enough: Real| -> Real {
        let mut best = start;
        for &m in cands {
            if best <= enough {
                break;
            }
            let mut worst: Real = 0.0;
            for v in verts {
                worst = worst.max(term(m, &to3(v), best));
                if worst >= best {
                    break;
                }
            }
            best = best.min(worst);
        }
        best
    };
    let mut s_in: Real = node.deviation;
    let mut rest: Vec<Poly2> = vec![q_poly];
    let mut next: Vec<Poly2> = Vec::new();
    // Clipping buffers, ping-ponged by reference.
    let (mut buf_a, mut buf_b, mut outside) =
        (Poly2::default(), Poly2::default(), Poly2::default());
    for (_, m, p) in &usable {
        if rest.is_empty() {
            break;
        }
        next.clear();
        for piece in &rest {
            // A region that m's term bounds by `s_in` as a whole is done.
            let mut whole: Real = 0.0;
            for v in piece.as_slice() {
                whole = whole.max(term(*m, &to3(v), s_in));
                if whole > s_in {
                    break;
                }
            }
            if whole <= s_in {
                continue;
            }
            // The part above candidate m, and the rest of the piece as disjoint convex parts:
            // the same half-planes cut both, and what is left after the last is the part above.
            if p.beside(piece) {
                next.push(*piece);
                continue;
            }
            let mark = next.len();
            let (mut inside, mut spare) = (&mut buf_a, &mut buf_b);
            inside.assign(piece);
            for i in 0..p.len {
                let (p0, p1) = (p.pts[i], p.pts[if i + 1 == p.len { 0 } else { i + 1 }]);
                inside.clip_into(&p1, &p0, &mut outside);
                if outside.len >= 3 && outside.signed_area() > 0.0 {
                    next.push(outside);
                }
                inside.clip_into(&p0, &p1, spare);
                std::mem::swap(&mut inside, &mut spare);
                if inside.len < 3 {
                    break;
                }
            }
            if inside.len < 3 {
                // Nothing above m: the piece goes on whole.
                next.truncate(mark);
                next.push(*piece);
                continue;
            }
            let mut b: Real = 0.0;
            for v in inside.as_slice() {
                b = b.max(term(*m, &to3(v), Real::INFINITY));
            }
            if b > s_in {
                // Slivers left by rounding can land on a poor candidate: try every term.
                b = b.min(best_term(inside.as_slice(), b, s_in));
                s_in = s_in.max(b);
            }
        }
        std::mem::swap(&mut rest, &mut next);
        if rest.len() > MAX_REGIONS {
            break;
        }
    }
    // Whatever is left: the best single term per region.
    for r in &rest {
        s_in = s_in.max(best_term(r.as_slice(), Real::INFINITY, s_in));
    }
    s_in
}
