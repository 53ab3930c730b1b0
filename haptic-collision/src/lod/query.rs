//! The query: both hierarchies walked together (tool placed in the obstacle's mesh frame).

use haptic_core::{Contact, ContactSet, Mat3, NO_FEATURE, Pose, QueryStats, Real, Vec3};

use super::build::{Hierarchy, Node, plane_basis};
use super::{LodError, MAX_PIECE_VERTICES};
use crate::area::SampleSplit;
use crate::geometry::{
    PairContact, closest_point_on_polygon_2d, convex_polygon_pair, crossing_witness,
};

/// The rigid map from the tool's body frame to one obstacle's mesh frame, and what is needed to
/// write contacts in the world frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frames {
    /// Tool body → obstacle mesh frame: rotation.
    pub rot: Mat3,
    /// Tool body → obstacle mesh frame: translation.
    pub trans: Vec3,
    /// Obstacle mesh → world: rotation.
    pub obs_rot: Mat3,
    /// Obstacle mesh → world: translation.
    pub obs_pos: Vec3,
    /// World → tool body: rotation (transpose of the tool's orientation).
    pub tool_rot_t: Mat3,
    /// Tool position (world).
    pub tool_pos: Vec3,
}

impl Frames {
    /// Frames for the tool at `tool` and an obstacle at `obstacle` (both body → world).
    pub fn new(tool: &Pose, obstacle: &Pose) -> Self {
        let rt = tool.orientation.to_rotation_matrix().into_inner();
        let ro = obstacle.orientation.to_rotation_matrix().into_inner();
        let ro_t = ro.transpose();
        Self {
            rot: ro_t * rt,
            trans: ro_t * (tool.position - obstacle.position),
            obs_rot: ro,
            obs_pos: obstacle.position,
            tool_rot_t: rt.transpose(),
            tool_pos: tool.position,
        }
    }

    /// A tool-frame point in the obstacle frame.
    #[inline]
    pub fn point(&self, p: &Vec3) -> Vec3 {
        self.rot * p + self.trans
    }

    /// Writes a pair result (obstacle frame) as a world-frame contact standing for `area_m2`
    /// of the tool's surface.
    ///
    /// # Errors
    /// [`LodError::Core`] if the contact is not finite (a degenerate input).
    #[inline]
    pub fn emit(
        &self,
        pc: &PairContact,
        feature_a: u32,
        feature_b: u32,
        area_m2: Real,
        out: &mut ContactSet,
    ) -> Result<(), LodError> {
        let p_a = self.obs_rot * pc.p_a + self.obs_pos;
        let p_b = self.obs_rot * pc.p_b + self.obs_pos;
        let n = self.obs_rot * pc.n;
        let r_a = self.tool_rot_t * (p_a - self.tool_pos);
        let c = Contact::new(p_a, r_a, p_b, n, pc.depth)?
            .with_features(feature_a, feature_b)
            .with_area(area_m2);
        out.push(c);
        Ok(())
    }
}

/// Whether a tool node (centre `ca` already in the obstacle frame) and an obstacle node are farther apart than `delta` (conservative: spheres and slabs).
#[inline]
fn culled(a: &Node, ca: &Vec3, b: &Node, frames: &Frames, delta: Real) -> bool {
    let d = ca - b.center;
    let reach = a.radius + b.radius + delta;
    if d.norm_squared() > reach * reach {
        return true;
    }
    if b.normal.dot(&(ca - b.plane_point)).abs() - b.half_thickness - a.radius > delta {
        return true;
    }
    // The tool's slab, in the obstacle frame.
    let na = frames.rot * a.normal;
    let pa = frames.point(&a.plane_point);
    na.dot(&(b.center - pa)).abs() - a.half_thickness - b.radius > delta
}

/// The tool's piece of `a` in the obstacle frame, into `buf`; returns its length and normal.
#[inline]
fn place_piece(
    tool: &Hierarchy,
    a: &Node,
    frames: &Frames,
    buf: &mut [Vec3; MAX_PIECE_VERTICES],
) -> (usize, Vec3) {
    let piece = tool.piece_of(a);
    for (dst, v) in buf.iter_mut().zip(piece) {
        *dst = frames.point(v);
    }
    (piece.len(), frames.rot * a.normal)
}

