//! SpaceMouse-class 6-DOF input: the HID report parser and the mapping from deflections to a
//! handle pose. Pure code over bytes, always compiled and tested without hardware; the hidapi
//! driver that feeds it is [`crate::hid`] (feature `hid`).
//!
//! # Report layout (3Dconnexion SpaceNavigator, SpaceMouse and successors)
//!
//! Input reports are numbered; the first byte is the report id, the payload follows:
//!
//! | id | payload | meaning |
//! |---|---|---|
//! | 1 | 6 bytes | translation `x, y, z`, little-endian `i16` each (older devices) |
//! | 1 | 12 bytes | translation `x, y, z` then rotation `rx, ry, rz`, `i16` LE (newer devices) |
//! | 2 | 6 bytes | rotation `rx, ry, rz`, `i16` LE (older devices) |
//! | 3 | 1 – 4+ bytes | button bit mask, little-endian (bit i = button i); bytes past 4 ignored |
//!
//! Other ids (LED, battery and vendor reports) are [`ReportError::Unknown`]; the tracker skips
//! them. A payload shorter than its id requires, or an id-1 payload of 7 – 11 bytes (a cut
//! 12-byte report), is [`ReportError::Truncated`]. Deflections are about ±350 counts at full
//! scale on the devices documented publicly. The HID frame has `x` to the right, `y` towards the
//! user and `z` down; [`SpaceMouseConfig::axis_signs`] maps it to the handle's frame (default:
//! `x` right, `y` away from the user, `z` up).

use haptic_core::{DeviceLimits, DeviceState, Pose, Real, Twist, Vec3};
use nalgebra::UnitQuaternion;

use crate::error::{DeviceError, finite_time};

/// Report id of translation (and, with a 12-byte payload, rotation) reports.
pub const REPORT_TRANSLATION: u8 = 1;
/// Report id of rotation reports.
pub const REPORT_ROTATION: u8 = 2;
/// Report id of button reports.
pub const REPORT_BUTTONS: u8 = 3;

/// A parsed input report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpaceMouseReport {
    /// Translation deflection `x, y, z` (counts, HID frame).
    Translation([i16; 3]),
    /// Rotation deflection `rx, ry, rz` (counts, HID frame).
    Rotation([i16; 3]),
    /// Both at once (newer devices' 12-byte report 1).
    Motion {
        /// Translation deflection (counts).
        translation: [i16; 3],
        /// Rotation deflection (counts).
        rotation: [i16; 3],
    },
    /// Button bit mask (bit i = button i pressed).
    Buttons(u32),
}

/// A report that could not be parsed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// Zero bytes.
    #[error("empty report")]
    Empty,
    /// Fewer payload bytes than the report id requires.
    #[error("report {report_id} truncated: {found} payload bytes, expected {expected}")]
    Truncated {
        /// The report id.
        report_id: u8,
        /// Payload bytes required.
        expected: usize,
        /// Payload bytes found.
        found: usize,
    },
    /// A report id this parser does not read.
    #[error("unknown report id {report_id} ({len} payload bytes)")]
    Unknown {
        /// The report id.
        report_id: u8,
        /// Payload length.
        len: usize,
    },
}

fn axes(p: &[u8]) -> [i16; 3] {
    [
        i16::from_le_bytes([p[0], p[1]]),
        i16::from_le_bytes([p[2], p[3]]),
        i16::from_le_bytes([p[4], p[5]]),
    ]
}

