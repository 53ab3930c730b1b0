//! Time-budgeted contact queries: a user sets how long a contact update may take (a contact
//! rate), not an error threshold, and the contact stage picks the threshold.
//!
//! The LOD back-end's cost falls as its error threshold grows (coarser pieces, fewer pairs):
//! on the jaws the whole contact stage goes as about `θ^-½` between 0.4 % and 2.5 % (16.7 ms
//! and 6.4 ms, `docs/performance.md`). After each update that found contacts the
//! [`ThresholdController`] moves the threshold by the square root of the ratio of the update's
//! measured cost to the budget, in log space (`θ ← θ · (t / budget)^½`, at most ×4 or ÷4 a
//! step), within `[min_threshold, max_threshold]`: a cost `c θ^-p` converges to the budget
//! geometrically (each step removes a share `p/2` of the log error), and one slow update (a
//! page fault, a busy core) moves it by half its excess only. Updates in free space and failed
//! ones do not move it. Each update reports the threshold its query held
//! (`CollisionBackend::threshold_reached`: the one asked, or less where the back-end holds a
//! tighter one). A budget that the coarsest threshold cannot meet is not met: the threshold
//! stays at its ceiling, the budget's or the coarsest the back-end reaches, whichever is lower
//! (under `LodBackend`'s default rule, `δ / radius`: on the jaws 2.7 %, where a query costs
//! about a third of one at 0.4 %).
//!
//! This is a controller across updates, not a refinement within one query that stops when the
//! time is up: an update may overrun when the contact changes abruptly (the next one is
//! coarser). With a budget, which threshold a query uses depends on the machine's speed, so a
//! virtual-time run is no longer the same from one machine (or run) to the next.

use haptic_core::Real;

use crate::error::RuntimeError;

/// A time budget per contact update (query, clustering and linearization).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryBudget {
    /// Wall time an update may take (s): the contact rate wanted is its inverse.
    pub budget_s: Real,
    /// The finest threshold used (fraction of the tool's bounding radius), and the first.
    pub min_threshold: Real,
    /// The coarsest threshold used.
    pub max_threshold: Real,
}

impl QueryBudget {
    /// A budget of `budget_s` seconds an update, thresholds between 0.1 % and 10 % of the tool's
    /// bounding radius.
    ///
    /// # Errors
    /// [`RuntimeError::Config`] (`query_budget.budget_s`) for a budget that is not positive
    /// and finite.
    pub fn new(budget_s: Real) -> Result<Self, RuntimeError> {
        let b = Self {
            budget_s,
            min_threshold: 0.001,
            max_threshold: 0.1,
        };
        b.validate()?;
        Ok(b)
    }

    /// Checks the fields.
    ///
    /// # Errors
    /// [`RuntimeError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), RuntimeError> {
        if !(self.budget_s.is_finite() && self.budget_s > 0.0) {
            return Err(RuntimeError::config(
                "query_budget.budget_s",
                format!("must be positive and finite, got {}", self.budget_s),
            ));
        }
        if !(self.min_threshold.is_finite() && self.min_threshold > 0.0) {
            return Err(RuntimeError::config(
                "query_budget.min_threshold",
                format!("must be positive and finite, got {}", self.min_threshold),
            ));
        }
        if !(self.max_threshold.is_finite() && self.max_threshold >= self.min_threshold) {
            return Err(RuntimeError::config(
                "query_budget.max_threshold",
                format!(
                    "must be finite and at least min_threshold ({}), got {}",
                    self.min_threshold, self.max_threshold
                ),
            ));
        }
        Ok(())
    }
}

/// Picks each update's error threshold from the cost of the ones before (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThresholdController {
    budget: QueryBudget,
    threshold: Real,
}

impl ThresholdController {
    /// A controller starting at the finest threshold of `budget`.
    pub fn new(budget: QueryBudget) -> Self {
        Self {
            budget,
            threshold: budget.min_threshold,
        }
    }

    /// A controller starting at `threshold`, brought within the budget's range.
    pub fn starting_at(budget: QueryBudget, threshold: Real) -> Self {
        let t = if threshold.is_finite() {
            threshold
        } else {
            budget.min_threshold
        };
        Self {
            budget,
            threshold: t.clamp(budget.min_threshold, budget.max_threshold),
        }
    }

    /// The threshold for the next update.
    pub fn threshold(&self) -> Real {
        self.threshold
    }

    /// The budget.
    pub fn budget(&self) -> &QueryBudget {
        &self.budget
    }

    /// Holds the threshold at or below `ceiling` (and at or above the budget's finest): the
    /// coarsest threshold the back-end reaches
    /// ([`haptic_core::CollisionBackend::threshold_reached`]), beyond which a coarser one
    /// would cost the same and only misreport what the queries hold. A non-finite ceiling
    /// changes nothing.
    pub fn hold_at_most(&mut self, ceiling: Real) {
        if ceiling.is_finite() {
            self.threshold = self.threshold.min(ceiling).max(self.budget.min_threshold);
        }
    }

