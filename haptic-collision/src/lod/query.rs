//! The query: both hierarchies walked together (tool placed in the obstacle's mesh frame).

use haptic_core::{
    Contact, ContactSet, Mat3, NO_FEATURE, Pose, QueryStats, Real, Vec3, gap_weight_m,
};

use super::build::{Hierarchy, Node, PieceBall};
use super::refine::{
    FACING_COS, Written, band_weight_m3, overhang_weight_error_m3, refine_regions,
    wall_weight_error_m3, weight_error_m3, weight_unsure,
};
use super::{LodError, MAX_PIECE_VERTICES};
use crate::geometry::PairContact;
use crate::slab::{HeightOffset, RegionContact, beside_prism_m, pair_region, pair_region_beside};

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
        out.push(self.contact(pc, feature_a, feature_b, area_m2)?);
        Ok(())
    }

    /// Writes a closest approach (obstacle frame) as a world-frame contact of
    /// [`super::closest::closest_approach_area_m2`] at `delta_m` and no stiffness share: it reports the
    /// distance and pushes nothing, alone in its call too (`closest.rs`).
    ///
    /// # Errors
    /// [`LodError::Core`] if the contact is not finite (a degenerate input).
    #[inline]
    pub fn emit_closest_approach(
        &self,
        pc: &PairContact,
        delta_m: Real,
        out: &mut ContactSet,
    ) -> Result<(), LodError> {
        let c = self.contact(
            pc,
            NO_FEATURE,
            NO_FEATURE,
            super::closest::closest_approach_area_m2(delta_m),
        )?;
        out.push(c.with_stiffness_share(0.0));
        Ok(())
    }

    /// A pair result (obstacle frame) as a world-frame contact standing for `area_m2`.
    #[inline]
    fn contact(
        &self,
        pc: &PairContact,
        feature_a: u32,
        feature_b: u32,
        area_m2: Real,
    ) -> Result<Contact, LodError> {
        let p_a = self.obs_rot * pc.p_a + self.obs_pos;
        let p_b = self.obs_rot * pc.p_b + self.obs_pos;
        let n = self.obs_rot * pc.n;
        let r_a = self.tool_rot_t * (p_a - self.tool_pos);
        Ok(Contact::new(p_a, r_a, p_b, n, pc.depth)?
            .with_features(feature_a, feature_b)
            .with_area(area_m2))
    }
}

/// A tool node's bounding sphere centre and slab in the obstacle frame, placed once for the run
/// of pairs that share the tool node (the walk descends the obstacle's node in place).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PlacedNode {
    index: u32,
    center: Vec3,
    normal: Vec3,
    /// `normal · plane_point`: where the slab's mid-plane lies along `normal`.
    offset: Real,
}

impl PlacedNode {
    pub(crate) const NONE: Self = Self {
        index: u32::MAX,
        center: Vec3::new(0.0, 0.0, 0.0),
        normal: Vec3::new(0.0, 0.0, 0.0),
        offset: 0.0,
    };

    /// Node `index` (`a`) placed by `frames`, unless it is the one already placed.
    #[inline]
    pub(crate) fn place(&mut self, index: u32, a: &Node, frames: &Frames) {
        if self.index != index {
            let normal = frames.rot * a.normal;
            *self = Self {
                index,
                center: frames.point(&a.center),
                normal,
                // `(R n)·(R p + t) = n·p + (R n)·t`.
                offset: a.normal.dot(&a.plane_point) + normal.dot(&frames.trans),
            };
        }
    }
}

/// Whether a tool node (placed in the obstacle frame) and an obstacle node are farther apart
/// than `delta` (conservative: spheres and slabs). The walk's cull at `δ`, and the closest
/// approach's bound (`closest.rs`) at the distance found so far.
#[inline]
pub(crate) fn culled(a: &Node, placed: &PlacedNode, b: &Node, delta: Real) -> bool {
    let ca = &placed.center;
    let d = ca - b.center;
    let reach = a.radius + b.radius + delta;
    if d.norm_squared() > reach * reach {
        return true;
    }
    if b.normal.dot(&(ca - b.plane_point)).abs() - b.half_thickness - a.radius > delta {
        return true;
    }
    // The tool's slab, in the obstacle frame.
    (placed.normal.dot(&b.center) - placed.offset).abs() - a.half_thickness - b.radius > delta
}

