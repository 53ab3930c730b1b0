//! The [`Device`] trait: a haptic (or input-only) device, and its errors ([`Error`], [`ErrorKind`]).

use crate::error::CoreError;
use crate::math::{Real, Vec3};
use crate::state::{DeviceState, Wrench};

/// What a device can do: force and torque limits, workspace, nominal rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceLimits {
    /// Largest force magnitude the device can render (N); 0 for an input-only device.
    pub max_force_n: Real,
    /// Largest torque magnitude the device can render (N m); 0 for none.
    pub max_torque_nm: Real,
    /// Lower corner of the reachable workspace (m, world frame).
    pub workspace_min_m: Vec3,
    /// Upper corner of the reachable workspace (m, world frame).
    pub workspace_max_m: Vec3,
    /// The rate the device is meant to be served at (Hz).
    pub nominal_rate_hz: Real,
}

impl DeviceLimits {
    /// Validated limits.
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] for negative limits, a
    /// non-positive rate or an empty workspace.
    pub fn new(
        max_force_n: Real,
        max_torque_nm: Real,
        workspace_min_m: Vec3,
        workspace_max_m: Vec3,
        nominal_rate_hz: Real,
    ) -> Result<Self, CoreError> {
        use crate::check;
        check::non_negative("limits.max_force_n", max_force_n)?;
        check::non_negative("limits.max_torque_nm", max_torque_nm)?;
        check::positive("limits.nominal_rate_hz", nominal_rate_hz)?;
        check::all_finite(
            "limits.workspace",
            workspace_min_m
                .iter()
                .chain(workspace_max_m.iter())
                .copied(),
        )?;
        if (0..3).any(|i| workspace_min_m[i] >= workspace_max_m[i]) {
            return Err(CoreError::OutOfRange {
                what: "limits.workspace",
                value: (workspace_max_m - workspace_min_m).min(),
                expected: "min < max on every axis",
            });
        }
        Ok(Self {
            max_force_n,
            max_torque_nm,
            workspace_min_m,
            workspace_max_m,
            nominal_rate_hz,
        })
    }

    /// Clamps a wrench to the limits, keeping directions. Returns the clamped wrench and whether
    /// anything was clamped. A non-finite wrench becomes zero (and counts as clamped).
    pub fn saturate(&self, w: &Wrench) -> (Wrench, bool) {
        if !w.is_finite() {
            return (Wrench::zero(), true);
        }
        let mut out = *w;
        let mut clamped = false;
        let f = w.force.norm();
        if f > self.max_force_n {
            out.force = clamp_norm(&w.force, f, self.max_force_n);
            clamped = true;
        }
        let t = w.torque.norm();
        if t > self.max_torque_nm {
            out.torque = clamp_norm(&w.torque, t, self.max_torque_nm);
            clamped = true;
        }
        (out, clamped)
    }

    /// Whether a wrench is finite and within the limits (with a relative slack of 1e-12).
    pub fn admits(&self, w: &Wrench) -> bool {
        w.is_finite()
            && w.force.norm() <= self.max_force_n * (1.0 + 1e-12)
            && w.torque.norm() <= self.max_torque_nm * (1.0 + 1e-12)
    }
}

/// A haptic device, or an input-only device that reports zero force capability.
///
/// The runtime calls [`Device::read`] once per haptic period, then [`Device::command`] with the
/// wrench to render at the handle (force in N, torque in N m, world frame). `now_s` is the
/// runtime's clock (wall time in real-time mode, simulated time in deterministic mode), so a
/// simulated device can advance to it and a real one can time-stamp with it.
///
/// Contract for implementers:
/// - Every operation that touches hardware is fallible; errors say their
///   [`ErrorKind`] (disconnected, timeout, …) through [`Error::kind`].
/// - `command` must never render more than [`Device::limits`]; callers saturate before sending,
///   and a device should clamp too.
/// - `command_zero` must work whenever the device is reachable: it is the safe state.
/// - `read` and `command` are called from the haptic thread: no allocation, no blocking I/O
///   beyond the device transaction itself.
/// - Configuration (opening, calibration) stays out of the trait, in constructors.
pub trait Device {
    /// The device's error type.
    type Error: Error;

