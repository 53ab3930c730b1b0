//! The two halves of the multirate pipeline (Section III-A), shared by the real-time and the
//! virtual-time modes: the haptic step (steps 1–6) and the contact update (steps 1–4).

use haptic_cluster::Clusterer;
use haptic_core::{
    CollisionBackend, ContactModel, ContactSet, Device, DeviceLimits, DeviceState,
    IntegrationError, Integrator, LinearizationMode, LinearizedContact, QueryParams, Real,
    RigidBody, ToolState, Wrench,
    device::{Error as _, ErrorKind},
};
use haptic_dynamics::LinearizedBackwardEuler;
use haptic_dynamics::forces::HapticForces;

use crate::telemetry::DurationHistogram;

/// The tool state the haptic thread publishes for the contact thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolMessage {
    /// Sequence number, increasing.
    pub seq: u64,
    /// Haptic time of the state (s).
    pub time_s: Real,
    /// The state.
    pub state: ToolState,
}

/// What the contact thread publishes: the linearized contact model and what it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactUpdate {
    /// Sequence number, increasing; 0 is the initial "no contact" update.
    pub seq: u64,
    /// Haptic time of the tool state the update was computed at (s).
    pub query_time_s: Real,
    /// The linearized contact wrench (eq. 42).
    pub model: LinearizedContact,
    /// Raw contacts returned by the collision query.
    pub raw_contact_count: usize,
    /// Clusters (representatives) the model was built from.
    pub cluster_count: usize,
    /// Deepest raw penetration (m); 0 when nothing penetrates.
    pub max_penetration_m: Real,
    /// Whether the broad phase found nothing near the tool (no further work was done).
    pub broad_phase_only: bool,
    /// The error threshold the query held (fraction of the tool's bounding radius): the one
    /// asked, or less where the back-end holds a tighter one
    /// (`CollisionBackend::threshold_reached`).
    pub error_threshold: Real,
}

impl ContactUpdate {
    /// The initial update: no contact.
    pub fn none() -> Self {
        Self {
            seq: 0,
            query_time_s: 0.0,
            model: LinearizedContact::none(),
            raw_contact_count: 0,
            cluster_count: 0,
            max_penetration_m: 0.0,
            broad_phase_only: true,
            error_threshold: 0.0,
        }
    }

    /// Makes this update equal to `other`, copying only the contact tangents in use (see
    /// [`LinearizedContact::copy_from`]): a few kB for a handful of contacts, instead of the
    /// model's whole 15 kB.
    #[inline]
    pub fn copy_from(&mut self, other: &Self) {
        // Destructured, so that a field added later cannot be left out of the copy.
        let Self {
            seq,
            query_time_s,
            model,
            raw_contact_count,
            cluster_count,
            max_penetration_m,
            broad_phase_only,
            error_threshold,
        } = other;
        self.seq = *seq;
        self.query_time_s = *query_time_s;
        self.model.copy_from(model);
        self.raw_contact_count = *raw_contact_count;
        self.cluster_count = *cluster_count;
        self.max_penetration_m = *max_penetration_m;
        self.broad_phase_only = *broad_phase_only;
        self.error_threshold = *error_threshold;
    }
}