/// Whether a tool piece inside the ball of `radius_m` about `center` (obstacle frame) and the
/// obstacle piece inside the ball `b` lie beside each other as seen along the obstacle piece's
/// normal `nb` (the balls' shadows on its plane are apart), so that no part of the tool's lies
/// over the obstacle's and [`pair_region`] finds nothing, and are no nearer than `found_m`, so
/// that their closest approach is not needed either (`closest_approaches` keeps only one nearer
/// than the nearest found).
#[inline]
pub(crate) fn beside(
    center: &Vec3,
    radius_m: Real,
    b: &PieceBall,
    nb: &Vec3,
    found_m: Real,
) -> bool {
    let d = center - b.center;
    let along = nb.dot(&d);
    let apart2 = d.norm_squared();
    let r = radius_m + b.radius_m;
    let near = r + found_m;
    apart2 - along * along > r * r && (found_m <= 0.0 || apart2 >= near * near)
}

/// The tool's piece of `a` in the obstacle frame, into `buf`; returns its length and normal.
#[inline]
pub(crate) fn place_piece(
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
pub(crate) fn plane_gap(poly: &[Vec3], n: &Vec3, p0: &Vec3) -> Real {
    let (mut lo, mut hi) = (Real::INFINITY, Real::NEG_INFINITY);
    for v in poly {
        let h = n.dot(&(v - p0));
        lo = lo.min(h);
        hi = hi.max(h);
    }
    lo.max(-hi).max(0.0)
}

/// Whether the two polygons' projections on the line from `from` to `to` (their nodes' sphere
/// centres, near the pieces' middles) are more than `delta` apart (then so are the polygons).
#[inline]
fn apart_along(a: &[Vec3], b: &[Vec3], from: &Vec3, to: &Vec3, delta: Real) -> bool {
    let d = to - from;
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

/// What one traversal of the tool against one obstacle needs.
#[derive(Clone, Copy)]
pub(crate) struct Walk<'a> {
    /// The tool's hierarchy.
    pub tool: &'a Hierarchy,
    /// The obstacle's hierarchy.
    pub obs: &'a Hierarchy,
    /// The obstacle's index (in `Scratch::nearest` and `Scratch::apart`).
    pub obstacle: u32,
    pub frames: &'a Frames,
    /// Absolute error threshold (m) on `s_a + s_b`; 0 descends to triangles.
    pub epsilon_m: Real,
    /// Distance tolerance δ (m).
    pub delta_m: Real,
    /// The least normal coherence both coarse pieces of a pair that writes a contact must have
    /// to stop there ([`super::StoppingRule::min_coherence`]) in a walk pair by pair
    /// ([`Pass::PairByPair`]); below 0, any.
    pub min_coherence: Real,
    /// Whether the regions' bound on their force's error is held within the
    /// threshold of the net force by refining the largest (`refine.rs`,
    /// [`super::StoppingRule::refines_regions`]).
    pub refine: bool,
    /// Whether a stopped pair is dropped only when its pieces, shifted and spread by the heights
    /// of the surfaces they stand for, lie beyond δ, rather than the pieces themselves
    /// ([`super::StoppingRule::culls_at_surfaces`]).
    pub cull_at_surfaces: bool,
    /// Pair by pair below the regions taken out (`refine.rs`), the largest weight error a
    /// region may have per unit of its weight, `ρ`: a coarse pair whose region's is larger is
    /// descended. Infinite elsewhere.
    pub weight_error_per_weight: Real,
    /// The height over which the obstacle piece's normal spread counts in the stopping rule
    /// (m): a pair stops where `s_a + s_b + h tan φ_b ≤ ε`, `tan φ_b` the obstacle piece's
    /// [`super::SurfaceMoments::spread_tan`] ([`super::StoppingRule::spread_height_m`]: `δ`
    /// under the budgeted rule, 0 under the paper's). The budgeted rule also looks that far
    /// beyond the obstacle piece's prism, `s_a + s_b + h tan φ_b`, for the surfaces of pieces
    /// that do not face each other (`refine.rs`).
    pub spread_height_m: Real,
}

/// Scratch reused by every query, so that a query allocates nothing once warm.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scratch {
    /// The traversal stack of node pairs (tool, obstacle).
    pub stack: Vec<(u32, u32)>,
    /// Stopped pairs whose closest approach may lie outside their region (they do not cross
    /// over the obstacle piece): a lower bound on their distance, the obstacle and the nodes.
    pub apart: Vec<(Real, u32, u32, u32)>,
    /// Per obstacle: the smallest distances written and found so far.
    pub nearest: Vec<Nearest>,
    /// Per obstacle: the frames of this query.
    pub frames: Vec<Frames>,
    /// The regions the walk wrote against the obstacle at hand, when it refines them
    /// (`refine.rs`).
    pub written: Vec<Written>,
}

