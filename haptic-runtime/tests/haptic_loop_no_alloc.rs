//! The haptic loop allocates nothing: its step is counted with a global allocator, in contact
//! (linearized model in use) and for each integrator. Counted on the thread that steps (the
//! haptic thread's contract): under load in CI the process-wide count once saw 4 allocations
//! from elsewhere in the test process while the steps ran.

mod common;

use common::{BoxOnFloor, FaultyIntegrator, IntegratorFault};
use haptic_core::{DeviceLimits, Integrator, Pose, RigidBody, Vec3};
use haptic_device::{HandDevice, HandParams, ScriptedDevice, Waypoint};
use haptic_dynamics::{
    ForwardEuler, LinearizedBackwardEuler, NewtonBackwardEuler, PenaltyModel, PenaltyParams, Rk4,
};
use haptic_runtime::{PipelineBuilder, PipelineConfig};
use haptic_test_support::alloc::{CountingAllocator, thread_allocations};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

const HALF_M: f64 = 0.025;

/// Allocations of 2,000 haptic steps in contact, and how many of them fell back to the
/// semi-implicit step.
fn steps_allocate<I: Integrator>(integrator: I) -> (usize, u64) {
    let limits =
        DeviceLimits::new(10.0, 1.0, Vec3::repeat(-0.5), Vec3::repeat(0.5), 1000.0).unwrap();
    let start = Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.002));
    let press = Pose::from_position(Vec3::new(0.0, 0.0, HALF_M - 0.005));
    let target = ScriptedDevice::from_waypoints(
        vec![Waypoint::new(0.0, start), Waypoint::new(0.1, press)],
        limits,
    )
    .unwrap();
    let hand = HandDevice::new(HandParams::default(), target, limits).unwrap();
    let i = 0.1 * (2.0 * HALF_M).powi(2) / 6.0;
    let mut p = PipelineBuilder::new(RigidBody::from_principal(0.1, [i, i, i]).unwrap(), start)
        .integrator(integrator)
        .backend(BoxOnFloor::new(HALF_M))
        .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
        .device(hand)
        .config(PipelineConfig::default())
        .build()
        .unwrap();
    // Warm up: run in virtual time (which also builds contact updates) until in contact.
    p.run_virtual(
        0.3,
        haptic_runtime::ContactLatency::FixedRate { rate_hz: 500.0 },
        |_, _| {},
    )
    .unwrap();
    assert!(!p.haptic().contact().model.is_empty(), "not in contact");
    let update = *p.haptic().contact();
    let before = thread_allocations();
    for k in 0..2000 {
        let t = 0.3 + k as f64 * 1e-3;
        if k % 4 == 0 {
            let mut u = update;
            u.seq += 1 + k as u64;
            p.haptic_mut().receive_contact(&u, t);
        }
        p.haptic_mut().step(t, 1e-3).unwrap();
    }
    let allocations = thread_allocations() - before;
    (allocations, p.haptic().stats.solver_fallbacks)
}

#[test]
fn haptic_steps_allocate_nothing() {
    assert_eq!(
        steps_allocate(LinearizedBackwardEuler).0,
        0,
        "backward Euler"
    );
    assert_eq!(
        steps_allocate(NewtonBackwardEuler::default()).0,
        0,
        "Newton backward Euler"
    );
    assert_eq!(steps_allocate(Rk4).0, 0, "RK4");
    assert_eq!(steps_allocate(ForwardEuler).0, 0, "forward Euler");
    // Steps whose Newton solve does not converge take the semi-implicit step instead: that path
    // allocates nothing either (every measured step takes it).
    let (allocations, fallbacks) = steps_allocate(FaultyIntegrator::new(
        IntegratorFault::NotConvergedIn(1..u64::MAX),
    ));
    assert_eq!(allocations, 0, "semi-implicit fallback");
    assert!(fallbacks >= 2000, "{fallbacks} fallback steps");
}
