//! The pipeline: a builder that composes an [`Integrator`], a [`CollisionBackend`], a
//! [`ContactModel`] (with clustering) and a [`Device`], and the two ways to run it.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{
    CollisionBackend, ContactModel, Device, Integrator, LinearizationMode, Pose, QueryParams, Real,
    RigidBody, ToolState, Vec3,
};
use haptic_dynamics::coupling::{CouplingParams, Grasp, VirtualCoupling};
use haptic_dynamics::forces::HapticForces;

use crate::error::RuntimeError;
use crate::stages::{
    ContactStage, ContactUpdate, DeviceFailure, HapticStage, SafetyConfig, ToolMessage,
    panic_message,
};
use crate::telemetry::{DurationHistogram, LiveTelemetry, RunMode, Snapshot, Summary};

/// Rates, tolerances and switches of a pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineConfig {
    /// Haptic rate (Hz): 1 kHz by default, up to 10 kHz.
    pub haptic_rate_hz: Real,
    /// Collision query parameters: distance tolerance `δ` and error threshold.
    pub query: QueryParams,
    /// Clustering parameters (K, iteration cap).
    pub cluster: ClusterParams,
    /// Linearized contact model, or forces held constant between updates (the ablation).
    pub linearization: LinearizationMode,
    /// Gravity (m/s²), `None` for a gravity-compensated tool (the default).
    pub gravity: Option<Vec3>,
    /// Safety settings.
    pub safety: SafetyConfig,
    /// Try to raise the haptic thread's priority and pin the threads to cores.
    pub realtime_scheduling: bool,
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
            linearization: LinearizationMode::Linearized,
            gravity: None,
            safety: SafetyConfig::default(),
            realtime_scheduling: true,
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
            && self.haptic_rate_hz > 0.0
            && self.haptic_rate_hz <= 20_000.0)
        {
            return Err(RuntimeError::config(
                "haptic_rate_hz",
                "must be in (0, 20000] Hz",
            ));
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

/// A typestate builder: each part is set once, and `build` exists only when all four are.
pub struct PipelineBuilder<I, B, C, D> {
    body: RigidBody,
    tool_pose: Pose,
    coupling: CouplingParams,
    config: PipelineConfig,
    integrator: I,
    backend: B,
    contact_model: C,
    device: D,
}

impl PipelineBuilder<(), (), (), ()> {
    /// Starts a pipeline for a tool of mass properties `body` whose centre-of-mass frame starts at
    /// `tool_pose`; it is grasped where the device handle is at the first reading.
    pub fn new(body: RigidBody, tool_pose: Pose) -> Self {
        Self {
            body,
            tool_pose,
            coupling: CouplingParams::default(),
            config: PipelineConfig::default(),
            integrator: (),
            backend: (),
            contact_model: (),
            device: (),
        }
    }
}

impl<I, B, C, D> PipelineBuilder<I, B, C, D> {
    /// The integrator.
    pub fn integrator<I2: Integrator>(self, integrator: I2) -> PipelineBuilder<I2, B, C, D> {
        PipelineBuilder {
            body: self.body,
            tool_pose: self.tool_pose,
            coupling: self.coupling,
            config: self.config,
            integrator,
            backend: self.backend,
            contact_model: self.contact_model,
            device: self.device,
        }
    }

    /// The collision back-end.
    pub fn backend<B2: CollisionBackend>(self, backend: B2) -> PipelineBuilder<I, B2, C, D> {
        PipelineBuilder {
            body: self.body,
            tool_pose: self.tool_pose,
            coupling: self.coupling,
            config: self.config,
            integrator: self.integrator,
            backend,
            contact_model: self.contact_model,
            device: self.device,
        }
    }

    /// The contact model (applied to cluster representatives).
    pub fn contact_model<C2: ContactModel>(
        self,
        contact_model: C2,
    ) -> PipelineBuilder<I, B, C2, D> {
        PipelineBuilder {
            body: self.body,
            tool_pose: self.tool_pose,
            coupling: self.coupling,
            config: self.config,
            integrator: self.integrator,
            backend: self.backend,
            contact_model,
            device: self.device,
        }
    }

    /// The device.
    pub fn device<D2: Device>(self, device: D2) -> PipelineBuilder<I, B, C, D2> {
        PipelineBuilder {
            body: self.body,
            tool_pose: self.tool_pose,
            coupling: self.coupling,
            config: self.config,
            integrator: self.integrator,
            backend: self.backend,
            contact_model: self.contact_model,
            device,
        }
    }

    /// The virtual coupling parameters.
    pub fn coupling(mut self, coupling: CouplingParams) -> Self {
        self.coupling = coupling;
        self
    }

    /// Rates, tolerances and switches.
    pub fn config(mut self, config: PipelineConfig) -> Self {
        self.config = config;
        self
    }
}

impl<I: Integrator, B: CollisionBackend, C: ContactModel, D: Device> PipelineBuilder<I, B, C, D> {
    /// Reads the device once, grasps the tool, and assembles the pipeline.
    ///
    /// # Errors
    /// [`RuntimeError::Config`] for a bad configuration, [`RuntimeError::Device`] if the first
    /// reading fails, [`RuntimeError::Setup`] if the grasp cannot be made.
    pub fn build(mut self) -> Result<Pipeline<I, B, C, D>, RuntimeError> {
        self.config.validate()?;
        let first = self.device.read(0.0).map_err(|e| RuntimeError::Device {
            kind: haptic_core::device::Error::kind(&e),
            message: e.to_string(),
            summary: Box::default(),
        })?;
        if !first.is_finite() {
            return Err(RuntimeError::Setup(
                "the first device reading is not finite".into(),
            ));
        }
        let tool = ToolState::at_rest(&self.tool_pose);
        let setup = |e: haptic_dynamics::DynamicsError| RuntimeError::Setup(e.to_string());
        let grasp = Grasp::new(&tool, &first.pose).map_err(setup)?;
        let coupling = VirtualCoupling::new(self.coupling, grasp, &first).map_err(setup)?;
        let forces = HapticForces {
            coupling,
            contact: haptic_core::LinearizedContact::none(),
            mode: self.config.linearization,
            gravity: self.config.gravity,
        };
        if self.config.cluster.max_clusters > haptic_core::MAX_REPRESENTATIVES {
            return Err(RuntimeError::config(
                "cluster",
                format!(
                    "max_clusters {} is more than a linearized contact model holds ({})",
                    self.config.cluster.max_clusters,
                    haptic_core::MAX_REPRESENTATIVES
                ),
            ));
        }
        let clusterer = Clusterer::new(self.config.cluster)
            .map_err(|e| RuntimeError::config("cluster", e.to_string()))?;
        Ok(Pipeline {
            haptic: HapticStage::new(
                self.integrator,
                self.device,
                self.body,
                forces,
                tool,
                self.config.safety,
            ),
            contact: ContactStage::new(
                self.backend,
                self.contact_model,
                clusterer,
                self.body,
                self.config.query,
            ),
            config: self.config,
            live: LiveTelemetry::default(),
        })
    }
}

/// Contact-side statistics of a run.
#[derive(Debug, Clone, Default)]
struct ContactStats {
    updates: u64,
    latency: DurationHistogram,
    broad_phase_only: u64,
    raw_max: u64,
    clusters_max: u64,
    max_penetration_m: Real,
    errors: u64,
    first_error: Option<String>,
    panicked: Option<String>,
    first_update_s: Option<Real>,
    last_update_s: Real,
}

impl ContactStats {
    fn record(&mut self, u: &ContactUpdate, latency_s: Real, available_s: Real) {
        self.updates += 1;
        self.latency.record(latency_s);
        if u.broad_phase_only {
            self.broad_phase_only += 1;
        }
        self.raw_max = self.raw_max.max(u.raw_contacts as u64);
        self.clusters_max = self.clusters_max.max(u.clusters as u64);
        self.max_penetration_m = self.max_penetration_m.max(u.max_penetration_m);
        self.first_update_s.get_or_insert(available_s);
        self.last_update_s = available_s;
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
    live: LiveTelemetry,
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
        mut observe: impl FnMut(Real, &HapticStage<I, D>),
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
                &mut observe,
            )
        }))
        .map_err(|payload| panic_message(&*payload));
        drop(haptic);
        let simulated = self.haptic.stats.steps as Real * dt;
        let mut summary = self.summarize(RunMode::VirtualTime, simulated, &stats);
        summary.scheduling = "virtual time: single thread".into();
        finish(summary, outcome)
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
            raw_contacts_max: c.raw_max,
            clusters_max: c.clusters_max,
            max_penetration_m: c.max_penetration_m,
            max_coupling_deviation_m: h.max_coupling_deviation_m,
            max_force_n: h.max_force_n,
            saturation_events: h.saturation_events,
            zero_force_steps: h.zero_force_steps,
            solver_failures: h.solver_failures,
            contact_errors: c.errors,
            contact_stale_steps: h.stale_steps,
            contact_thread_panicked: c.panicked.is_some(),
            haptic_thread_panic: None,
            incidents,
            realtime_scheduling_granted: false,
            scheduling: String::new(),
        }
    }
}

