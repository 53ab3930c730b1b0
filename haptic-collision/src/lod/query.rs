//! The query: both hierarchies walked together (tool placed in the obstacle's mesh frame).

use haptic_core::{Contact, ContactSet, Mat3, NO_FEATURE, Pose, QueryStats, Real, Vec3};

use super::build::{Hierarchy, Node};
use super::{LodError, MAX_PIECE_VERTICES};
use crate::geometry::{PairContact, closest_point_on_polygon, convex_polygon_pair};

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

    /// Writes a pair result (obstacle frame) as a world-frame contact.
    ///
    /// # Errors
    /// [`LodError::Contact`] if the contact is not finite (a degenerate input).
    #[inline]
    pub fn emit(
        &self,
        pc: &PairContact,
        feature_a: u32,
        feature_b: u32,
        out: &mut ContactSet,
    ) -> Result<(), LodError> {
        let p_a = self.obs_rot * pc.p_a + self.obs_pos;
        let p_b = self.obs_rot * pc.p_b + self.obs_pos;
        let n = self.obs_rot * pc.n;
        let r_a = self.tool_rot_t * (p_a - self.tool_pos);
        let c = Contact::new(p_a, r_a, p_b, n, pc.depth)?.with_features(feature_a, feature_b);
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

/// Whether every vertex of `poly` lies more than `delta` from the plane `(n, p0)`, all on the same
/// side (then the polygon is farther than `delta` from anything in that plane).
#[inline]
fn beyond_plane(poly: &[Vec3], n: &Vec3, p0: &Vec3, delta: Real) -> bool {
    let (mut lo, mut hi) = (Real::INFINITY, Real::NEG_INFINITY);
    for v in poly {
        let h = n.dot(&(v - p0));
        lo = lo.min(h);
        hi = hi.max(h);
    }
    lo > delta || hi < -delta
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

/// The extra contacts of a coarse (piece–piece) pair: the regions within `δ` are sampled at the
/// tool piece's vertices and centroid, each against the obstacle piece, so that a coarse pair
/// reports a spread of depths like the triangle pairs it stands for, not only its closest
/// approach. Each sample reports what a triangle pair reports, a distance: `depth = −distance`
/// to the obstacle piece and `n` along the closest-point direction, on whichever side of the
/// obstacle piece it lies. (A triangle that lies below the obstacle's surface by `h` is, for
/// every triangle pair it belongs to, `h` away; giving coarse samples a positive depth there
/// made the coarse levels push much harder than threshold 0 on the jaws.) For the same reason
/// the caller reports crossing pieces as touching (depth 0) rather than with the pieces'
/// separating-axis depth, which measures how two large polygons cross and is not bounded by
/// the size of the triangles below them.
fn emit_samples(
    a: &[Vec3],
    b: &[Vec3],
    nb: &Vec3,
    delta: Real,
    frames: &Frames,
    out: &mut ContactSet,
) -> Result<(), LodError> {
    let centroid = a.iter().sum::<Vec3>() / a.len() as Real;
    for x in a.iter().chain(std::iter::once(&centroid)) {
        let c = closest_point_on_polygon(x, b, nb);
        let d = (c - x).norm();
        if d <= 0.0 {
            continue;
        }
        let sample = PairContact {
            p_a: *x,
            p_b: c,
            n: (c - x) / d,
            depth: -d,
            distance: d,
        };
        if sample.depth >= -delta {
            frames.emit(&sample, NO_FEATURE, NO_FEATURE, out)?;
        }
    }
    Ok(())
}

/// What one traversal needs besides the hierarchies.
pub(crate) struct Walk<'a> {
    pub frames: &'a Frames,
    /// Absolute error threshold (m) on `s_a + s_b`; 0 descends to triangles.
    pub epsilon_m: Real,
    /// Distance tolerance δ (m).
    pub delta_m: Real,
}

/// Walks tool × obstacle from the root pair, writing contacts into `out`.
///
/// # Errors
/// [`LodError::Contact`] for a non-finite contact.
pub(crate) fn collide(
    tool: &Hierarchy,
    obs: &Hierarchy,
    walk: &Walk<'_>,
    stack: &mut Vec<(u32, u32)>,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    stack.clear();
    stack.push((0, 0));
    let frames = walk.frames;
    let mut buf = [Vec3::zeros(); MAX_PIECE_VERTICES];
    while let Some((ia, ib)) = stack.pop() {
        let a = &tool.nodes[ia as usize];
        let b = &obs.nodes[ib as usize];
        stats.node_pairs_tested += 1;
        let ca = frames.point(&a.center);
        if culled(a, &ca, b, frames, walk.delta_m) {
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
            if beyond_plane(&buf[..len], &b.normal, &b.plane_point, walk.delta_m)
                || beyond_plane(pb, &na, &pa, walk.delta_m)
                || apart_along_centroids(&buf[..len], pb, walk.delta_m)
            {
                continue;
            }
            stats.primitive_pairs_tested += 1;
            let pc = convex_polygon_pair(&buf[..len], &na, pb, &b.normal);
            if pc.depth < -walk.delta_m {
                continue;
            }
            if leaf_a && leaf_b {
                frames.emit(&pc, a.triangle, b.triangle, out)?;
            } else {
                // Crossing pieces report touching (depth 0), see `emit_samples`.
                let mut touching = pc;
                touching.depth = touching.depth.min(0.0);
                frames.emit(&touching, NO_FEATURE, NO_FEATURE, out)?;
                emit_samples(&buf[..len], pb, &b.normal, walk.delta_m, frames, out)?;
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
    Ok(())
}