/// Parses one input report (report id first, as hidraw and hidapi deliver it).
///
/// # Errors
/// [`ReportError::Empty`], [`ReportError::Truncated`] or [`ReportError::Unknown`].
pub fn parse_report(bytes: &[u8]) -> Result<SpaceMouseReport, ReportError> {
    let (&report_id, payload) = bytes.split_first().ok_or(ReportError::Empty)?;
    let found = payload.len();
    let truncated = |expected| ReportError::Truncated {
        report_id,
        expected,
        found,
    };
    match report_id {
        REPORT_TRANSLATION => match found {
            0..6 => Err(truncated(6)),
            6 => Ok(SpaceMouseReport::Translation(axes(payload))),
            7..12 => Err(truncated(12)),
            _ => Ok(SpaceMouseReport::Motion {
                translation: axes(&payload[..6]),
                rotation: axes(&payload[6..12]),
            }),
        },
        REPORT_ROTATION if found < 6 => Err(truncated(6)),
        REPORT_ROTATION => Ok(SpaceMouseReport::Rotation(axes(payload))),
        REPORT_BUTTONS if found == 0 => Err(truncated(1)),
        REPORT_BUTTONS => {
            let mut mask = [0u8; 4];
            let n = found.min(4);
            mask[..n].copy_from_slice(&payload[..n]);
            Ok(SpaceMouseReport::Buttons(u32::from_le_bytes(mask)))
        }
        _ => Err(ReportError::Unknown {
            report_id,
            len: found,
        }),
    }
}

/// How deflections move the handle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlMode {
    /// The handle's offset from home is proportional to the deflection (springs back to home
    /// when released).
    Position,
    /// The handle's velocity is proportional to the deflection (stays where it is when
    /// released).
    Rate,
}

/// Configuration of the deflection-to-pose mapping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceMouseConfig {
    /// Position or rate control.
    pub mode: ControlMode,
    /// Counts at full deflection (about 350 on SpaceNavigator-class devices).
    pub full_scale_counts: Real,
    /// Dead band, as a fraction of full scale, below which a deflection counts as zero.
    pub deadband: Real,
    /// Position mode: offset at full deflection (m).
    pub max_offset_m: Real,
    /// Position mode: rotation at full deflection (rad).
    pub max_angle_rad: Real,
    /// Rate mode: speed at full deflection (m/s).
    pub max_speed_m_s: Real,
    /// Rate mode: angular rate at full deflection (rad/s).
    pub max_rate_rad_s: Real,
    /// Sign of each HID axis `x, y, z, rx, ry, rz` in the handle frame.
    pub axis_signs: [Real; 6],
    /// The pose the handle starts at (and, in position mode, returns to).
    pub home: Pose,
    /// Lower corner of the workspace (m).
    pub workspace_min_m: Vec3,
    /// Upper corner of the workspace (m).
    pub workspace_max_m: Vec3,
    /// The rate the runtime serves the device at (Hz); the device itself reports at 60 – 125 Hz.
    pub nominal_rate_hz: Real,
}

impl Default for SpaceMouseConfig {
    fn default() -> Self {
        Self {
            mode: ControlMode::Position,
            full_scale_counts: 350.0,
            deadband: 0.05,
            max_offset_m: 0.05,
            max_angle_rad: 0.5,
            max_speed_m_s: 0.1,
            max_rate_rad_s: 1.0,
            axis_signs: [1.0, -1.0, -1.0, 1.0, -1.0, -1.0],
            home: Pose::identity(),
            workspace_min_m: Vec3::repeat(-0.1),
            workspace_max_m: Vec3::repeat(0.1),
            nominal_rate_hz: 1000.0,
        }
    }
}

impl SpaceMouseConfig {
    /// The device's limits: zero force and torque (no force output), the workspace and rate.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] for an empty workspace or a bad rate.
    pub fn limits(&self) -> Result<DeviceLimits, DeviceError> {
        Ok(DeviceLimits::new(
            0.0,
            0.0,
            self.workspace_min_m,
            self.workspace_max_m,
            self.nominal_rate_hz,
        )?)
    }

