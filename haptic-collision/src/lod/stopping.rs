//! When the walk may stop at a pair of coarse pieces: the stopping rule.
//!
//! The paper's rule (ref. \[9\]) bounds where the pieces lie: a pair stops when the sum of the
//! pieces' surface deviations is within `ε = error_threshold × tool radius`. It says nothing of
//! which way the surfaces face. A node whose triangles face many ways (a thread's two flanks, a
//! fork's tine, a cusp) can lie within `ε` of a flat piece and still push, through that piece,
//! along a normal its surface does not have: the threads of a bolt pushed radially by their
//! coarse pieces come out 2.3 times too strong
//! (`docs/experiments/lod-accuracy-and-speed-probes.md`, probes 13 and 14).
//!
//! [`StoppingRule::DeviationAndCoherence`] adds the error a piece makes in the force it
//! integrates. A node's normal coherence is `c = |Σ aᵢ nᵢ| / Σ aᵢ` over its triangles (1 for a
//! flat patch, 0 where its faces cancel): the surface's normals add up to `c` times its area,
//! which a piece pushing along one normal counts whole, so `1 − c` is about the relative error
//! in force of standing for the surface with one normal. A pair that writes a contact stops
//! only where both pieces have `1 − c ≤ error_threshold` (below the cap that follows);
//! otherwise it is descended like any other pair. Pairs without a contact stop as before, so the distance guarantee is unchanged,
//! and at threshold 0 both rules descend to triangles and give the same contacts.
//!
//! It also bounds the error a piece makes in depth by the penalty's own reach: its `ε` is
//! `min(error_threshold × tool radius, δ)`, and its coherence condition reads the threshold that
//! this `ε` stands for (`ε / tool radius`). The penalty weighs a point by its gap `d + δ`, within
//! `δ` of the obstacle's surface: a piece that may lie more than `δ` from the surface it stands
//! for can put a region anywhere in that band or outside it, whatever the tool's size. The paper
//! measures `ε` against the tool's size alone; for a long tool with small features (a fork: `ε`
//! is 2.4 `δ` at 2.5 %) that is where its error came from
//! (`docs/experiments/lod-accuracy-and-speed-probes.md`, probe 21).
//!
//! And it drops a stopped pair only where the surfaces its pieces stand for are out of reach,
//! not the pieces themselves: the piece-level cull reaches as far as the region's integral
//! does (`δ` plus the height offset of the surfaces about their pieces, `slab.rs`). With `ε` up to
//! `δ`, a piece can lie more than `δ` from the other while its surface comes well within it:
//! the fork in the mug lost contacts of 2 N at 0.5 mm that way
//! (`docs/experiments/lod-accuracy-and-speed-probes.md`, probe 22). The paper's rule keeps the
//! cull at the pieces, as the paper does.
//!
//! [`StoppingRule::CoherenceBudget`] asks the same of the regions' sum instead of each region:
//! it walks as the paper's rule does (with the cap and the cull above), then bounds the error
//! of the regions written, `Σ wᵢ (1 − cᵢ) + √(Σ eᵢ²)` (`wᵢ` a region's penalty weight `∫g`,
//! `eᵢ = aᵢ sᵢ + wᵢ (1 − kᵢ)` its weight's error from its area `aᵢ`, the half-width `sᵢ` of its
//! surfaces' heights about its pieces and the share `kᵢ` of them the surfaces cover: the errors
//! of its force's direction added, of its weight in quadrature), against the
//! threshold's share of the net force, `τ |Σ wᵢ nᵢ|`; where it is larger, the regions with the
//! largest bounds are refined under the coherence condition until the rest is within it, and
//! the same in the moment the clustering reads, `τ |Σ wᵢ gᵢ nᵢ|` (`refine.rs`). The refinement goes where the force is, and where opposed contacts cancel the
//! budget shrinks with their resultant. On the jaws it refines a few dozen of about a thousand
//! regions, where the coherence rule descends every incoherent one
//! (`docs/experiments/lod-accuracy-and-speed-probes.md`, probe 24).

use std::fmt;
use std::str::FromStr;

use haptic_core::Real;