/// Why a contact update failed (the update is dropped and counted).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ContactStageError {
    /// The collision back-end returned an error (its own type, boxed: the stage is generic
    /// over the back-end).
    #[error("collision query failed: {0}")]
    Collision(#[source] Box<dyn std::error::Error + Send + Sync + 'static>),
    /// Clustering failed.
    #[error("clustering failed: {0}")]
    Cluster(#[from] haptic_cluster::ClusterError),
    /// The contact model failed.
    #[error("contact model failed: {0}")]
    Model(#[from] haptic_core::ContactModelError),
}

/// Steps 1–4 of the contact thread: fetch tool state → collision query → cluster → penalty forces
/// and Jacobians at the representatives → linearized model.
pub struct ContactStage<B, C> {
    backend: B,
    model: C,
    clusterer: Clusterer,
    body: RigidBody,
    params: QueryParams,
    raw: ContactSet,
    representatives: ContactSet,
    seq: u64,
    /// With a time budget, the threshold of each query.
    budget: Option<crate::ThresholdController>,
}

impl<B: CollisionBackend, C: ContactModel> ContactStage<B, C> {
    /// A contact stage.
    pub fn new(
        backend: B,
        model: C,
        clusterer: Clusterer,
        body: RigidBody,
        params: QueryParams,
    ) -> Self {
        Self {
            backend,
            model,
            clusterer,
            body,
            params,
            raw: ContactSet::with_capacity(256),
            representatives: ContactSet::with_capacity(16),
            seq: 0,
            budget: None,
        }
    }

    /// The stage with a time budget per update (`None`: the fixed threshold of its query
    /// parameters): each query's threshold is picked from the cost of the updates with
    /// contacts before it, starting at the query parameters' threshold (within the budget's
    /// range).
    pub fn with_budget(mut self, budget: Option<crate::QueryBudget>) -> Self {
        self.budget =
            budget.map(|b| crate::ThresholdController::starting_at(b, self.params.error_threshold));
        self
    }

    /// The collision back-end.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// The raw contacts of the last update.
    pub fn raw_contacts(&self) -> &ContactSet {
        &self.raw
    }

    /// The representatives of the last update.
    pub fn representatives(&self) -> &ContactSet {
        &self.representatives
    }

    /// The weight (m) of each representative of the last update, in their order: the sum of its
    /// raw contacts' weights `d_i + δ` (see `haptic_cluster`).
    pub fn representative_weights(&self) -> &[Real] {
        // In free space the clusterer is not called: its last weights belong to older contacts.
        if self.representatives.is_empty() {
            &[]
        } else {
            self.clusterer.representative_weights()
        }
    }

    /// One contact update at the tool state `tool`, computed at haptic time `time_s`.
    ///
    /// A convenience over [`ContactStage::update_into`], which writes the update where it is
    /// published instead of returning a 15 kB value.
    ///
    /// # Errors
    /// [`ContactStageError`] when the back-end, the clustering or the model fails.
    pub fn update(
        &mut self,
        tool: &ToolState,
        time_s: Real,
    ) -> Result<ContactUpdate, ContactStageError> {
        let mut update = ContactUpdate::none();
        self.update_into(tool, time_s, &mut update)?;
        Ok(update)
    }

    /// One contact update at the tool state `tool`, computed at haptic time `time_s`, written
    /// over `out` (whatever it held): every field is set, and of the model's tangents only the
    /// ones in use, so that free space costs the query and a few dozen bytes.
    ///
    /// # Errors
    /// [`ContactStageError`] when the back-end, the clustering or the model fails; `out` is then
    /// partly written and should not be published.
    pub fn update_into(
        &mut self,
        tool: &ToolState,
        time_s: Real,
        out: &mut ContactUpdate,
    ) -> Result<(), ContactStageError> {
        let Some(b) = &self.budget else {
            return self.update_at_threshold(tool, time_s, out);
        };
        self.params.error_threshold = b.threshold();
        let started = std::time::Instant::now();
        let result = self.update_at_threshold(tool, time_s, out);
        // Only updates that found contacts say what a threshold costs: free space (the broad
        // phase alone) and failures take nanoseconds and would pull the threshold to the
        // finest just before the next contact.
        if let (Ok(()), Some(b)) = (&result, &mut self.budget) {
            if out.raw_contact_count > 0 {
                b.observe(started.elapsed().as_secs_f64());
                let coarsest = QueryParams {
                    error_threshold: b.budget().max_threshold,
                    ..self.params
                };
                b.hold_at_most(self.backend.threshold_reached(&coarsest));
            }
        }
        result
    }

    /// One update at the current query parameters, into `out`.
    fn update_at_threshold(
        &mut self,
        tool: &ToolState,
        time_s: Real,
        out: &mut ContactUpdate,
    ) -> Result<(), ContactStageError> {
        let stats = self
            .backend
            .query(&tool.pose(), &self.params, &mut self.raw)
            .map_err(|e| ContactStageError::Collision(Box::new(e)))?;
        self.seq += 1;
        out.seq = self.seq;
        out.query_time_s = time_s;
        out.error_threshold = self.backend.threshold_reached(&self.params);
        if self.raw.is_empty() {
            // Free space: no clustering, no penalty, no Jacobian.
            self.representatives.clear();
            out.model.clear();
            out.raw_contact_count = 0;
            out.cluster_count = 0;
            out.max_penetration_m = 0.0;
            out.broad_phase_only = !stats.broad_phase_hit;
            return Ok(());
        }
        out.broad_phase_only = false;
        out.raw_contact_count = self.raw.len();
        out.max_penetration_m = self.raw.max_depth_m().unwrap_or(0.0).max(0.0);
        let clustered = self.clusterer.cluster(
            self.raw.as_slice(),
            self.params.delta_m,
            &mut self.representatives,
        )?;
        out.cluster_count = clustered.clusters;
        self.model.linearize(
            &self.body,
            tool,
            self.representatives.as_slice(),
            &mut out.model,
        )?;
        Ok(())
    }
}

/// What one haptic step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepOutcome {
    /// The tool was integrated and a force sent.
    Stepped,
    /// A NaN (device reading or state) or a failed solve: zero force was sent.
    ZeroForce {
        /// Whether the integrator failed (as opposed to bad device data).
        solver_failure: bool,
    },
}

/// A device failure that ends the run.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceFailure {
    /// Kind of the failure.
    pub kind: ErrorKind,
    /// Message.
    pub message: String,
}