    fn validate(&self) -> Result<DeviceLimits, DeviceError> {
        haptic_core::check::positive("spacemouse.full_scale_counts", self.full_scale_counts)?;
        haptic_core::check::positive("spacemouse.max_offset_m", self.max_offset_m)?;
        haptic_core::check::positive("spacemouse.max_angle_rad", self.max_angle_rad)?;
        haptic_core::check::positive("spacemouse.max_speed_m_s", self.max_speed_m_s)?;
        haptic_core::check::positive("spacemouse.max_rate_rad_s", self.max_rate_rad_s)?;
        haptic_core::check::in_half_open(
            "spacemouse.deadband",
            self.deadband,
            0.0,
            1.0,
            "in [0, 1)",
        )?;
        haptic_core::check::all_finite("spacemouse.axis_signs", self.axis_signs.iter().copied())?;
        if !self.home.is_finite() {
            return Err(haptic_core::CoreError::NonFinite {
                what: "spacemouse.home",
            }
            .into());
        }
        self.limits()
    }
}

/// Turns a stream of reports into handle readings; the pure half of the HID driver.
#[derive(Debug, Clone)]
pub struct SpaceMouseTracker {
    config: SpaceMouseConfig,
    limits: DeviceLimits,
    translation: [i16; 3],
    rotation: [i16; 3],
    buttons: u32,
    pose: Pose,
    last_t_s: Option<Real>,
    reports: u64,
    unknown_reports: u64,
}

