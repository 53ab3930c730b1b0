//! The closest approach: after the walk, the smallest separation between the tool's and an
//! obstacle's surfaces, written as a contact of negligible area where it is closer than every
//! contact written against that obstacle.
//!
//! A region's contact sits at its weighted mean depth, and a pair's closest points may lie
//! beyond the obstacle piece's edges, outside every region; so the stopped pairs whose closest
//! approach could be closer than every contact written are searched (`Scratch::apart`, and the
//! pair whose region's nearest point was the nearest found). A stopped pair's pieces may be
//! nearer than its surfaces by up to the two deviations (`ε` together, up to `δ`): written at
//! the pieces' distance, the closest approach of surfaces a little beyond `δ` became a contact
//! within it, and a contact alone in a call pushes with the whole stiffness whatever its area
//! (the clustering's shares are relative), a force of up to `k_c ε` where there is none (the
//! fork at the rim of the mug before it touches, errors of 1 at 10 % of the poses:
//! `docs/experiments/lod-accuracy-and-speed-probes.md`, probe 27). So the distance written is
//! always one between triangles, found by branch and bound on the nodes' bounding spheres and
//! slabs (the walk's cull, `query::culled`, at the distance found so far), and the walk keeps
//! every stopped pair whose surfaces (its pieces less their deviations) may be nearer than the
//! distance found:
//! - where nothing else is written against the obstacle, the exact smallest one under every
//!   candidate whose pieces' distance less the two deviations is below the distance found so
//!   far, within `δ`;
//! - beside regions, where the closest approach weighs nothing, the smallest one under the pair
//!   whose pieces are nearest, when those are nearer than every contact written; then, within
//!   `ε` (the threshold's error), under every other candidate whose surfaces may come more than
//!   `ε` nearer (its pieces' distance, no less than the nearest pieces' or the distance found,
//!   less the two deviations): subtrees that cannot come `ε` nearer than the best are skipped.
//!   The distance reported is within `ε` of the surfaces' smallest. The nearest pieces' pair
//!   alone was up to two deviations off (1.01 ε in a regression of
//!   `threshold_error_is_bounded`, the deviation rule); every candidate searched exactly cost the gears at
//!   0.4 % a fifth more node pairs and twice the time; this costs 10 % more node pairs there on
//!   the fine gears, 0.3 % on the jaws at 2.5 %.
//!
//! Where a written contact crosses (in contact, most calls), nothing can be closer and nothing
//! is searched.
//!
//! The contact reports a distance and stands for no surface: it carries no stiffness share
//! (`Contact::stiffness_share` 0), so that it pushes nothing, alone in its call too. With the
//! share of 1 a back-end's contacts carry, a closest approach alone (at a first touch, where
//! the coarse pieces have no region yet) pushed with the clustering's whole stiffness at its
//! depth, while the regions of the all-pairs reference beside the same closest approach push
//! at theirs: the suite's fork on the cow at 2.5 % had errors of 5.5 at its first touches
//! (1.0 since: no force where the reference's is 10⁻⁵ of the median).

use haptic_core::{ContactSet, Pose, QueryStats, Real, Vec3};

use super::build::Hierarchy;
use super::query::{Frames, Nearest, PlacedNode, Scratch, culled, descend, place_piece, plane_gap};
use super::{LodError, MAX_PIECE_VERTICES};
use crate::compact::area_floor_m2;
use crate::geometry::{self, PairContact, closest_points_below, convex_polygon_pair};

/// The area a closest-approach contact stands for at the penalty's reach `delta_m` (m²): the
/// compaction's floor, `10⁻¹² δ²`, so that it weighs nothing beside the regions in any units;
/// not 0, which the clustering reads as "this back-end does not measure areas" and then weighs
/// every contact of the call alike.
#[inline]
pub(crate) fn closest_approach_area_m2(delta_m: Real) -> Real {
    area_floor_m2(delta_m)
}

/// A pair's closest approach as a contact: where the polygons cross, touching (depth 0) at the
/// middle of their separating-axis contact, since the regions carry the force and the
/// separating-axis depth measures the polygons' sizes rather than how far the tool went in.
pub(crate) fn touching_if_crossing(pc: PairContact) -> PairContact {
    if pc.depth <= 0.0 {
        return pc;
    }
    let x = (pc.p_a + pc.p_b) * 0.5;
    PairContact {
        p_a: x,
        p_b: x,
        depth: 0.0,
        distance: 0.0,
        ..pc
    }
}