/// Counters and histograms the haptic stage keeps for itself.
#[derive(Debug, Clone, Default)]
pub struct HapticStats {
    /// Steps taken (including zero-force ones).
    pub steps: u64,
    /// Step compute time.
    pub step_time: DurationHistogram,
    /// Largest force sent (N).
    pub max_force_n: Real,
    /// Largest coupling deviation (m).
    pub max_coupling_deviation_m: Real,
    /// Commands clamped to the device limits.
    pub saturation_events: u64,
    /// Steps that sent zero force: a NaN reading or state, or a failed solve (those are also
    /// counted in `solver_failures`).
    pub zero_force_steps: u64,
    /// Integration failures (zero force sent, tool put back at the handle).
    pub solver_failures: u64,
    /// Steps whose Newton solve did not converge and that took the semi-implicit step instead
    /// ([`SafetyConfig::semi_implicit_fallback`]); not counted in `solver_failures`.
    pub solver_fallbacks: u64,
    /// Steps with a stale (faded) contact model.
    pub stale_steps: u64,
    /// Contact updates that arrived late: at the tool's state when they were received, some
    /// contact was pressed beyond its reach (the tool had travelled more than `δ` into a surface
    /// since the query). The sign that `δ` or the contact rate is too small for the motion
    /// (`docs/stability.md`).
    pub late_contact_updates: u64,
    /// Tool resets after the coupling deviation passed the divergence bound.
    pub divergences: u64,
    /// Largest `| |q| - 1 |` of the tool state seen.
    pub max_quat_norm_error: Real,
    /// Passivity observer: energy that has flowed from the device port into the simulation,
    /// translational and rotational (J), counted with the wrench actually sent (after
    /// saturation and any controller damping). Negative means the simulation has generated
    /// energy.
    pub port_energy_j: [Real; 2],
    /// Lowest value `port_energy_j[0] + port_energy_j[1]` reached (J).
    pub min_port_energy_j: Real,
    /// Steps in which the passivity controller added damping.
    pub passivity_corrections: u64,
}

/// Safety settings of the haptic stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyConfig {
    /// After this long without a fresh contact update (s), contact forces fade out.
    pub contact_timeout_s: Real,
    /// Duration of the fade from full to zero contact force (s).
    pub contact_fade_s: Real,
    /// A coupling deviation beyond this (m) counts as a divergence: the tool is put back at the
    /// handle, at rest.
    pub divergence_bound_m: Real,
    /// The passivity controller (Hannaford & Ryu 2002) at the device port: when the passivity
    /// observer finds that the simulation has generated energy, a variable damping on the wrench
    /// sent dissipates exactly that energy in the same step. Off by default.
    pub passivity_controller: bool,
    /// Blend a contact model that arrives *late* in over the interval since the previous one (a
    /// linear cross-fade of the two models' wrenches and Jacobians), instead of switching at
    /// once. Late: at the tool's current state some contact is pressed beyond its tangent's
    /// reach ([`haptic_core::LinearizedContact::beyond_reach`]), because the tool moved more than
    /// `δ` between two queries into a surface the earlier query could not see; switching at once
    /// would apply the whole penalty force of that depth in one step, which throws a light tool
    /// out. Models that arrive in time switch at once (no added latency). On by default.
    pub contact_blend: bool,
    /// A step whose Newton solve does not converge ([`IntegrationError::NotConverged`], from
    /// [`haptic_dynamics::NewtonBackwardEuler`]) takes the semi-implicit backward Euler step
    /// from the same state instead ([`LinearizedBackwardEuler`], the paper's method, with the
    /// material Jacobian), counted in [`HapticStats::solver_fallbacks`]; off, such a step sends
    /// zero force and puts the tool back at the handle. Damped Newton can cycle where a contact
    /// reaches its cap or switches off, and a light tool on stiff contacts meets such kinks
    /// often; the semi-implicit step is stable there (`docs/stability.md`). Other failures (a
    /// non-finite state or force, a singular system) still send zero force. On by default.
    pub semi_implicit_fallback: bool,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            contact_timeout_s: 0.1,
            contact_fade_s: 0.1,
            divergence_bound_m: 0.5,
            passivity_controller: false,
            contact_blend: true,
            semi_implicit_fallback: true,
        }
    }
}

