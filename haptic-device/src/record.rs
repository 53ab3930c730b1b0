//! [`Recorder`] and [`ReplayDevice`]: any device's readings, and the wrenches it was sent, to and
//! from CSV, bit for bit.
//!
//! # Format (version 1)
//!
//! UTF-8 text. First, metadata lines `# key = value`; then one column-header line; then one row
//! per read. Lines that start with `#` and blank lines are ignored after the header, and so are
//! `#` lines without `=` and unknown keys before it.
//!
//! ```text
//! # haptic-device recording
//! # format_version = 1
//! # device = simulated hand
//! # rate_hz = 1000.0
//! # workspace_scale = 0.4
//! # force_scale = 2.5
//! # nominal_rate_hz = 1000.0
//! # max_force_n = 5.0
//! # max_torque_nm = 0.5
//! # workspace_min_m = -0.2 -0.2 -0.2
//! # workspace_max_m = 0.2 0.2 0.2
//! t_s,stamp_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s,wx_rad_s,wy_rad_s,wz_rad_s,buttons,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm,commands
//! 0.001,0.001,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0,0.0,0.0,0.0,0.0,0.0,0.0,1
//! ```
//!
//! | column | meaning | unit |
//! |---|---|---|
//! | `t_s` | the `now_s` the device was read at; strictly increasing | s |
//! | `stamp_s` | the reading's own time stamp (`DeviceState::timestamp_s`) | s |
//! | `x_m`, `y_m`, `z_m` | handle position, world frame | m |
//! | `qw`, `qx`, `qy`, `qz` | handle orientation, unit quaternion, body to world | – |
//! | `vx_m_s` … `vz_m_s` | linear velocity, world frame | m/s |
//! | `wx_rad_s` … `wz_rad_s` | angular velocity, world frame | rad/s |
//! | `buttons` | button bit mask, decimal | – |
//! | `fx_n` … `fz_n` | force of the last wrench commanded before the next read (zero before any) | N |
//! | `tx_nm` … `tz_nm` | its torque | N m |
//! | `commands` | how many commands came between this read and the next | – |
//!
//! Metadata: `rate_hz` is the rate the recording was taken at (by default the device's nominal
//! rate, `nominal_rate_hz`); `workspace_scale` and `force_scale` say which scaling (see [`crate::ScaledDevice`])
//! lies between the physical handle and the recorded values (1 and 1 when none); the limits are
//! the recorded device's, so that a replay reports the same.
//!
//! Floats are written with Rust's shortest round-trip representation (`{:?}`), so parsing them
//! gives back the same `f64`, bit for bit (`-0.0` included). The wrench is recorded as the
//! recorder received it, before any clamping by the device.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3, Wrench};
use nalgebra::{Quaternion, UnitQuaternion};

use crate::error::{CsvProblem, DeviceError, finite_time};
use crate::scripted::check_state;

/// The version of the format this crate writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// The column names, in order.
pub const COLUMNS: [&str; 23] = [
    "t_s", "stamp_s", "x_m", "y_m", "z_m", "qw", "qx", "qy", "qz", "vx_m_s", "vy_m_s", "vz_m_s",
    "wx_rad_s", "wy_rad_s", "wz_rad_s", "buttons", "fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm",
    "tz_nm", "commands",
];

/// The column-header line.
pub const COLUMN_HEADER: &str = "t_s,stamp_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s,\
wx_rad_s,wy_rad_s,wz_rad_s,buttons,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm,commands";

/// Tolerance on `| |q| - 1 |` for recorded orientations.
const UNIT_TOL: Real = 1e-9;

/// What a recording says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingHeader {
    /// Name of the recorded device (one line).
    pub device: String,
    /// Rate the recording was taken at (Hz).
    pub rate_hz: Real,
    /// Workspace scale between the physical handle and the recorded poses (1 if none).
    pub workspace_scale: Real,
    /// Force scale between the recorded wrenches and the physical handle (1 if none).
    pub force_scale: Real,
    /// The recorded device's limits.
    pub limits: DeviceLimits,
}

impl RecordingHeader {
    /// The header for `device`: its name and limits, its nominal rate, scales 1.
    pub fn for_device<D: Device + ?Sized>(device: &D) -> Self {
        let limits = device.limits();
        Self {
            device: device.name().to_owned(),
            rate_hz: limits.nominal_rate_hz,
            workspace_scale: 1.0,
            force_scale: 1.0,
            limits,
        }
    }

