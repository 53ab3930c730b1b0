//! The recording format: its header, its rows, and their parsing.

use std::io::Write;

use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3, Wrench};
use nalgebra::{Quaternion, UnitQuaternion};

use crate::error::{CsvProblem, DeviceError};

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
pub(super) const UNIT_TOL: Real = 1e-9;

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

    pub(super) fn validate(&self) -> Result<(), DeviceError> {
        haptic_core::check::positive("recording.rate_hz", self.rate_hz)?;
        haptic_core::check::positive("recording.workspace_scale", self.workspace_scale)?;
        haptic_core::check::positive("recording.force_scale", self.force_scale)?;
        Ok(())
    }

    pub(super) fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
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

pub(super) fn write_row(line: &mut String, s: &RecordedSample) {
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

pub(super) fn parse_row(text: &str, line: usize) -> Result<RecordedSample, DeviceError> {
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

/// Metadata gathered before the column header.
#[derive(Debug, Default)]
pub(super) struct Meta {
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
    pub(super) fn parse(&mut self, comment: &str, line: usize) -> Result<(), DeviceError> {
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

    pub(super) fn header(&self, line: usize) -> Result<RecordingHeader, DeviceError> {
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
