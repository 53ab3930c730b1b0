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
//! in force of standing for the surface with one normal. A pair that writes a contact stops only where both
//! pieces have `1 − c ≤ error_threshold`; otherwise it is descended like any other pair. Pairs
//! without a contact stop as before, so the distance guarantee is unchanged, and at threshold 0
//! both rules descend to triangles and give the same contacts.

use haptic_core::Real;

/// When the multiresolution walk stops at a pair of coarse pieces (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum StoppingRule {
    /// The paper's rule: `s_a + s_b ≤ ε` (the pieces' surface deviations within
    /// `error_threshold × tool radius`). The default.
    #[default]
    Deviation,
    /// The paper's rule, and where the pair writes a contact, each piece's normal coherence
    /// within the threshold: `1 − c ≤ error_threshold`. More accurate on surfaces with features
    /// smaller than `ε` (threads, tines, cusps), slower where coarse pieces of curved surfaces
    /// are in contact.
    DeviationAndCoherence,
}

impl StoppingRule {
    /// The least normal coherence a contact's pieces may have at `error_threshold` (below 0:
    /// any).
    pub(crate) fn min_coherence(self, error_threshold: Real) -> Real {
        match self {
            Self::Deviation => -1.0,
            Self::DeviationAndCoherence => 1.0 - error_threshold,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_rule_accepts_any_coherence_and_the_other_follows_the_threshold() {
        assert!(StoppingRule::Deviation.min_coherence(0.025) < 0.0);
        assert_eq!(StoppingRule::default(), StoppingRule::Deviation);
        let c = StoppingRule::DeviationAndCoherence.min_coherence(0.025);
        assert!((c - 0.975).abs() < 1e-15);
        // At threshold 0 every coarse pair fails; triangle pairs are exempt (coherence 1).
        assert_eq!(StoppingRule::DeviationAndCoherence.min_coherence(0.0), 1.0);
    }
}
