//! A Newton solve that does not converge takes the semi-implicit step instead
//! (`SafetyConfig::semi_implicit_fallback`, on by default): the device keeps rendering the
//! contact with no zero-force step and no reset, and the stage counts the fallbacks; with the
//! fallback off, the same steps send zero force and count as solver failures.

mod common;

use common::{BoxOnFloor, FaultyIntegrator, HALF_M, IntegratorFault, box_body, pressing_hand};
use haptic_core::{Pose, Real, Vec3};
use haptic_dynamics::{PenaltyModel, PenaltyParams};
use haptic_runtime::stages::HapticStats;
use haptic_runtime::{ContactLatency, PipelineBuilder, PipelineConfig, SafetyConfig};

/// Haptic steps `FAIL_FROM..FAIL_TO` do not converge: the box is pressed on the floor by then.
const FAIL_FROM: u64 = 600;
const FAIL_TO: u64 = 610;

/// The box pressed on the floor for 1 s with `semi_implicit_fallback` set to `fallback`: the
/// stage's statistics and the force sent at each step (N).
fn run(fallback: bool) -> (HapticStats, Vec<Real>) {
    let mut p = PipelineBuilder::new(
        box_body(),
        Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.01)),
    )
    .integrator(FaultyIntegrator::new(IntegratorFault::NotConvergedIn(
        FAIL_FROM..FAIL_TO,
    )))
    .backend(BoxOnFloor::new(HALF_M))
    .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
    .device(pressing_hand())
    .config(PipelineConfig {
        realtime_scheduling: false,
        safety: SafetyConfig {
            semi_implicit_fallback: fallback,
            ..SafetyConfig::default()
        },
        ..PipelineConfig::default()
    })
    .build()
    .unwrap();
    let mut forces = Vec::new();
    let summary = p
        .run_virtual(1.0, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, h| {
            forces.push(h.last_wrench().force.norm());
        })
        .unwrap();
    assert_eq!(summary.solver_failures, p.haptic().stats.solver_failures);
    assert_eq!(summary.solver_fallbacks, p.haptic().stats.solver_fallbacks);
    (p.haptic().stats.clone(), forces)
}

#[test]
fn a_newton_solve_that_does_not_converge_takes_the_semi_implicit_step() {
    let failing = (FAIL_FROM - 1) as usize..(FAIL_TO - 1) as usize;
    let (stats, forces) = run(true);
    assert_eq!(stats.solver_fallbacks, FAIL_TO - FAIL_FROM);
    assert_eq!(stats.solver_failures, 0);
    assert_eq!(stats.zero_force_steps, 0);
    assert_eq!(stats.divergences, 0);
    // The box is pressed on the floor: a real force, continuous through the failing steps.
    let before = forces[failing.start - 1];
    assert!(
        before > 0.5,
        "the hand does not press ({before} N): nothing is checked"
    );
    for f in &forces[failing.clone()] {
        assert!(
            (f - before).abs() < 0.05 * before,
            "{f} N against {before} N"
        );
    }

    let (stats, forces) = run(false);
    assert_eq!(stats.solver_fallbacks, 0);
    assert_eq!(stats.solver_failures, FAIL_TO - FAIL_FROM);
    assert!(forces[failing].iter().all(|f| *f == 0.0));
}
