//! The budgeted rule's refinement ([`super::StoppingRule::CoherenceBudget`]): the regions'
//! bound on the error of their force, held within the threshold of the net force by refining
//! the regions that hold most of it.
//!
//! A region pushes along one normal (its obstacle piece's, turned by the normal field where it
//! lies), while the surfaces its two pieces stand for face many ways. With `c` the lesser of the
//! two pieces' normal coherences (`|Σ aᵢ nᵢ| / Σ aᵢ` over their triangles, 1 for a flat patch),
//! the force `w n` it writes (`w = ∫g`, the penalty's weight over the region) is off the force
//! its surfaces would give by about `w (1 − c)` (`stopping.rs`). The paper's rule does not see
//! this; asking every region for `1 − c ≤ τ` (`τ = ε / r`, the threshold the walk stands for)
//! bounds each region's error by the same fraction as the threshold, but descends every coarse
//! pair of a curved or bumpy surface, whether it carries much of the force or not.
//!
//! Its weight is not sure either. The surfaces lie about the pieces by heights whose mean and
//! variance the pieces carry (`slab::HeightOffset`), and `w` is averaged over a uniform spread
//! of half-width `s` about that mean, the same over the whole piece. Where the heights are not
//! spread that way (a curved cap whose lowest point alone comes within `δ`, a region over part
//! of a piece whose mean lies elsewhere), `w` is off by up to about `a s`, `a` the area the region
//! stands for: the weight's change were the surfaces `s` nearer or farther. And a region's
//! area is counted by the share `k` of its pieces that their surfaces cover (the convex piece of
//! a patch that is not convex spreads beyond it; `SurfaceMoments::cover`), while the part of
//! the pieces it lies over may be covered more or less: `w` is off by up to about `w (1 − k)`
//! more. On the peg, whose coarse pieces' covers are about a half, that term took its error at
//! 2.5 % from 0.470 to 0.228. The force `w n` is off by at most `w |Δn| + |Δw|`; over the
//! regions, the direction bounds add (the regions of one curved surface err the same way) and
//! the weights' errors add in quadrature (a spread's half-width is a statistic, and its sign
//! differs from region to region): `Σ wᵢ (1 − cᵢ) + √(Σ eᵢ²)`, `eᵢ = aᵢ sᵢ + wᵢ (1 − kᵢ)`.
//! Without the weights' term, the spoon in the cup's p90 error at 2.5 % was 0.346 (0.037 with
//! the spread's) and the spoon in the mug's median 0.049 (0.005), for 10 % more instructions a
//! jaws query; added linearly, 53 % more (`docs/decisions.md`, "Stopping rule", twenty-fourth
//! session).
//!
//! Where a planar piece's uncovered share lies in one place (the convex hull of a few segments
//! of a washer, overhanging its opening by the chord's sagitta), a region over that place is off
//! by far more than `w (1 − k)`: the cow's feet on a bowl's rim weighed up to five times the rim
//! under them. The build measures, along each edge of a planar piece, the band outside which the
//! piece lies under its surface and that band's uncovered area (`overhang.rs`); a facing region's
//! weight over the bands it reaches, of either piece, is bounded (`slab::pair_region_beside`),
//! and `eᵢ` takes the larger of that bound less `(1 − k) W` (`W = w / k`) and its other terms
//! ([`overhang_weight_error_m3`]): the rim 0.097 / 0.332 → 0.024 / 0.063 at 2.5 %, for 1.5 % more
//! wall time a jaws query, whose pieces are curved and not measured (probe 40).
//!
//! So the rule bounds the sum instead, against the force the user feels: after the walk, the
//! error of the regions written, `Σ wᵢ (1 − cᵢ) + √(Σ eᵢ²)`, is compared with
//! `τ |Σ wᵢ nᵢ|`. Where it is larger, the regions with the largest bounds are taken out,
//! largest first, until what is left is within `τ |Σ wᵢ nᵢ|`; each pair taken out is
//! descended and walked again, where a region is written only if both its pieces have
//! `1 − c ≤ τ`. The net force is that of the regions
//! first written: where opposed contacts cancel (a peg in its hole, a bolt in its nut), it is
//! small, the budget with it, and more is refined. Triangle pairs (`c = 1`, `s = 0`) are never
//! taken out, so at threshold 0 nothing changes. Each obstacle is refined against its own net
//! force.
//!
//! **Both moments the contacts are read in.** The penalty pushes with `Σ wᵢ nᵢ`, but the
//! clustering's representatives push with `N k_c Σ wᵢ gᵢ nᵢ / W` (`haptic-cluster`, the
//! stiffness shares; `gᵢ = ∫g² / ∫g` a region's `g`-weighted mean gap, `W = Σ wᵢ`), and the two
//! cancel differently: where deep contacts push against each other (a spoon's bowl buried in a
//! bumpy terrain, gears whose teeth press both flanks), `|Σ wᵢ gᵢ nᵢ|` can be a thirtieth of
//! `Σ wᵢ gᵢ` while `|Σ wᵢ nᵢ|` is a sixth of `Σ wᵢ`, and errors the penalty's budget allows
//! come out several times larger in what the user feels. So the regions are held in both: after
//! the fewest largest that bring the rest within `τ |Σ wᵢ nᵢ|`, the fewest of the rest, their
//! bounds and forces weighed by their gaps `gᵢ` (the same relative errors, in the other
//! moment), that bring what is left within `τ |Σ wᵢ gᵢ nᵢ|` (`select::Moment`); the rounds
//! follow both net forces, and below the regions taken out a region's weight error is held
//! to the lesser of the two shares. Quick suite at 2.5 %, clustered median / p90: the coarse
//! gears 0.042 / 0.052 → 0.041 / 0.043 (the suite's worst), the rest within 0.003, no
//! unclustered error worse by more than 0.005; 44 unseen pairs all hold, eight better; the
//! Newell teaspoon on a terrain with `δ` = 5 % of its diagonal, p90 0.116 → 0.076; for 2 % more
//! node pairs and 7.5 % more wall time a jaws query at 2.5 % (1.5 % at 0.4 %; probe 42).
//! Holding the clustering's moment alone took 2.4 % fewer node pairs a jaws query and gave
//! the same clustered errors, but the penalty's own error grew up to threefold (the spoon in
//! the cup 0.004 → 0.013 at the median): the contacts are a back-end's answer to any contact
//! model, not only to this clustering's.
//!
//! The net force the budget is taken from is the first walk's, and the regions taken out may
//! push far less once refined: at a first touch, coarse pieces whose spread reaches within `δ`
//! where their surfaces do not write regions that the surfaces below them do not have. The
//! regions left were held against a force that is gone. So the refinement goes in rounds:
//! after the regions taken out are walked again, the net force of what is written now is
//! taken, and where it is smaller, the regions left are held against its budget, and more are
//! taken out, until they are within it or none is left (in at most eight rounds, the last
//! refining every region left; no query of the quick suite took more than seven, and seven
//! in ten of those that took more than one took two). The Newell teaspoon lowered onto a
//! wavy slab pushed where the all-pairs reference pushes nothing at 35 of 7,375 poses, and
//! now at one (10⁻²² m³); `cargo xtask bench collision --scene newell_teaspoon.stl,slab.stl`
//! at 2.5 %, 0.035 / 0.116 → 0.025 / 0.099 (median / p90; the reference pushing nothing at
//! 15 of its 200 poses, LOD at each), for 0.8 % more instructions a jaws query.
//!
//! Below the regions taken out, the regions written pair by pair spend no budget of their own,
//! and their weights can be off as much as the ones they replace: on a curved wall whose
//! contacts push nearly all ways at once (a round peg in its hole), the net force is a
//! sixteenth of `Σ wᵢ`, and the convex pieces of its irregular patches have weights off by up to
//! three times where they lie. So there a region is written only if, besides the coherence,
//! its weight error is within its share of the budget `B = τ |Σ wᵢ nᵢ|`:
//! `eᵢ ≤ ρ wᵢ`, `ρ = √3 B / √(Σ wⱼ²)` over the weights `wⱼ` of the regions taken out. The
//! regions below split those weights (`Σ wᵢ² ≤ Σ wⱼ²`), and an error spread evenly over
//! `±eᵢ` has the standard deviation `eᵢ / √3`: independent, their sum's is at most `B`. A pair
//! whose region is not is descended. Over the quick suite at 2.5 %, the peg in its hole's
//! error without clustering went from 0.158 to 0.034 (median; 0.143 to 0.009 at 0.4 %), the
//! spoon in the cup's p90 from 0.036 to 0.013, for 5 % more node pairs a jaws query and no
//! change elsewhere beyond the clustering's own (`docs/experiments/lod-accuracy-and-speed-probes.md`,
//! probe 29). Descending where the weight error is a bound of `e` rather than a standard
//! deviation of `e / √3` (the share `B` rather than `√3 B`) took 15 % more node pairs a jaws
//! query for the same errors; `2 B` took 3 % more and the same errors, `4 B` 1 % more and
//! left the bolt's fine tessellation worse (0.054 rather than 0.048 clustered, 0.091 rather
//! than 0.079 without).
//!
//! One kind of region is refined whatever the budget: one whose pieces fail the coherence
//! condition and lie beyond `δ` of each other, within reach only through the surfaces they
//! stand for (`RegionContact::pieces_beyond`). Its depth is held at `−δ` and its weight is the
//! surfaces' spread's, next to nothing,
//! while the surfaces themselves may come well within `δ` (the fork in the mug lost 2 N that
//! way beside regions whose weight made the budget;
//! `docs/experiments/lod-accuracy-and-speed-probes.md`, probe 24). Regions whose pieces lie
//! apart within `δ` keep a weight that says what their pieces do, and are left to the budget:
//! marking them too took 227 of the 262 regions a jaws query refined at 2.5 %, for 14 % more
//! instructions; over the suite it made the fork's p90 0.036 rather than 0.081 and the spoon
//! in the mug's median 0.058 rather than 0.049 (`docs/decisions.md`, twenty-third session).
//!
//! And one kind of region has a weight no spread can tell: that of coarse pieces that do not
//! face each other ([`weight_unsure`]: their normals more than 75° from opposed) and do not
//! stand exactly for their surfaces (a deviation, or a cover short of 1). Edge-on, the tool
//! piece crosses the obstacle piece's prism, and its region is a band `2δ` tall along the
//! prism's wall, whose place the piece knows only within its deviation: a round peg's wall
//! beside its hole's rim is in the convex pieces' prisms where they overhang the opening (and
//! the surface is not there), or beside them where they stop short of the rim (and it is).
//! Facing the same way, the tool piece lies behind the obstacle's surface, where the weight
//! jumps from `2δ` to 0 at the penalty's lower cut (a bolt's flank behind the nut's other
//! flank). The region is then all there or all missing, and the regions of one rim or one
//! flank err the same way: its weight is its bound, added to the direction bounds, not in
//! quadrature. Such a pair whose tool piece lies beside the obstacle piece's prism, by less
//! than the two deviations (`slab::beside_prism_m`), is descended rather than dropped,
//! and pair by pair (below a region taken out) its region is not written but descended,
//! down to pieces that stand for their surfaces or face each other. The suite's peg in its
//! hole at 2.5 %: 0.199 / 0.312 → 0.117 / 0.284 (median / p90), the bolt in its nut 0.106 /
//! 0.128 → 0.037 / 0.080 and 0.068 / 0.098 → 0.040 / 0.057 on its fine tessellation, for 9 %
//! more node pairs and 43 % more instructions a jaws query, whose error did not need it
//! (`docs/experiments/lod-accuracy-and-speed-probes.md`, probe 28).
//!
//! Where such a pair has no region and lies past a corner of the obstacle piece's prism, no
//! wall of the prism separates them, but a side of the tool piece's shadow may: an edge-on
//! chord of a round wall, its shadow a thin band, beside a rim piece's corner. It is measured
//! across that side too (`slab::beside_prism_m`), and descended where that is within the
//! deviations: the suite's peg at 2.5 %, p90 0.280 → 0.059, for 0.9 % more instructions a
//! jaws query (probe 30). Both are measured on the part of the tool piece within reach of
//! the obstacle's plane, and where that part lies over the prism (above the penalty's slab
//! or below it, where the surfaces may still reach) the pair is beside by nothing and
//! descended: a piece crossing the obstacle's plane steeply, over the prism only far below
//! it, had been dropped (probe 34: the suite's peg at 2.5 %, 0.017 / 0.059 → 0.012 / 0.023).
//!
//! How far beside counts is the two deviations and the lean of the obstacle surface's own
//! prisms: the triangles an obstacle piece stands for lean from it by up to `φ_b` (its normal
//! spread, [`super::SurfaceMoments::spread_tan`]), so at the penalty's reach `δ` their prisms
//! lie up to `δ tan φ_b` aside of the piece's, the lean the stopping rule counts against `ε`
//! (`StoppingRule::spread_height_m`), and reach a tool piece beside its prism. The Newell
//! teaspoon on Spot (1/20, `δ` = 2 mm): a flat piece of the spoon standing edge-on 0.3–1.7 mm
//! beside a piece of the cow of coherence 0.80 was dropped while 31 of their triangle pairs
//! pushed 7 % of the force, sideways; at 2.5 % the bench's error was 0.020 / 0.126 (median /
//! p90), now 0.015 / 0.070, and the suite's fork on the cow's p90 0.054 → 0.027, for 2.5 % more
//! node pairs and 5 % more wall time a jaws query (probe 39). Counting the lean in the facing
//! pieces' bands too (below) took 3.6 % more node pairs a jaws query and made the suite's
//! coarse gears worse (p90 0.052 → 0.058).
//!
//! Pieces that face each other have a weight the spread can tell, where they have a region.
//! Where they have none, the tool piece's shadow lying beyond a wall of the obstacle piece's
//! prism, the surfaces they stand for may still lie over each other in a band along that wall:
//! as wide as the two deviations less how far beyond it the shadow lies, as long as the two
//! shadows face each other across it, at the pieces' weight `δ − gap` ([`band_weight_m3`];
//! `slab::pair_region_beside` measures it where it finds the wall). On a wall whose contacts
//! push all ways at once (a peg centred in its bushing, a bolt's flanks), those bands are where
//! the force that does not cancel is lost: a peg centred in a bushing whose wall has 33
//! segments against its 40 was pushed sideways by 0.24 of its wrench. So the first walk notes
//! such a pair ([`Written::band`], no contact and no force) with the band's weight as its
//! weight error, and the budget takes it out like a region, largest first; below the regions
//! taken out, such a pair is descended where its band may weigh more than its share of the
//! budget, `ρ` times the lesser piece's area at that weight (what a region between them could
//! weigh at most). Quick suite at 2.5 %, clustered median / p90: the bushing's p90 0.111 →
//! 0.081, the bolts 0.041 / 0.071 → 0.038 / 0.045 and 0.038 / 0.055 → 0.031 / 0.043, the fine
//! gears' p90 0.033 → 0.018, for 7 % more node pairs and 20 % more instructions a jaws query.
//! Descending every such pair below the regions taken out gave the same errors for 21 % more
//! node pairs; dropping them there, 5 %, and the bushing's p90 not at all; the pieces past a
//! corner of the prism too (measured across the sides of the tool piece's shadow, a square
//! band), the same errors for 43 % more instructions (probe 32).
//!
//! Past a corner of the obstacle piece's prism no wall separates the pieces, and there the
//! surfaces may meet within the two deviations and the lean of the obstacle surface's own
//! prisms at the penalty's reach, `δ tan φ_b`, as for pieces that do not face each other: such a
//! pair is a square band at the corner, `w² g` (`w` that reach less how far beside the prism
//! the tool piece lies, `slab::beside_prism_m`), and so is a tool piece over the prism but out
//! of the slab (beside it by nothing), whose surfaces may lie within the deviations where the
//! spread's half-width, a statistic, puts none. Spot under the fork at a first touch with
//! `δ` = 3 % of the fork's diagonal: a flat piece of the fork 0.8 mm past the corner of a cow
//! piece of deviation 0.7 mm and lean `tan φ_b` = 0.29 had been dropped, and LOD wrote a
//! hundredth of the reference's weight; `cargo xtask bench collision --scene
//! basemesh_fork.stl,spot.stl --delta-mm 5.625` at 2.5 %, p90 0.123 → 0.043. Quick suite at
//! 2.5 %, clustered p90: the fork on the cow 0.027 → 0.015, the remeshed peg 0.047 → 0.033, the
//! coarse bolt 0.030 → 0.024 (without the pieces over the prism out of the slab, 0.025 and
//! 0.031), for 1.2 % more node pairs and 6–8 % more wall time a jaws query at 2.5 % (4 % at
//! 0.4 %; probe 42). The lean in the bands along a wall too took 3.7 % more node pairs a jaws
//! query and made the coarse gears worse (0.052 → 0.057).
//!
//! A region that ends along a wall of the obstacle piece's prism (where the tool piece
//! overhangs it) ends where the surfaces' own prisms do not: the obstacle's triangles lean from
//! its piece by up to `φ_b` (its [`super::SurfaceMoments::spread_tan`]), so that at the
//! region's height `h` over the piece their walls lie `h tan φ_b` aside. Where the pieces of
//! two walls meet at a seam of the obstacle's, the region there is a sliver whose weight that
//! lean decides: a peg centred in a bushing and tilted by 0.1°, both walls' first vertices at
//! the same angle (the suite's coarse bushing), wrote a tool piece over the obstacle piece
//! beside its own with a fifth of the weight its triangles have (0.58 against 3.15 ·
//! 10⁻¹² m³), and the wrench, the tilt's torque alone, was off by 0.23. So the first walk
//! measures each facing coarse region's length `L` along the walls
//! (`slab::RegionContact::walls_m`) and adds `L h tan φ_b g` to its weight's error
//! ([`wall_weight_error_m3`], `h` its depth's size and the spread's half-width, `g` its
//! weight per area). Quick suite at 2.5 %, clustered median / p90: the coarse bushing 0.008 /
//! 0.116 → 0.006 / 0.037, the fork on the cow 0.018 / 0.071 → 0.003 / 0.054, the jaws 0.014 /
//! 0.020 → 0.011 / 0.017, the rest within 0.013 either way, for 7 % more instructions a jaws
//! query (1 % of them measuring the walls). The same term below the regions taken out, in the
//! share `ρ`, took 19 % more and changed no error (probe 37).