/// A lower bound on the distance from the polygon `poly` to anything in the plane `(n, p0)`: how
/// far its nearest vertex is when all its vertices lie on one side, 0 when they straddle it.
#[inline]
fn plane_gap(poly: &[Vec3], n: &Vec3, p0: &Vec3) -> Real {
    let (mut lo, mut hi) = (Real::INFINITY, Real::NEG_INFINITY);
    for v in poly {
        let h = n.dot(&(v - p0));
        lo = lo.min(h);
        hi = hi.max(h);
    }
    lo.max(-hi).max(0.0)
}

/// Whether the two polygons' projections on the line through their centroids are more than
/// `delta` apart (then so are the polygons).
#[inline]
fn apart_along_centroids(a: &[Vec3], b: &[Vec3], delta: Real) -> bool {
    let ca = a.iter().sum::<Vec3>() / a.len() as Real;
    let cb = b.iter().sum::<Vec3>() / b.len() as Real;
    let d = cb - ca;
    let len = d.norm();
    if len.is_nan() || len <= 0.0 {
        return false;
    }
    let u = d / len;
    let a_max = a
        .iter()
        .map(|v| u.dot(v))
        .fold(Real::NEG_INFINITY, Real::max);
    let b_min = b.iter().map(|v| u.dot(v)).fold(Real::INFINITY, Real::min);
    b_min - a_max > delta
}

/// Subdivisions of each fan triangle's edges in [`fan_samples`].
const SAMPLE_LEVEL: usize = 3;

/// The sample key of a coarse pair's crossing contact (sample indices stay below it).
const CROSSING_SAMPLE: usize = 63;

/// Most sample points of a coarse pair (`1 + m · L (L + 1) / 2` for a piece of `m` vertices).
const MAX_SAMPLES: usize = 1 + MAX_PIECE_VERTICES * SAMPLE_LEVEL * (SAMPLE_LEVEL + 1) / 2;