    /// The same with the given scales.
    pub fn with_scales(mut self, workspace_scale: Real, force_scale: Real) -> Self {
        self.workspace_scale = workspace_scale;
        self.force_scale = force_scale;
        self
    }

    fn validate(&self) -> Result<(), DeviceError> {
        haptic_core::check::positive("rate_hz", self.rate_hz)?;
        haptic_core::check::positive("workspace_scale", self.workspace_scale)?;
        haptic_core::check::positive("force_scale", self.force_scale)?;
        Ok(())
    }

    fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        let l = &self.limits;
        let device: String = self
            .device
            .chars()
            .map(|c| if c.is_control() { ' ' } else { c })
            .collect();
        writeln!(w, "# haptic-device recording")?;
        writeln!(w, "# format_version = {FORMAT_VERSION}")?;
        writeln!(w, "# device = {device}")?;
        writeln!(w, "# rate_hz = {:?}", self.rate_hz)?;
        writeln!(w, "# workspace_scale = {:?}", self.workspace_scale)?;
        writeln!(w, "# force_scale = {:?}", self.force_scale)?;
        writeln!(w, "# nominal_rate_hz = {:?}", l.nominal_rate_hz)?;
        writeln!(w, "# max_force_n = {:?}", l.max_force_n)?;
        writeln!(w, "# max_torque_nm = {:?}", l.max_torque_nm)?;
        let v = |v: &Vec3| format!("{:?} {:?} {:?}", v.x, v.y, v.z);
        writeln!(w, "# workspace_min_m = {}", v(&l.workspace_min_m))?;
        writeln!(w, "# workspace_max_m = {}", v(&l.workspace_max_m))?;
        writeln!(
            w,
            "# one row per read: t_s read time (s), stamp_s device time stamp (s), position (m), \
             unit quaternion wxyz, velocity (m/s), angular velocity (rad/s), buttons, last wrench \
             commanded before the next read (N, N m), number of commands"
        )?;
        writeln!(w, "{COLUMN_HEADER}")
    }
}

/// One recorded read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordedSample {
    /// The time the device was read at (s).
    pub t_s: Real,
    /// What it returned.
    pub state: DeviceState,
    /// The last wrench commanded before the next read (zero before any command).
    pub wrench: Wrench,
    /// How many commands came between this read and the next.
    pub commands: u32,
}

fn write_row(line: &mut String, s: &RecordedSample) {
    use std::fmt::Write as _;
    line.clear();
    let p = &s.state.pose.position;
    let q = s.state.pose.orientation.as_ref();
    let v = &s.state.twist.linear;
    let w = &s.state.twist.angular;
    let f = &s.wrench.force;
    let t = &s.wrench.torque;
    // Writing to a String cannot fail.
    let _ = writeln!(
        line,
        "{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{},{:?},{:?},{:?},{:?},{:?},{:?},{}",
        s.t_s,
        s.state.timestamp_s,
        p.x,
        p.y,
        p.z,
        q.w,
        q.i,
        q.j,
        q.k,
        v.x,
        v.y,
        v.z,
        w.x,
        w.y,
        w.z,
        s.state.buttons,
        f.x,
        f.y,
        f.z,
        t.x,
        t.y,
        t.z,
        s.commands
    );
}