use haptic_core::{Contact, ContactSet, QueryStats, Real, Vec3};

use super::LodError;
use super::query::{Pass, Scratch, Walk, descend, walk_from_stack};

mod select;
use select::{Moment, take_largest};

/// The cosine of the largest angle from opposed at which two pieces face each other: 75°.
/// Beyond it, a region is mostly a band along the obstacle prism's wall, or lies behind the
/// obstacle's surface. (Over the quick suite, 60° and 85° gave the same errors; 30° took 45 %
/// more node pairs a jaws query for the same.)
pub(crate) const FACING_COS: Real = 0.258_819_045_102_520_8;

/// Whether the weight of a coarse pair's region is unsure as a whole (see the module docs): the
/// pieces, of normals whose dot product is `cos_ab`, do not face each other (more than 75°
/// from opposed), and do not stand exactly for their surfaces (`deviation_sum_m`, the two
/// deviations added, above 0, or `cover`, the two covers multiplied, below 1).
#[inline]
pub(crate) fn weight_unsure(cos_ab: Real, deviation_sum_m: Real, cover: Real) -> bool {
    cos_ab > -FACING_COS && (deviation_sum_m > 0.0 || cover < 1.0)
}

/// A region the walk wrote, for the refinement to choose from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Written {
    /// Its contact's index in the output.
    pub index: u32,
    /// The pair (tool node, obstacle node) that wrote it.
    pub pair: (u32, u32),
    /// The bound on its force's direction error, `w (1 − c)` (m³: the penalty's weight `∫g`, a
    /// force over the stiffness), or its whole weight `w` where that is unsure
    /// ([`weight_unsure`]).
    pub bound: Real,
    /// The estimate of its weight's error, `a s + w (1 − k)` (m³): the weight's change were the
    /// surfaces a half-width `s` nearer or farther than the spread `w` was averaged over (`a`
    /// the area it stands for), and were the part of the pieces it covers all surface or none
    /// rather than the share `k` of them that is (the pieces' covers multiplied).
    pub weight_bound: Real,
    /// Its force over the stiffness, `w n` (obstacle frame, m³).
    pub force: Vec3,
    /// Its `g`-weighted mean gap, `∫g² / ∫g` (m): what its force weighs in the clustering's
    /// moment `Σ w g n` ([`Moment::Clustering`]), and its bounds with it.
    pub gap_m: Real,
    /// Whether it is refined whatever the budget: its pieces are less coherent than the rule
    /// asks and lie beyond `δ` of each other, so that its weight says nothing of what their
    /// surfaces push.
    pub always: bool,
}