/// Steps 1–6 of the haptic thread: read device → linearise coupling → linearised contact →
/// solve → coupling force with the new state → send to device.
pub struct HapticStage<I, D> {
    integrator: I,
    device: D,
    body: RigidBody,
    forces: HapticForces,
    tool: ToolState,
    limits: DeviceLimits,
    safety: SafetyConfig,
    contact: ContactUpdate,
    contact_received_s: Real,
    /// How long the newest contact model takes to blend in (s): the interval since the one
    /// before.
    contact_blend_s: Real,
    last_wrench: Wrench,
    /// Statistics of the run so far.
    pub stats: HapticStats,
}

impl<I: Integrator, D: Device> HapticStage<I, D> {
    /// A haptic stage; `forces` holds the coupling (already grasped), `tool` the initial state.
    pub fn new(
        integrator: I,
        device: D,
        body: RigidBody,
        forces: HapticForces,
        tool: ToolState,
        safety: SafetyConfig,
    ) -> Self {
        let limits = device.limits();
        let mut forces = forces;
        forces.jacobian_kind = integrator.jacobian_kind();
        Self {
            integrator,
            device,
            body,
            forces,
            tool,
            limits,
            safety,
            contact: ContactUpdate::none(),
            contact_received_s: 0.0,
            contact_blend_s: 0.0,
            last_wrench: Wrench::zero(),
            stats: HapticStats::default(),
        }
    }

    /// The current tool state.
    pub fn tool(&self) -> &ToolState {
        &self.tool
    }

    /// The tool's rigid body.
    pub fn body(&self) -> &RigidBody {
        &self.body
    }

    /// The last wrench sent to the device.
    pub fn last_wrench(&self) -> &Wrench {
        &self.last_wrench
    }

    /// The device.
    pub fn device(&self) -> &D {
        &self.device
    }

    /// The device, mutably.
    pub fn device_mut(&mut self) -> &mut D {
        &mut self.device
    }

    /// The coupling and contact forces.
    pub fn forces(&self) -> &HapticForces {
        &self.forces
    }

    /// The latest contact update in use.
    pub fn contact(&self) -> &ContactUpdate {
        &self.contact
    }

    /// Hands a new contact update to the stage (takes effect at the next step).
    #[inline]
    pub fn receive_contact(&mut self, update: &ContactUpdate, now_s: Real) {
        if update.seq != self.contact.seq {
            // Blend the new model in over the time the last one lasted (see
            // `SafetyConfig::contact_blend`).
            self.contact_blend_s =
                (now_s - self.contact_received_s).clamp(0.0, self.safety.contact_timeout_s);
            // Copies of the tangents in use only: the models are 15 kB each, and this runs on
            // the haptic thread at every update.
            self.contact.copy_from(update);
            self.contact_received_s = now_s;
            let late = update.model.beyond_reach(&self.tool.to_vector());
            self.stats.late_contact_updates += u64::from(late);
            if self.safety.contact_blend && late && self.contact_blend_s > 0.0 {
                self.forces.previous_contact.copy_from(&self.forces.contact);
                self.forces.blend = 0.0;
            } else {
                self.forces.blend = 1.0;
            }
            self.forces.contact.copy_from(&update.model);
        }
    }

    fn send_zero(&mut self) -> Result<(), DeviceFailure> {
        self.last_wrench = Wrench::zero();
        self.device.command_zero().map_err(|e| DeviceFailure {
            kind: e.kind(),
            message: e.to_string(),
        })
    }

