//! Test fixtures: the box over a floor (from `haptic-test-support`), and back-ends that
//! misbehave on purpose.

#![allow(dead_code)]

use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use haptic_core::{
    CollisionBackend, ContactSet, ForceModel, IntegrationError, Integrator, Pose, QueryParams,
    QueryStats, Real, RigidBody, ToolState,
};
use haptic_dynamics::LinearizedBackwardEuler;

pub use haptic_test_support::box_on_floor::*;

/// Held by each test of a binary whose real-time tests measure rates and time-outs: they run
/// one at a time, so that they do not compete for this 2-core machine with the binary's other
/// tests (the test harness runs them on parallel threads; a real-time pipeline spins one core
/// and needs the other for its contact thread). A test that panicked does not block the rest.
pub fn one_at_a_time() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Wraps a back-end: the `stall_at`-th query *that finds contacts* sleeps for `stall`, the
/// `panic_at`-th panics (counted on contact queries, so that a contact model is in use when the
/// fault hits, however slowly a loaded machine runs the contact thread).
pub struct Misbehaving<B> {
    pub inner: B,
    pub queries: u64,
    pub stall_at: Option<u64>,
    pub stall: Duration,
    pub panic_at: Option<u64>,
}

impl<B> Misbehaving<B> {
    pub fn new(inner: B) -> Self {
        Self {
            inner,
            queries: 0,
            stall_at: None,
            stall: Duration::ZERO,
            panic_at: None,
        }
    }
}

impl<B: CollisionBackend> CollisionBackend for Misbehaving<B> {
    type Error = B::Error;
    fn name(&self) -> &str {
        "misbehaving"
    }
    fn tool_bounding_radius_m(&self) -> Real {
        self.inner.tool_bounding_radius_m()
    }
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        self.inner.threshold_reached(params)
    }
    fn query(
        &mut self,
        pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, B::Error> {
        let stats = self.inner.query(pose, params, out)?;
        if !out.is_empty() {
            self.queries += 1;
            if self.stall_at == Some(self.queries) {
                std::thread::sleep(self.stall);
            }
            if self.panic_at == Some(self.queries) {
                panic!("injected collision back-end panic");
            }
        }
        Ok(stats)
    }
}

/// What [`FaultyIntegrator`] does wrong, counted in its steps (the first step is 1).
#[derive(Debug, Clone)]
pub enum IntegratorFault {
    /// Panics on this step.
    PanicAt(u64),
    /// Reports a Newton solve that did not converge on these steps, as full-Newton BE does
    /// where damped Newton cycles at a contact's kink.
    NotConvergedIn(std::ops::Range<u64>),
}

/// Semi-implicit backward Euler with a fault injected on purpose.
pub struct FaultyIntegrator {
    pub steps: u64,
    pub fault: IntegratorFault,
}

impl FaultyIntegrator {
    pub fn new(fault: IntegratorFault) -> Self {
        Self { steps: 0, fault }
    }
}

impl Integrator for FaultyIntegrator {
    fn name(&self) -> &'static str {
        "faulty"
    }
    fn uses_jacobian(&self) -> bool {
        true
    }
    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        self.steps += 1;
        match &self.fault {
            IntegratorFault::PanicAt(step) if *step == self.steps => {
                panic!("injected integrator panic")
            }
            IntegratorFault::NotConvergedIn(steps) if steps.contains(&self.steps) => {
                return Err(IntegrationError::NotConverged {
                    iterations: 20,
                    residual: 0.3,
                });
            }
            _ => {}
        }
        LinearizedBackwardEuler.step(body, state, t_s, dt_s, forces)
    }
}