impl Written {
    /// The region of contact `index`, written by `pair` with weight `w` (`∫g`, m³) along `n`
    /// over the area `area_m2`, its pieces' lesser normal coherence `coherence`, their
    /// surfaces' height half-width `spread_m` ([`crate::slab::HeightOffset`]) and the share
    /// `cover` of the pieces their surfaces cover (the two covers multiplied); `always` refined
    /// or by the budget; `unsure` whether its weight is unsure as a whole ([`weight_unsure`]).
    /// Its `g`-weighted mean gap is `w / area_m2` (the region's contact stands for
    /// `(∫g)² / ∫g²`).
    #[inline]
    pub fn of(
        index: usize,
        pair: (u32, u32),
        (w, area_m2): (Real, Real),
        (coherence, spread_m, cover): (Real, Real, Real),
        n: &Vec3,
        always: bool,
        unsure: bool,
    ) -> Self {
        let direction = w * (1.0 - coherence).max(0.0);
        Self {
            index: index as u32,
            pair,
            bound: if unsure { direction.max(w) } else { direction },
            weight_bound: weight_error_m3(w, area_m2, spread_m, cover),
            force: n * w,
            gap_m: if area_m2 > 0.0 { w / area_m2 } else { 0.0 },
            always,
        }
    }
}

