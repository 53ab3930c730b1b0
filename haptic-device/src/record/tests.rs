//! Recording and replay: round trips bit for bit, and every malformed input a typed error.

use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3, Wrench};
use nalgebra::{Quaternion, UnitQuaternion};

use super::format::*;
use super::*;
use crate::error::{CsvProblem, DeviceError};
use crate::hand::{HandDevice, HandParams};
use crate::scripted::{ScriptedDevice, Waypoint};
use haptic_core::{device::Error as _, device::ErrorKind};
use proptest::prelude::*;

fn limits() -> DeviceLimits {
    DeviceLimits::new(5.0, 0.5, Vec3::repeat(-0.2), Vec3::repeat(0.2), 1000.0).unwrap()
}

fn hand() -> HandDevice {
    let target = ScriptedDevice::from_waypoints(
        vec![
            Waypoint::new(0.0, Pose::identity()),
            Waypoint::new(
                0.3,
                Pose {
                    position: Vec3::new(0.05, -0.02, 0.01),
                    orientation: UnitQuaternion::from_scaled_axis(Vec3::new(0.3, 0.1, -0.2)),
                },
            ),
        ],
        limits(),
    )
    .unwrap();
    HandDevice::new(HandParams::default(), target, limits()).unwrap()
}

/// Drives a hand with a spring feedback at 1 kHz through a recorder; returns the file, the
/// states read and the wrenches sent.
fn record_run(steps: usize) -> (Vec<u8>, Vec<(Real, DeviceState)>, Vec<Wrench>) {
    let header = RecordingHeader::for_device(&hand()).with_scales(0.4, 2.5);
    let mut rec = Recorder::with_header(hand(), Vec::new(), header).unwrap();
    let mut states = Vec::new();
    let mut sent = Vec::new();
    for n in 0..steps {
        let t = 0.001 * n as Real;
        let s = rec.read(t).unwrap();
        // Something that is neither round nor small: every bit of the floats matters.
        let w = Wrench::new(
            -s.pose.position * 173.3 + Vec3::new(1e-300, -0.0, 1.0 / 3.0),
            s.twist.angular * -0.0123,
        );
        rec.command(&w).unwrap();
        states.push((t, s));
        sent.push(w);
    }
    (rec.finish().unwrap(), states, sent)
}

#[test]
fn column_header_matches_columns() {
    assert_eq!(COLUMN_HEADER, COLUMNS.join(","));
}