/// The smallest distances of one obstacle's contacts in a query.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Nearest {
    /// The smallest distance written (m): of a contact in the output.
    pub written_m: Real,
    /// The smallest distance found (m): written, or the nearest point of a region.
    pub found_m: Real,
    /// The pair (tool node, obstacle node) whose region gave `found_m`, when it was not
    /// written.
    pub found_pair: Option<(u32, u32)>,
}

impl Nearest {
    /// Nothing found yet.
    pub const NONE: Self = Self {
        written_m: Real::INFINITY,
        found_m: Real::INFINITY,
        found_pair: None,
    };

    /// A contact at `distance_m` was written.
    #[inline]
    pub fn written(&mut self, distance_m: Real) {
        self.written_m = self.written_m.min(distance_m);
        if distance_m <= self.found_m {
            self.found_m = distance_m;
            self.found_pair = None;
        }
    }

    /// Pair `(ia, ib)` has a region whose nearest point is at `distance_m`.
    #[inline]
    pub fn found(&mut self, distance_m: Real, ia: u32, ib: u32) {
        if distance_m < self.found_m {
            self.found_m = distance_m;
            self.found_pair = Some((ia, ib));
        }
    }
}

/// Walks the tool against obstacle `walk.obstacle` from the root pair and writes one contact per
/// stopped pair into `out` ([`pair_region`]), noting the distances in `scratch.nearest` and the
/// pairs whose closest approach may lie outside their region in `scratch.apart`; then, where
/// the walk refines its regions, refines them (`refine.rs`).
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
pub(crate) fn collide(
    walk: &Walk<'_>,
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    scratch.stack.clear();
    scratch.stack.push((0, 0));
    if !walk.refine {
        return walk_from_stack(walk, Pass::PairByPair, scratch, out, stats);
    }
    let start = out.len();
    scratch.written.clear();
    walk_from_stack(walk, Pass::Record, scratch, out, stats)?;
    refine_regions(walk, start, scratch, out, stats)?;
    if out.len() == start && walk.epsilon_m > 0.0 {
        first_touch(walk, scratch, out, stats)?;
    }
    Ok(())
}

/// Where the budgeted rule's walk wrote no region against the obstacle, its net force is none,
/// and so is its budget: no coarse pair may stand for the surfaces. The stopped pairs that came
/// within reach without a region (`scratch.apart`, at a first touch the coarse pieces that lie
/// beside each other or beyond the slab while a few triangles touch) are walked again down to
/// their triangles, which write the exact regions. Without it, at a first touch the all-pairs
/// reference pushed a little and LOD not at all (the suite's fork on the cow, errors of 1 at
/// 2.5 %); it costs nothing where a region is written, which is every call in contact.
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
/// The most pairs [`first_touch`] walks down one by one (each compared with every other for
/// overlaps); beyond them it walks from the roots.
const FIRST_TOUCH_PAIRS_MAX: usize = 256;