/// Pins the current thread to `core`, if given, and, if `realtime`, asks for real-time
/// scheduling (`SCHED_FIFO` at priority [`REALTIME_PRIORITY`] on Linux; the highest priority of
/// the current policy elsewhere). Returns whether real-time scheduling was granted, and what
/// happened in words.
fn apply_scheduling(core: Option<usize>, realtime: bool) -> (bool, String) {
    let mut notes = Vec::new();
    if let Some(core) = core {
        let pinned = core_affinity::get_core_ids()
            .and_then(|ids| ids.get(core).copied())
            .map(core_affinity::set_for_current)
            .unwrap_or(false);
        notes.push(if pinned {
            format!("pinned to core {core}")
        } else {
            format!("could not pin to core {core}")
        });
    }
    let mut granted = false;
    if realtime {
        match request_realtime() {
            Ok(what) => {
                granted = true;
                notes.push(what);
            }
            Err(why) => notes.push(format!("real-time scheduling not granted ({why})")),
        }
    }
    (granted, notes.join(", "))
}

/// The `SCHED_FIFO` priority the haptic thread asks for (1–99): above the kernel's threaded
/// interrupt handlers' default of 50, below the watchdogs at 99.
pub const REALTIME_PRIORITY: u8 = 80;

#[cfg(target_os = "linux")]
fn request_realtime() -> Result<String, String> {
    use thread_priority::{
        RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
        set_thread_priority_and_policy, thread_native_id,
    };
    let value = ThreadPriorityValue::try_from(REALTIME_PRIORITY)?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map(|()| format!("real-time SCHED_FIFO priority {REALTIME_PRIORITY}"))
    .map_err(|e| format!("{e:?}"))
}

