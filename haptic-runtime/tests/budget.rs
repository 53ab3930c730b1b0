//! A time budget per contact update picks each query's threshold: the finest when updates are
//! cheap, the coarsest when they cannot fit, and every update and its record say which.

mod common;

use common::{BoxOnFloor, HALF_M, box_body, pressing_hand};
use haptic_core::{Pose, Vec3};
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::{ContactLatency, PipelineBuilder, PipelineConfig, QueryBudget, Summary};

fn run_with(budget_s: f64) -> Summary {
    let mut p = PipelineBuilder::new(
        box_body(),
        Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.01)),
    )
    .integrator(LinearizedBackwardEuler)
    .backend(BoxOnFloor::new(HALF_M))
    .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
    .device(pressing_hand())
    .config(PipelineConfig {
        realtime_scheduling: false,
        query_budget: Some(QueryBudget::new(budget_s).unwrap()),
        ..PipelineConfig::default()
    })
    .build()
    .unwrap();
    p.run_virtual(0.5, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, _| {})
        .unwrap()
}

#[test]
fn cheap_updates_stay_at_the_finest_threshold() {
    // The box's query takes microseconds: a second's budget is never reached.
    let s = run_with(1.0);
    assert!(
        s.raw_contact_count_max > 0,
        "the box never touched the floor"
    );
    assert_eq!(s.error_threshold_median, 0.001);
    assert_eq!(s.error_threshold_max, 0.001);
}

#[test]
fn updates_that_cannot_fit_go_to_the_coarsest_threshold() {
    // A nanosecond is less than any update: the threshold climbs to its ceiling.
    let s = run_with(1e-9);
    assert!(s.raw_contact_count_max > 0);
    assert_eq!(s.error_threshold_median, 0.1);
    assert_eq!(s.error_threshold_max, 0.1);
}

#[test]
fn a_bad_budget_is_refused_when_the_pipeline_is_built() {
    let r = PipelineBuilder::new(box_body(), Pose::identity())
        .integrator(LinearizedBackwardEuler)
        .backend(BoxOnFloor::new(HALF_M))
        .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
        .device(pressing_hand())
        .config(PipelineConfig {
            query_budget: Some(QueryBudget {
                budget_s: -1.0,
                min_threshold: 0.001,
                max_threshold: 0.1,
            }),
            ..PipelineConfig::default()
        })
        .build();
    assert!(r.is_err());
}
