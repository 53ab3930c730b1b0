//! The pipeline: a builder that composes an [`Integrator`], a [`CollisionBackend`], a
//! [`ContactModel`] (with clustering) and a [`Device`], and the two ways to run it.
//!
//! One file per part: `config` (rates, tolerances, latency), `builder` (the typestate
//! builder), `virtual_time` (the deterministic single-thread run) and `real_time` (the haptic
//! and contact threads).

mod builder;
mod config;
mod real_time;
mod virtual_time;

pub use builder::PipelineBuilder;
pub use config::{ContactLatency, PipelineConfig};
pub use real_time::REALTIME_PRIORITY;

use std::sync::atomic::Ordering;

use haptic_core::{CollisionBackend, ContactModel, Device, Integrator, Real};

use crate::error::RuntimeError;
use crate::stages::{ContactStage, ContactUpdate, DeviceFailure, HapticStage};
use crate::telemetry::{DurationHistogram, LiveTelemetry, RunMode, Snapshot, Summary};

/// Contact-side statistics of a run.
#[derive(Debug, Clone, Default)]
struct ContactStats {
    updates: u64,
    latency: DurationHistogram,
    broad_phase_only: u64,
    raw_max: u64,
    cluster_count_max: u64,
    max_penetration_m: Real,
    errors: u64,
    first_error: Option<String>,
    panicked: Option<String>,
    first_update_s: Option<Real>,
    last_update_s: Real,
    /// The error thresholds of the updates with contacts (a budget picks them).
    thresholds: ThresholdStats,
}

/// Bins of [`ThresholdStats`]: 40 a decade from 1e-5 to 10 (each about 6 % wide).
const THRESHOLD_BINS: usize = 240;

/// Error thresholds in fixed logarithmic bins: a run of any length takes the same memory, and
/// recording one allocates nothing. Quantiles are bin centres (within 3 %), brought within the
/// smallest and largest values seen (so a run at one threshold reports it exactly).
#[derive(Debug, Clone)]
struct ThresholdStats {
    zero: u64,
    bins: [u64; THRESHOLD_BINS],
    count: u64,
    min: Real,
    max: Real,
}

impl Default for ThresholdStats {
    fn default() -> Self {
        Self {
            zero: 0,
            bins: [0; THRESHOLD_BINS],
            count: 0,
            min: Real::INFINITY,
            max: 0.0,
        }
    }
}

impl ThresholdStats {
    fn record(&mut self, t: Real) {
        if !(t.is_finite() && t >= 0.0) {
            return;
        }
        self.count += 1;
        self.min = self.min.min(t);
        self.max = self.max.max(t);
        if t == 0.0 {
            self.zero += 1;
        } else {
            let i = ((t.log10() + 5.0) * 40.0).floor().max(0.0) as usize;
            self.bins[i.min(THRESHOLD_BINS - 1)] += 1;
        }
    }

    /// The `f`-quantile (0 when nothing was recorded).
    fn quantile(&self, f: Real) -> Real {
        if self.count == 0 {
            return 0.0;
        }
        let rank = ((self.count - 1) as Real * f.clamp(0.0, 1.0)).round() as u64;
        if rank < self.zero {
            return 0.0;
        }
        let mut seen = self.zero;
        for (i, n) in self.bins.iter().enumerate() {
            seen += n;
            if rank < seen {
                let centre = 10f64.powf((i as Real + 0.5) / 40.0 - 5.0);
                return centre.clamp(self.min, self.max);
            }
        }
        self.max
    }
}

impl ContactStats {
    fn record(&mut self, u: &ContactUpdate, latency_s: Real, available_s: Real) {
        self.updates += 1;
        self.latency.record(latency_s);
        if u.broad_phase_only {
            self.broad_phase_only += 1;
        }
        self.raw_max = self.raw_max.max(u.raw_contact_count as u64);
        self.cluster_count_max = self.cluster_count_max.max(u.cluster_count as u64);
        self.max_penetration_m = self.max_penetration_m.max(u.max_penetration_m);
        self.first_update_s.get_or_insert(available_s);
        self.last_update_s = available_s;
        if u.raw_contact_count > 0 {
            self.thresholds.record(u.error_threshold);
        }
    }

    /// The `f`-quantile of the thresholds of the updates with contacts (0 without any).
    fn threshold_quantile(&self, f: Real) -> Real {
        self.thresholds.quantile(f)
    }

    fn rate_hz(&self, duration_s: Real) -> Real {
        if duration_s > 0.0 {
            self.updates as Real / duration_s
        } else {
            0.0
        }
    }
}

/// A composed pipeline, ready to run in real time or in virtual time.
///
/// The haptic loop is generic over all four parts: static dispatch, no allocation, no lock.
pub struct Pipeline<I, B, C, D> {
    haptic: HapticStage<I, D>,
    contact: ContactStage<B, C>,
    config: PipelineConfig,
    live: std::sync::Arc<LiveTelemetry>,
}

impl<I: Integrator, B: CollisionBackend, C: ContactModel, D: Device> Pipeline<I, B, C, D> {
    /// The haptic stage (tool state, device, statistics).
    pub fn haptic(&self) -> &HapticStage<I, D> {
        &self.haptic
    }

    /// The haptic stage, mutably.
    pub fn haptic_mut(&mut self) -> &mut HapticStage<I, D> {
        &mut self.haptic
    }

    /// The contact stage.
    pub fn contact(&self) -> &ContactStage<B, C> {
        &self.contact
    }

    /// The configuration.
    pub fn config(&self) -> &PipelineConfig {
        &self.config
    }