#[cfg(not(target_os = "linux"))]
fn request_realtime() -> Result<String, String> {
    thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Max)
        .map(|()| "highest thread priority".to_string())
        .map_err(|e| format!("{e:?}"))
}

/// How the real-time haptic thread waits for its deadlines: in the periods it sleeps (one in
/// `sleep_every`), it sleeps until `spin` before the deadline and spins from there; in the
/// others it spins from the end of its step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct WaitPlan {
    spin: Duration,
    sleep_every: u64,
}

impl WaitPlan {
    /// The plan for a period of `period`.
    ///
    /// A thread without real-time scheduling has 50 µs of timer slack and is woken late under
    /// load: it sleeps every period and spins for the last 200 µs. A real-time thread has no
    /// slack and usually wakes within tens of microseconds, but not always (on a virtual machine,
    /// a few wake-ups in a thousand take over 60 µs), so it sleeps as seldom as it may. It must
    /// sleep: the kernel stops a real-time thread that runs more than `sched_rt_runtime_us` of
    /// every `sched_rt_period_us` (950 ms of each second by default) for the rest of that
    /// second. It sleeps in enough periods to stay off the CPU for twice the kernel's reserve
    /// (10 % by default), and spins for the last 60 µs of those periods. Where the administrator
    /// has turned the throttling off (`sched_rt_runtime_us = -1`), it never sleeps.
    fn new(realtime_granted: bool, period: Duration) -> Self {
        if !realtime_granted {
            return Self {
                spin: Duration::from_micros(200),
                sleep_every: 1,
            };
        }
        let Some(reserve) = realtime_reserve() else {
            return Self {
                spin: period,
                sleep_every: u64::MAX,
            };
        };
        let spin = Duration::from_micros(60).min(period.mul_f64(0.6));
        let sleep_fraction = (period - spin).as_secs_f64() / period.as_secs_f64();
        let periods = (sleep_fraction / (2.0 * reserve)).floor();
        Self {
            spin,
            sleep_every: if periods >= 1.0 { periods as u64 } else { 1 },
        }
    }