impl Written {
    /// The same region, its weight's error `walls_m3` larger: that of its boundary along the
    /// obstacle piece's prism's walls ([`wall_weight_error_m3`]).
    #[inline]
    pub fn with_wall_error(mut self, walls_m3: Real) -> Self {
        self.weight_bound += walls_m3.max(0.0);
        self
    }

    /// The same region, its weight's error raised where it may lie over the part of its pieces
    /// that overhangs their surfaces, `overhang_m3` of its weight at most
    /// ([`overhang_weight_error_m3`], against the estimate so far; `cover` the pieces' covers
    /// multiplied).
    #[inline]
    pub fn with_overhang_error(mut self, overhang_m3: Real, cover: Real) -> Self {
        let w = self.force.norm();
        self.weight_bound += overhang_weight_error_m3(overhang_m3, w, cover, self.weight_bound);
        self
    }

    /// The index of a pair that wrote no contact ([`Written::band`]).
    pub const NO_CONTACT: u32 = u32::MAX;

    /// A pair of facing pieces that wrote no region though the surfaces they stand for may
    /// have one: the tool piece lies beyond a wall of the obstacle piece's prism by less than
    /// their two deviations (or past a corner of it, within their reach), so that a band of the
    /// surfaces may lie over each other there, with the weight `weight_m3` at most, at the gap
    /// `gap_m` (`δ − gap`). No contact and no force; its weight's error is that weight.
    #[inline]
    pub fn band(pair: (u32, u32), weight_m3: Real, gap_m: Real) -> Self {
        Self {
            index: Self::NO_CONTACT,
            pair,
            bound: 0.0,
            weight_bound: weight_m3.max(0.0),
            force: Vec3::zeros(),
            gap_m: gap_m.max(0.0),
            always: false,
        }
    }
}