impl SpaceMouseTracker {
    /// A tracker at the home pose, with no deflection.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] for a non-positive scale or gain, a dead band outside
    /// `[0, 1)` or non-finite signs; [`DeviceError::Parameter`] for an empty workspace.
    pub fn new(config: SpaceMouseConfig) -> Result<Self, DeviceError> {
        let limits = config.validate()?;
        let mut pose = config.home;
        pose.position = clamp_box(&pose.position, &limits);
        Ok(Self {
            config,
            limits,
            translation: [0; 3],
            rotation: [0; 3],
            buttons: 0,
            pose,
            last_t_s: None,
            reports: 0,
            unknown_reports: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SpaceMouseConfig {
        &self.config
    }

    /// The limits (zero force and torque).
    pub fn limits(&self) -> DeviceLimits {
        self.limits
    }

    /// Applies one raw report. Unknown report ids are skipped and counted.
    ///
    /// # Errors
    /// [`ReportError::Empty`] or [`ReportError::Truncated`]; the state is then unchanged.
    pub fn feed(&mut self, bytes: &[u8]) -> Result<(), ReportError> {
        match parse_report(bytes) {
            Ok(r) => {
                self.apply(r);
                Ok(())
            }
            Err(ReportError::Unknown { .. }) => {
                self.unknown_reports += 1;
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    /// Applies one parsed report.
    pub fn apply(&mut self, report: SpaceMouseReport) {
        self.reports += 1;
        match report {
            SpaceMouseReport::Translation(t) => self.translation = t,
            SpaceMouseReport::Rotation(r) => self.rotation = r,
            SpaceMouseReport::Motion {
                translation,
                rotation,
            } => {
                self.translation = translation;
                self.rotation = rotation;
            }
            SpaceMouseReport::Buttons(b) => self.buttons = b,
        }
    }

    /// Reports applied so far.
    pub fn reports(&self) -> u64 {
        self.reports
    }

    /// Reports with an unknown id skipped so far.
    pub fn unknown_reports(&self) -> u64 {
        self.unknown_reports
    }

    /// The raw deflection counts `(translation, rotation)`, HID frame.
    pub fn counts(&self) -> ([i16; 3], [i16; 3]) {
        (self.translation, self.rotation)
    }

    /// The deflections in the handle frame, each in `[-1, 1]` after the dead band:
    /// `(translation, rotation)`.
    pub fn deflection(&self) -> (Vec3, Vec3) {
        let c = &self.config;
        let norm = |counts: i16, sign: Real| {
            let n = (Real::from(counts) / c.full_scale_counts).clamp(-1.0, 1.0);
            let m = ((n.abs() - c.deadband) / (1.0 - c.deadband)).max(0.0);
            sign * m.copysign(n)
        };
        let t = Vec3::from_fn(|i, _| norm(self.translation[i], c.axis_signs[i]));
        let r = Vec3::from_fn(|i, _| norm(self.rotation[i], c.axis_signs[i + 3]));
        (t, r)
    }

    /// The handle's state at `now_s`: position mode maps the current deflection to a pose
    /// (twist by difference with the previous reading); rate mode integrates the deflection as a
    /// velocity since the previous reading. The position stays in the workspace.
    ///
    /// # Errors
    /// [`DeviceError::BadTime`] for a non-finite time, [`DeviceError::TimeWentBack`] for a time
    /// before the previous reading.
    pub fn state(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        let dt_s = match self.last_t_s {
            Some(t) if now_s < t => {
                return Err(DeviceError::TimeWentBack {
                    previous_s: t,
                    now_s,
                });
            }
            Some(t) => now_s - t,
            None => 0.0,
        };
        let (t, r) = self.deflection();
        let c = self.config;
        let twist = match c.mode {
            ControlMode::Position => {
                let new = Pose {
                    position: clamp_box(&(c.home.position + t * c.max_offset_m), &self.limits),
                    orientation: UnitQuaternion::from_scaled_axis(r * c.max_angle_rad)
                        * c.home.orientation,
                };
                let twist = if dt_s > 0.0 {
                    Twist {
                        linear: (new.position - self.pose.position) / dt_s,
                        angular: (new.orientation * self.pose.orientation.inverse()).scaled_axis()
                            / dt_s,
                    }
                } else {
                    Twist::zero()
                };
                self.pose = new;
                twist
            }
            ControlMode::Rate => {
                let mut v = t * c.max_speed_m_s;
                let w = r * c.max_rate_rad_s;
                let target = self.pose.position + v * dt_s;
                let clamped = clamp_box(&target, &self.limits);
                for k in 0..3 {
                    if clamped[k] != target[k] {
                        v[k] = 0.0;
                    }
                }
                self.pose.position = clamped;
                self.pose.orientation =
                    UnitQuaternion::from_scaled_axis(w * dt_s) * self.pose.orientation;
                Twist {
                    linear: v,
                    angular: w,
                }
            }
        };
        self.last_t_s = Some(now_s);
        Ok(DeviceState {
            pose: self.pose,
            twist,
            buttons: self.buttons,
            timestamp_s: now_s,
        })
    }
}

fn clamp_box(x: &Vec3, l: &DeviceLimits) -> Vec3 {
    Vec3::from_fn(|i, _| x[i].clamp(l.workspace_min_m[i], l.workspace_max_m[i]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    // Reports as a SpaceNavigator (6-byte reports 1 and 2) and a SpaceMouse Wireless (13-byte
    // report 1) send them.
    /// Translation x = +100, y = -30 (0xffe2), z = 0.
    const NAV_TRANSLATION: [u8; 7] = [0x01, 0x64, 0x00, 0xe2, 0xff, 0x00, 0x00];
    /// Rotation rx = 0, ry = -30, rz = 350.
    const NAV_ROTATION: [u8; 7] = [0x02, 0x00, 0x00, 0xe2, 0xff, 0x5e, 0x01];
    /// Buttons 0 and 1 pressed.
    const NAV_BUTTONS: [u8; 3] = [0x03, 0x03, 0x00];
    /// Translation (-350, 0, 175), rotation (0, 0, -175).
    const WIRELESS_MOTION: [u8; 13] = [
        0x01, 0xa2, 0xfe, 0x00, 0x00, 0xaf, 0x00, 0x00, 0x00, 0x00, 0x00, 0x51, 0xff,
    ];
    /// A battery report (id 0x17), which the parser does not read.
    const BATTERY: [u8; 2] = [0x17, 0x64];
    /// An LED report (id 4).
    const LED: [u8; 2] = [0x04, 0x01];

    #[test]
    fn parses_recorded_reports() {
        assert_eq!(
            parse_report(&NAV_TRANSLATION),
            Ok(SpaceMouseReport::Translation([100, -30, 0]))
        );
        assert_eq!(
            parse_report(&NAV_ROTATION),
            Ok(SpaceMouseReport::Rotation([0, -30, 350]))
        );
        assert_eq!(parse_report(&NAV_BUTTONS), Ok(SpaceMouseReport::Buttons(3)));
        assert_eq!(
            parse_report(&WIRELESS_MOTION),
            Ok(SpaceMouseReport::Motion {
                translation: [-350, 0, 175],
                rotation: [0, 0, -175],
            })
        );
        // Extremes of i16, wide button masks (bytes past 4 ignored), padded motion reports.
        assert_eq!(
            parse_report(&[0x02, 0x00, 0x80, 0xff, 0x7f, 0xff, 0xff]),
            Ok(SpaceMouseReport::Rotation([i16::MIN, i16::MAX, -1]))
        );
        assert_eq!(
            parse_report(&[0x03, 0x01, 0x00, 0x00, 0x80, 0xff]),
            Ok(SpaceMouseReport::Buttons(0x8000_0001))
        );
        assert_eq!(
            parse_report(&[0x03, 0x04]),
            Ok(SpaceMouseReport::Buttons(4))
        );
        let mut padded = WIRELESS_MOTION.to_vec();
        padded.extend([0; 3]);
        assert_eq!(parse_report(&padded), parse_report(&WIRELESS_MOTION));
    }

    #[test]
    fn truncated_empty_and_unknown_reports() {
        assert_eq!(parse_report(&[]), Err(ReportError::Empty));
        assert_eq!(
            parse_report(&NAV_TRANSLATION[..5]),
            Err(ReportError::Truncated {
                report_id: 1,
                expected: 6,
                found: 4
            })
        );
        assert_eq!(
            parse_report(&WIRELESS_MOTION[..10]),
            Err(ReportError::Truncated {
                report_id: 1,
                expected: 12,
                found: 9
            })
        );
        assert_eq!(
            parse_report(&NAV_ROTATION[..1]),
            Err(ReportError::Truncated {
                report_id: 2,
                expected: 6,
                found: 0
            })
        );
        assert_eq!(
            parse_report(&NAV_BUTTONS[..1]),
            Err(ReportError::Truncated {
                report_id: 3,
                expected: 1,
                found: 0
            })
        );
        assert_eq!(
            parse_report(&BATTERY),
            Err(ReportError::Unknown {
                report_id: 0x17,
                len: 1
            })
        );
        assert_eq!(
            parse_report(&[0x00, 1, 2, 3, 4, 5, 6]),
            Err(ReportError::Unknown {
                report_id: 0,
                len: 6
            })
        );
    }

    #[test]
    fn tracker_skips_unknown_and_rejects_truncated() {
        let mut t = SpaceMouseTracker::new(SpaceMouseConfig::default()).unwrap();
        t.feed(&NAV_TRANSLATION).unwrap();
        t.feed(&BATTERY).unwrap();
        t.feed(&LED).unwrap();
        assert_eq!((t.reports(), t.unknown_reports()), (1, 2));
        let before = t.counts();
        assert!(matches!(
            t.feed(&NAV_ROTATION[..4]),
            Err(ReportError::Truncated { .. })
        ));
        assert_eq!(t.counts(), before);
        assert!(t.feed(&[]).is_err());
        // The driver turns the error into a DeviceError of kind InvalidData.
        let e: DeviceError = ReportError::Empty.into();
        assert_eq!(
            haptic_core::device::Error::kind(&e),
            haptic_core::device::ErrorKind::InvalidData
        );
    }

    #[test]
    fn deflection_mapping_signs_and_deadband() {
        let mut t = SpaceMouseTracker::new(SpaceMouseConfig::default()).unwrap();
        t.feed(&WIRELESS_MOTION).unwrap();
        let (tr, rot) = t.deflection();
        // x = -350 is full left; z = +175 counts is half way down, i.e. -z in the handle frame,
        // reduced by the dead band: (0.5 - 0.05) / 0.95.
        let half = 0.45 / 0.95;
        assert_relative_eq!(tr, Vec3::new(-1.0, 0.0, -half), epsilon = 1e-15);
        assert_relative_eq!(rot, Vec3::new(0.0, 0.0, half), epsilon = 1e-15);
        // Inside the dead band: nothing. Beyond full scale: 1.
        t.apply(SpaceMouseReport::Translation([17, -17, 2000]));
        let (tr, _) = t.deflection();
        assert_eq!(tr, Vec3::new(0.0, 0.0, -1.0));
    }

    #[test]
    fn position_control() {
        let mut t = SpaceMouseTracker::new(SpaceMouseConfig::default()).unwrap();
        let s0 = t.state(0.0).unwrap();
        assert_eq!(s0.pose, Pose::identity());
        assert_eq!(s0.twist, Twist::zero());
        t.feed(&WIRELESS_MOTION).unwrap();
        t.feed(&NAV_BUTTONS).unwrap();
        let s = t.state(0.01).unwrap();
        let half = 0.45 / 0.95;
        assert_relative_eq!(
            s.pose.position,
            Vec3::new(-0.05, 0.0, -0.05 * half),
            epsilon = 1e-15
        );
        assert_relative_eq!(s.pose.orientation.angle(), 0.5 * half, epsilon = 1e-12);
        assert_relative_eq!(s.twist.linear, s.pose.position / 0.01, epsilon = 1e-12);
        assert_eq!(s.buttons, 3);
        // Released: back home.
        t.apply(SpaceMouseReport::Motion {
            translation: [0; 3],
            rotation: [0; 3],
        });
        assert_eq!(t.state(0.02).unwrap().pose, Pose::identity());
        assert!(matches!(
            t.state(0.01),
            Err(DeviceError::TimeWentBack { .. })
        ));
        assert!(matches!(
            t.state(Real::NAN),
            Err(DeviceError::BadTime { .. })
        ));
    }

    #[test]
    fn rate_control_integrates_and_stops_at_the_wall() {
        let config = SpaceMouseConfig {
            mode: ControlMode::Rate,
            ..SpaceMouseConfig::default()
        };
        let mut t = SpaceMouseTracker::new(config).unwrap();
        t.state(0.0).unwrap();
        // Full right (+x) and full yaw.
        t.apply(SpaceMouseReport::Motion {
            translation: [350, 0, 0],
            rotation: [0, 0, -350],
        });
        let s = t.state(0.5).unwrap();
        assert_relative_eq!(s.pose.position.x, 0.05, epsilon = 1e-15);
        assert_relative_eq!(s.twist.linear.x, 0.1, epsilon = 1e-15);
        assert_relative_eq!(s.twist.angular.z, 1.0, epsilon = 1e-15);
        assert_relative_eq!(s.pose.orientation.angle(), 0.5, epsilon = 1e-12);
        // One more second: the wall at 0.1 m stops it.
        let s = t.state(1.5).unwrap();
        assert_eq!(s.pose.position.x, 0.1);
        assert_eq!(s.twist.linear.x, 0.0);
        // Released: it stays.
        t.apply(SpaceMouseReport::Translation([0; 3]));
        t.apply(SpaceMouseReport::Rotation([0; 3]));
        let s = t.state(2.0).unwrap();
        assert_eq!(s.pose.position.x, 0.1);
        assert_eq!(s.twist, Twist::zero());
    }

    #[test]
    fn bad_configs() {
        let bad = |c: SpaceMouseConfig| SpaceMouseTracker::new(c).is_err();
        let d = SpaceMouseConfig::default();
        assert!(bad(SpaceMouseConfig { deadband: 1.0, ..d }));
        assert!(bad(SpaceMouseConfig {
            full_scale_counts: 0.0,
            ..d
        }));
        assert!(bad(SpaceMouseConfig {
            axis_signs: [1.0, Real::NAN, 1.0, 1.0, 1.0, 1.0],
            ..d
        }));
        assert!(bad(SpaceMouseConfig {
            workspace_min_m: Vec3::repeat(0.2),
            ..d
        }));
        let l = d.limits().unwrap();
        assert_eq!((l.max_force_n, l.max_torque_nm), (0.0, 0.0));
    }
}
