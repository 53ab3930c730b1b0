//! The crate's error type, [`DeviceError`], and what each variant means to the runtime.

use haptic_core::{CoreError, Real, device::ErrorKind};

use crate::spacemouse::ReportError;

/// What is wrong with one line of a recording (see [`crate::record`] for the format).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CsvProblem {
    /// The file has no column header line.
    #[error("no column header line")]
    MissingHeader,
    /// The column header is not the one this version writes.
    #[error("unexpected column header (expected `{expected}`)")]
    BadHeader {
        /// The header this version writes and reads.
        expected: &'static str,
    },
    /// A metadata line (`# key = value`) the format requires is absent.
    #[error("missing metadata `# {key} = …` before the column header")]
    MissingMetadata {
        /// The key.
        key: &'static str,
    },
    /// A metadata value could not be read.
    #[error("bad value for metadata `{key}`")]
    BadMetadata {
        /// The key.
        key: &'static str,
    },
    /// The recording was written by another format version.
    #[error("unsupported format version {found}")]
    UnsupportedVersion {
        /// The version found.
        found: u32,
    },
    /// A row has too few (or too many) columns.
    #[error("expected {expected} columns, found {found}")]
    ColumnCount {
        /// Number of columns of the format.
        expected: usize,
        /// Number found on the line.
        found: usize,
    },
    /// A field is not a number.
    #[error("column `{column}` is not a number")]
    NotANumber {
        /// Column name.
        column: &'static str,
    },
    /// A field is NaN or infinite.
    #[error("column `{column}` is not finite")]
    NonFinite {
        /// Column name.
        column: &'static str,
    },
    /// The orientation quaternion of a row is not unit.
    #[error("orientation quaternion has norm {norm}, expected 1")]
    NonUnitQuaternion {
        /// The norm found.
        norm: Real,
    },
    /// `t_s` does not increase strictly from the previous row.
    #[error("time {t_s} s does not increase (previous row at {previous_s} s)")]
    TimeNotIncreasing {
        /// Time of the previous row (s).
        previous_s: Real,
        /// Time of this row (s).
        t_s: Real,
    },
    /// The recording holds no sample at all.
    #[error("the recording holds no sample")]
    NoSamples,
    /// The metadata describe impossible device limits.
    #[error("invalid device limits in metadata: {0}")]
    Limits(CoreError),
}