    /// Takes the measured cost (s) of the update made at [`ThresholdController::threshold`] and
    /// returns the next threshold. A non-finite or negative cost changes nothing.
    pub fn observe(&mut self, cost_s: Real) -> Real {
        if !(cost_s.is_finite() && cost_s >= 0.0) {
            return self.threshold;
        }
        let ratio = (cost_s / self.budget.budget_s).clamp(1.0 / 16.0, 16.0);
        self.threshold = (self.threshold * ratio.sqrt())
            .clamp(self.budget.min_threshold, self.budget.max_threshold);
        self.threshold
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A budget the back-end's coarsest threshold cannot meet holds the threshold at that one,
    /// not at the budget's ceiling.
    #[test]
    fn a_back_end_that_coarsens_no_further_holds_the_threshold_at_its_coarsest() {
        let budget = QueryBudget::new(1e-3).unwrap();
        let mut c = ThresholdController::new(budget);
        let coarsest = 0.027;
        // The cost stops falling at the coarsest threshold: 4 ms, over the budget.
        let cost = |t: Real| 4e-3 * (coarsest / t.min(coarsest)).sqrt();
        for _ in 0..40 {
            let t = c.threshold();
            c.observe(cost(t));
            c.hold_at_most(coarsest);
            assert!(c.threshold() <= coarsest);
        }
        assert_eq!(c.threshold(), coarsest);
        // A ceiling below the finest threshold holds it at the finest; a NaN changes nothing.
        c.hold_at_most(1e-6);
        assert_eq!(c.threshold(), budget.min_threshold);
        c.hold_at_most(Real::NAN);
        assert_eq!(c.threshold(), budget.min_threshold);
    }

    /// With a cost `c / θ`, the threshold settles where the cost meets the budget.
    #[test]
    fn a_cost_inverse_in_the_threshold_settles_on_the_budget() {
        let budget = QueryBudget::new(2e-3).unwrap();
        let mut c = ThresholdController::new(budget);
        let cost = |t: Real| 5e-5 / t; // 50 ms at 0.1 %, 2 ms at 2.5 %
        for _ in 0..40 {
            let t = c.threshold();
            c.observe(cost(t));
        }
        assert!(
            (c.threshold() - 0.025).abs() < 0.025 * 0.01,
            "{}",
            c.threshold()
        );
        assert!((cost(c.threshold()) - 2e-3).abs() < 2e-3 * 0.01);
    }

    /// With the jaws' cost `c θ^-½`, it settles too, more slowly.
    #[test]
    fn a_cost_in_the_inverse_square_root_settles_on_the_budget() {
        let budget = QueryBudget::new(8e-3).unwrap();
        let mut c = ThresholdController::starting_at(budget, 0.025);
        let cost = |t: Real| 1e-3 / t.sqrt(); // 10 ms at 1 %, 8 ms at 1.56 %
        for _ in 0..80 {
            let t = c.threshold();
            c.observe(cost(t));
        }
        assert!(
            (cost(c.threshold()) - 8e-3).abs() < 8e-3 * 0.01,
            "{}",
            c.threshold()
        );
        assert_eq!(
            ThresholdController::starting_at(budget, 0.0).threshold(),
            budget.min_threshold
        );
    }

    /// A fast machine stays at the finest threshold, a slow one at the coarsest; one slow
    /// update moves the threshold by at most ×4.
    #[test]
    fn thresholds_stay_in_range_and_move_by_bounded_steps() {
        let budget = QueryBudget::new(1e-3).unwrap();
        let mut c = ThresholdController::new(budget);
        for _ in 0..10 {
            c.observe(1e-6);
        }
        assert_eq!(c.threshold(), budget.min_threshold);
        let before = c.threshold();
        c.observe(10.0);
        assert!((c.threshold() / before - 4.0).abs() < 1e-12);
        for _ in 0..20 {
            c.observe(10.0);
        }
        assert_eq!(c.threshold(), budget.max_threshold);
        // Costs that are not costs change nothing.
        for bad in [Real::NAN, Real::INFINITY, -1.0] {
            assert_eq!(c.observe(bad), budget.max_threshold);
        }
    }

    #[test]
    fn bad_budgets_are_config_errors() {
        for b in [0.0, -1.0, Real::NAN, Real::INFINITY] {
            assert!(matches!(
                QueryBudget::new(b),
                Err(RuntimeError::Config { field, .. }) if field == "query_budget.budget_s"
            ));
        }
        let inverted = QueryBudget {
            max_threshold: 1e-4,
            ..QueryBudget::new(1e-3).unwrap()
        };
        assert!(matches!(
            inverted.validate(),
            Err(RuntimeError::Config { field, .. }) if field == "query_budget.max_threshold"
        ));
    }
}
