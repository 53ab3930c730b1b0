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
use super::deviation::{DeviationScratch, final_deviation};
use super::moments::{NormalField, SurfaceMoments, surface_moments};
use super::overhang::{Across, NodeSurface, Overhang, OverhangScratch, overhang_widths};
use super::split::TriangleData;
use super::topology::{PARALLEL_TOPOLOGY_MIN, Tree};
use crate::geometry::{closest_point_on_polygon_2d, plane_basis, triangle_normal};
use crate::mesh::TriMesh;

/// Marks "no right child" (a leaf).
pub(crate) const LEAF: u32 = u32::MAX;

/// Below this fraction of a node's radius, a deviation the build computes is roundoff and
/// counts as none; within this fraction, two axes of a node's box are equally long
/// (`split.rs`); within this fraction of a piece's area, the piece covers its surface
/// exactly (`moments.rs`). The query tells exact pieces from approximate ones (a deviation of
/// 0, a cover of 1: `refine::weight_unsure`), and a flat face's piece came out with a deviation
/// of 0 or of 10⁻¹⁷ of its radius, and a cover of 1 or of 1 − 3 · 10⁻¹⁶, by how its coordinates
/// rounded. A nanometre a metre is far above the build's roundoff and far below any deviation
/// the walk weighs. In the query, a tool point within this fraction of a wall's edge length of
/// the wall's plane lies on the wall of the obstacle's prism (`slab.rs`).
pub(crate) const ROUNDOFF_REL: Real = 1e-9;

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
    /// By piece vertex: where the piece overhangs its surface along its edge from that vertex
    /// (`overhang.rs`; none for a leaf's triangle, infinite where not measured).
    pub(crate) overhang: Vec<Overhang>,
    /// Area and height moments of the surface below each node, by node index (derived from
    /// the leaves' triangles, so not saved with the hierarchy).
    pub(crate) moments: Vec<SurfaceMoments>,
    /// Per node: how its surface's normal turns across its piece (`moments.rs`).
    pub(crate) normal_fields: Vec<NormalField>,
    /// Per node: a ball that holds its piece (derived from the pieces, so not saved).
    pub(crate) piece_balls: Vec<PieceBall>,
    radius_about_origin_m: Real,
    triangle_count: usize,
    height: usize,
    build_s: Real,
}

/// Scratch buffers reused while building.
#[derive(Default)]
struct Scratch {
    pts: Vec<[Real; 2]>,
    /// Corners in the node's plane frame `(u, w, height)`, each vertex once.
    corners: Vec<[Real; 3]>,
    hull: Vec<[Real; 2]>,
    /// By mesh vertex: the last node whose corners took it (`u32::MAX` for none yet).
    taken_by: Vec<u32>,
    /// The overhang's outline edges.
    overhang: OverhangScratch,
}

