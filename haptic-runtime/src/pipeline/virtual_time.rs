//! The deterministic run: one thread, simulated time, contact updates after a latency.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use haptic_core::{CollisionBackend, ContactModel, Device, Integrator, Real};

use crate::error::RuntimeError;
use crate::recording::RunObserver;
use crate::stages::{ContactStage, ContactUpdate, DeviceFailure, HapticStage, panic_message};
use crate::telemetry::{RunMode, Summary};

use super::{ContactLatency, ContactStats, Pipeline, finish};

impl<I: Integrator, B: CollisionBackend, C: ContactModel, D: Device> Pipeline<I, B, C, D> {
    /// Runs `duration_s` of simulated time, single-threaded and deterministic: the same pipeline
    /// stepped at the haptic rate, with each contact update taking effect after `latency`.
    /// `observe` is called after every haptic step (for recording series); pass `|_, _| {}` for
    /// none.
    ///
    /// Every way out of the run ends at zero force: a panic of the contact stage is reported and
    /// its contact forces fade (as in real time), a panic of the haptic step (device, integrator,
    /// contact model) stops the run.
    ///
    /// # Errors
    /// [`RuntimeError::Device`] if the device fails, [`RuntimeError::HapticPanic`] if the haptic
    /// step panics; zero force has been commanded in both cases.
    pub fn run_virtual(
        &mut self,
        duration_s: Real,
        latency: ContactLatency,
        observe: impl FnMut(Real, &HapticStage<I, D>),
    ) -> Result<Summary, RuntimeError> {
        self.run_virtual_observed(duration_s, latency, &mut StepObserver(observe))
    }

    /// [`Pipeline::run_virtual`] with an observer that also sees every contact query (the raw
    /// contacts and the representatives), as a [`crate::RunRecorder`] records them.
    ///
    /// # Errors
    /// As [`Pipeline::run_virtual`].
    pub fn run_virtual_observed(
        &mut self,
        duration_s: Real,
        latency: ContactLatency,
        observer: &mut impl RunObserver<I, D>,
    ) -> Result<Summary, RuntimeError> {
        let dt = 1.0 / self.config.haptic_rate_hz;
        let steps = (duration_s / dt).round().max(0.0) as u64;
        let mut stats = ContactStats::default();
        let contact = &mut self.contact;
        let mut haptic = self.haptic.zero_force_guard();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            virtual_loop(
                &mut haptic,
                contact,
                steps,
                dt,
                latency,
                &mut stats,
                observer,
            )
        }))
        .map_err(|payload| panic_message(&*payload));
        drop(haptic);
        let simulated = self.haptic.stats.steps as Real * dt;
        let mut summary = self.summarize(RunMode::VirtualTime, simulated, &stats);
        summary.scheduling = "virtual time: single thread".into();
        finish(summary, outcome)
    }
}

/// The body of the virtual-time run: contact updates take effect after `latency` of simulated
/// time; a panicking contact stage is reported and no longer asked, as in real time. Returns a
/// device failure that ended the run, if any.
fn virtual_loop<I, B, C, D>(
    haptic: &mut HapticStage<I, D>,
    contact: &mut ContactStage<B, C>,
    steps: u64,
    dt: Real,
    latency: ContactLatency,
    stats: &mut ContactStats,
    observe: &mut impl RunObserver<I, D>,
) -> Option<DeviceFailure>
where
    I: Integrator,
    B: CollisionBackend,
    C: ContactModel,
    D: Device,
{
    // The update in flight, written in place (it is 15 kB): `pending` holds when it started
    // and when it takes effect.
    let mut update = ContactUpdate::none();
    let mut pending: Option<(Real, Real)> = None; // (start, ready)
    let mut next_start_s = 0.0;
    for k in 0..steps {
        let t = k as Real * dt;
        if let Some((start, ready)) = pending {
            if ready <= t + 1e-12 {
                haptic.receive_contact(&update, t);
                stats.record(&update, ready - start, t);
                pending = None;
                next_start_s = ready;
            }
        }
        if pending.is_none() && stats.panicked.is_none() && t + 1e-12 >= next_start_s {
            let tool = *haptic.tool();
            let started = Instant::now();
            let result = catch_unwind(AssertUnwindSafe(|| {
                contact.update_into(&tool, t, &mut update)
            }));
            let cost_s = started.elapsed().as_secs_f64();
            let delay = match latency {
                ContactLatency::FixedRate { rate_hz } => 1.0 / rate_hz,
                ContactLatency::Measured { scale, min_s } => (cost_s * scale).max(min_s),
            };
            match result {
                Ok(Ok(())) => {
                    observe.contact_update(
                        t,
                        t + delay,
                        &update,
                        contact.raw_contacts(),
                        contact.representatives(),
                        contact.representative_weights(),
                        cost_s,
                    );
                    pending = Some((t, t + delay));
                }
                Ok(Err(e)) => {
                    stats.errors += 1;
                    stats.first_error.get_or_insert_with(|| e.to_string());
                    next_start_s = t + delay;
                }
                Err(payload) => stats.panicked = Some(panic_message(&*payload)),
            }
        }
        let started = Instant::now();
        let outcome = haptic.step(t, dt);
        haptic
            .stats
            .step_time
            .record(started.elapsed().as_secs_f64());
        if let Err(f) = outcome {
            return Some(f);
        }
        observe.haptic_step(t + dt, haptic);
    }
    None
}

/// A closure over haptic steps, as an observer that ignores contact queries.
struct StepObserver<F>(F);

impl<I, D, F: FnMut(Real, &HapticStage<I, D>)> RunObserver<I, D> for StepObserver<F> {
    fn haptic_step(&mut self, t_s: Real, haptic: &HapticStage<I, D>) {
        (self.0)(t_s, haptic);
    }

    fn contact_update(
        &mut self,
        _: Real,
        _: Real,
        _: &ContactUpdate,
        _: &haptic_core::ContactSet,
        _: &haptic_core::ContactSet,
        _: &[Real],
        _: Real,
    ) {
    }
}
