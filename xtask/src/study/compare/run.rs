//! One configuration of `study compare`, run in virtual time, and what it measured.

use std::time::Instant;

use haptic_collision::{LodBackend, ParryBackend};
use haptic_core::{CollisionBackend, ContactSet, Device, Integrator, QueryParams, Real, Vec3};
use haptic_device::{DeviceError, ReplayDevice};
use haptic_dynamics::{
    CouplingParams, ForwardEuler, IntegratorKind, LinearizedBackwardEuler, NewtonBackwardEuler,
    PenaltyModel, PenaltyParams, Rk4,
};
use haptic_runtime::{
    ContactLatency, ContactUpdate, HapticStage, PipelineBuilder, RunObserver, RuntimeError,
    SceneParts, Summary,
};

use super::spec::{Backend, Config, Study};

/// Rate at which the force sent is sampled for the error against the reference (Hz).
pub(crate) const SAMPLE_HZ: Real = 1000.0;
/// Contact rate when neither the scene nor the study gives one (Hz).
const DEFAULT_CONTACT_HZ: Real = 250.0;

/// What one configuration measured.
pub(crate) struct Measured {
    /// The run's summary, or the error that ended it.
    pub(crate) summary: Result<Summary, String>,
    /// The force sent, sampled at [`SAMPLE_HZ`] from `1 / SAMPLE_HZ` on (N).
    pub(crate) forces: Vec<Vec3>,
    /// Wall time of the whole run and of the haptic steps alone (s).
    pub(crate) wall_s: Real,
    pub(crate) haptic_s: Real,
    /// Wall time of the contact stage's queries, clustering and linearization (s).
    pub(crate) contact_s: Real,
    /// Tool resets (the coupling stretched past the divergence bound).
    pub(crate) resets: u64,
}

/// Samples the force sent and adds up the contact stage's cost.
struct Sampler {
    forces: Vec<Vec3>,
    contact_s: Real,
}

impl<I: Integrator, D: Device> RunObserver<I, D> for Sampler {
    fn haptic_step(&mut self, t: Real, h: &HapticStage<I, D>) {
        // The force sent at each 1 ms mark (the first step at or after it).
        while (self.forces.len() + 1) as Real / SAMPLE_HZ <= t + 1e-9 {
            self.forces.push(h.last_wrench().force);
        }
    }

    fn contact_update(
        &mut self,
        _: Real,
        _: Real,
        _: &ContactUpdate,
        _: &ContactSet,
        _: &ContactSet,
        _: &[Real],
        query_time_s: Real,
    ) {
        self.contact_s += query_time_s;
    }
}

/// The scene's parts with a configuration's values in place, the contact rate (Hz) and the
/// haptic rate (Hz).
pub(crate) fn configure(base: &SceneParts, c: &Config) -> anyhow::Result<(SceneParts, Real)> {
    let mut p = base.clone();
    if let Some(m) = c.mass_kg {
        p.body = p.body.with_mass(m)?;
    }
    if let Some(k) = c.coupling_stiffness_n_per_m {
        // The linear damping scales with the stiffness: the same relaxation time.
        let ratio = k / base.coupling.stiffness_n_per_m;
        p.coupling = CouplingParams {
            stiffness_n_per_m: k,
            damping_ns_per_m: base.coupling.damping_ns_per_m * ratio,
            ..base.coupling
        };
    }
    if let Some(k) = c.contact_stiffness_n_per_m {
        let ratio = k / base.penalty.stiffness_n_per_m;
        p.penalty = PenaltyParams::new(
            k,
            base.penalty.damping_ns_per_m * ratio,
            base.penalty.delta_m,
        )?;
    }
    if let Some(th) = c.error_threshold {
        p.config.query = QueryParams::new(base.config.query.delta_m, th)?;
    }
    if let Some(hz) = c.haptic_hz {
        p.config.haptic_rate_hz = hz;
    }
    p.config.realtime_scheduling = false;
    p.config.validate()?;
    let contact_hz = c
        .contact_hz
        .or(base.contact_hz)
        .unwrap_or(DEFAULT_CONTACT_HZ);
    Ok((p, contact_hz))
}

/// The device of the study: the scene's simulated hand, or the recording replayed.
fn device(
    study: &Study,
    parts: &SceneParts,
) -> anyhow::Result<Box<dyn Device<Error = DeviceError> + Send>> {
    Ok(match &study.motion {
        Some(path) => Box::new(ReplayDevice::open(path)?),
        None => Box::new(parts.hand_device()?),
    })
}

/// Runs configuration `c` for the study's duration.
pub(crate) fn run(
    study: &Study,
    base: &SceneParts,
    lod: &LodBackend,
    c: &Config,
    duration_s: Real,
) -> anyhow::Result<Measured> {
    let (parts, contact_hz) = configure(base, c)?;
    match c.backend {
        Backend::Lod => with_integrator(
            study,
            &parts,
            lod.clone(),
            c.integrator,
            contact_hz,
            duration_s,
        ),
        Backend::Parry => {
            let parry = ParryBackend::new(&parts.tool_mesh, &parts.obstacles)?;
            with_integrator(study, &parts, parry, c.integrator, contact_hz, duration_s)
        }
    }
}