fn parse_row(text: &str, line: usize) -> Result<RecordedSample, DeviceError> {
    let mut fields = [""; 23];
    let mut found = 0;
    for field in text.split(',') {
        if found < fields.len() {
            fields[found] = field.trim();
        }
        found += 1;
    }
    if found != fields.len() {
        return Err(DeviceError::csv(
            line,
            CsvProblem::ColumnCount {
                expected: fields.len(),
                found,
            },
        ));
    }
    let mut x = [0.0; 23];
    for (i, field) in fields.iter().enumerate() {
        let column = COLUMNS[i];
        if column == "buttons" || column == "commands" {
            continue;
        }
        let v: Real = field
            .parse()
            .map_err(|_| DeviceError::csv(line, CsvProblem::NotANumber { column }))?;
        if !v.is_finite() {
            return Err(DeviceError::csv(line, CsvProblem::NonFinite { column }));
        }
        x[i] = v;
    }
    let int = |i: usize| -> Result<u32, DeviceError> {
        fields[i]
            .parse()
            .map_err(|_| DeviceError::csv(line, CsvProblem::NotANumber { column: COLUMNS[i] }))
    };
    let buttons = int(15)?;
    let commands = int(22)?;
    let q = Quaternion::new(x[5], x[6], x[7], x[8]);
    let norm = q.norm();
    if (norm - 1.0).abs() > UNIT_TOL {
        return Err(DeviceError::csv(
            line,
            CsvProblem::NonUnitQuaternion { norm },
        ));
    }
    Ok(RecordedSample {
        t_s: x[0],
        state: DeviceState {
            pose: Pose {
                position: Vec3::new(x[2], x[3], x[4]),
                // Kept as written, not renormalised: a replay is bit-exact.
                orientation: UnitQuaternion::new_unchecked(q),
            },
            twist: Twist {
                linear: Vec3::new(x[9], x[10], x[11]),
                angular: Vec3::new(x[12], x[13], x[14]),
            },
            buttons,
            timestamp_s: x[1],
        },
        wrench: Wrench::new(
            Vec3::new(x[16], x[17], x[18]),
            Vec3::new(x[19], x[20], x[21]),
        ),
        commands,
    })
}

/// Records every reading of a device, and every wrench it is sent, as CSV (format in the
/// [module docs](self)).
///
/// A row is written when the next read comes (it carries the commands that answered its
/// reading), and the last one by [`Recorder::finish`] or, failing that, on drop (errors then
/// ignored). Reads must go strictly forward in time. A failed read or command is passed on and
/// not recorded; a reading with NaN or Inf is an error ([`DeviceError::NonFinite`]), not a row.
///
/// Rows are formatted into a reused buffer and written through `W` (wrap files in a
/// [`BufWriter`], as [`Recorder::create`] does).
pub struct Recorder<D, W: Write> {
    inner: D,
    writer: Option<W>,
    line: String,
    pending: Option<RecordedSample>,
    last_wrench: Wrench,
    rows: u64,
}

impl<D: std::fmt::Debug, W: Write> std::fmt::Debug for Recorder<D, W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("inner", &self.inner)
            .field("rows", &self.rows)
            .finish_non_exhaustive()
    }
}

impl<D: Device> Recorder<D, BufWriter<File>> {
    /// Records `inner` to a new file at `path` (truncated if it exists).
    ///
    /// # Errors
    /// [`DeviceError::Io`] if the file cannot be created or the header written.
    pub fn create(inner: D, path: impl AsRef<Path>) -> Result<Self, DeviceError> {
        let file = File::create(path).map_err(|source| DeviceError::Io {
            context: "creating a recording",
            source,
        })?;
        Self::new(inner, BufWriter::new(file))
    }
}

impl<D: Device, W: Write> Recorder<D, W> {
    /// Records `inner` to `writer`, with the header [`RecordingHeader::for_device`].
    ///
    /// # Errors
    /// [`DeviceError::Io`] if the header cannot be written.
    pub fn new(inner: D, writer: W) -> Result<Self, DeviceError> {
        let header = RecordingHeader::for_device(&inner);
        Self::with_header(inner, writer, header)
    }

    /// Records `inner` to `writer` with the given header.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] for a non-positive rate or scale, [`DeviceError::Io`] if the
    /// header cannot be written.
    pub fn with_header(
        inner: D,
        mut writer: W,
        header: RecordingHeader,
    ) -> Result<Self, DeviceError> {
        header.validate()?;
        header
            .write_to(&mut writer)
            .map_err(|source| DeviceError::Io {
                context: "writing a recording header",
                source,
            })?;
        Ok(Self {
            inner,
            writer: Some(writer),
            line: String::with_capacity(512),
            pending: None,
            last_wrench: Wrench::zero(),
            rows: 0,
        })
    }

    /// The recorded device.
    pub fn inner(&self) -> &D {
        &self.inner
    }