fn first_touch(
    walk: &Walk<'_>,
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    let (tool, obs) = (walk.tool, walk.obs);
    // A node's subtree is the `2 t − 1` nodes from it on (depth-first order, `t` its triangles).
    let below = |i: u32, j: u32, t: u32| (i..i + 2 * t - 1).contains(&j);
    let Scratch { apart, stack, .. } = scratch;
    stack.clear();
    // The stopped pairs within reach of this obstacle, with their place in `apart`.
    let near = || {
        apart
            .iter()
            .enumerate()
            .filter(|&(_, &(gap, o, _, _))| o == walk.obstacle && gap <= walk.delta_m)
            .map(|(k, &(_, _, ia, ib))| (k, ia, ib))
    };
    // Many pairs within reach and no region (a tool hovering over a wide surface): the whole
    // walk at `ε` = 0, rather than comparing every pair with every other.
    if near().count() > FIRST_TOUCH_PAIRS_MAX {
        stack.push((0, 0));
    } else {
        for (k, ia, ib) in near() {
            let (a, b) = (&tool.nodes[ia as usize], &obs.nodes[ib as usize]);
            // Two triangles are exact already; a pair inside another's subtrees (a band the
            // budget took out, and the pairs written below it), or listed before, is walked
            // with it.
            let inside = near().any(|(l, ja, jb)| {
                let (ta, tb) = (
                    tool.nodes[ja as usize].triangles,
                    obs.nodes[jb as usize].triangles,
                );
                if (ja, jb) == (ia, ib) {
                    l < k
                } else {
                    below(ja, ia, ta) && below(jb, ib, tb)
                }
            });
            if !(inside || a.is_leaf() && b.is_leaf()) {
                descend(ia, a, ib, b, stack);
            }
        }
    }
    let exact = Walk {
        epsilon_m: 0.0,
        ..*walk
    };
    walk_from_stack(&exact, Pass::PairByPair, scratch, out, stats)
}

/// How a walk treats the regions it writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Pass {
    /// Pair by pair: a region whose pieces are less coherent than `walk.min_coherence` is not
    /// written; its pair is descended (the paper's rule asks for no coherence). The walk of the
    /// coherence rule, and the walk below the regions the budgeted rule refines, where a region
    /// whose weight is unsure (`refine::weight_unsure`) is descended too.
    PairByPair,
    /// Every region is written whatever its pieces' coherence, and noted in `scratch.written`
    /// for the refinement to choose from (`refine.rs`): the budgeted rule's first walk.
    Record,
}