/// The weight a band of the surfaces of two facing pieces may have where the tool piece's
/// shadow lies beyond a wall of the obstacle piece's prism (m³; module docs): `width_m` (the
/// two deviations less how far beyond) by the length the shadows face each other over,
/// `shared_m`, and `width_m` more (the band's ends), at the weight `g_m` (`δ − gap`, m). Past a
/// corner of the prism, `shared_m` is 0: a square of `width_m` (the deviations and the lean
/// less how far beside).
#[inline]
pub(crate) fn band_weight_m3(width_m: Real, shared_m: Real, g_m: Real) -> Real {
    let width_m = width_m.max(0.0);
    width_m * (shared_m.max(0.0) + width_m) * g_m.max(0.0)
}

/// The error of a region's weight where it ends along the walls of the obstacle piece's prism
/// (m³; module docs): over `walls_m` of its boundary, the prisms of the surfaces the piece
/// stands for lean from its own by up to `lean_tan` (the piece's
/// [`super::SurfaceMoments::spread_tan`]), so that at the region's height `height_m` over the
/// piece their walls lie `height_m · lean_tan` aside, a band of the weight `g_m` either way.
#[inline]
pub(crate) fn wall_weight_error_m3(
    walls_m: Real,
    height_m: Real,
    lean_tan: Real,
    g_m: Real,
) -> Real {
    walls_m.max(0.0) * height_m.max(0.0) * lean_tan.max(0.0) * g_m.max(0.0)
}

/// The estimate of a region's weight error, `a s + w (1 − k)` (m³; module docs), for its weight
/// `w` (`∫g`, m³) over the area `area_m2`, its surfaces' height half-width `spread_m` and the
/// share `cover` of its pieces that they cover.
#[inline]
pub(crate) fn weight_error_m3(w: Real, area_m2: Real, spread_m: Real, cover: Real) -> Real {
    area_m2 * spread_m.max(0.0) + w * (1.0 - cover).clamp(0.0, 1.0)
}