/// Every error of this crate's devices.
///
/// Each variant maps to one [`ErrorKind`] through [`haptic_core::device::Error::kind`], which
/// is what the runtime reacts to:
///
/// | variant | kind | runtime reaction |
/// |---|---|---|
/// | [`Disconnected`](Self::Disconnected) | `Disconnected` | stop the run |
/// | [`Timeout`](Self::Timeout) | `Timeout` | stop the run |
/// | [`NotFound`](Self::NotFound) | `NotFound` | (constructors only) |
/// | [`NonFinite`](Self::NonFinite), [`Report`](Self::Report), [`Csv`](Self::Csv) | `InvalidData` | zero force this period, go on |
/// | anything else | `Other` | stop the run |
///
/// A device whose reading would contain NaN or Inf returns [`DeviceError::NonFinite`] instead
/// of the reading, as the `Device::read` contract asks.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// The device was unplugged, its handle closed, or a [`crate::FaultInjector`] simulates it.
    #[error("device disconnected: {detail}")]
    Disconnected {
        /// What was observed.
        detail: String,
    },
    /// The device stopped answering.
    #[error("device did not answer (stalled for {stalled_s} s so far)")]
    Timeout {
        /// How long it has been silent, on the caller's clock (s).
        stalled_s: Real,
    },
    /// No device was found to open.
    #[error("no device found: {detail}")]
    NotFound {
        /// What was looked for.
        detail: String,
    },
    /// A reading (pose, twist, time stamp) or a trajectory sample was NaN or infinite.
    #[error("device produced a non-finite {what}")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
    },
    /// A HID report could not be parsed.
    #[error("bad HID report: {0}")]
    Report(#[from] ReportError),
    /// A recording could not be read: what is wrong, and on which line (1-based).
    #[error("recording line {line}: {problem}")]
    Csv {
        /// 1-based line number in the file.
        line: usize,
        /// What is wrong.
        problem: CsvProblem,
    },
    /// Reading or writing a recording failed.
    #[error("I/O error while {context}: {source}")]
    Io {
        /// What was being done.
        context: &'static str,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A trajectory given as waypoints has none.
    #[error("a trajectory needs at least one waypoint")]
    NoWaypoints,
    /// A waypoint has a non-finite time or pose, or a non-unit orientation.
    #[error("waypoint {index} is not finite or not normalised")]
    BadWaypoint {
        /// Index of the waypoint.
        index: usize,
    },
    /// Waypoint times do not increase strictly.
    #[error("waypoint {index} at {t_s} s does not come after the previous one at {previous_s} s")]
    WaypointTimeNotIncreasing {
        /// Index of the offending waypoint.
        index: usize,
        /// Time of the previous waypoint (s).
        previous_s: Real,
        /// Time of this waypoint (s).
        t_s: Real,
    },
    /// A parameter (a gain, a scale, the device limits, ...) is not finite or out of range: see
    /// [`haptic_core::check`], which names it by its field path.
    #[error("invalid parameter: {0}")]
    Parameter(#[from] CoreError),
    /// The caller's clock was NaN or infinite.
    #[error("read time {now_s} s is not finite")]
    BadTime {
        /// The time given (s).
        now_s: Real,
    },
    /// A device with internal dynamics, or a recorder, was read at a time before its previous
    /// reading (or, for a recorder, not after it).
    #[error("read at {now_s} s after a read at {previous_s} s: time must not go back")]
    TimeWentBack {
        /// Time of the previous read (s).
        previous_s: Real,
        /// Time of this read (s).
        now_s: Real,
    },
    /// The HID layer failed (enumeration, opening); the message is hidapi's.
    #[error("HID error while {operation}: {message}")]
    Hid {
        /// What was being done.
        operation: &'static str,
        /// hidapi's message.
        message: String,
    },
    /// An error of a wrapped device whose error type is not this one; its kind is kept.
    #[error("{source}")]
    Inner {
        /// The wrapped error's kind.
        kind: ErrorKind,
        /// The wrapped error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
}

impl DeviceError {
    /// Converts any device's error into this type, keeping its kind. An error that already is a
    /// [`DeviceError`] is returned unchanged (not nested).
    pub fn from_device<E: haptic_core::device::Error>(e: E) -> Self {
        let kind = e.kind();
        let boxed: Box<dyn std::error::Error + Send + Sync + 'static> = Box::new(e);
        match boxed.downcast::<DeviceError>() {
            Ok(own) => *own,
            Err(source) => Self::Inner { kind, source },
        }
    }

    /// A CSV error at `line`.
    pub(crate) fn csv(line: usize, problem: CsvProblem) -> Self {
        Self::Csv { line, problem }
    }
}

impl haptic_core::device::Error for DeviceError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Disconnected { .. } => ErrorKind::Disconnected,
            Self::Timeout { .. } => ErrorKind::Timeout,
            Self::NotFound { .. } => ErrorKind::NotFound,
            Self::NonFinite { .. } | Self::Report(_) | Self::Csv { .. } => ErrorKind::InvalidData,
            Self::Inner { kind, .. } => *kind,
            Self::Io { .. }
            | Self::NoWaypoints
            | Self::BadWaypoint { .. }
            | Self::WaypointTimeNotIncreasing { .. }
            | Self::Parameter(_)
            | Self::BadTime { .. }
            | Self::TimeWentBack { .. }
            | Self::Hid { .. } => ErrorKind::Other,
        }
    }
}

/// Checks that a read time is finite.
pub(crate) fn finite_time(now_s: Real) -> Result<Real, DeviceError> {
    if now_s.is_finite() {
        Ok(now_s)
    } else {
        Err(DeviceError::BadTime { now_s })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use haptic_core::{DeviceFault, device::Error as _};

    #[test]
    fn kinds_follow_the_table() {
        let k = |e: DeviceError| e.kind();
        assert_eq!(
            k(DeviceError::Disconnected { detail: "x".into() }),
            ErrorKind::Disconnected
        );
        assert_eq!(
            k(DeviceError::Timeout { stalled_s: 0.1 }),
            ErrorKind::Timeout
        );
        assert_eq!(
            k(DeviceError::NotFound { detail: "x".into() }),
            ErrorKind::NotFound
        );
        assert_eq!(
            k(DeviceError::NonFinite { what: "pose" }),
            ErrorKind::InvalidData
        );
        assert_eq!(
            k(DeviceError::csv(3, CsvProblem::NoSamples)),
            ErrorKind::InvalidData
        );
        assert_eq!(k(DeviceError::NoWaypoints), ErrorKind::Other);
    }

    #[test]
    fn from_device_keeps_kind_and_does_not_nest() {
        let own = DeviceError::from_device(DeviceError::Timeout { stalled_s: 2.0 });
        assert!(matches!(own, DeviceError::Timeout { stalled_s } if stalled_s == 2.0));
        let foreign = DeviceError::from_device(DeviceFault::new(ErrorKind::CommandRejected, "no"));
        assert_eq!(foreign.kind(), ErrorKind::CommandRejected);
        assert!(matches!(foreign, DeviceError::Inner { .. }));
        assert!(foreign.to_string().contains("no"));
    }

    #[test]
    fn parameter_checks() {
        assert!(finite_time(1.0).is_ok());
        assert!(matches!(
            finite_time(Real::NAN),
            Err(DeviceError::BadTime { .. })
        ));
    }
}