    /// One haptic period at time `now_s` with step `dt_s`. No allocation, no lock, no I/O beyond
    /// the device transaction.
    ///
    /// # Errors
    /// A [`DeviceFailure`] other than bad data (disconnection, timeout): zero force has been
    /// commanded (if the device still answers) and the run should stop.
    pub fn step(&mut self, now_s: Real, dt_s: Real) -> Result<StepOutcome, DeviceFailure> {
        self.stats.steps += 1;
        // 1. Read the device.
        let reading: DeviceState = match self.device.read(now_s) {
            Ok(s) if s.is_finite() => s,
            Ok(_) => return self.zero_force_step(false),
            Err(e) if e.kind() == ErrorKind::InvalidData => {
                return self.zero_force_step(false);
            }
            Err(e) => {
                let failure = DeviceFailure {
                    kind: e.kind(),
                    message: e.to_string(),
                };
                let _ = self.device.command_zero();
                self.last_wrench = Wrench::zero();
                return Err(failure);
            }
        };
        // 2. The coupling to the new handle pose (linearised inside the implicit solve).
        if self.forces.coupling.set_device(&reading).is_err() {
            return self.zero_force_step(false);
        }
        // 3. The linearized contact model, blended in after an update, faded when stale.
        let age_s = now_s - self.contact_received_s;
        if self.forces.blend < 1.0 {
            self.forces.blend = if self.contact_blend_s > 0.0 {
                ((age_s + dt_s) / self.contact_blend_s).clamp(0.0, 1.0)
            } else {
                1.0
            };
        }
        if age_s > self.safety.contact_timeout_s && !self.contact.model.is_empty() {
            self.stats.stale_steps += 1;
            let fade = (1.0 - (age_s - self.safety.contact_timeout_s) / self.safety.contact_fade_s)
                .clamp(0.0, 1.0);
            // Set in place: the model is a few kB, not worth a copy per step.
            self.forces.contact.scale = self.contact.model.scale * fade;
        }
        // On fixed frames, contacts pressed beyond their reach yield (a plastic cap).
        if self.forces.mode == LinearizationMode::FixedFrames
            && !(self.forces.contact.is_empty() && self.forces.previous_contact.is_empty())
        {
            let y = self.tool.to_vector();
            let kin = haptic_core::Kinematics::new(&self.body, &y);
            self.forces.contact.yield_beyond_reach(&y, &kin);
            self.forces.previous_contact.yield_beyond_reach(&y, &kin);
        }
        // 4. Solve for the new state.
        let stepped =
            match self
                .integrator
                .step(&self.body, &self.tool, now_s, dt_s, &mut self.forces)
            {
                Err(IntegrationError::NotConverged { .. })
                    if self.safety.semi_implicit_fallback =>
                {
                    self.stats.solver_fallbacks += 1;
                    self.semi_implicit_step(now_s, dt_s)
                }
                other => other,
            };
        let new_state = match stepped {
            Ok(s) if s.is_finite() => s,
            _ => {
                // The state cannot be advanced from here: put the tool back at the handle,
                // at rest, so that the next step starts from a sane state.
                self.tool = self.forces.coupling.tool_at_handle();
                return self.zero_force_step(true);
            }
        };
        let quat_err = (new_state.q.coords.norm() - 1.0).abs();
        self.stats.max_quat_norm_error = self.stats.max_quat_norm_error.max(quat_err);
        self.tool = new_state;
        let deviation = self.forces.coupling.deviation(&self.tool).translation_m;
        self.stats.max_coupling_deviation_m = self.stats.max_coupling_deviation_m.max(deviation);
        if deviation > self.safety.divergence_bound_m {
            self.stats.divergences += 1;
            self.tool = self.forces.coupling.tool_at_handle();
        }
        // 5. The coupling force with the new state, saturated to the device, damped by the
        //    passivity controller (if on) and saturated again; the observer counts what is sent.
        let reaction = self.forces.coupling.device_reaction(&self.body, &self.tool);
        let (mut wrench, clamped) = self.limits.saturate(&reaction);
        if clamped {
            self.stats.saturation_events += 1;
        }
        if self.safety.passivity_controller {
            self.passivity_control(&mut wrench, &reading, dt_s);
            wrench = self.limits.saturate(&wrench).0;
        }
        if !wrench.is_finite() {
            return self.zero_force_step(true);
        }
        self.passivity_observe(&wrench, &reading, dt_s);
        // 6. Send it.
        self.device.command(&wrench).map_err(|e| DeviceFailure {
            kind: e.kind(),
            message: e.to_string(),
        })?;
        self.last_wrench = wrench;
        self.stats.max_force_n = self.stats.max_force_n.max(wrench.force.norm());
        Ok(StepOutcome::Stepped)
    }