    /// Whether period `k` sleeps.
    fn sleeps(&self, k: u64) -> bool {
        k % self.sleep_every == 0
    }
}

/// The fraction of each second the kernel keeps from real-time threads (Linux:
/// `1 − sched_rt_runtime_us / sched_rt_period_us`, 5 % by default); `None` where it keeps none
/// (`sched_rt_runtime_us = -1`). Read once per run, before the loop; the default where the files
/// cannot be read.
fn realtime_reserve() -> Option<Real> {
    let read = |name: &str| -> Option<Real> {
        std::fs::read_to_string(format!("/proc/sys/kernel/{name}"))
            .ok()?
            .trim()
            .parse()
            .ok()
    };
    match (read("sched_rt_runtime_us"), read("sched_rt_period_us")) {
        (Some(runtime), _) if runtime < 0.0 => None,
        (Some(runtime), Some(period)) if period > 0.0 && runtime <= period => {
            Some((1.0 - runtime / period).max(0.01))
        }
        _ => Some(0.05),
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
    observe: &mut impl FnMut(Real, &HapticStage<I, D>),
) -> Option<DeviceFailure>
where
    I: Integrator,
    B: CollisionBackend,
    C: ContactModel,
    D: Device,
{
    let mut pending: Option<(Real, Real, ContactUpdate)> = None; // (start, ready, update)
    let mut next_start_s = 0.0;
    for k in 0..steps {
        let t = k as Real * dt;
        if let Some((start, ready, update)) = pending {
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
            let result = catch_unwind(AssertUnwindSafe(|| contact.update(&tool, t)));
            let cost_s = started.elapsed().as_secs_f64();
            let delay = match latency {
                ContactLatency::FixedRate { rate_hz } => 1.0 / rate_hz,
                ContactLatency::Measured { scale, min_s } => (cost_s * scale).max(min_s),
            };
            match result {
                Ok(Ok(update)) => pending = Some((t, t + delay, update)),
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
        observe(t + dt, haptic);
    }
    None
}

/// The channels and flags the real-time haptic thread shares with the others.
struct HapticThreadLinks<'a> {
    tool_in: triple_buffer::Input<ToolMessage>,
    contact_out: triple_buffer::Output<(ContactUpdate, Real)>,
    live: &'a LiveTelemetry,
    stop: &'a AtomicBool,
}

/// The body of the real-time haptic thread: `steps` periods of `dt`, each against its own
/// deadline `t0 + (k + 1) dt`, waited for as `wait` says. Stops early when `stop` is raised. Returns a device failure that ended the run,
/// and the loop's own duration (s), from its start to the end of its last period.
fn realtime_haptic_loop<I: Integrator, D: Device>(
    haptic: &mut HapticStage<I, D>,
    links: &mut HapticThreadLinks<'_>,
    steps: u64,
    dt: Real,
    wait: WaitPlan,
) -> (Option<DeviceFailure>, Real) {
    let live = links.live;
    let t0 = Instant::now();
    for k in 0..steps {
        if links.stop.load(Ordering::Relaxed) {
            break;
        }
        // From the start, not accumulated: no drift, and no narrowing of `k`.
        let deadline = t0 + Duration::from_secs_f64((k + 1) as Real * dt);
        let now_s = t0.elapsed().as_secs_f64();
        if links.contact_out.update() {
            let (update, _) = *links.contact_out.output_buffer();
            haptic.receive_contact(&update, now_s);
        }
        let started = Instant::now();
        let outcome = haptic.step(now_s, dt);
        haptic
            .stats
            .step_time
            .record(started.elapsed().as_secs_f64());
        if let Err(f) = outcome {
            return (Some(f), t0.elapsed().as_secs_f64());
        }
        links.tool_in.write(ToolMessage {
            seq: k + 1,
            time_s: now_s,
            state: *haptic.tool(),
        });
        live.haptic_steps.store(k + 1, Ordering::Relaxed);
        live.time_s.store(now_s);
        live.max_force_n.store(haptic.stats.max_force_n);
        live.zero_force_steps
            .store(haptic.stats.zero_force_steps, Ordering::Relaxed);
        let after = Instant::now();
        if after > deadline {
            live.deadline_misses.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let remaining = deadline - after;
        if wait.sleeps(k) && remaining > wait.spin {
            std::thread::sleep(remaining - wait.spin);
        }
        while Instant::now() < deadline {
            std::hint::spin_loop();
        }
    }
    (None, t0.elapsed().as_secs_f64())
}

/// The body of the real-time contact thread: an update for every new tool state, until `stop`.
/// A panic of the stage ends the thread and is reported; the haptic thread fades the contact
/// forces out.
fn contact_thread_loop<B: CollisionBackend, C: ContactModel>(
    contact: &mut ContactStage<B, C>,
    mut tool_out: triple_buffer::Output<ToolMessage>,
    mut contact_in: triple_buffer::Input<(ContactUpdate, Real)>,
    live: &LiveTelemetry,
    stop: &AtomicBool,
    start: Instant,
) -> ContactStats {
    let mut stats = ContactStats::default();
    let mut last_seq = 0;
    while !stop.load(Ordering::Acquire) {
        tool_out.update();
        let msg = *tool_out.output_buffer();
        if msg.seq == last_seq {
            std::thread::sleep(Duration::from_micros(20));
            continue;
        }
        last_seq = msg.seq;
        let started = Instant::now();
        match catch_unwind(AssertUnwindSafe(|| contact.update(&msg.state, msg.time_s))) {
            Ok(Ok(update)) => {
                let latency = started.elapsed().as_secs_f64();
                let now = start.elapsed().as_secs_f64();
                contact_in.write((update, latency));
                stats.record(&update, latency, now);
                live.contact_updates.fetch_add(1, Ordering::Relaxed);
                live.raw_contacts
                    .store(update.raw_contacts as u64, Ordering::Relaxed);
                live.clusters
                    .store(update.clusters as u64, Ordering::Relaxed);
                live.max_penetration_m.store(stats.max_penetration_m);
            }
            Ok(Err(e)) => {
                stats.errors += 1;
                stats.first_error.get_or_insert_with(|| e.to_string());
            }
            Err(payload) => {
                stats.panicked = Some(panic_message(&*payload));
                live.contact_thread_dead.store(true, Ordering::Release);
                break;
            }
        }
    }
    stats
}

/// Raises a flag when dropped: the watcher's way of stopping the other threads on every exit,
/// its own panics (in a progress callback) included.
struct RaiseOnDrop<'a>(&'a AtomicBool);

impl Drop for RaiseOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
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

impl<I, B, C, D> Pipeline<I, B, C, D>
where
    I: Integrator + Send,
    B: CollisionBackend + Send,
    C: ContactModel + Send,
    D: Device + Send,
{
    /// Runs `duration_s` of wall time: the haptic thread at the fixed haptic rate, the contact
    /// thread as fast as it can, exchanging the latest tool state and the latest linearized
    /// contact model through lock-free single-slot (triple) buffers. The calling thread watches
    /// and calls `progress` about ten times a second with a live snapshot.
    ///
    /// If the contact thread stalls or panics, the haptic thread keeps its rate on the last
    /// model and fades contact forces out after the timeout; the summary says what happened.
    /// Every way out of the haptic loop, a panic included, ends at zero force.
    ///
    /// # Errors
    /// [`RuntimeError::Device`] if the device fails, [`RuntimeError::HapticPanic`] if the haptic
    /// thread panics; zero force has been commanded in both cases.
    pub fn run_realtime(
        &mut self,
        duration_s: Real,
        mut progress: impl FnMut(&Snapshot),
    ) -> Result<Summary, RuntimeError> {
        let dt = 1.0 / self.config.haptic_rate_hz;
        let steps = (duration_s / dt).round().max(0.0) as u64;
        let (tool_in, tool_out) = triple_buffer::triple_buffer(&ToolMessage {
            seq: 0,
            time_s: 0.0,
            state: *self.haptic.tool(),
        });
        let (contact_in, contact_out) =
            triple_buffer::triple_buffer(&(ContactUpdate::none(), 0.0 as Real));
        let stop = AtomicBool::new(false);
        let scheduling_wanted = self.config.realtime_scheduling;
        let live = &self.live;
        let haptic = &mut self.haptic;
        let contact = &mut self.contact;
        let start = Instant::now();
        let (outcome, loop_s, contact_stats, granted, notes) = std::thread::scope(|s| {
            let stop = &stop;
            let _stop_all = RaiseOnDrop(stop);
            let contact_thread = s.spawn(move || {
                let (_, note) = if scheduling_wanted {
                    apply_scheduling(Some(0), false)
                } else {
                    (false, String::new())
                };
                let stats = contact_thread_loop(contact, tool_out, contact_in, live, stop, start);
                (stats, note)
            });
            let haptic_thread = s.spawn(move || {
                let mut haptic = haptic.zero_force_guard();
                let (granted, note) = if scheduling_wanted {
                    apply_scheduling(Some(1), true)
                } else {
                    (false, String::new())
                };
                let mut links = HapticThreadLinks {
                    tool_in,
                    contact_out,
                    live,
                    stop,
                };
                let wait = WaitPlan::new(granted, Duration::from_secs_f64(dt));
                let started = Instant::now();
                let outcome = catch_unwind(AssertUnwindSafe(|| {
                    realtime_haptic_loop(&mut haptic, &mut links, steps, dt, wait)
                }))
                .map_err(|payload| panic_message(&*payload));
                drop(haptic);
                stop.store(true, Ordering::Release);
                let loop_s = match &outcome {
                    Ok((_, loop_s)) => *loop_s,
                    Err(_) => started.elapsed().as_secs_f64(),
                };
                (outcome.map(|(failure, _)| failure), loop_s, granted, note)
            });
            while !haptic_thread.is_finished() {
                progress(&live.snapshot());
                std::thread::sleep(Duration::from_millis(100));
            }
            let (outcome, loop_s, granted, haptic_note) =
                haptic_thread.join().unwrap_or_else(|_| {
                    (
                        Err("the haptic thread panicked outside its loop".into()),
                        start.elapsed().as_secs_f64(),
                        false,
                        String::new(),
                    )
                });
            stop.store(true, Ordering::Release);
            let (contact_stats, contact_note) = contact_thread.join().unwrap_or_else(|_| {
                let stats = ContactStats {
                    panicked: Some("contact thread could not be joined".into()),
                    ..ContactStats::default()
                };
                (stats, String::new())
            });
            (
                outcome,
                loop_s,
                contact_stats,
                granted,
                format!("haptic thread: {haptic_note}; contact thread: {contact_note}"),
            )
        });
        progress(&self.live.snapshot());
        // Rates over the haptic loop's own duration: the watcher notices the end up to a
        // tenth of a second late.
        let mut summary = self.summarize(RunMode::RealTime, loop_s, &contact_stats);
        summary.realtime_scheduling_granted = granted;
        summary.scheduling = if scheduling_wanted {
            notes
        } else {
            "not requested".into()
        };
        finish(summary, outcome)
    }
}