/// How much a region's weight error may exceed its estimate `base` (m³; [`weight_error_m3`]
/// and what else counts it) where the region may lie over the part of the obstacle piece that
/// overhangs its surface (module docs): of its whole weight `W = w / k` (`w` counts the share
/// `k` of it, `cover`), up to `overhang_m3` ([`crate::slab::RegionContact::overhang_m3`]) may
/// stand for no surface, so that the surfaces' weight lies between `W − overhang_m3` and `W`,
/// and `w` may be off by `overhang_m3 − (1 − k) W`. The estimate takes the larger of that and
/// `base`, which counts the same deviation of the surfaces from the pieces as heights.
#[inline]
pub(crate) fn overhang_weight_error_m3(
    overhang_m3: Real,
    w: Real,
    cover: Real,
    base: Real,
) -> Real {
    if overhang_m3 <= 0.0 {
        return 0.0;
    }
    let k = cover.clamp(0.0, 1.0);
    let whole = if k > 0.0 { w / k } else { w };
    (overhang_m3.min(whole) - (1.0 - k) * whole - base).max(0.0)
}

/// `√3`: an error spread evenly over `±e` has the standard deviation `e / √3`.
const SQRT_3: Real = 1.732_050_807_568_877_2;

/// Below the regions `taken` out, the largest weight error a region may have per unit of its
/// weight, `ρ = √3 B / √(Σ wⱼ²)` over the taken regions' weights `wⱼ`, for the budget `B`
/// (m³; module docs): the regions written below them, whose weights `wᵢ` split theirs
/// (`Σ wᵢ² ≤ Σ wⱼ²`), then err by `√(Σ (eᵢ/√3)²) ≤ B` in standard deviation. Infinite where
/// the taken regions weigh nothing.
fn weight_error_per_weight(budget: Real, taken: &[Written], moment: Moment) -> Real {
    let weights_squared: Real = taken
        .iter()
        .map(|w| (w.force * moment.scale(w)).norm_squared())
        .sum();
    let rho = SQRT_3 * budget / weights_squared.sqrt();
    // (An empty sum is −0: nothing weighed.)
    if weights_squared > 0.0 && rho >= 0.0 {
        rho
    } else {
        Real::INFINITY
    }
}

/// The most rounds [`refine_regions`] takes regions out in; the last takes every one left
/// with an error.
const MAX_ROUNDS: usize = 8;

/// Refines the regions written against `obstacle` since `out[start]` (noted in
/// `scratch.written`) as the module docs say, in rounds: the regions taken out against the
/// budget are walked again below, and where the net force left after that is smaller than the
/// one the budget was taken from, the regions left are held against the smaller budget, and
/// more are taken out, until what is left is within the budget of the force written, or, in
/// the last of [`MAX_ROUNDS`], all of them.
///
/// # Errors
/// [`LodError::Core`] for a non-finite contact.
pub(crate) fn refine_regions(
    walk: &Walk<'_>,
    start: usize,
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    let tau = 1.0 - walk.min_coherence;
    let net_of = |written: &[Written], moment: Moment| {
        written
            .iter()
            .fold(Vec3::zeros(), |sum, w| sum + w.force * moment.scale(w))
            .norm()
    };
    let mut net = net_of(&scratch.written, Moment::Penalty);
    let mut net_clustering = net_of(&scratch.written, Moment::Clustering);
    for round in 1..=MAX_ROUNDS {
        // The last round refines every region left that has an error at all, so that the
        // rounds stay few whatever the scene.
        let (budget, budget_clustering) = if round < MAX_ROUNDS {
            (tau * net, tau * net_clustering)
        } else {
            (0.0, 0.0)
        };
        // The penalty's moment first, then more of those left for the clustering's.
        let penalty = take_largest(&mut scratch.written, budget, Moment::Penalty);
        let taken = penalty
            + take_largest(
                &mut scratch.written[penalty..],
                budget_clustering,
                Moment::Clustering,
            );
        if taken == 0 {
            return Ok(());
        }
        let budgets = (budget, budget_clustering);
        refine_taken(walk, start, taken, budgets, scratch, out, stats)?;
        // The force the user feels is the one written now: where the regions taken out pushed
        // more than the surfaces below them (coarse pieces whose spread reaches within `δ`
        // where the surfaces do not, at a first touch), the regions left must be held against
        // what is left of it, in either moment.
        let contacts = &out.as_slice()[start..];
        let left = net_force(contacts, walk.delta_m, Moment::Penalty);
        let left_clustering = net_force(contacts, walk.delta_m, Moment::Clustering);
        if left.is_nan()
            || left_clustering.is_nan()
            || (left >= net && left_clustering >= net_clustering)
        {
            return Ok(());
        }
        net = net.min(left);
        net_clustering = net_clustering.min(left_clustering);
    }
    Ok(())
}

/// The norm of the net force over the stiffness of `contacts` in `moment`: `|Σ a g n|` (m³,
/// the penalty's) or `|Σ a g² n|` (m⁴, the clustering's).
fn net_force(contacts: &[Contact], delta_m: Real, moment: Moment) -> Real {
    contacts
        .iter()
        .fold(Vec3::zeros(), |sum, c| {
            let g = c.gap_weight_m(delta_m);
            sum + c.n * (c.area_m2 * g * moment.weight(g))
        })
        .norm()
}