    /// Live counters, readable while running.
    pub fn live(&self) -> Snapshot {
        self.live.snapshot()
    }

    /// The live counters themselves, shared: another thread can read them (lock-free) while
    /// the pipeline runs, as a server that hands the pipeline to a thread of its own does.
    pub fn live_handle(&self) -> std::sync::Arc<LiveTelemetry> {
        self.live.clone()
    }

    fn summarize(&self, mode: RunMode, duration_s: Real, c: &ContactStats) -> Summary {
        let h = &self.haptic.stats;
        let mut incidents = Vec::new();
        if let Some(p) = &c.panicked {
            incidents.push(format!(
                "contact thread panicked: {p}; contact forces faded out"
            ));
        }
        if c.errors > 0 {
            incidents.push(format!(
                "{} contact updates failed (first: {})",
                c.errors,
                c.first_error.clone().unwrap_or_default()
            ));
        }
        if h.stale_steps > 0 {
            incidents.push(format!(
                "contact model older than {:.0} ms during {} haptic steps: contact forces faded",
                self.config.safety.contact_timeout_s * 1e3,
                h.stale_steps
            ));
        }
        if h.late_contact_updates > 0 {
            incidents.push(format!(
                "{} of {} contact updates arrived late: the tool moved more than delta = {:.2} mm \
                 into a surface between query and update; raise delta or the contact rate",
                h.late_contact_updates,
                c.updates,
                self.config.query.delta_m * 1e3
            ));
        }
        if h.divergences > 0 {
            incidents.push(format!(
                "tool diverged {} times and was put back at the handle",
                h.divergences
            ));
        }
        if h.solver_failures > 0 {
            incidents.push(format!(
                "{} integration steps failed: zero force sent",
                h.solver_failures
            ));
        }
        if h.solver_fallbacks > 0 {
            incidents.push(format!(
                "{} Newton solves did not converge: those steps took the semi-implicit step",
                h.solver_fallbacks
            ));
        }
        if h.zero_force_steps > h.solver_failures {
            incidents.push(format!(
                "{} device readings were NaN or invalid: zero force sent",
                h.zero_force_steps - h.solver_failures
            ));
        }
        Summary {
            mode,
            duration_s,
            haptic_steps: h.steps,
            haptic_rate_hz: if duration_s > 0.0 {
                h.steps as Real / duration_s
            } else {
                0.0
            },
            step_p50_s: h.step_time.quantile_s(0.5),
            step_p99_s: h.step_time.quantile_s(0.99),
            step_p999_s: h.step_time.quantile_s(0.999),
            step_max_s: h.step_time.max_s(),
            deadline_misses: self.live.deadline_misses.load(Ordering::Relaxed),
            contact_updates: c.updates,
            contact_rate_hz: c.rate_hz(duration_s),
            contact_latency_p50_s: c.latency.quantile_s(0.5),
            contact_latency_max_s: c.latency.max_s(),
            broad_phase_only_queries: c.broad_phase_only,
            raw_contact_count_max: c.raw_max,
            cluster_count_max: c.cluster_count_max,
            max_penetration_m: c.max_penetration_m,
            max_coupling_deviation_m: h.max_coupling_deviation_m,
            max_force_n: h.max_force_n,
            saturation_events: h.saturation_events,
            zero_force_steps: h.zero_force_steps,
            solver_failures: h.solver_failures,
            solver_fallbacks: h.solver_fallbacks,
            contact_errors: c.errors,
            contact_stale_steps: h.stale_steps,
            late_contact_updates: h.late_contact_updates,
            contact_thread_panicked: c.panicked.is_some(),
            error_threshold_median: c.threshold_quantile(0.5),
            error_threshold_max: c.threshold_quantile(1.0),
            haptic_thread_panic: None,
            incidents,
            realtime_scheduling_granted: false,
            scheduling: String::new(),
        }
    }
}

/// The result of a run from its summary and how the haptic loop ended.
fn finish(
    mut summary: Summary,
    outcome: Result<Option<DeviceFailure>, String>,
) -> Result<Summary, RuntimeError> {
    match outcome {
        Ok(None) => Ok(summary),
        Ok(Some(f)) => Err(RuntimeError::Device {
            kind: f.kind,
            message: f.message,
            summary: Box::new(summary),
        }),
        Err(message) => {
            summary.incidents.push(format!(
                "haptic thread panicked: {message}; zero force commanded"
            ));
            summary.haptic_thread_panic = Some(message.clone());
            Err(RuntimeError::HapticPanic {
                message,
                summary: Box::new(summary),
            })
        }
    }
}

#[cfg(test)]
mod threshold_stats_tests {
    use super::*;

    #[test]
    fn quantiles_of_binned_thresholds() {
        let mut s = ThresholdStats::default();
        assert_eq!(s.quantile(0.5), 0.0);
        for _ in 0..10 {
            s.record(0.025);
        }
        // One value: reported exactly.
        assert_eq!(s.quantile(0.5), 0.025);
        for t in [
            0.0, 0.0, 0.001, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1,
        ] {
            s.record(t);
        }
        // 24 values: 2 zeros, 0.001, ten at 2.5 %, eleven at 10 %.
        assert_eq!(s.quantile(0.0), 0.0);
        assert!(
            (s.quantile(0.5) / 0.025 - 1.0).abs() < 0.03,
            "{}",
            s.quantile(0.5)
        );
        assert_eq!(s.quantile(1.0), 0.1);
        // Not a threshold: ignored.
        s.record(Real::NAN);
        s.record(-1.0);
        assert_eq!(s.count, 24);
    }
}