fn with_integrator<B: CollisionBackend + Send>(
    study: &Study,
    parts: &SceneParts,
    backend: B,
    kind: IntegratorKind,
    contact_hz: Real,
    duration_s: Real,
) -> anyhow::Result<Measured> {
    // Static dispatch in the haptic loop: one monomorphized pipeline per integrator.
    match kind {
        IntegratorKind::LinearizedBackwardEuler => simulate(
            study,
            parts,
            backend,
            LinearizedBackwardEuler,
            contact_hz,
            duration_s,
        ),
        IntegratorKind::NewtonBackwardEuler => simulate(
            study,
            parts,
            backend,
            NewtonBackwardEuler::default(),
            contact_hz,
            duration_s,
        ),
        IntegratorKind::Rk4 => simulate(study, parts, backend, Rk4, contact_hz, duration_s),
        IntegratorKind::ForwardEuler => {
            simulate(study, parts, backend, ForwardEuler, contact_hz, duration_s)
        }
    }
}

fn simulate<I: Integrator + Send, B: CollisionBackend + Send>(
    study: &Study,
    parts: &SceneParts,
    backend: B,
    integrator: I,
    contact_hz: Real,
    duration_s: Real,
) -> anyhow::Result<Measured> {
    let mut pipeline = PipelineBuilder::new(parts.body, parts.tool_pose)
        .integrator(integrator)
        .backend(backend)
        .contact_model(PenaltyModel::new(parts.penalty)?)
        .device(device(study, parts)?)
        .coupling(parts.coupling)
        .config(parts.config)
        .build()?;
    let mut sampler = Sampler {
        forces: Vec::new(),
        contact_s: 0.0,
    };
    let clock = Instant::now();
    let outcome = pipeline.run_virtual_observed(
        duration_s,
        ContactLatency::FixedRate {
            rate_hz: contact_hz,
        },
        &mut sampler,
    );
    let wall_s = clock.elapsed().as_secs_f64();
    let haptic = &pipeline.haptic().stats;
    let haptic_s = haptic.step_time.mean_s() * haptic.steps as Real;
    let resets = haptic.divergences;
    let summary = outcome.map_err(|e: RuntimeError| e.to_string());
    Ok(Measured {
        summary,
        forces: sampler.forces,
        wall_s,
        haptic_s,
        contact_s: sampler.contact_s,
        resets,
    })
}

/// The reference of a configuration: the same physical parameters, full-Newton backward Euler at
/// `factor` times the finest haptic rate of the study (at most 20 kHz), exact contacts (LOD at
/// threshold 0) queried at every haptic step.
pub(crate) fn reference_of(c: &Config, finest_haptic_hz: Real, factor: Real) -> Config {
    let hz = (factor * finest_haptic_hz).min(20_000.0);
    Config {
        integrator: IntegratorKind::NewtonBackwardEuler,
        backend: Backend::Lod,
        error_threshold: Some(0.0),
        haptic_hz: Some(hz),
        contact_hz: Some(hz),
        ..*c
    }
}

/// `‖F − F_ref‖_rms / ‖F_ref‖_rms` over the samples both have; `None` when there are none or
/// the reference sends (almost) no force.
pub(crate) fn force_error_rel(forces: &[Vec3], reference: &[Vec3]) -> Option<Real> {
    let n = forces.len().min(reference.len());
    if n == 0 || rms(&reference[..n]) < MIN_REFERENCE_RMS_N {
        return None;
    }
    let (mut diff, mut refn) = (0.0, 0.0);
    for (f, r) in forces[..n].iter().zip(&reference[..n]) {
        diff += (f - r).norm_squared();
        refn += r.norm_squared();
    }
    Some((diff / refn).sqrt())
}

/// A reference whose force RMS is below this (N) sends no force to compare with.
pub(crate) const MIN_REFERENCE_RMS_N: Real = 1e-6;

/// RMS of the force samples (N).
pub(crate) fn rms(forces: &[Vec3]) -> Real {
    if forces.is_empty() {
        return 0.0;
    }
    (forces.iter().map(Vec3::norm_squared).sum::<Real>() / forces.len() as Real).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_error_is_relative_to_the_reference() {
        let r = vec![Vec3::new(1.0, 0.0, 0.0); 4];
        assert_eq!(force_error_rel(&r, &r), Some(0.0));
        let f = vec![Vec3::new(1.1, 0.0, 0.0); 4];
        assert!((force_error_rel(&f, &r).unwrap() - 0.1).abs() < 1e-12);
        assert!((rms(&f) - 1.1).abs() < 1e-12);
        assert_eq!(force_error_rel(&[], &r), None);
        assert_eq!(force_error_rel(&f, &[Vec3::zeros(); 4]), None);
    }
}