    /// A human-readable name.
    fn name(&self) -> &str;

    /// Limits of the device.
    fn limits(&self) -> DeviceLimits;

    /// Reads the handle's state at time `now_s` (s).
    ///
    /// # Errors
    /// Device specific; a NaN pose must be an error of kind `InvalidData`, not a value.
    fn read(&mut self, now_s: Real) -> Result<DeviceState, Self::Error>;

    /// Commands a wrench at the handle.
    ///
    /// # Errors
    /// Device specific.
    fn command(&mut self, wrench: &Wrench) -> Result<(), Self::Error>;

    /// Commands zero force and torque: the safe state.
    ///
    /// # Errors
    /// As [`Device::command`].
    fn command_zero(&mut self) -> Result<(), Self::Error> {
        self.command(&Wrench::zero())
    }
}

impl<D: Device + ?Sized> Device for &mut D {
    type Error = D::Error;
    fn name(&self) -> &str {
        (**self).name()
    }
    fn limits(&self) -> DeviceLimits {
        (**self).limits()
    }
    fn read(&mut self, now_s: Real) -> Result<DeviceState, Self::Error> {
        (**self).read(now_s)
    }
    fn command(&mut self, wrench: &Wrench) -> Result<(), Self::Error> {
        (**self).command(wrench)
    }
    fn command_zero(&mut self) -> Result<(), Self::Error> {
        (**self).command_zero()
    }
}

impl<D: Device + ?Sized> Device for Box<D> {
    type Error = D::Error;
    fn name(&self) -> &str {
        (**self).name()
    }
    fn limits(&self) -> DeviceLimits {
        (**self).limits()
    }
    fn read(&mut self, now_s: Real) -> Result<DeviceState, Self::Error> {
        (**self).read(now_s)
    }
    fn command(&mut self, wrench: &Wrench) -> Result<(), Self::Error> {
        (**self).command(wrench)
    }
    fn command_zero(&mut self) -> Result<(), Self::Error> {
        (**self).command_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> DeviceLimits {
        DeviceLimits::new(5.0, 0.5, Vec3::repeat(-0.1), Vec3::repeat(0.1), 1000.0).unwrap()
    }

    #[test]
    fn limits_reject_bad_input() {
        let lo = Vec3::repeat(-0.1);
        let hi = Vec3::repeat(0.1);
        assert!(matches!(
            DeviceLimits::new(-1.0, 0.5, lo, hi, 1000.0),
            Err(CoreError::OutOfRange {
                what: "limits.max_force_n",
                ..
            })
        ));
        assert!(matches!(
            DeviceLimits::new(1.0, -0.5, lo, hi, 1000.0),
            Err(CoreError::OutOfRange {
                what: "limits.max_torque_nm",
                ..
            })
        ));
        assert!(matches!(
            DeviceLimits::new(1.0, 0.5, lo, hi, 0.0),
            Err(CoreError::OutOfRange {
                what: "limits.nominal_rate_hz",
                ..
            })
        ));
        assert!(matches!(
            DeviceLimits::new(Real::NAN, 0.5, lo, hi, 1000.0),
            Err(CoreError::NonFinite {
                what: "limits.max_force_n"
            })
        ));
        assert!(matches!(
            DeviceLimits::new(1.0, 0.5, hi, lo, 1000.0),
            Err(CoreError::OutOfRange {
                what: "limits.workspace",
                ..
            })
        ));
        assert!(matches!(
            DeviceLimits::new(1.0, 0.5, lo, Vec3::new(Real::NAN, 0.0, 0.0), 1000.0),
            Err(CoreError::NonFinite {
                what: "limits.workspace"
            })
        ));
    }

    #[test]
    fn saturate_clamps_and_zeroes_nan() {
        let l = limits();
        let (w, c) = l.saturate(&Wrench::new(Vec3::new(10.0, 0.0, 0.0), Vec3::zeros()));
        assert!(c && (w.force.norm() - 5.0).abs() < 1e-12 && l.admits(&w));
        let (w, c) = l.saturate(&Wrench::new(
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.1),
        ));
        assert!(!c && w.force.x == 1.0);
        let (w, c) = l.saturate(&Wrench::new(Vec3::new(Real::NAN, 0.0, 0.0), Vec3::zeros()));
        assert!(c && w == Wrench::zero());
    }