/// Walks the pairs on `scratch.stack` and everything below them that is not culled, as
/// [`collide`] says, in `pass`.
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
pub(crate) fn walk_from_stack(
    walk: &Walk<'_>,
    pass: Pass,
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    let Scratch {
        stack,
        apart,
        nearest,
        written,
        ..
    } = scratch;
    let (tool, obs, obstacle) = (walk.tool, walk.obs, walk.obstacle);
    let frames = walk.frames;
    let delta = walk.delta_m;
    let min_coherence = if pass == Pass::Record {
        -1.0
    } else {
        walk.min_coherence
    };
    // The tool piece last placed (`piece_of`, the buffer's length and its normal): the
    // pairs of one tool node against the obstacle nodes it is descended against come one
    // after the other.
    let mut buf = [Vec3::zeros(); MAX_PIECE_VERTICES];
    let mut piece_of = u32::MAX;
    let (mut len, mut na) = (0, Vec3::zeros());
    let nearest = &mut nearest[obstacle as usize];
    let mut placed = PlacedNode::NONE;
    while let Some((ia, ib)) = stack.pop() {
        let a = &tool.nodes[ia as usize];
        let b = &obs.nodes[ib as usize];
        stats.node_pairs_tested += 1;
        placed.place(ia, a, frames);
        if culled(a, &placed, b, delta) {
            continue;
        }
        let (leaf_a, leaf_b) = (a.is_leaf(), b.is_leaf());
        // Stopping rule of the CLOD traversal: both pieces within the error budget.
        // The obstacle piece's triangles lean from its prism by its normal spread, `h tan φ_b`
        // aside at the height `h`: where that is comparable with the penalty's reach, the
        // piece's prism does not tell which part of the tool its surface lies under.
        let stop = (leaf_a && leaf_b)
            || (walk.epsilon_m > 0.0
                && a.deviation
                    + b.deviation
                    + walk.spread_height_m * obs.moments_of(ib).spread_tan
                    <= walk.epsilon_m);
        if stop {
            let (da, db) = (tool.piece_ball_of(ia), obs.piece_ball_of(ib));
            // (The surfaces lie within the deviations of the pieces' balls: no nearer than the
            // distance found, they are not needed for the closest approach.)
            let deviations_m = a.deviation + b.deviation;
            if beside(
                &frames.point(&da.center),
                da.radius_m,
                db,
                &b.normal,
                if nearest.found_m > 0.0 {
                    nearest.found_m + deviations_m
                } else {
                    nearest.found_m
                },
            ) {
                continue;
            }
            if piece_of != ia {
                (len, na) = place_piece(tool, a, frames, &mut buf);
                piece_of = ia;
            }
            let cos_ab = na.dot(&b.normal);
            let pa = frames.point(&a.plane_point);
            let pb = obs.piece_of(b);
            let gap =
                plane_gap(&buf[..len], &b.normal, &b.plane_point).max(plane_gap(pb, &na, &pa));
            // A leaf's moments are those of a flat triangle (no offset, full cover), so the same
            // path gives the exact region of two triangles.
            let offset = |ia, ib| {
                let (ma, mb) = (tool.moments_of(ia), obs.moments_of(ib));
                (ma, mb, HeightOffset::of_pieces(ma, mb, cos_ab))
            };
            // Piece-level cull: one piece entirely beyond reach on one side of the other's plane,
            // or along the line between them. The reach is δ, or under the coherence rule as far
            // as `pair_region` integrates the surfaces the pieces stand for (`stopping.rs`).
            let early = walk.cull_at_surfaces.then(|| offset(ia, ib));
            let reach = early.map_or(delta, |(_, _, o)| delta + o.reach_m());
            if gap > reach || apart_along(&buf[..len], pb, &placed.center, &b.center, reach) {
                continue;
            }
            stats.primitive_pairs_tested += 1;
            let (ma, mb, offset) = early.unwrap_or_else(|| offset(ia, ib));
            // The share of the pieces their surfaces cover, and how far the surfaces lie from
            // the pieces at most.
            let cover = ma.cover * mb.cover;
            // Facing coarse pieces under the budgeted rule measure where they lie beside each
            // other's prisms (below).
            let facing = walk.refine && !(leaf_a && leaf_b) && cos_ab <= -FACING_COS;
            // The first walk measures where their region ends along the obstacle prism's walls,
            // where those of the surfaces lean from them (`refine.rs`).
            let regions = if facing {
                let walls = pass == Pass::Record && mb.spread_tan > 0.0;
                let overhang = (tool.overhang_of(a, ma), obs.overhang_of(b, mb));
                pair_region_beside(&buf[..len], pb, &b.normal, delta, offset, walls, overhang)
            } else {
                pair_region(&buf[..len], pb, &b.normal, delta, offset)
            };
            // The budgeted rule: pieces that do not face each other and do not stand exactly
            // for their surfaces put a region where those surfaces may have none, or none
            // where they may have one (`refine.rs`). Beside the obstacle piece's prism within
            // their deviations and the lean of its surface's own prisms at the penalty's reach
            // (`h tan φ_b`, as the stopping rule counts it), such a pair is descended; pair by
            // pair, so is its region.
            let unsure =
                walk.refine && !(leaf_a && leaf_b) && weight_unsure(cos_ab, deviations_m, cover);
            if unsure
                && regions.region.is_none()
                && beside_prism_m(&buf[..len], pb, &b.normal, delta + offset.reach_m())
                    < deviations_m + walk.spread_height_m * mb.spread_tan
            {
                descend(ia, a, ib, b, stack);
                continue;
            }
            // Facing coarse pieces with no region, beyond a wall of the obstacle piece's prism
            // by less than their deviations: the surfaces they stand for may lie over each
            // other in a band along it (`refine.rs`). Past a corner of the prism, where no wall
            // separates them, they may within their deviations and the lean of the obstacle
            // surface's own prisms, as pieces that do not face each other may (above): a square
            // band at the corner. So is a tool piece over the prism but out of the slab, beside
            // it by nothing (`beside_prism_m`): its surfaces lie within the deviations of it,
            // which may reach further than the spread's half-width (a statistic) lets its
            // region's weight say. The first walk shows the band's weight to the budget; below
            // the regions taken out, the pair is descended where the band may weigh more than
            // its share.
            let band = match regions.beside {
                Some((beside_m, shared_m)) => {
                    (beside_m < deviations_m).then_some((deviations_m - beside_m, shared_m))
                }
                None if facing && regions.region.is_none() && regions.nearest_m.is_infinite() => {
                    let reach_m = deviations_m + walk.spread_height_m * mb.spread_tan;
                    // Below the regions taken out, a band no wider than that reach is within
                    // its share whatever how far beside the prism the tool piece lies.
                    let within_share = pass == Pass::PairByPair
                        && reach_m * reach_m
                            <= walk.weight_error_per_weight * ma.area_m2.min(mb.area_m2);
                    if within_share {
                        None
                    } else {
                        let beside_m =
                            beside_prism_m(&buf[..len], pb, &b.normal, delta + offset.reach_m());
                        (beside_m < reach_m).then_some((reach_m - beside_m, 0.0))
                    }
                }
                None => None,
            };
            if let Some((width_m, shared_m)) = band {
                let g_m = gap_weight_m(-gap, delta);
                let band_m3 = band_weight_m3(width_m, shared_m, g_m);
                if pass == Pass::Record {
                    written.push(Written::band((ia, ib), band_m3, g_m));
                } else if band_m3 > walk.weight_error_per_weight * ma.area_m2.min(mb.area_m2) * g_m
                {
                    descend(ia, a, ib, b, stack);
                    continue;
                }
            }
            // The coherence rule (`stopping.rs`): a contact between pieces whose surfaces face
            // too many ways is not written; the pair is descended like any other. Below a
            // region taken out, so is one whose weight is less sure than its share of the
            // budget allows (`refine.rs`).
            let weight_loose = |r: &RegionContact| {
                let area_m2 = r.area_m2 * cover;
                let w = area_m2 * gap_weight_m(r.depth_m, delta);
                let base = weight_error_m3(w, area_m2, offset.half_width_m, cover);
                base + overhang_weight_error_m3(r.overhang_m3, w, cover, base)
                    > walk.weight_error_per_weight * w
            };
            if regions.region.is_some()
                && !(leaf_a && leaf_b)
                && (ma.coherence.min(mb.coherence) < min_coherence
                    || (pass == Pass::PairByPair
                        && (unsure || regions.region.as_ref().is_some_and(weight_loose))))
            {
                descend(ia, a, ib, b, stack);
                continue;
            }
            if let Some(r) = regions.region {
                // Along the obstacle surface's normal where the region lies (the piece's own
                // normal for a triangle, whose field is zero).
                let nb = if leaf_b {
                    b.normal
                } else {
                    obs.normal_field_of(ib).normal_at(&b.normal, &r.centroid)
                };
                let pc = r.pair_contact(&nb);
                let (fa, fb) = if leaf_a && leaf_b {
                    (a.triangle, b.triangle)
                } else {
                    (NO_FEATURE, NO_FEATURE)
                };
                let area_m2 = r.area_m2 * cover;
                if pass == Pass::Record {
                    let coherence = ma.coherence.min(mb.coherence);
                    let g_m = gap_weight_m(pc.depth, delta);
                    let height_m = pc.depth.abs() + offset.half_width_m;
                    let walls_m3 = wall_weight_error_m3(r.walls_m, height_m, mb.spread_tan, g_m);
                    written.push(
                        Written::of(
                            out.len(),
                            (ia, ib),
                            (area_m2 * g_m, area_m2),
                            (coherence, offset.half_width_m, cover),
                            &pc.n,
                            r.pieces_beyond(delta) && coherence < walk.min_coherence,
                            unsure,
                        )
                        .with_overhang_error(r.overhang_m3, cover)
                        .with_wall_error(walls_m3 * cover),
                    );
                }
                frames.emit(&pc, fa, fb, area_m2, out)?;
                nearest.written(pc.distance);
            }
            if regions.nearest_m.is_finite() {
                nearest.found(regions.nearest_m, ia, ib);
            }
            // Its closest approach may lie outside the region (beyond an edge of `b`), unless
            // even its surfaces' lower bound is beyond a distance already found (which only
            // decreases, so `closest_approaches` would skip it).
            if regions.nearest_m > 0.0 && gap - deviations_m < nearest.found_m {
                apart.push((gap, obstacle, ia, ib));
            }
            continue;
        }
        descend(ia, a, ib, b, stack);
    }
    Ok(())
}

/// Pushes the children pairs of `(ia, ib)`, not both leaves: the node with the larger deviation
/// is split (ties: the larger one).
#[inline]
pub(crate) fn descend(ia: u32, a: &Node, ib: u32, b: &Node, stack: &mut Vec<(u32, u32)>) {
    let split_a = if a.is_leaf() {
        false
    } else if b.is_leaf() {
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