/// The closest approach between the surfaces under the stopped pairs that could hold one closer
/// than written (`scratch.apart`, emptied, and each obstacle's `found_pair`), one contact per
/// obstacle where it is within `δ` and closer than every contact written against that obstacle:
/// the exact distance between the tool's and the obstacle's triangles (0 where they cross),
/// whatever the threshold. The contact stands for [`closest_approach_area_m2`] with no
/// stiffness share: it reports the distance without adding to the force, integrated or
/// clustered.
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
pub(crate) fn closest_approaches(
    tool: &Hierarchy,
    obstacles: &[(Hierarchy, Pose)],
    delta_m: Real,
    epsilon_m: Real,
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    let Scratch {
        apart,
        nearest,
        frames,
        stack,
        ..
    } = scratch;
    // By obstacle, so that each obstacle's closest approach is found in one run.
    apart.sort_unstable_by_key(|&(_, o, ia, ib)| (o, ia, ib));
    for (o, found) in nearest.iter_mut().enumerate() {
        let run = {
            let lo = apart.partition_point(|x| (x.1 as usize) < o);
            let hi = apart.partition_point(|x| (x.1 as usize) <= o);
            &apart[lo..hi]
        };
        let search = Search {
            tool,
            obs: &obstacles[o].0,
            frames: &frames[o],
        };
        // A distance is never below 0: where a written contact crosses, none is closer.
        let limit = found.written_m.min(delta_m);
        let closest = if limit <= 0.0 || limit.is_nan() {
            None
        } else if found.written_m.is_finite() {
            // Beside regions: the stopped pieces nearest each other, if nearer than written,
            // searched down to their triangles.
            match search.among_pieces(run, found, delta_m) {
                Some((pc, ia, ib)) if pc.distance < found.written_m => {
                    let mut best = (limit, None);
                    stats.node_pairs_tested += search.search_below(ia, ib, 0.0, stack, &mut best);
                    // The nearest pieces' surfaces may lie up to their deviations farther than
                    // another pair's: that pair is searched too where its surfaces may come
                    // more than `ε` nearer than those found, so that the distance reported is
                    // within `ε` of the surfaces' (up to two deviations off before, up to 2ε).
                    // Every other pair's pieces are at least as far apart as these, or as the
                    // distance found (which, shifted by the surfaces' mean offsets, may be the
                    // nearer: then these are the pair that found it).
                    let floor_m = pc.distance.min(found.found_m);
                    for &(gap, _, ja, jb) in run {
                        let lower = search.lower_bound(gap.max(floor_m), ja, jb);
                        if lower < best.0 - epsilon_m && (ja, jb) != (ia, ib) {
                            stats.node_pairs_tested +=
                                search.search_below(ja, jb, epsilon_m, stack, &mut best);
                        }
                    }
                    best.1
                }
                _ => None,
            }
        } else {
            search.among_triangles(run, found, limit, stack, stats)
        };
        if let Some(pc) = closest {
            frames[o].emit_closest_approach(&pc, delta_m, out)?;
            found.written(pc.distance);
        }
    }
    apart.clear();
    Ok(())
}

/// The branch and bound for one obstacle's closest approach.
struct Search<'a> {
    tool: &'a Hierarchy,
    obs: &'a Hierarchy,
    frames: &'a Frames,
}

