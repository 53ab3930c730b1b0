//! A time budget per contact update picks each query's threshold: the finest when updates are
//! cheap, the coarsest when they cannot fit, and every update and its record say which.

mod common;

use std::sync::{Arc, Mutex};

use common::{BoxOnFloor, HALF_M, box_body, pressing_hand};
use haptic_core::{CollisionBackend, ContactSet, Pose, QueryParams, QueryStats, Real, Vec3};
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::recording::{FORMAT, RecordingHeader, VERSION};
use haptic_runtime::{
    ContactLatency, PipelineBuilder, PipelineConfig, QueryBudget, RunRecorder, RunRecording,
    Summary,
};

/// The box on the floor, noting the threshold of every query and whether it found contacts;
/// with a `ceiling`, a back-end that holds no coarser threshold than that one (as
/// `LodBackend` holds none above `δ / radius` under its default rule).
struct Probe {
    inner: BoxOnFloor,
    seen: Arc<Mutex<Vec<(Real, bool)>>>,
    ceiling: Option<Real>,
}

impl CollisionBackend for Probe {
    type Error = <BoxOnFloor as CollisionBackend>::Error;
    fn name(&self) -> &str {
        "probe"
    }
    fn tool_bounding_radius_m(&self) -> Real {
        self.inner.tool_bounding_radius_m()
    }
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        self.ceiling
            .map_or(params.error_threshold, |c| params.error_threshold.min(c))
    }
    fn query(
        &mut self,
        pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, Self::Error> {
        let r = self.inner.query(pose, params, out);
        self.seen
            .lock()
            .unwrap()
            .push((params.error_threshold, !out.is_empty()));
        r
    }
}

/// The box starts 1 cm above the floor (free space), then the hand presses it down.
#[test]
fn free_space_does_not_move_the_threshold_and_records_say_which_was_used() {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let mut p = PipelineBuilder::new(
        box_body(),
        Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.01)),
    )
    .integrator(LinearizedBackwardEuler)
    .backend(Probe {
        inner: BoxOnFloor::new(HALF_M),
        seen: seen.clone(),
        ceiling: None,
    })
    .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
    .device(pressing_hand())
    .config(PipelineConfig {
        realtime_scheduling: false,
        // No update fits a nanosecond: each one with contacts coarsens the next, ×4.
        query_budget: Some(QueryBudget::new(1e-9).unwrap()),
        ..PipelineConfig::default()
    })
    .build()
    .unwrap();
    let header = RecordingHeader {
        format: FORMAT.to_owned(),
        version: VERSION,
        name: "probe".to_owned(),
        settings: Vec::new(),
        meshes: Vec::new(),
        haptic_rate_hz: 1000.0,
        frame_rate_hz: 100.0,
        contact_cap: 16,
    };
    let mut rec = RunRecorder::new(Vec::new(), &header, 0.0).unwrap();
    let summary = p
        .run_virtual_observed(0.5, ContactLatency::FixedRate { rate_hz: 500.0 }, &mut rec)
        .unwrap();
    let r = RunRecording::from_reader(&rec.finish(&summary).unwrap()[..]).unwrap();
    let seen = seen.lock().unwrap().clone();
    let first_contact = seen
        .iter()
        .position(|s| s.1)
        .expect("the box never touched");
    assert!(
        first_contact > 5,
        "the box touched at once: no free space to test"
    );
    // Free space: the threshold stays where it started (the finest), not pulled anywhere.
    assert!(
        seen[..=first_contact].iter().all(|s| s.0 == 0.001),
        "{seen:?}"
    );
    // Then each update with contacts coarsens the next, ×4, up to the ceiling.
    assert_eq!(seen[first_contact + 1].0, 0.004);
    assert_eq!(seen.last().unwrap().0, 0.1);
    // Every record carries the threshold its query used, in order.
    let recorded: Vec<Real> = r.updates.iter().map(|u| u.threshold).collect();
    let queried: Vec<Real> = seen.iter().map(|s| s.0).collect();
    assert_eq!(recorded, queried);
}

/// The box pressed onto the floor for half a second, through `backend`, with a budget of
/// `budget_s` an update.
fn run_with<B: CollisionBackend + Send + 'static>(backend: B, budget_s: f64) -> Summary {
    let mut p = PipelineBuilder::new(
        box_body(),
        Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.01)),
    )
    .integrator(LinearizedBackwardEuler)
    .backend(backend)
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
    let s = run_with(BoxOnFloor::new(HALF_M), 1.0);
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
    let s = run_with(BoxOnFloor::new(HALF_M), 1e-9);
    assert!(s.raw_contact_count_max > 0);
    assert_eq!(s.error_threshold_median, 0.1);
    assert_eq!(s.error_threshold_max, 0.1);
}

#[test]
fn a_back_end_that_coarsens_no_further_holds_the_threshold_at_its_coarsest() {
    // No update fits a nanosecond, but above 3 % the back-end's queries are all alike: the
    // threshold climbs to 3 %, not to the budget's 10 %, and the updates report 3 %.
    let seen = Arc::new(Mutex::new(Vec::new()));
    let probe = Probe {
        inner: BoxOnFloor::new(HALF_M),
        seen: seen.clone(),
        ceiling: Some(0.03),
    };
    let s = run_with(probe, 1e-9);
    assert!(s.raw_contact_count_max > 0, "the box never touched");
    let seen = seen.lock().unwrap().clone();
    let asked = seen.iter().map(|s| s.0).fold(0.0, Real::max);
    assert_eq!(asked, 0.03, "{seen:?}");
    assert_eq!(seen.last().unwrap().0, 0.03);
    assert_eq!(s.error_threshold_max, 0.03);
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
