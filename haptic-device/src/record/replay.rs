//! The [`ReplayDevice`]: a recording played back as a device, bit for bit.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3, Wrench};
use nalgebra::UnitQuaternion;

use crate::error::{CsvProblem, DeviceError, finite_time};
use crate::scripted::check_state;

use super::format::*;

/// recorded limits and kept ([`ReplayDevice::last_command`]); they move nothing.
#[derive(Debug, Clone)]
/// Plays a recording back: the same readings at the same times, bit for bit.
///
/// `read(t)` at a recorded `t_s` returns that row's reading exactly. Between two rows it
/// interpolates (position, twist and time stamp linearly, orientation along the shortest arc;
/// buttons of the earlier row). Before the first row and after the last the handle rests at the
/// first or last pose with zero twist, time-stamped `now_s`. Commands are clamped to the
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