impl Search<'_> {
    /// A lower bound on the distance between the surfaces under the pair `(ia, ib)` whose pieces
    /// are at least `gap_m` apart: less the two deviations, each a two-sided Hausdorff bound.
    #[inline]
    fn lower_bound(&self, gap_m: Real, ia: u32, ib: u32) -> Real {
        gap_m - self.tool.nodes[ia as usize].deviation - self.obs.nodes[ib as usize].deviation
    }

    /// The stopped pieces' closest approach within `δ`, among the candidates whose lower bound
    /// is below the nearest distance found (`found.found_m`), else that of the pair whose region
    /// gave it: the exact distance between the pieces, within the two deviations of the
    /// surfaces'.
    fn among_pieces(
        &self,
        run: &[(Real, u32, u32, u32)],
        found: &Nearest,
        delta_m: Real,
    ) -> Option<(PairContact, u32, u32)> {
        let mut buf = [Vec3::zeros(); MAX_PIECE_VERTICES];
        let mut pieces = |ia: u32, ib: u32| {
            let (a, b) = (&self.tool.nodes[ia as usize], &self.obs.nodes[ib as usize]);
            let (len, na) = place_piece(self.tool, a, self.frames, &mut buf);
            let pc = convex_polygon_pair(&buf[..len], &na, self.obs.piece_of(b), &b.normal);
            touching_if_crossing(pc)
        };
        let mut near = found.found_m;
        let mut closest = None;
        for &(gap, _, ia, ib) in run {
            if gap >= near {
                continue;
            }
            let pc = pieces(ia, ib);
            if pc.distance < near && pc.depth >= -delta_m {
                near = pc.distance;
                closest = Some((pc, ia, ib));
            }
        }
        // Nothing closer than the nearest sample: that sample's pair holds the closest approach.
        if closest.is_none()
            && let Some((ia, ib)) = found.found_pair
        {
            let pc = pieces(ia, ib);
            if pc.depth >= -delta_m {
                closest = Some((pc, ia, ib));
            }
        }
        closest
    }

    /// The surfaces' closest approach within `δ`: the smallest distance between the triangles
    /// under the candidates and the pair whose region gave the nearest distance found, each
    /// searched where its lower bound (its pieces' less the two deviations, each a two-sided
    /// Hausdorff bound) is below the distance found so far, the lowest bound first.
    fn among_triangles(
        &self,
        run: &[(Real, u32, u32, u32)],
        found: &Nearest,
        limit_m: Real,
        stack: &mut Vec<(u32, u32)>,
        stats: &mut QueryStats,
    ) -> Option<PairContact> {
        let bound = |gap: Real, ia: u32, ib: u32| self.lower_bound(gap, ia, ib);
        let candidates = || {
            run.iter()
                .map(|&(gap, _, ia, ib)| (bound(gap, ia, ib), ia, ib))
                .chain(
                    found
                        .found_pair
                        .map(|(ia, ib)| (bound(found.found_m, ia, ib), ia, ib)),
                )
        };
        let first = candidates().min_by(|x, y| x.0.total_cmp(&y.0))?;
        let mut best = (limit_m, None);
        stats.node_pairs_tested += self.search_below(first.1, first.2, 0.0, stack, &mut best);
        for (lower, ia, ib) in candidates() {
            if lower < best.0 && (lower, ia, ib) != first {
                stats.node_pairs_tested += self.search_below(ia, ib, 0.0, stack, &mut best);
            }
        }
        best.1
    }

    /// Lowers `best` (a distance and the triangle pair's closest approach there) to the smallest
    /// distance between the triangles under `(ia, ib)`, where that is more than `slack_m` below
    /// it: subtrees that cannot come that much nearer are skipped, so the distance found is
    /// within `slack_m` of the smallest (0: the smallest).
    fn search_below(
        &self,
        ia: u32,
        ib: u32,
        slack_m: Real,
        stack: &mut Vec<(u32, u32)>,
        best: &mut (Real, Option<PairContact>),
    ) -> u64 {
        let mut tested = 0;
        let mut buf = [Vec3::zeros(); MAX_PIECE_VERTICES];
        let mut placed = PlacedNode::NONE;
        stack.clear();
        stack.push((ia, ib));
        while let Some((ia, ib)) = stack.pop() {
            tested += 1;
            let a = &self.tool.nodes[ia as usize];
            let b = &self.obs.nodes[ib as usize];
            placed.place(ia, a, self.frames);
            if culled(a, &placed, b, best.0 - slack_m) {
                continue;
            }
            if a.is_leaf() && b.is_leaf() {
                // A leaf's piece is its triangle.
                let (len, na) = place_piece(self.tool, a, self.frames, &mut buf);
                let pb = self.obs.piece_of(b);
                // Either triangle wholly beyond the other's plane by the distance found: they are
                // no nearer, and their exact distance is not needed (the fork in the mug, 4.4 %
                // fewer instructions a query).
                let pa = self.frames.point(&a.plane_point);
                let gap =
                    plane_gap(&buf[..len], &b.normal, &b.plane_point).max(plane_gap(pb, &na, &pa));
                if gap >= best.0 - slack_m {
                    continue;
                }
                // Apart (a plane between them): only a distance below the best found is
                // needed, and the candidates no nearer are skipped (5.7 % fewer instructions a
                // query of the fork in the mug). Otherwise they may cross.
                let pc = if gap > 0.0 {
                    closest_points_below(&buf[..len], &na, pb, &b.normal, best.0)
                        .and_then(|(p, q)| geometry::apart(p, q))
                } else {
                    Some(touching_if_crossing(convex_polygon_pair(
                        &buf[..len],
                        &na,
                        pb,
                        &b.normal,
                    )))
                };
                if let Some(pc) = pc.filter(|pc| pc.distance < best.0) {
                    *best = (pc.distance, Some(pc));
                }
                continue;
            }
            // The child pair whose centres are nearer popped first, for a small bound early.
            let at = stack.len();
            descend(ia, a, ib, b, stack);
            let apart = |&(ia, ib): &(u32, u32)| {
                (self.frames.point(&self.tool.nodes[ia as usize].center)
                    - self.obs.nodes[ib as usize].center)
                    .norm_squared()
            };
            if apart(&stack[at]) < apart(&stack[at + 1]) {
                stack.swap(at, at + 1);
            }
        }
        tested
    }
}