    #[test]
    fn saturated_wrenches_never_exceed_the_limits_by_rounding() {
        // Many directions and magnitudes: the clamped norm is never above the limit, not even
        // by an ulp (plain scaling by max / norm exceeds it on some of these).
        let l = limits();
        let mut x: u64 = 0x2545_F491_4F6C_DD1D;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as Real / (1u64 << 53) as Real - 0.5
        };
        let mut plain_over = 0;
        for _ in 0..20_000 {
            let v = Vec3::new(next(), next(), next()) * (1.0 + 1e3 * next().abs());
            if v.norm() <= l.max_force_n {
                continue;
            }
            plain_over += usize::from((v * (l.max_force_n / v.norm())).norm() > l.max_force_n);
            let (w, c) = l.saturate(&Wrench::new(v, v));
            assert!(c);
            assert!(w.force.norm() <= l.max_force_n, "{}", w.force.norm());
            assert!(w.torque.norm() <= l.max_torque_nm, "{}", w.torque.norm());
            assert!((w.force.norm() / l.max_force_n - 1.0).abs() < 1e-14);
            assert!((w.force.normalize() - v.normalize()).norm() < 1e-14);
        }
        assert!(
            plain_over > 0,
            "the test never met the rounding it guards against"
        );
    }
}

/// `v` (of norm `norm > max`) scaled to norm `max` or just below: `v · (max / norm)` can come
/// out an ulp or two above `max` by rounding (a spoon pressed into a cup was sent
/// 10.000000000000002 N against a 10 N limit), so the scale is lowered by an ulp until it is not.
fn clamp_norm(v: &Vec3, norm: Real, max: Real) -> Vec3 {
    if norm.is_nan() || norm <= 0.0 {
        return Vec3::zeros();
    }
    let mut scale = max / norm;
    for _ in 0..8 {
        let out = v * scale;
        if out.norm() <= max {
            return out;
        }
        scale *= 1.0 - Real::EPSILON;
    }
    v * (scale * 0.5)
}

/// What went wrong with a device, independent of the device's own error type.
///
/// Modelled on `embedded-hal`'s `ErrorKind`: every device error maps to one kind, so generic code
/// (the runtime) can react without knowing the concrete device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The device was unplugged or its handle closed.
    Disconnected,
    /// The device did not answer in time.
    Timeout,
    /// No device was found to open.
    NotFound,
    /// The device sent data that could not be understood (a bad report, a NaN pose).
    InvalidData,
    /// The device rejected a command.
    CommandRejected,
    /// Anything else.
    Other,
}

/// An error reported by a [`Device`]: any error type that can say its [`ErrorKind`] (as
/// `embedded_hal::digital::Error` does).
///
/// Implement it for your device's error type; generic code calls `e.kind()` with this trait in
/// scope (`use haptic_core::device::Error as _;`).
pub trait Error: std::error::Error + Send + Sync + 'static {
    /// The kind of failure, for generic handling.
    fn kind(&self) -> ErrorKind;
}

/// A ready-made device error for implementers who need nothing more specific.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("device error: {kind:?}: {message}")]
pub struct DeviceFault {
    /// The kind of failure.
    pub kind: ErrorKind,
    /// Human-readable detail.
    pub message: String,
}

impl DeviceFault {
    /// A fault of the given kind with a message.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
}

impl Error for DeviceFault {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

impl Error for std::convert::Infallible {
    fn kind(&self) -> ErrorKind {
        match *self {}
    }
}