/// When the multiresolution walk stops at a pair of coarse pieces (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum StoppingRule {
    /// The paper's rule: `s_a + s_b ≤ ε` (the pieces' surface deviations within
    /// `error_threshold × tool radius`). The paper's studies use it (`cargo xtask study jaws`).
    Deviation,
    /// The paper's rule with `ε` at most `δ`, and where the pair writes a contact, each piece's
    /// normal coherence within the threshold `ε` stands for: `1 − c ≤ ε / tool radius`. More
    /// accurate on surfaces with features smaller than `ε` (threads, tines, cusps) and on long
    /// tools, slower where coarse pieces of curved surfaces are in contact. A stopped pair is
    /// dropped only where the surfaces its pieces stand for are beyond `δ`.
    DeviationAndCoherence,
    /// The coherence rule's cap and cull, and its coherence condition held for the regions
    /// together rather than one by one: the walk stops as the paper's rule does, then the
    /// regions whose bound `w (1 − c) + a s + w (1 − k)` on their force's error (its
    /// direction's, and its weight's: over the area `a` where the surfaces spread `± s` about the
    /// pieces, and where they cover a share `k` of them) is largest
    /// are refined (the direction bounds added, the weights' in quadrature)
    /// under the coherence condition until the bounds left sum to at most the threshold's share
    /// of the net force (`ε / tool radius` of `|Σ w n|`, per obstacle), and of the clustering's
    /// `|Σ w g n|`, each bound weighed by its region's mean gap `g`. A region whose pieces lie
    /// beyond `δ` of each other (within reach only through the surfaces they stand for) and are
    /// less coherent than the condition asks is refined whatever the budget: its weight, next to
    /// nothing, says nothing of what those surfaces push; nor does the weight of coarse pieces
    /// that do not face each other (edge-on, or the tool behind the obstacle's surface) and do
    /// not stand exactly for their surfaces, which is all there or all missing: it counts whole
    /// in the bound, and is descended pair by pair. Nearly as accurate as
    /// [`StoppingRule::DeviationAndCoherence`] where the net force is not a small residual of
    /// opposed ones, at much less of its cost where many small coarse regions touch (the jaws).
    /// The default: of the three, the one whose error at a threshold depends least on the
    /// scene (`docs/decisions.md`, "Stopping rule").
    #[default]
    CoherenceBudget,
}

impl StoppingRule {
    /// Every rule.
    pub const ALL: [Self; 3] = [
        Self::Deviation,
        Self::DeviationAndCoherence,
        Self::CoherenceBudget,
    ];

    /// The rule's name in scene files (`contact.stopping_rule`), on the command line and in
    /// Python: `"deviation"`, `"coherence"` or `"coherence-budget"`. [`FromStr`] reads it back.
    pub fn name(self) -> &'static str {
        match self {
            Self::Deviation => "deviation",
            Self::DeviationAndCoherence => "coherence",
            Self::CoherenceBudget => "coherence-budget",
        }
    }

    /// The walk's error budget `ε` (m) on `s_a + s_b` at `error_threshold` for a tool of
    /// bounding radius `radius_m`, with the penalty reaching `delta_m`.
    pub(crate) fn epsilon_m(self, error_threshold: Real, radius_m: Real, delta_m: Real) -> Real {
        let epsilon_m = error_threshold * radius_m;
        if self.caps_epsilon_at_delta() {
            epsilon_m.min(delta_m)
        } else {
            epsilon_m
        }
    }

    /// Whether the walk's `ε` is capped at `δ` (every rule but the paper's).
    fn caps_epsilon_at_delta(self) -> bool {
        matches!(self, Self::DeviationAndCoherence | Self::CoherenceBudget)
    }

    /// The threshold a walk at `error_threshold` holds, for a tool of bounding radius
    /// `radius_m` with the penalty reaching `delta_m`: `error_threshold`, or under a rule that
    /// caps `ε` at `δ`, at most `δ / radius_m` ([`StoppingRule::epsilon_m`] over the radius).
    pub(crate) fn threshold_reached(
        self,
        error_threshold: Real,
        radius_m: Real,
        delta_m: Real,
    ) -> Real {
        if self.caps_epsilon_at_delta() && radius_m > 0.0 {
            error_threshold.min(delta_m / radius_m)
        } else {
            error_threshold
        }
    }

    /// The height over which an obstacle piece's normal spread counts against the threshold
    /// (m): a coarse pair stops only where `s_a + s_b + h tan φ_b ≤ ε` (`tan φ_b` the obstacle
    /// piece's [`super::SurfaceMoments::spread_tan`]). Each of the obstacle piece's triangles
    /// has its own prism, leaning from the piece's by the angle between their normals, so that
    /// at the height `h` a triangle's prism lies up to `h tan φ` aside of where the piece's
    /// puts it: which part of the tool lies over the surface is off by that much, as the
    /// surface's height is off by the deviation. Under the budgeted rule `h` is `δ`, the
    /// penalty's reach; the paper's and the coherence rule ask nothing of it (0).
    ///
    /// Why: where the obstacle's triangles are smaller than `δ` and its surface curved on that
    /// scale (the suite's fork on an 8.5 cm cow, `δ` = 2 mm), pieces whose deviations made `ε`
    /// stood for 46 triangles whose normals spread by 40°, and their regions, a sliver where the
    /// tool crossed the piece's prism, pushed a fiftieth of what the triangles below them push:
    /// a p90 error of 0.192 at 2.5 %, whatever the budget (its bounds scale with the regions
    /// found). With the spread: 0.085, and the full suite's worst median 0.039 → 0.030, for 5 %
    /// fewer instructions a jaws query at 2.5 % (the finer pieces' regions need less refining)
    /// and 9 % more at 0.4 % (`docs/decisions.md`, "Stopping rule", thirtieth session).
    pub(crate) fn spread_height_m(self, delta_m: Real) -> Real {
        match self {
            Self::CoherenceBudget => delta_m,
            Self::Deviation | Self::DeviationAndCoherence => 0.0,
        }
    }

    /// Whether the regions written are refined until their bound on the error of their force is
    /// within the threshold of the net force (`refine.rs`).
    pub(crate) fn refines_regions(self) -> bool {
        matches!(self, Self::CoherenceBudget)
    }

    /// Whether a stopped pair is dropped only when the surfaces its pieces stand for (the
    /// pieces shifted and spread by their height offset) lie beyond `δ`, rather than the pieces.
    pub(crate) fn culls_at_surfaces(self) -> bool {
        matches!(self, Self::DeviationAndCoherence | Self::CoherenceBudget)
    }

    /// The least normal coherence a contact's pieces may have when the walk's budget is
    /// `epsilon_m` for a tool of bounding radius `radius_m` (below 0: any).
    pub(crate) fn min_coherence(self, epsilon_m: Real, radius_m: Real) -> Real {
        match self {
            Self::Deviation => -1.0,
            Self::DeviationAndCoherence | Self::CoherenceBudget if radius_m > 0.0 => {
                1.0 - epsilon_m / radius_m
            }
            // A tool without extent (a single point): no coarse piece to stop at.
            Self::DeviationAndCoherence | Self::CoherenceBudget => 1.0,
        }
    }
}