impl Hierarchy {
    /// Builds the hierarchy of `mesh` (mesh frame).
    pub fn build(mesh: &TriMesh) -> Self {
        let start = Instant::now();
        let data = TriangleData::of(mesh);
        let tris = &data.corners;
        let n = tris.len();
        // Topology, in depth-first pre-order: children come after their parent.
        let Tree {
            nodes,
            ranges,
            perm,
            height,
        } = Tree::build(&data.view(), PARALLEL_TOPOLOGY_MIN);
        // Where each triangle is in `perm` (a node's triangles are a range of it), and the
        // triangles across each one's edges: a node's surface's outline (`overhang.rs`).
        let mut rank = vec![0u32; n];
        for (i, &t) in perm.iter().enumerate() {
            rank[t as usize] = i as u32;
        }
        let across = Across::of(mesh);
        // Pass 1 (any order, in parallel): bounds, plane, slab, piece, the surface → piece
        // deviation and where the piece overhangs its surface.
        type Piece = ([Vec3; MAX_PIECE_VERTICES], usize);
        type Widths = ([Real; MAX_PIECE_VERTICES], [Real; MAX_PIECE_VERTICES]);
        let pass1: Vec<((Node, Piece), Widths)> = (0..nodes.len())
            .into_par_iter()
            .map_init(
                || (Scratch::default(), Vec::with_capacity(MAX_PIECE_VERTICES)),
                |(scratch, local): &mut (Scratch, Vec<Vec3>), index| {
                    let (lo, hi) = ranges[index];
                    let node_tris = &perm[lo as usize..hi as usize];
                    local.clear();
                    let mut node = nodes[index];
                    let mut widths = ([0.0; MAX_PIECE_VERTICES], [0.0; MAX_PIECE_VERTICES]);
                    fill_bounds(&mut node, node_tris, tris);
                    if node.is_leaf() {
                        let t = &tris[node.triangle as usize];
                        node.normal = triangle_normal(t).unwrap_or_else(Vec3::z);
                        node.plane_point = t[0];
                        node.half_thickness = 0.0;
                        node.deviation = 0.0;
                        local.extend_from_slice(t);
                    } else {
                        let stamp = index as u32;
                        fill_piece(&mut node, node_tris, tris, mesh, stamp, scratch, local);
                        // Measured on planar pieces only (`overhang.rs`).
                        widths = (
                            [Real::INFINITY; MAX_PIECE_VERTICES],
                            [Real::INFINITY; MAX_PIECE_VERTICES],
                        );
                        if local.len() >= 3 && planar(node_tris, tris) {
                            let surface = NodeSurface {
                                triangles: node_tris,
                                rank: &rank,
                                range: (lo, hi),
                                basis: plane_basis(&node.normal),
                                origin: node.center,
                            };
                            let hull = &scratch.hull;
                            overhang_widths(
                                hull,
                                &surface,
                                tris,
                                &across,
                                &mut scratch.overhang,
                                &mut widths.0,
                                &mut widths.1,
                            );
                        }
                    }
                    let mut verts = [Vec3::zeros(); MAX_PIECE_VERTICES];
                    verts[..local.len()].copy_from_slice(local);
                    ((node, (verts, local.len())), widths)
                },
            )
            .collect();
        let (pass1, widths): (Vec<(Node, Piece)>, Vec<Widths>) = pass1.into_iter().unzip();
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
        for node in &mut nodes {
            if node.deviation <= ROUNDOFF_REL * node.radius {
                node.deviation = 0.0;
            }
        }
        let vertex_count = pieces.iter().map(|p| p.1).sum();
        let mut piece: Vec<Vec3> = Vec::with_capacity(vertex_count);
        let mut overhang: Vec<Overhang> = Vec::with_capacity(vertex_count);
        for ((node, (verts, len)), widths) in nodes.iter_mut().zip(&pieces).zip(&widths) {
            node.piece_start = piece.len() as u32;
            node.piece_len = *len as u32;
            piece.extend_from_slice(&verts[..*len]);
            overhang.extend((0..*len).map(|k| Overhang {
                width_m: widths.0[k],
                area_m2: widths.1[k],
            }));
        }
        let radius_about_origin_m = mesh
            .vertices()
            .iter()
            .map(|v| v.norm())
            .fold(0.0, Real::max);
        let (moments, normal_fields) = surface_moments(&nodes, &piece);
        let piece_balls = piece_balls(&nodes, &piece);
        Self {
            nodes,
            piece,
            overhang,
            moments,
            normal_fields,
            piece_balls,
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
        overhang: Vec<Overhang>,
        radius_about_origin_m: Real,
        triangle_count: usize,
        height: usize,
        build_s: Real,
    ) -> Self {
        let (moments, normal_fields) = surface_moments(&nodes, &piece);
        let piece_balls = piece_balls(&nodes, &piece);
        Self {
            nodes,
            piece,
            overhang,
            moments,
            normal_fields,
            piece_balls,
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
            + self.overhang.capacity() * std::mem::size_of::<Overhang>()
            + self.moments.capacity() * std::mem::size_of::<SurfaceMoments>()
            + self.normal_fields.capacity() * std::mem::size_of::<NormalField>()
            + self.piece_balls.capacity() * std::mem::size_of::<PieceBall>()
    }

    /// Area and height moments of the surface below node `i`.
    #[inline]
    pub(crate) fn moments_of(&self, i: u32) -> &SurfaceMoments {
        &self.moments[i as usize]
    }

    /// A ball that holds node `i`'s piece.
    #[inline]
    pub(crate) fn piece_ball_of(&self, i: u32) -> &PieceBall {
        &self.piece_balls[i as usize]
    }

    /// How node `i`'s surface normal turns across its piece.
    pub(crate) fn normal_field_of(&self, i: u32) -> &NormalField {
        &self.normal_fields[i as usize]
    }

    /// The piece of node `i` (vertices CCW about the node normal).
    #[inline]
    pub(crate) fn piece_of(&self, node: &Node) -> &[Vec3] {
        &self.piece[node.piece_start as usize..(node.piece_start + node.piece_len) as usize]
    }

    /// By edge of the piece of `node` (from each vertex), where it overhangs its surface
    /// (`overhang.rs`); empty for a piece that is not planar (its surface's normals spread, as
    /// its `moments` say: not measured).
    #[inline]
    pub(crate) fn overhang_of(&self, node: &Node, moments: &SurfaceMoments) -> &[Overhang] {
        if moments.coherence < 1.0 {
            return &[];
        }
        &self.overhang[node.piece_start as usize..(node.piece_start + node.piece_len) as usize]
    }
}

/// A ball that holds a node's piece (mesh frame; the node's bounding sphere holds its triangles,
/// which a coarse piece may overhang): the walk's test of whether two stopped pieces lie beside
/// each other (`query.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PieceBall {
    /// Centre: the middle of the piece's bounding box.
    pub center: Vec3,
    /// Radius (m): the distance to the piece's farthest vertex; infinite for a node without a
    /// piece.
    pub radius_m: Real,
}

impl PieceBall {
    /// The ball about the middle of `verts`' bounding box through the farthest of them (with the
    /// bounding spheres' slack); about `center` with an infinite radius when there are none (a
    /// node without a piece).
    pub(crate) fn of(verts: &[Vec3], center: Vec3) -> Self {
        if verts.is_empty() {
            return Self {
                center,
                radius_m: Real::INFINITY,
            };
        }
        let (center, radius_m) = ball_about_box(verts.iter());
        Self { center, radius_m }
    }
}

/// Each node's [`PieceBall`].
fn piece_balls(nodes: &[Node], piece: &[Vec3]) -> Vec<PieceBall> {
    nodes
        .iter()
        .map(|node| {
            let s = node.piece_start as usize;
            let verts = piece.get(s..s + node.piece_len as usize).unwrap_or(&[]);
            PieceBall::of(verts, node.center)
        })
        .collect()
}

/// Bounding sphere (centre of the corners' box, radius to the farthest corner).
fn fill_bounds(node: &mut Node, node_tris: &[u32], tris: &[[Vec3; 3]]) {
    (node.center, node.radius) = ball_about_box(node_tris.iter().flat_map(|&t| &tris[t as usize]));
}

/// The ball about the middle of `points`' bounding box through the farthest of them, with a hair
/// of slack so that rounding in the distance tests never culls a touching pair.
fn ball_about_box<'a>(points: impl Iterator<Item = &'a Vec3> + Clone) -> (Vec3, Real) {
    let (mut bmin, mut bmax) = (Vec3::repeat(Real::INFINITY), Vec3::repeat(-Real::INFINITY));
    for v in points.clone() {
        bmin = bmin.inf(v);
        bmax = bmax.sup(v);
    }
    let c = (bmin + bmax) * 0.5;
    let r2 = points.fold(0.0, |r2: Real, v| r2.max((v - c).norm_squared()));
    (c, r2.sqrt() * (1.0 + 1e-12))
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

/// Whether the triangles `node_tris` lie in one plane: their normals agree to within
/// `ROUNDOFF_REL` (the coherence `|Σ aᵢ nᵢ| / Σ aᵢ` of `moments.rs` rounds to 1 there).
fn planar(node_tris: &[u32], tris: &[[Vec3; 3]]) -> bool {
    let (mut sum, mut len) = (Vec3::zeros(), 0.0);
    for &t in node_tris {
        let [a, b, c] = &tris[t as usize];
        let an = (b - a).cross(&(c - a));
        sum += an;
        len += an.norm();
    }
    len > 0.0 && sum.norm() >= (1.0 - ROUNDOFF_REL) * len
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