    /// The recorded device, mutably.
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.inner
    }

    /// Rows written so far (the pending one excluded).
    pub fn rows_written(&self) -> u64 {
        self.rows
    }

    fn flush_pending(&mut self) -> Result<(), DeviceError> {
        if let (Some(sample), Some(w)) = (self.pending.take(), self.writer.as_mut()) {
            write_row(&mut self.line, &sample);
            w.write_all(self.line.as_bytes())
                .map_err(|source| DeviceError::Io {
                    context: "writing a recording row",
                    source,
                })?;
            self.rows += 1;
        }
        Ok(())
    }

    /// Writes the last row, flushes, and returns the writer.
    ///
    /// # Errors
    /// [`DeviceError::Io`] if writing or flushing fails.
    pub fn finish(mut self) -> Result<W, DeviceError> {
        self.flush_pending()?;
        match self.writer.take() {
            Some(mut w) => {
                w.flush().map_err(|source| DeviceError::Io {
                    context: "flushing a recording",
                    source,
                })?;
                Ok(w)
            }
            None => Err(DeviceError::Io {
                context: "finishing a recording",
                source: std::io::Error::other("the recording was already finished"),
            }),
        }
    }
}

impl<D, W: Write> Drop for Recorder<D, W> {
    fn drop(&mut self) {
        if let (Some(sample), Some(w)) = (self.pending.take(), self.writer.as_mut()) {
            write_row(&mut self.line, &sample);
            let _ = w.write_all(self.line.as_bytes());
        }
        if let Some(w) = self.writer.as_mut() {
            let _ = w.flush();
        }
    }
}

impl<D: Device, W: Write> Device for Recorder<D, W> {
    type Error = DeviceError;

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        if let Some(p) = &self.pending {
            if now_s <= p.t_s {
                return Err(DeviceError::TimeWentBack {
                    previous_s: p.t_s,
                    now_s,
                });
            }
        }
        let state = self.inner.read(now_s).map_err(DeviceError::from_device)?;
        let state = check_state(state)?;
        self.flush_pending()?;
        self.pending = Some(RecordedSample {
            t_s: now_s,
            state,
            wrench: self.last_wrench,
            commands: 0,
        });
        Ok(state)
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        self.inner
            .command(wrench)
            .map_err(DeviceError::from_device)?;
        self.last_wrench = *wrench;
        if let Some(p) = &mut self.pending {
            p.wrench = *wrench;
            p.commands = p.commands.saturating_add(1);
        }
        Ok(())
    }

    fn command_zero(&mut self) -> Result<(), DeviceError> {
        self.inner
            .command_zero()
            .map_err(DeviceError::from_device)?;
        self.last_wrench = Wrench::zero();
        if let Some(p) = &mut self.pending {
            p.wrench = Wrench::zero();
            p.commands = p.commands.saturating_add(1);
        }
        Ok(())
    }
}

/// Plays a recording back: the same readings at the same times, bit for bit.
///
/// `read(t)` at a recorded `t_s` returns that row's reading exactly. Between two rows it
/// interpolates (position, twist and time stamp linearly, orientation along the shortest arc;
/// buttons of the earlier row). Before the first row and after the last the handle rests at the
/// first or last pose with zero twist, time-stamped `now_s`. Commands are clamped to the
/// recorded limits and kept ([`ReplayDevice::last_command`]); they move nothing.
#[derive(Debug, Clone)]
pub struct ReplayDevice {
    header: RecordingHeader,
    samples: Vec<RecordedSample>,
    name: String,
    cursor: usize,
    last_command: Wrench,
    commands_received: u64,
}

