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
//! Not on every scene: where the net force is a small residual of contacts pushing all round
//! (the suite's ring seated on a cone, a spoon on a wavy slab), the budgeted rule refines most
//! of its coarse regions again, and a query at 2.5 % costs more than one at threshold 0 (1.01
//! against 0.78 ms on the ring; `docs/results.md`). There a budget the finest threshold cannot
//! meet drove the threshold to its ceiling, the slowest and least accurate choice. So the
//! controller estimates the slope of the log cost against the log threshold from the updates
//! whose thresholds differ by a tenth or more (an exponential mean, a measurement weighing
//! 0.3), and over the budget it goes coarser only while that slope is below −0.1; otherwise
//! finer, by the same step. Under the budget it always goes finer. While the threshold rests
//! at an end of its range, the estimate drifts back to the jaws' −½ (by 2 % an update), so that
//! a scene whose cost turns back is tried again.
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

/// The slope of the log cost against the log threshold a controller assumes before it has
/// measured one, and falls back to where it measures none: the jaws' (`θ^-½`).
const PRIOR_SLOPE: Real = -0.5;

/// Above this slope of the log cost against the log threshold, a coarser threshold is taken
/// not to make an update cheaper.
const COARSER_HELPS_BELOW: Real = -0.1;

/// The least change of the log threshold from one update to the next that measures the slope
/// (a tenth): over smaller ones, the cost's own spread from update to update is larger than
/// what the threshold changed.
const SLOPE_STEP: Real = 0.1;

/// How far one measurement moves the slope's estimate (an exponential mean).
const SLOPE_WEIGHT: Real = 0.3;

/// How far the estimate returns to [`PRIOR_SLOPE`] at each update that measures nothing, so
/// that a threshold held at an end of its range is tried again: about half way in 35 updates.
const SLOPE_FORGETTING: Real = 0.02;

/// Picks each update's error threshold from the cost of the ones before (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThresholdController {
    budget: QueryBudget,
    threshold: Real,
    /// The log threshold and log cost of the last update observed.
    last: Option<(Real, Real)>,
    /// The estimated slope of the log cost against the log threshold.
    slope: Real,
}

impl ThresholdController {
    /// A controller starting at the finest threshold of `budget`.
    pub fn new(budget: QueryBudget) -> Self {
        Self::starting_at(budget, budget.min_threshold)
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
            last: None,
            slope: PRIOR_SLOPE,
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

    /// The estimated slope of the log cost of an update against its log threshold (see the
    /// module docs): about −½ on the jaws, above 0 where a coarser threshold costs more.
    pub fn slope(&self) -> Real {
        self.slope
    }

    /// Takes the measured cost (s) of the update made at [`ThresholdController::threshold`] and
    /// returns the next threshold. A non-finite or negative cost changes nothing.
    pub fn observe(&mut self, cost_s: Real) -> Real {
        if !(cost_s.is_finite() && cost_s >= 0.0) {
            return self.threshold;
        }
        let here = (self.threshold.ln(), cost_s.max(1e-12).ln());
        let measured = self.last.and_then(|(t0, c0)| {
            let dt = here.0 - t0;
            (dt.abs() >= SLOPE_STEP).then(|| ((here.1 - c0) / dt).clamp(-3.0, 3.0))
        });
        match measured {
            Some(m) => self.slope += SLOPE_WEIGHT * (m - self.slope),
            None => self.slope += SLOPE_FORGETTING * (PRIOR_SLOPE - self.slope),
        }
        self.last = Some(here);
        let ratio = (cost_s / self.budget.budget_s).clamp(1.0 / 16.0, 16.0);
        // Under the budget, finer; over it, coarser only where coarser has been cheaper.
        let step = if ratio > 1.0 && self.slope > COARSER_HELPS_BELOW {
            ratio.sqrt().recip()
        } else {
            ratio.sqrt()
        };
        self.threshold =
            (self.threshold * step).clamp(self.budget.min_threshold, self.budget.max_threshold);
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

    /// Where a coarser threshold costs more (a scene whose coarse regions are mostly refined
    /// again, the suite's ring on its cone), a budget the finest cannot meet holds the finest,
    /// the cheapest and most accurate, rather than the coarsest; it once drove the threshold to
    /// its ceiling.
    #[test]
    fn where_coarser_costs_more_an_unmet_budget_holds_the_finest() {
        let budget = QueryBudget::new(5e-4).unwrap();
        let mut c = ThresholdController::starting_at(budget, 0.025);
        let cost = |t: Real| 1e-3 * (t / 0.001).powf(0.3);
        let mut seen = Vec::new();
        for _ in 0..200 {
            let t = c.threshold();
            seen.push(t);
            c.observe(cost(t));
        }
        // Mostly at the finest: the estimate drifts back towards the prior while the threshold
        // rests there, and a try coarser now and then measures the slope again.
        let tail = &seen[100..];
        let finest = tail.iter().filter(|&&t| t == budget.min_threshold).count();
        assert!(
            finest * 10 >= tail.len() * 8,
            "{finest} of {}: {tail:?}",
            tail.len()
        );
        let worst = tail.iter().copied().fold(0.0, Real::max);
        assert!(worst < 0.004, "{tail:?}");
    }

    /// Where the cost falls, then rises with the threshold, an unmet budget holds the threshold
    /// near the cheapest.
    #[test]
    fn an_unmet_budget_settles_near_the_cheapest_threshold() {
        let budget = QueryBudget::new(1e-3).unwrap();
        let mut c = ThresholdController::new(budget);
        let cheapest = 0.01;
        let cost = |t: Real| {
            let x = t / cheapest;
            2e-3 * x.sqrt().max(x.sqrt().recip())
        };
        let mut costs = Vec::new();
        for _ in 0..300 {
            let t = c.threshold();
            costs.push(cost(t));
            c.observe(cost(t));
        }
        let tail = &costs[100..];
        let mean = tail.iter().sum::<Real>() / tail.len() as Real;
        assert!(mean < 1.5 * 2e-3, "mean cost {mean}");
    }

    /// Costs that scatter by ±30 % from update to update (contact changing, a busy core) about
    /// the jaws' `c θ^-½`: the slope's estimate stays negative enough that the threshold still
    /// settles on the budget, not at the finest.
    #[test]
    fn a_scattered_cost_still_settles_on_the_budget() {
        let budget = QueryBudget::new(8e-3).unwrap();
        let mut c = ThresholdController::new(budget);
        let mut rng = haptic_test_support::rng::Lcg(7);
        let mut thresholds = Vec::new();
        for _ in 0..400 {
            let t = c.threshold();
            thresholds.push(t);
            let scatter = 1.0 + 0.3 * (2.0 * rng.next() - 1.0);
            c.observe(1e-3 / t.sqrt() * scatter);
        }
        // 8 ms without the scatter at θ = 1.56 %.
        let mut tail = thresholds[200..].to_vec();
        tail.sort_by(Real::total_cmp);
        let median = tail[tail.len() / 2];
        assert!(
            (0.0125..0.02).contains(&median),
            "median threshold {median}"
        );
        assert!(c.slope() < COARSER_HELPS_BELOW, "{}", c.slope());
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