/// The sample points of a tool piece and the fraction of its area each stands for: the centroid
/// and a regular grid on each triangle of the fan from the centroid (the points shared by two
/// fan triangles taken once), of level [`SAMPLE_LEVEL`] or lower so that there are at most
/// `budget` points (at least the centroid and the vertices). Returns their number.
///
/// A point of fan triangle `i` stands for that triangle's area over its points, a point on the
/// edge two fan triangles share for the mean of theirs, the centroid for the mean fan triangle;
/// the fractions add up to 1. Equal shares would over-weigh the narrow fan triangles of an
/// irregular piece, which get as many points as the wide ones.
#[inline]
fn fan_samples(
    a: &[Vec3],
    pts: &mut [Vec3; MAX_SAMPLES],
    wts: &mut [Real; MAX_SAMPLES],
    budget: u32,
) -> usize {
    let m = a.len();
    let centroid = a.iter().sum::<Vec3>() / m as Real;
    let mut level = SAMPLE_LEVEL;
    while level > 1 && 1 + m * level * (level + 1) / 2 > budget as usize {
        level -= 1;
    }
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
struct PlanarPiece {
    origin: Vec3,
    u: Vec3,
    w: Vec3,
    n: Vec3,
    verts: [[Real; 2]; MAX_PIECE_VERTICES],
    len: usize,
}

impl PlanarPiece {
    fn new(b: &[Vec3], nb: &Vec3) -> Self {
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
    fn closest_within(&self, x: &Vec3, delta: Real) -> Option<(Vec3, Real)> {
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

/// The contacts of a coarse (piece–piece) pair, which stand for those of the triangle pairs below
/// it:
/// - where the pieces cross, one contact at a point of their intersection, touching (depth 0),
///   with the normal `−n_b` (out of the tool, into the obstacle). Triangle pairs that cross
///   report small separating-axis depths; the pieces' own separating-axis depth measures how two
///   large polygons cross and is not bounded by the size of the triangles below them;
/// - samples spread over the tool piece ([`fan_samples`], at most `budget`), each with what a triangle pair
///   reports, its distance to the obstacle piece: `depth = −distance`, `n` along the closest-point
///   direction, on whichever side of the obstacle piece it lies (a triangle below the obstacle's
///   surface by `h` is `h` away from every triangle it is paired with), kept when within `δ`.
///
/// Each contact stands for a share of `area_m2`, the surface area below the tool node: the
/// crossing contact one equal share, every sample generated (within `δ` or not) its part of the
/// rest by its weight from [`fan_samples`].
///
/// On the jaws at 2.5 %, these contacts (rather than the pieces' exact closest points and
/// samples at the vertices alone) bring the error of the clustered wrench from 10 % to about
/// 4 %, in less time (`docs/decisions.md`). Returns the smallest distance reported (0 when crossing,
/// infinite when nothing is within `δ`).
#[allow(clippy::too_many_arguments)]
fn emit_coarse(
    a: &[Vec3],
    node: u32,
    tags: &mut Vec<(u32, u64)>,
    area_m2: Real,
    budget: u32,
    na: &Vec3,
    b: &[Vec3],
    nb: &Vec3,
    delta: Real,
    frames: &Frames,
    out: &mut ContactSet,
) -> Result<Real, LodError> {
    let mut nearest = Real::INFINITY;
    let mut pts = [Vec3::zeros(); MAX_SAMPLES];
    let mut wts = [0.0; MAX_SAMPLES];
    let count = fan_samples(a, &mut pts, &mut wts, budget);
    let crossing = crossing_witness(a, na, b, nb);
    // The crossing contact takes one sample's share; the samples the rest, by their weights.
    let share = area_m2 / (count + usize::from(crossing.is_some())) as Real;
    let sampled_m2 = area_m2 - if crossing.is_some() { share } else { 0.0 };
    if let Some(x) = crossing {
        let touching = PairContact {
            p_a: x,
            p_b: x,
            n: -nb,
            depth: 0.0,
            distance: 0.0,
        };
        tags.push((out.len() as u32, SampleSplit::key(node, CROSSING_SAMPLE)));
        frames.emit(&touching, NO_FEATURE, NO_FEATURE, share, out)?;
        nearest = 0.0;
    }
    let piece = PlanarPiece::new(b, nb);
    for (k, x) in pts[..count].iter().enumerate() {
        let Some((c, _)) = piece.closest_within(x, delta) else {
            continue;
        };
        // Distance and normal from the 3-D points themselves: the planar frame's distance `d`
        // can differ from `|c − x|` by rounding, and at a few ulps from the piece that made a
        // normal of norm √5 (seen on gears in mesh, whose flat faces are coarse pieces even at
        // threshold 0).
        let gap = c - x;
        let len = gap.norm();
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        let sample = PairContact {
            p_a: *x,
            p_b: c,
            n: gap / len,
            depth: -len,
            distance: len,
        };
        tags.push((out.len() as u32, SampleSplit::key(node, k)));
        frames.emit(&sample, NO_FEATURE, NO_FEATURE, sampled_m2 * wts[k], out)?;
        nearest = nearest.min(len);
    }
    Ok(nearest)
}

/// What one traversal needs besides the hierarchies.
pub(crate) struct Walk<'a> {
    pub frames: &'a Frames,
    /// Absolute error threshold (m) on `s_a + s_b`; 0 descends to triangles.
    pub epsilon_m: Real,
    /// Distance tolerance δ (m).
    pub delta_m: Real,
}

/// Scratch reused by every query, so that a query allocates nothing once warm.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scratch {
    /// The traversal stack of node pairs (tool, obstacle).
    pub stack: Vec<(u32, u32)>,
    /// Coarse pairs whose pieces do not cross: a lower bound on their distance, and the nodes.
    pub apart: Vec<(Real, u32, u32)>,
    /// Coarse contacts of the whole query (all obstacles): their index in the contact set and
    /// their sample's key, for [`SampleSplit`]. Cleared by the query, not by each walk.
    pub tags: Vec<(u32, u64)>,
}

/// Walks tool × obstacle from the root pair, writing contacts into `out`.
///
/// The coarse pairs' samples need not include their pieces' closest points, so after the walk
/// the pairs whose lower bound is below the smallest distance reported are searched exactly, and
/// the closest approach found (if closer) is reported too: the smallest distance reported is
/// then the exact distance between the stopped pieces.
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
pub(crate) fn collide(
    tool: &Hierarchy,
    obs: &Hierarchy,
    walk: &Walk<'_>,
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    let Scratch { stack, apart, tags } = scratch;
    stack.clear();
    apart.clear();
    stack.push((0, 0));
    let frames = walk.frames;
    let delta = walk.delta_m;
    let mut buf = [Vec3::zeros(); MAX_PIECE_VERTICES];
    let mut nearest = Real::INFINITY;
    while let Some((ia, ib)) = stack.pop() {
        let a = &tool.nodes[ia as usize];
        let b = &obs.nodes[ib as usize];
        stats.node_pairs_tested += 1;
        let ca = frames.point(&a.center);
        if culled(a, &ca, b, frames, delta) {
            continue;
        }
        let (leaf_a, leaf_b) = (a.is_leaf(), b.is_leaf());
        // Stopping rule of the CLOD traversal: both pieces within the error budget.
        let stop = (leaf_a && leaf_b)
            || (walk.epsilon_m > 0.0 && a.deviation + b.deviation <= walk.epsilon_m);
        if stop {
            let (len, na) = place_piece(tool, a, frames, &mut buf);
            let pa = frames.point(&a.plane_point);
            let pb = obs.piece_of(b);
            // Piece-level cull: one piece entirely beyond δ on one side of the other's plane.
            let gap =
                plane_gap(&buf[..len], &b.normal, &b.plane_point).max(plane_gap(pb, &na, &pa));
            if gap > delta || apart_along_centroids(&buf[..len], pb, delta) {
                continue;
            }
            stats.primitive_pairs_tested += 1;
            if leaf_a && leaf_b {
                let pc = convex_polygon_pair(&buf[..len], &na, pb, &b.normal);
                if pc.depth >= -delta {
                    // The triangle's whole area; `AreaSplit` shares it among its contacts.
                    frames.emit(&pc, a.triangle, b.triangle, tool.area_of(ia), out)?;
                    nearest = nearest.min(pc.distance);
                }
            } else {
                // No more samples than the triangle pairs the coarse pair stands for.
                let budget = a.triangles.saturating_mul(b.triangles);
                let near = emit_coarse(
                    &buf[..len],
                    ia,
                    tags,
                    tool.area_of(ia),
                    budget,
                    &na,
                    pb,
                    &b.normal,
                    delta,
                    frames,
                    out,
                )?;
                nearest = nearest.min(near);
                if near > 0.0 {
                    apart.push((gap, ia, ib));
                }
            }
            continue;
        }
        // Descend the node with the larger deviation (ties: the larger one).
        let split_a = if leaf_a {
            false
        } else if leaf_b {
            true
        } else if a.deviation != b.deviation {
            a.deviation > b.deviation
        } else {
            a.radius >= b.radius
        };
        if split_a {
            stack.push((a.right, ib));
            stack.push((ia + 1, ib));
        } else {
            stack.push((ia, b.right));
            stack.push((ia, ib + 1));
        }
    }
    // The closest approach among the coarse pairs that could hold one closer than reported.
    let mut closest: Option<(PairContact, Real)> = None;
    for &(gap, ia, ib) in apart.iter() {
        if gap >= nearest {
            continue;
        }
        let (a, b) = (&tool.nodes[ia as usize], &obs.nodes[ib as usize]);
        let (len, na) = place_piece(tool, a, frames, &mut buf);
        let pc = convex_polygon_pair(&buf[..len], &na, obs.piece_of(b), &b.normal);
        if pc.distance < nearest && pc.depth >= -delta {
            nearest = pc.distance;
            // One sample's share of the tool piece, as `emit_coarse` gives.
            let samples = fan_samples(
                &buf[..len],
                &mut [Vec3::zeros(); MAX_SAMPLES],
                &mut [0.0; MAX_SAMPLES],
                a.triangles.saturating_mul(b.triangles),
            );
            closest = Some((pc, tool.area_of(ia) / samples as Real));
        }
    }
    if let Some((pc, area_m2)) = closest {
        frames.emit(&pc, NO_FEATURE, NO_FEATURE, area_m2, out)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::closest_point_on_polygon;
    use proptest::prelude::*;

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
            let frames = Frames::new(&Pose::identity(), &Pose::identity());
            let mut out = ContactSet::new();
            let mut tags = Vec::new();
            let r = emit_coarse(&a, 0, &mut tags, 1e-4, 64, &(-n), &b, &n, 1e-3, &frames, &mut out);
            prop_assert_eq!(tags.len(), out.len());
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
            let count = fan_samples(&a, &mut pts, &mut wts, u32::MAX);
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
            prop_assert_eq!(fan_samples(&a, &mut pts, &mut wts, (1 + 3 * m) as u32), 1 + 3 * m);
            prop_assert_eq!(fan_samples(&a, &mut pts, &mut wts, 3 * m as u32), 1 + m);
            prop_assert_eq!(fan_samples(&a, &mut pts, &mut wts, 0), 1 + m);
        }
    }
}