impl ReplayDevice {
    /// Opens a recording file.
    ///
    /// # Errors
    /// [`DeviceError::Io`] if it cannot be read, [`DeviceError::Csv`] (with the line) if it is
    /// malformed.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, DeviceError> {
        let file = File::open(path).map_err(|source| DeviceError::Io {
            context: "opening a recording",
            source,
        })?;
        Self::from_reader(BufReader::new(file))
    }

    /// Reads a recording from `reader`.
    ///
    /// # Errors
    /// [`DeviceError::Io`] if reading fails; [`DeviceError::Csv`] with the 1-based line and
    /// the [`CsvProblem`]: wrong column count, a field that is not a number, NaN or Inf, a
    /// non-unit quaternion, a time that does not increase, a missing or bad header or metadata,
    /// or no row at all.
    pub fn from_reader(reader: impl BufRead) -> Result<Self, DeviceError> {
        let mut meta = Meta::default();
        let mut header: Option<RecordingHeader> = None;
        let mut samples: Vec<RecordedSample> = Vec::new();
        let mut last_line = 0;
        for (index, text) in reader.lines().enumerate() {
            let line = index + 1;
            last_line = line;
            let text = text.map_err(|source| DeviceError::Io {
                context: "reading a recording",
                source,
            })?;
            let text = text.trim();
            if text.is_empty() {
                continue;
            }
            if let Some(comment) = text.strip_prefix('#') {
                if header.is_none() {
                    meta.parse(comment, line)?;
                }
                continue;
            }
            if header.is_none() {
                if text != COLUMN_HEADER {
                    return Err(DeviceError::csv(
                        line,
                        CsvProblem::BadHeader {
                            expected: COLUMN_HEADER,
                        },
                    ));
                }
                header = Some(meta.header(line)?);
                continue;
            }
            let sample = parse_row(text, line)?;
            if let Some(prev) = samples.last() {
                if sample.t_s <= prev.t_s {
                    return Err(DeviceError::csv(
                        line,
                        CsvProblem::TimeNotIncreasing {
                            previous_s: prev.t_s,
                            t_s: sample.t_s,
                        },
                    ));
                }
            }
            samples.push(sample);
        }
        let Some(header) = header else {
            return Err(DeviceError::csv(
                last_line.max(1),
                CsvProblem::MissingHeader,
            ));
        };
        if samples.is_empty() {
            return Err(DeviceError::csv(last_line.max(1), CsvProblem::NoSamples));
        }
        Ok(Self {
            name: format!("replay of {}", header.device),
            header,
            samples,
            cursor: 0,
            last_command: Wrench::zero(),
            commands_received: 0,
        })
    }

    /// The recording's header.
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// Every recorded read, in time order.
    pub fn samples(&self) -> &[RecordedSample] {
        &self.samples
    }

    /// The time span `[first, last]` of the recording (s).
    pub fn time_span_s(&self) -> (Real, Real) {
        let first = self.samples.first().map_or(0.0, |s| s.t_s);
        let last = self.samples.last().map_or(0.0, |s| s.t_s);
        (first, last)
    }

    /// The last command received, clamped to the recorded limits.
    pub fn last_command(&self) -> Wrench {
        self.last_command
    }

    /// How many commands were received.
    pub fn commands_received(&self) -> u64 {
        self.commands_received
    }

    /// The index `i` with `t_i <= t < t_{i+1}`, for `t` strictly inside the recording.
    fn interval(&mut self, t: Real) -> usize {
        let s = &self.samples;
        let fits = |i: usize| i + 1 < s.len() && s[i].t_s <= t && t < s[i + 1].t_s;
        if !fits(self.cursor) {
            self.cursor = if fits(self.cursor + 1) {
                self.cursor + 1
            } else {
                s.partition_point(|x| x.t_s <= t).saturating_sub(1)
            };
        }
        self.cursor
    }
}

impl Device for ReplayDevice {
    type Error = DeviceError;

    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.header.limits
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        let (Some(first), Some(last)) = (self.samples.first(), self.samples.last()) else {
            return Err(DeviceError::csv(0, CsvProblem::NoSamples));
        };
        let rest = |s: &RecordedSample| DeviceState {
            pose: s.state.pose,
            twist: Twist::zero(),
            buttons: s.state.buttons,
            timestamp_s: now_s,
        };
        if now_s <= first.t_s {
            return Ok(if now_s == first.t_s {
                first.state
            } else {
                rest(first)
            });
        }
        if now_s >= last.t_s {
            return Ok(if now_s == last.t_s {
                last.state
            } else {
                rest(last)
            });
        }
        let i = self.interval(now_s);
        let (a, b) = (&self.samples[i], &self.samples[i + 1]);
        if now_s == a.t_s {
            return Ok(a.state);
        }
        let u = (now_s - a.t_s) / (b.t_s - a.t_s);
        let lerp = |x: &Vec3, y: &Vec3| x + (y - x) * u;
        let qa = a.state.pose.orientation;
        let rel = (qa.inverse() * b.state.pose.orientation).scaled_axis();
        check_state(DeviceState {
            pose: Pose {
                position: lerp(&a.state.pose.position, &b.state.pose.position),
                orientation: qa * UnitQuaternion::from_scaled_axis(rel * u),
            },
            twist: Twist {
                linear: lerp(&a.state.twist.linear, &b.state.twist.linear),
                angular: lerp(&a.state.twist.angular, &b.state.twist.angular),
            },
            buttons: a.state.buttons,
            timestamp_s: a.state.timestamp_s + (b.state.timestamp_s - a.state.timestamp_s) * u,
        })
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        self.last_command = self.header.limits.saturate(wrench).0;
        self.commands_received += 1;
        Ok(())
    }
}

