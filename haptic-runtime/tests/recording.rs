//! A run recorded and read back; foreign, other-version and truncated files give typed errors.

mod common;

use common::{BoxOnFloor, HALF_M, box_body, pressing_hand};
use haptic_core::{Pose, Vec3};
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::recording::{
    DEFAULT_CONTACT_CAP, FORMAT, RecordingError, RecordingHeader, VERSION,
};
use haptic_runtime::{ContactLatency, PipelineBuilder, PipelineConfig, RunRecorder, RunRecording};

fn header() -> RecordingHeader {
    RecordingHeader {
        format: FORMAT.to_owned(),
        version: VERSION,
        name: "box on floor".to_owned(),
        settings: vec![("integrator".to_owned(), "backward_euler".to_owned())],
        meshes: Vec::new(),
        haptic_rate_hz: 1000.0,
        frame_rate_hz: 500.0,
        contact_cap: DEFAULT_CONTACT_CAP,
    }
}

fn recorded() -> Vec<u8> {
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
        ..PipelineConfig::default()
    })
    .build()
    .unwrap();
    let mut rec = RunRecorder::new(Vec::new(), &header(), 0.0).unwrap();
    let summary = p
        .run_virtual_observed(0.5, ContactLatency::FixedRate { rate_hz: 500.0 }, &mut rec)
        .unwrap();
    rec.finish(&summary).unwrap()
}

#[test]
fn a_recording_reads_back_whole() {
    let bytes = recorded();
    let r = RunRecording::from_reader(&bytes[..]).unwrap();
    assert_eq!(r.header, header());
    assert_eq!(
        r.frames.len(),
        250,
        "500 steps at 1 kHz, recorded at 500 Hz"
    );
    assert!((r.frames[0].t - 0.001).abs() < 1e-12);
    assert_eq!(r.updates.len(), 250, "0.5 s at 500 Hz");
    let touching = r
        .updates
        .iter()
        .filter(|u| !u.representatives.is_empty())
        .count();
    assert!(touching > 100, "{touching} updates with contacts");
    assert!(r.updates.iter().all(|u| u.raw.len() <= DEFAULT_CONTACT_CAP));
    assert_eq!(r.summary.haptic_steps, 500);
    // The box sits on the floor at the end.
    let last = r.frames.last().unwrap();
    assert!((last.tool[2] - HALF_M).abs() < 1e-3, "{}", last.tool[2]);
}

#[test]
fn foreign_other_version_and_truncated_files_are_typed_errors() {
    let bytes = recorded();
    let text = String::from_utf8(bytes).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(matches!(
        RunRecording::from_reader(&b"t_s,x,y\n1,2,3\n"[..]),
        Err(RecordingError::NotARecording)
    ));
    assert!(matches!(
        RunRecording::from_reader(&b""[..]),
        Err(RecordingError::NotARecording)
    ));
    let other = text.replacen(&format!("\"version\":{VERSION}"), "\"version\":99", 1);
    assert!(matches!(
        RunRecording::from_reader(other.as_bytes()),
        Err(RecordingError::UnsupportedVersion { found: 99 })
    ));
    let cut = lines[..lines.len() / 2].join("\n");
    assert!(matches!(
        RunRecording::from_reader(cut.as_bytes()),
        Err(RecordingError::Truncated { .. })
    ));
    let mut mid = lines[..lines.len() - 1].join("\n");
    mid.push_str("\n{\"frame\": {\"t\": 1.0");
    assert!(matches!(
        RunRecording::from_reader(mid.as_bytes()),
        Err(RecordingError::Truncated { .. })
    ));
    let garbage = format!("{}\n{{\"frame\": 3}}\n", lines[0]);
    assert!(matches!(
        RunRecording::from_reader(garbage.as_bytes()),
        Err(RecordingError::Malformed { line: 2, .. })
    ));
    assert!(matches!(
        RunRecording::read(std::path::Path::new("no/such/recording.jsonl")),
        Err(RecordingError::Io { .. })
    ));
}

/// A real-time run records too: frames from a buffer the haptic thread filled without
/// allocating, updates from the contact thread, written in time order afterwards.
#[test]
fn a_real_time_run_records_in_time_order() {
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
        ..PipelineConfig::default()
    })
    .build()
    .unwrap();
    let mut rec = RunRecorder::new(Vec::new(), &header(), 0.0).unwrap();
    let summary = p.run_realtime_recorded(0.3, |_| {}, &mut rec).unwrap();
    let bytes = rec.finish(&summary).unwrap();
    let r = RunRecording::from_reader(&bytes[..]).unwrap();
    assert!(
        r.frames.len() >= 140 && r.frames.len() <= 152,
        "{} frames at 500 Hz in 0.3 s",
        r.frames.len()
    );
    assert!(r.frames.windows(2).all(|w| w[0].t < w[1].t));
    assert!(!r.updates.is_empty());
    assert!(r.updates.windows(2).all(|w| w[0].t <= w[1].t));
}