#[test]
fn record_then_replay_is_bit_exact() {
    let (bytes, states, sent) = record_run(400);
    let mut replay = ReplayDevice::from_reader(bytes.as_slice()).unwrap();
    let h = replay.header().clone();
    assert_eq!(h.device, "simulated hand");
    assert_eq!(
        (h.rate_hz, h.workspace_scale, h.force_scale),
        (1000.0, 0.4, 2.5)
    );
    assert_eq!(h.limits, limits());
    assert_eq!(replay.limits(), limits());
    assert_eq!(replay.samples().len(), states.len());
    for (((t, s), w), r) in states.iter().zip(&sent).zip(replay.samples()) {
        assert_eq!(r.t_s.to_bits(), t.to_bits());
        assert_eq!(r.state, *s);
        assert_eq!(r.wrench, *w);
        assert_eq!(r.commands, 1);
        // `==` treats 0.0 and -0.0 as equal: compare the bits too.
        assert_eq!(r.wrench.force.y.to_bits(), w.force.y.to_bits());
    }
    // Reading the replay at the recorded times gives the recorded states exactly.
    for (t, s) in &states {
        assert_eq!(replay.read(*t).unwrap(), *s);
    }
    // And a second recording of the replay is the same file, byte for byte.
    let header = replay.header().clone();
    let mut again = Recorder::with_header(replay.clone(), Vec::new(), header).unwrap();
    for ((t, _), w) in states.iter().zip(&sent) {
        again.read(*t).unwrap();
        again.command(w).unwrap();
    }
    let bytes2 = again.finish().unwrap();
    let body = |b: &[u8]| {
        String::from_utf8(b.to_vec())
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with("# device"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(body(&bytes), body(&bytes2));
}

#[test]
fn replay_between_and_outside_samples() {
    let (bytes, states, _) = record_run(100);
    let mut r = ReplayDevice::from_reader(bytes.as_slice()).unwrap();
    assert_eq!(r.time_span_s(), (0.0, 0.099));
    // Halfway between two rows: the mean position, a time stamp between.
    let (a, b) = (states[40].1, states[41].1);
    let mid = r.read(0.0405).unwrap();
    let expected = (a.pose.position + b.pose.position) / 2.0;
    assert!((mid.pose.position - expected).norm() < 1e-15);
    assert!(mid.timestamp_s > a.timestamp_s && mid.timestamp_s < b.timestamp_s);
    let ang = a.pose.orientation.angle_to(&b.pose.orientation);
    assert!((mid.pose.orientation.angle_to(&a.pose.orientation) - ang / 2.0).abs() < 1e-12);
    // Out of order reads are fine for a replay.
    assert_eq!(r.read(0.002).unwrap(), states[2].1);
    // Outside: rest at the ends.
    let before = r.read(-1.0).unwrap();
    assert_eq!(before.pose, states[0].1.pose);
    assert_eq!((before.twist, before.timestamp_s), (Twist::zero(), -1.0));
    let after = r.read(5.0).unwrap();
    assert_eq!(after.pose, states[99].1.pose);
    assert_eq!(after.twist, Twist::zero());
    // Commands are clamped and counted.
    r.command(&Wrench::new(Vec3::new(0.0, 0.0, 9.0), Vec3::zeros()))
        .unwrap();
    assert_eq!(r.commands_received(), 1);
    assert!((r.last_command().force.z - 5.0).abs() < 1e-12);
    assert!(r.name().contains("simulated hand"));
}

#[test]
fn recorder_rows_carry_the_commands_that_answer_them() {
    let mut rec = Recorder::new(hand(), Vec::new()).unwrap();
    let f1 = Wrench::new(Vec3::new(1.0, 0.0, 0.0), Vec3::zeros());
    let f2 = Wrench::new(Vec3::new(0.0, 2.0, 0.0), Vec3::zeros());
    rec.command(&f1).unwrap(); // before any read: acts, but has no row
    rec.read(0.0).unwrap(); // row 0: no command after it, f1 still in force
    rec.read(0.001).unwrap(); // row 1: two commands, f2 last
    rec.command(&f1).unwrap();
    rec.command(&f2).unwrap();
    rec.read(0.002).unwrap(); // row 2: zero commanded
    rec.command_zero().unwrap();
    assert_eq!(rec.rows_written(), 2);
    assert!(matches!(
        rec.read(0.002),
        Err(DeviceError::TimeWentBack { .. })
    ));
    let bytes = rec.finish().unwrap();
    let r = ReplayDevice::from_reader(bytes.as_slice()).unwrap();
    let rows: Vec<_> = r.samples().iter().map(|s| (s.wrench, s.commands)).collect();
    assert_eq!(rows, vec![(f1, 0), (f2, 2), (Wrench::zero(), 1)]);
}

#[test]
fn drop_writes_the_last_row_and_files_work() {
    let dir = std::env::temp_dir().join(format!("haptic-device-rec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("run.csv");
    {
        let mut rec = Recorder::create(hand(), &path).unwrap();
        rec.read(0.0).unwrap();
        rec.read(0.001).unwrap();
    }
    let r = ReplayDevice::open(&path).unwrap();
    assert_eq!(r.samples().len(), 2);
    std::fs::remove_dir_all(&dir).unwrap();
    let e = ReplayDevice::open(dir.join("missing.csv")).unwrap_err();
    assert!(matches!(e, DeviceError::Io { .. }));
}

/// A valid file whose row `n` (0-based) is replaced by `row`.
fn with_row(n: usize, row: &str) -> String {
    let (bytes, _, _) = record_run(5);
    let text = String::from_utf8(bytes).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let first = lines.iter().position(|l| l == COLUMN_HEADER).unwrap() + 1;
    lines[first + n] = row.to_owned();
    lines.join("\n")
}

/// The line number (1-based) of data row `n`.
fn line_of_row(n: usize) -> usize {
    let (bytes, _, _) = record_run(5);
    let text = String::from_utf8(bytes).unwrap();
    text.lines().position(|l| l == COLUMN_HEADER).unwrap() + 2 + n
}

fn csv_error(text: &str) -> (usize, CsvProblem) {
    match ReplayDevice::from_reader(text.as_bytes()) {
        Err(e @ DeviceError::Csv { .. }) => {
            assert_eq!(e.kind(), ErrorKind::InvalidData);
            match e {
                DeviceError::Csv { line, problem } => (line, problem),
                _ => unreachable!(),
            }
        }
        other => panic!("expected a CSV error, got {other:?}"),
    }
}

fn valid_row(t: Real) -> String {
    format!(
        "{t:?},{t:?},0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0,0.0,0.0,0.0,0.0,0.0,0.0,1"
    )
}

#[test]
fn malformed_files_give_the_line_and_the_problem() {
    // Missing columns.
    let (line, p) = csv_error(&with_row(2, "0.002,0.002,0.0,0.0"));
    assert_eq!(line, line_of_row(2));
    assert_eq!(
        p,
        CsvProblem::ColumnCount {
            expected: 23,
            found: 4
        }
    );
    // Too many.
    let (_, p) = csv_error(&with_row(1, &format!("{},7", valid_row(0.001))));
    assert_eq!(
        p,
        CsvProblem::ColumnCount {
            expected: 23,
            found: 24
        }
    );
    // NaN.
    let nan = valid_row(0.003).replacen(",0.0,", ",NaN,", 1);
    let (line, p) = csv_error(&with_row(3, &nan));
    assert_eq!(line, line_of_row(3));
    assert_eq!(p, CsvProblem::NonFinite { column: "x_m" });
    let inf = format!(
        "{},-inf,1",
        valid_row(0.003).strip_suffix(",0.0,1").unwrap()
    );
    assert_eq!(
        csv_error(&with_row(3, &inf)).1,
        CsvProblem::NonFinite { column: "tz_nm" }
    );
    // Not a number.
    let word = valid_row(0.003).replacen(",1.0,", ",one,", 1);
    assert_eq!(
        csv_error(&with_row(3, &word)).1,
        CsvProblem::NotANumber { column: "qw" }
    );
    let buttons = valid_row(0.003).replacen(",0,", ",-1,", 1);
    assert_eq!(
        csv_error(&with_row(3, &buttons)).1,
        CsvProblem::NotANumber { column: "buttons" }
    );
    // Time that does not increase (equal, then going back).
    let (line, p) = csv_error(&with_row(2, &valid_row(0.001)));
    assert_eq!(line, line_of_row(2));
    assert_eq!(
        p,
        CsvProblem::TimeNotIncreasing {
            previous_s: 0.001,
            t_s: 0.001
        }
    );
    let (_, p) = csv_error(&with_row(4, &valid_row(0.0005)));
    assert!(matches!(p, CsvProblem::TimeNotIncreasing { t_s, .. } if t_s == 0.0005));
    // Non-unit quaternion.
    let q = valid_row(0.003).replacen(",1.0,", ",2.0,", 1);
    assert!(matches!(
        csv_error(&with_row(3, &q)).1,
        CsvProblem::NonUnitQuaternion { norm } if norm == 2.0
    ));
}

#[test]
fn malformed_headers() {
    let (bytes, _, _) = record_run(3);
    let good = String::from_utf8(bytes).unwrap();
    // Wrong column header.
    let bad = good.replace(COLUMN_HEADER, "t,x,y,z");
    let header_line = good.lines().position(|l| l == COLUMN_HEADER).unwrap() + 1;
    assert_eq!(
        csv_error(&bad),
        (
            header_line,
            CsvProblem::BadHeader {
                expected: COLUMN_HEADER
            }
        )
    );
    // Missing metadata: reported on the column-header line.
    let bad: String = good
        .lines()
        .filter(|l| !l.starts_with("# force_scale"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(
        csv_error(&bad),
        (
            header_line - 1,
            CsvProblem::MissingMetadata { key: "force_scale" }
        )
    );
    // Bad metadata values and versions, on their own line.
    let bad = good.replace("# rate_hz = 1000.0", "# rate_hz = fast");
    let line = good
        .lines()
        .position(|l| l.starts_with("# rate_hz"))
        .unwrap()
        + 1;
    assert_eq!(
        csv_error(&bad),
        (line, CsvProblem::BadMetadata { key: "rate_hz" })
    );
    let bad = good.replace(
        "# workspace_min_m = -0.2 -0.2 -0.2",
        "# workspace_min_m = -0.2 -0.2",
    );
    assert_eq!(
        csv_error(&bad).1,
        CsvProblem::BadMetadata {
            key: "workspace_min_m"
        }
    );
    let bad = good.replace("# format_version = 1", "# format_version = 7");
    assert_eq!(
        csv_error(&bad),
        (2, CsvProblem::UnsupportedVersion { found: 7 })
    );
    let bad = good.replace("# max_force_n = 5.0", "# max_force_n = -5.0");
    assert!(matches!(csv_error(&bad).1, CsvProblem::Limits(_)));
    // No header at all, no rows.
    assert_eq!(
        csv_error("# only a comment\n"),
        (1, CsvProblem::MissingHeader)
    );
    assert_eq!(csv_error(""), (1, CsvProblem::MissingHeader));
    let header_only: String = good
        .lines()
        .take(header_line)
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(
        csv_error(&header_only),
        (header_line, CsvProblem::NoSamples)
    );
    // Blank lines, CRLF and trailing comments are fine.
    let relaxed = good.replace('\n', "\r\n") + "\r\n# end\r\n\r\n";
    assert_eq!(
        ReplayDevice::from_reader(relaxed.as_bytes())
            .unwrap()
            .samples()
            .len(),
        3
    );
}

#[test]
fn bad_recorder_headers_and_failing_inner_devices() {
    let bad = RecordingHeader::for_device(&hand()).with_scales(0.0, 1.0);
    assert!(matches!(
        Recorder::with_header(hand(), Vec::new(), bad),
        Err(DeviceError::Parameter(haptic_core::CoreError::OutOfRange {
            what: "recording.workspace_scale",
            ..
        }))
    ));
    // A NaN from the recorded device is an error, and not a row.
    let nan = ScriptedDevice::from_fn(
        |t| Pose::from_position(Vec3::new(if t > 0.5 { Real::NAN } else { 0.0 }, 0.0, 0.0)),
        limits(),
    );
    let mut rec = Recorder::new(nan, Vec::new()).unwrap();
    rec.read(0.0).unwrap();
    assert_eq!(rec.read(1.0).unwrap_err().kind(), ErrorKind::InvalidData);
    let bytes = rec.finish().unwrap();
    assert_eq!(
        ReplayDevice::from_reader(bytes.as_slice())
            .unwrap()
            .samples()
            .len(),
        1
    );
}

fn arb_f64() -> impl Strategy<Value = Real> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        Just(-0.0),
        Just(5e-324),
        Just(f64::MAX),
        Just(0.1),
    ]
}

proptest! {
    #[test]
    fn any_finite_row_round_trips_bit_exactly(
        vals in proptest::collection::vec(arb_f64(), 19),
        q in proptest::array::uniform4(-1.0..1.0_f64),
        buttons in any::<u32>(),
        commands in any::<u32>(),
    ) {
        let q = Quaternion::new(q[0] + 1.5, q[1], q[2], q[3]);
        let q = UnitQuaternion::new_normalize(q);
        let v = |i: usize| Vec3::new(vals[i], vals[i + 1], vals[i + 2]);
        let sample = RecordedSample {
            t_s: vals[0],
            state: DeviceState {
                pose: Pose { position: v(1), orientation: q },
                twist: Twist { linear: v(4), angular: v(7) },
                buttons,
                timestamp_s: vals[10],
            },
            wrench: Wrench::new(v(11), v(14)),
            commands,
        };
        let mut line = String::new();
        write_row(&mut line, &sample);
        let back = parse_row(line.trim_end(), 1).unwrap();
        let bits = |s: &RecordedSample| {
            let mut b = vec![s.t_s.to_bits(), s.state.timestamp_s.to_bits()];
            b.extend(s.state.pose.position.iter().map(|x| x.to_bits()));
            b.extend(s.state.pose.orientation.coords.iter().map(|x| x.to_bits()));
            b.extend(s.state.twist.linear.iter().map(|x| x.to_bits()));
            b.extend(s.state.twist.angular.iter().map(|x| x.to_bits()));
            b.extend(s.wrench.force.iter().map(|x| x.to_bits()));
            b.extend(s.wrench.torque.iter().map(|x| x.to_bits()));
            b.push(u64::from(s.state.buttons));
            b.push(u64::from(s.commands));
            b
        };
        prop_assert_eq!(bits(&back), bits(&sample));
    }
}