/// Metadata gathered before the column header.
#[derive(Debug, Default)]
struct Meta {
    device: Option<String>,
    version: Option<u32>,
    rate_hz: Option<Real>,
    nominal_rate_hz: Option<Real>,
    workspace_scale: Option<Real>,
    force_scale: Option<Real>,
    max_force_n: Option<Real>,
    max_torque_nm: Option<Real>,
    workspace_min_m: Option<Vec3>,
    workspace_max_m: Option<Vec3>,
}

impl Meta {
    fn parse(&mut self, comment: &str, line: usize) -> Result<(), DeviceError> {
        let Some((key, value)) = comment.split_once('=') else {
            return Ok(());
        };
        let (key, value) = (key.trim(), value.trim());
        let bad = |key: &'static str| DeviceError::csv(line, CsvProblem::BadMetadata { key });
        let real = |key: &'static str| -> Result<Real, DeviceError> {
            value
                .parse::<Real>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(key))
        };
        let positive = |key: &'static str| -> Result<Real, DeviceError> {
            real(key).and_then(|v| if v > 0.0 { Ok(v) } else { Err(bad(key)) })
        };
        let vec3 = |key: &'static str| -> Result<Vec3, DeviceError> {
            let mut out = Vec3::zeros();
            let mut n = 0;
            for part in value.split_whitespace() {
                let v = part
                    .parse::<Real>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| bad(key))?;
                if n < 3 {
                    out[n] = v;
                }
                n += 1;
            }
            if n == 3 { Ok(out) } else { Err(bad(key)) }
        };
        match key {
            "format_version" => {
                let v: u32 = value.parse().map_err(|_| bad("format_version"))?;
                if v != FORMAT_VERSION {
                    return Err(DeviceError::csv(
                        line,
                        CsvProblem::UnsupportedVersion { found: v },
                    ));
                }
                self.version = Some(v);
            }
            "device" => self.device = Some(value.to_owned()),
            "rate_hz" => self.rate_hz = Some(positive("rate_hz")?),
            "nominal_rate_hz" => self.nominal_rate_hz = Some(positive("nominal_rate_hz")?),
            "workspace_scale" => self.workspace_scale = Some(positive("workspace_scale")?),
            "force_scale" => self.force_scale = Some(positive("force_scale")?),
            "max_force_n" => self.max_force_n = Some(real("max_force_n")?),
            "max_torque_nm" => self.max_torque_nm = Some(real("max_torque_nm")?),
            "workspace_min_m" => self.workspace_min_m = Some(vec3("workspace_min_m")?),
            "workspace_max_m" => self.workspace_max_m = Some(vec3("workspace_max_m")?),
            _ => {}
        }
        Ok(())
    }

    fn header(&self, line: usize) -> Result<RecordingHeader, DeviceError> {
        let missing =
            |key: &'static str| DeviceError::csv(line, CsvProblem::MissingMetadata { key });
        self.version.ok_or_else(|| missing("format_version"))?;
        let limits = DeviceLimits::new(
            self.max_force_n.ok_or_else(|| missing("max_force_n"))?,
            self.max_torque_nm.ok_or_else(|| missing("max_torque_nm"))?,
            self.workspace_min_m
                .ok_or_else(|| missing("workspace_min_m"))?,
            self.workspace_max_m
                .ok_or_else(|| missing("workspace_max_m"))?,
            self.nominal_rate_hz
                .ok_or_else(|| missing("nominal_rate_hz"))?,
        )
        .map_err(|e| DeviceError::csv(line, CsvProblem::Limits(e)))?;
        Ok(RecordingHeader {
            device: self.device.clone().unwrap_or_default(),
            rate_hz: self.rate_hz.ok_or_else(|| missing("rate_hz"))?,
            workspace_scale: self
                .workspace_scale
                .ok_or_else(|| missing("workspace_scale"))?,
            force_scale: self.force_scale.ok_or_else(|| missing("force_scale"))?,
            limits,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
                what: "workspace_scale",
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
}
