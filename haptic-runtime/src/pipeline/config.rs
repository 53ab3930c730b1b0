//! What a pipeline is configured with: rates, tolerances, switches, and the contact latency of
//! virtual-time runs.

use haptic_cluster::ClusterParams;
use haptic_core::{LinearizationMode, QueryParams, Real, Vec3};

use crate::error::RuntimeError;
use crate::stages::SafetyConfig;

/// Rates, tolerances and switches of a pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineConfig {
    /// Haptic rate (Hz): 1 kHz by default, up to 10 kHz.
    pub haptic_rate_hz: Real,
    /// Collision query parameters: distance tolerance `δ` and error threshold.
    pub query: QueryParams,
    /// Clustering parameters (K, iteration cap).
    pub cluster: ClusterParams,
    /// How the haptic thread uses the contact model between updates: on the representatives'
    /// fixed frames (the default), the paper's tangents, or held constant (the ablation).
    pub linearization: LinearizationMode,
    /// Gravity (m/s²), `None` for a gravity-compensated tool (the default).
    pub gravity: Option<Vec3>,
    /// Safety settings.
    pub safety: SafetyConfig,
    /// Try to raise the haptic thread's priority and pin the threads to cores.
    pub realtime_scheduling: bool,
    /// A time budget per contact update: the error threshold is then picked update by update
    /// to fit it ([`crate::budget`]), and `query.error_threshold` is not used. `None` (the
    /// default): every query at `query.error_threshold`.
    pub query_budget: Option<crate::QueryBudget>,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            haptic_rate_hz: 1000.0,
            query: QueryParams {
                delta_m: 1e-3,
                error_threshold: 0.0,
            },
            cluster: ClusterParams::default(),
            linearization: LinearizationMode::FixedFrames,
            gravity: None,
            safety: SafetyConfig::default(),
            realtime_scheduling: true,
            query_budget: None,
        }
    }
}

impl PipelineConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`RuntimeError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), RuntimeError> {
        if !(self.haptic_rate_hz.is_finite()
            && self.haptic_rate_hz >= 1.0
            && self.haptic_rate_hz <= 20_000.0)
        {
            return Err(RuntimeError::config(
                "haptic_rate_hz",
                "must be in [1, 20000] Hz",
            ));
        }
        if let Some(b) = &self.query_budget {
            b.validate()?;
        }
        QueryParams::new(self.query.delta_m, self.query.error_threshold)
            .map_err(|e| RuntimeError::config("query", e.to_string()))?;
        let s = &self.safety;
        for (field, v) in [
            ("safety.contact_timeout_s", s.contact_timeout_s),
            ("safety.contact_fade_s", s.contact_fade_s),
            ("safety.divergence_bound_m", s.divergence_bound_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(RuntimeError::config(field, "must be positive and finite"));
            }
        }
        if let Some(g) = self.gravity {
            if !g.iter().all(|c| c.is_finite()) {
                return Err(RuntimeError::config("gravity", "must be finite"));
            }
        }
        Ok(())
    }
}

/// When a contact update computed in virtual time takes effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactLatency {
    /// The contact thread delivers at a fixed rate (Hz): each update becomes available
    /// `1 / rate_hz` after the state it was computed from. Bit-for-bit reproducible.
    FixedRate {
        /// Contact updates per simulated second.
        rate_hz: Real,
    },
    /// Each update becomes available after the wall-clock cost of its own computation times
    /// `scale` (at least `min_s`): the measured contact rate of this machine, slowed down by
    /// `scale` to stand for a slower one. Not bit-reproducible, since it depends on timing.
    Measured {
        /// Factor on the measured cost.
        scale: Real,
        /// Smallest latency (s).
        min_s: Real,
    },
}