    /// Passivity controller (Hannaford & Ryu 2002), one per port (translation, rotation): where
    /// sending `F` would leave the port's energy `E − (F·v) Δt` negative, `F ← F − α v` with
    /// `α = −(E − (F·v) Δt) / (|v|² Δt)` dissipates the deficit, bringing it back to 0.
    fn passivity_control(&mut self, w: &mut Wrench, reading: &DeviceState, dt_s: Real) {
        let stats = &mut self.stats;
        let ports = [
            (&mut w.force, reading.twist.linear),
            (&mut w.torque, reading.twist.angular),
        ];
        for (k, (f, v)) in ports.into_iter().enumerate() {
            let predicted = stats.port_energy_j[k] - f.dot(&v) * dt_s;
            let v2 = v.norm_squared();
            if predicted.is_finite() && predicted < 0.0 && v2 > 1e-12 {
                *f -= v * (-predicted / (v2 * dt_s));
                stats.passivity_corrections += 1;
            }
        }
    }

    /// Passivity observer (Hannaford & Ryu 2002), one per port: `E ← E − (F·v) Δt` with the
    /// wrench actually sent, the energy that has entered the simulation through the port.
    fn passivity_observe(&mut self, w: &Wrench, reading: &DeviceState, dt_s: Real) {
        let stats = &mut self.stats;
        for (k, (f, v)) in [
            (w.force, reading.twist.linear),
            (w.torque, reading.twist.angular),
        ]
        .into_iter()
        .enumerate()
        {
            let p = f.dot(&v);
            if p.is_finite() {
                stats.port_energy_j[k] -= p * dt_s;
            }
        }
        let total = stats.port_energy_j[0] + stats.port_energy_j[1];
        stats.min_port_energy_j = stats.min_port_energy_j.min(total);
    }

    /// The semi-implicit backward Euler step from the current state, with the material
    /// Jacobian it asks for ([`SafetyConfig::semi_implicit_fallback`]).
    fn semi_implicit_step(
        &mut self,
        now_s: Real,
        dt_s: Real,
    ) -> Result<ToolState, IntegrationError> {
        let mut semi_implicit = LinearizedBackwardEuler;
        let kind = std::mem::replace(
            &mut self.forces.jacobian_kind,
            semi_implicit.jacobian_kind(),
        );
        let stepped = semi_implicit.step(&self.body, &self.tool, now_s, dt_s, &mut self.forces);
        self.forces.jacobian_kind = kind;
        stepped
    }

    fn zero_force_step(&mut self, solver_failure: bool) -> Result<StepOutcome, DeviceFailure> {
        self.stats.zero_force_steps += 1;
        if solver_failure {
            self.stats.solver_failures += 1;
        }
        self.send_zero()?;
        Ok(StepOutcome::ZeroForce { solver_failure })
    }

    /// Sets how the contact model is used between updates.
    pub fn set_linearization(&mut self, mode: LinearizationMode) {
        self.forces.mode = mode;
    }

    /// Commands zero force (the safe state), ignoring errors.
    pub fn shutdown(&mut self) {
        let _ = self.send_zero();
    }

    /// The stage behind a guard that commands zero force when it is dropped: hold it for the
    /// whole life of a haptic loop, so that every way out of the loop (its end, an error, a
    /// panic of the device, the integrator or the contact model) ends at zero force.
    pub fn zero_force_guard(&mut self) -> ZeroForceGuard<'_, I, D> {
        ZeroForceGuard { stage: self }
    }
}

/// Commands zero force when dropped, on every exit path, unwinding included
/// ([`HapticStage::zero_force_guard`]). Derefs to the stage.
pub struct ZeroForceGuard<'a, I: Integrator, D: Device> {
    stage: &'a mut HapticStage<I, D>,
}

impl<I: Integrator, D: Device> std::ops::Deref for ZeroForceGuard<'_, I, D> {
    type Target = HapticStage<I, D>;
    fn deref(&self) -> &Self::Target {
        self.stage
    }
}

impl<I: Integrator, D: Device> std::ops::DerefMut for ZeroForceGuard<'_, I, D> {
    fn deref_mut(&mut self) -> &mut Self::Target {
        self.stage
    }
}

impl<I: Integrator, D: Device> Drop for ZeroForceGuard<'_, I, D> {
    fn drop(&mut self) {
        // A device that panics again here must not turn an unwinding panic into an abort.
        let stage = &mut *self.stage;
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| stage.shutdown()));
    }
}

/// The message of a caught panic payload.
pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}