/// One round of [`refine_regions`]: the first `taken` of `scratch.written` (taken out against
/// `budget`) have their contacts removed and are walked again below, pair by pair; they leave
/// `scratch.written`, and the indices of those left follow their contacts.
fn refine_taken(
    walk: &Walk<'_>,
    start: usize,
    taken: usize,
    (budget, budget_clustering): (Real, Real),
    scratch: &mut Scratch,
    out: &mut ContactSet,
    stats: &mut QueryStats,
) -> Result<(), LodError> {
    let (tool, obs, obstacle) = (walk.tool, walk.obs, walk.obstacle);
    let written = &mut scratch.written;
    let below = Walk {
        weight_error_per_weight: weight_error_per_weight(
            budget,
            &written[..taken],
            Moment::Penalty,
        )
        .min(weight_error_per_weight(
            budget_clustering,
            &written[..taken],
            Moment::Clustering,
        )),
        ..*walk
    };
    written[..taken].sort_unstable_by_key(|w| w.index);
    // Their contacts out, the rest in order (bands, `Written::NO_CONTACT`, sort last and
    // match no contact).
    let (mut i, mut next) = (0, 0);
    out.retain(|_| {
        let keep = i < start
            || written[..taken]
                .get(next)
                .is_none_or(|w| w.index as usize != i);
        if !keep {
            next += 1;
        }
        i += 1;
        keep
    });
    // The regions left keep their contacts, each moved down by those removed before it.
    let (removed, left) = written.split_at_mut(taken);
    for w in left.iter_mut().filter(|w| w.index != Written::NO_CONTACT) {
        w.index -= removed.partition_point(|r| r.index < w.index) as u32;
    }
    // The smallest distance written against this obstacle, now that some are gone (every
    // contact since `start` is a region's, at distance `−depth`).
    let nearest = &mut scratch.nearest[obstacle as usize];
    nearest.written_m = out.as_slice()[start..]
        .iter()
        .map(|c| -c.depth_m)
        .fold(Real::INFINITY, Real::min);
    let stack = &mut scratch.stack;
    stack.clear();
    for w in removed.iter().rev() {
        let (ia, ib) = w.pair;
        descend(
            ia,
            &tool.nodes[ia as usize],
            ib,
            &obs.nodes[ib as usize],
            stack,
        );
    }
    written.drain(..taken);
    walk_from_stack(&below, Pass::PairByPair, scratch, out, stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The overhang's term: what the region's weight over the bands may be off by beyond the
    /// estimate already counted, `W u − (1 − k) W − base`, where above 0 (`W = w / k`, the
    /// banded weight at most `W`).
    #[test]
    fn a_regions_overhang_counts_beyond_its_estimate() {
        // `w` = 0.9 of a whole `W` = 1 (cover 0.9), its estimate `w (1 − k)` = 0.09.
        let (w, k, base) = (0.9, 0.9, 0.09);
        assert_eq!(overhang_weight_error_m3(0.0, w, k, base), 0.0);
        // Less over the bands than the cover already allows for: nothing more.
        assert_eq!(overhang_weight_error_m3(0.05, w, k, base), 0.0);
        let e = overhang_weight_error_m3(0.5, w, k, base);
        assert!((e - (0.5 - 0.1 - 0.09)).abs() < 1e-12, "{e}");
        // No more than the whole weight stands for no surface.
        let e = overhang_weight_error_m3(5.0, w, k, base);
        assert!((e - (1.0 - 0.1 - 0.09)).abs() < 1e-12, "{e}");
        assert!((overhang_weight_error_m3(Real::INFINITY, w, k, base) - e).abs() < 1e-12);
        // An estimate already as large: nothing more.
        assert_eq!(overhang_weight_error_m3(0.5, w, k, 1.0), 0.0);
        // A covered piece (k = 1): the banded weight itself, less the estimate.
        let e = overhang_weight_error_m3(0.3, 2.0, 1.0, 0.1);
        assert!((e - 0.2).abs() < 1e-12, "{e}");
    }

    /// The walls' term: the band `h tan φ` wide along the walls at the weight `g`, added to
    /// the weight's error; none without a wall or a lean.
    #[test]
    fn a_regions_walls_add_their_lean_to_its_weights_error() {
        let e = wall_weight_error_m3(0.004, 2e-4, 0.1, 3e-4);
        assert!((e - 0.004 * 2e-4 * 0.1 * 3e-4).abs() < 1e-24, "{e}");
        assert_eq!(wall_weight_error_m3(0.0, 2e-4, 0.1, 3e-4), 0.0);
        assert_eq!(wall_weight_error_m3(0.004, 2e-4, 0.0, 3e-4), 0.0);
        let w = Written::of(
            7,
            (1, 2),
            (2.0, 3.0),
            (0.9, 0.5, 0.75),
            &Vec3::z(),
            false,
            false,
        );
        assert_eq!(w.with_wall_error(0.25).weight_bound, w.weight_bound + 0.25);
        assert_eq!(w.with_wall_error(-1.0).weight_bound, w.weight_bound);
    }

    /// A region's bound is its direction's error `w (1 − c)`, its weight's `a s + w (1 − k)`;
    /// a triangle pair (`c = 1`, no spread, covered) has neither.
    #[test]
    fn a_regions_bound_adds_its_weights_error_to_its_directions() {
        // Weight 2 over 3 m², its pieces' coherence, spread and cover `m`.
        let of = |m: (Real, Real, Real), unsure: bool| {
            Written::of(7, (1, 2), (2.0, 3.0), m, &Vec3::z(), false, unsure)
        };
        let w = of((0.9, 0.5, 0.75), false);
        assert!((w.bound - 2.0 * 0.1).abs() < 1e-12, "{}", w.bound);
        assert_eq!(w.weight_bound, 3.0 * 0.5 + 2.0 * 0.25);
        assert_eq!(w.force, Vec3::new(0.0, 0.0, 2.0));
        let triangles = of((1.0, 0.0, 1.0), false);
        assert_eq!((triangles.bound, triangles.weight_bound), (0.0, 0.0));
        // An unsure weight is a bound as a whole, added like the direction's.
        let unsure = of((0.9, 0.5, 0.75), true);
        assert_eq!(unsure.bound, 2.0);
        assert_eq!(unsure.weight_bound, w.weight_bound);
    }

    /// Below the regions taken out, a region's weight error may be `√3 B / √(Σ wⱼ²)` of its
    /// weight: regions that split theirs and err evenly within that much err by at most the
    /// budget `B` in standard deviation.
    #[test]
    fn the_weight_error_below_taken_regions_is_their_share_of_the_budget() {
        let of = |w: Real| {
            Written::of(
                0,
                (1, 2),
                (w, 1.0),
                (1.0, 0.0, 1.0),
                &Vec3::x(),
                false,
                false,
            )
        };
        let taken = [of(3.0), of(4.0)];
        let rho = weight_error_per_weight(0.5, &taken, Moment::Penalty);
        assert!((rho - SQRT_3 * 0.5 / 5.0).abs() < 1e-12, "{rho}");
        // Split into four regions of weight 1.75, each erring by ρ w evenly: the standard
        // deviation of their sum is √4 · ρ 1.75 / √3 = 0.35 ≤ B.
        let sd = (4.0 * (rho * 1.75 / SQRT_3).powi(2)).sqrt();
        assert!(sd <= 0.5, "{sd}");
        // Nothing weighed: nothing to hold; a budget of 0 (opposed forces that cancel): exact.
        assert_eq!(
            weight_error_per_weight(0.5, &[], Moment::Penalty),
            Real::INFINITY
        );
        assert_eq!(
            weight_error_per_weight(0.0, &[], Moment::Penalty),
            Real::INFINITY
        );
        assert_eq!(weight_error_per_weight(0.0, &taken, Moment::Penalty), 0.0);
        // In the clustering's moment the weights count at their gaps (`w / area`, here `w`):
        // `√(3² · 3² + 4² · 4²)` = 18.36.
        let rho = weight_error_per_weight(0.5, &taken, Moment::Clustering);
        assert!(
            (rho - SQRT_3 * 0.5 / (81.0 + 256.0 as Real).sqrt()).abs() < 1e-12,
            "{rho}"
        );
    }

    /// A band is as wide as the deviations leave, as long as the shadows face each other and
    /// its width more, at the pieces' weight; it is noted with that weight as its weight error,
    /// no contact and no force, so that the budget may take it out but its net force is none.
    #[test]
    fn a_band_is_noted_with_its_weight_as_its_error_and_no_force() {
        assert_eq!(band_weight_m3(2.0, 3.0, 0.5), 2.0 * 5.0 * 0.5);
        // Shadows that face each other over nothing (past a corner): the band's ends, a square.
        assert_eq!(band_weight_m3(2.0, 0.0, 0.5), 2.0);
        // Beside by more than the deviations, or out of reach: nothing.
        assert_eq!(band_weight_m3(-1.0, 3.0, 0.5), 0.0);
        assert_eq!(band_weight_m3(2.0, 3.0, -0.5), 0.0);
        let band = Written::band((4, 5), 1.5, 0.5);
        assert_eq!(band.index, Written::NO_CONTACT);
        assert_eq!((band.bound, band.weight_bound, band.gap_m), (0.0, 1.5, 0.5));
        assert_eq!(band.force, Vec3::zeros());
        // Taken like a region whose weight error is that large.
        let mut w = select::written_with_bounds(&[0.2, 0.0]);
        w.push(band);
        assert_eq!(take_largest(&mut w, 1.0, Moment::Penalty), 1);
        assert_eq!(w[0].pair, (4, 5));
        assert_eq!(
            weight_error_per_weight(1.0, &w[..1], Moment::Penalty),
            Real::INFINITY
        );
    }

    /// Pieces are unsure of their region's weight where they neither face each other nor stand
    /// exactly for their surfaces.
    #[test]
    fn a_weight_is_unsure_where_inexact_pieces_do_not_face_each_other() {
        // Opposed, or within 75° of it: sure.
        assert!(!weight_unsure(-1.0, 1e-4, 0.5));
        assert!(!weight_unsure(-0.3, 1e-4, 0.5));
        // Edge-on, or facing the same way, with a deviation or a cover short of 1: unsure.
        assert!(weight_unsure(0.0, 1e-4, 1.0));
        assert!(weight_unsure(0.0, 0.0, 0.9));
        assert!(weight_unsure(0.9, 1e-4, 1.0));
        // Exact pieces (flat, convex, covered): sure whichever way they face.
        assert!(!weight_unsure(0.0, 0.0, 1.0));
        assert!(!weight_unsure(1.0, 0.0, 1.0));
    }
}