impl fmt::Display for StoppingRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a [`StoppingRule`]'s ([`StoppingRule::name`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{0}` is not a stopping rule: use \"deviation\", \"coherence\" or \"coherence-budget\"")]
pub struct UnknownStoppingRule(pub String);

impl FromStr for StoppingRule {
    type Err = UnknownStoppingRule;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|r| r.name() == name)
            .ok_or_else(|| UnknownStoppingRule(name.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_rule_accepts_any_coherence_and_the_others_follow_the_threshold() {
        let (r, delta) = (0.04, 1e-3);
        let rule = StoppingRule::DeviationAndCoherence;
        assert!(StoppingRule::Deviation.min_coherence(0.025 * r, r) < 0.0);
        assert_eq!(StoppingRule::default(), StoppingRule::CoherenceBudget);
        let eps = rule.epsilon_m(0.025, r, delta);
        assert_eq!(eps, 0.025 * r, "below δ: the paper's ε");
        let c = rule.min_coherence(eps, r);
        assert!((c - 0.975).abs() < 1e-15);
        // At threshold 0 every coarse pair fails; triangle pairs are exempt (coherence 1).
        assert_eq!(rule.min_coherence(rule.epsilon_m(0.0, r, delta), r), 1.0);
        assert_eq!(rule.min_coherence(0.0, 0.0), 1.0);
    }

    #[test]
    fn the_coherence_rule_caps_epsilon_at_delta_and_reads_the_threshold_it_stands_for() {
        let (r, delta) = (0.1, 1e-3);
        // 5 % of 10 cm is 5 mm: five penalty bands. The paper's rule keeps it, the other caps it.
        assert_eq!(StoppingRule::Deviation.epsilon_m(0.05, r, delta), 0.05 * r);
        let rule = StoppingRule::DeviationAndCoherence;
        let eps = rule.epsilon_m(0.05, r, delta);
        assert_eq!(eps, delta);
        // As if the threshold were δ / r = 1 %.
        assert!((rule.min_coherence(eps, r) - 0.99).abs() < 1e-15);
    }

    #[test]
    fn the_threshold_reached_is_the_one_epsilon_stands_for() {
        let (r, delta) = (0.04, 1e-3);
        for rule in StoppingRule::ALL {
            for threshold in [0.0, 0.004, 0.025, 0.05, 0.1] {
                let reached = rule.threshold_reached(threshold, r, delta);
                let eps = rule.epsilon_m(threshold, r, delta);
                assert!((reached * r - eps).abs() <= 1e-15, "{rule} {threshold}");
                assert!(reached <= threshold);
            }
        }
        // Below δ / r = 2.5 % every rule holds the threshold asked; above it only the paper's.
        assert_eq!(
            StoppingRule::CoherenceBudget.threshold_reached(0.01, r, delta),
            0.01
        );
        assert_eq!(
            StoppingRule::CoherenceBudget.threshold_reached(0.1, r, delta),
            delta / r
        );
        assert_eq!(
            StoppingRule::Deviation.threshold_reached(0.1, r, delta),
            0.1
        );
        // A tool without extent: the threshold asked.
        assert_eq!(
            StoppingRule::CoherenceBudget.threshold_reached(0.1, 0.0, delta),
            0.1
        );
    }

    #[test]
    fn names_read_back_and_a_typo_is_named() {
        for rule in StoppingRule::ALL {
            assert_eq!(rule.name().parse::<StoppingRule>(), Ok(rule));
            assert_eq!(rule.to_string(), rule.name());
        }
        let err = "normals".parse::<StoppingRule>().unwrap_err();
        assert!(err.to_string().contains("`normals`"), "{err}");
    }
}
