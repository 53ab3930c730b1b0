//! [`SaturatingDevice`]: clamps every command to the device's limits, and counts the clamps.

use haptic_core::{Device, DeviceLimits, DeviceState, Real, Wrench};

/// Wraps any device so that a wrench beyond its limits (force or torque magnitude, or not
/// finite) is clamped before it is sent, keeping its direction (a non-finite wrench becomes
/// zero), and each clamped command is counted.
#[derive(Debug)]
pub struct SaturatingDevice<D> {
    inner: D,
    clamp_count: u64,
    commands: u64,
}

impl<D: Device> SaturatingDevice<D> {
    /// Wraps `inner`.
    pub fn new(inner: D) -> Self {
        Self {
            inner,
            clamp_count: 0,
            commands: 0,
        }
    }

    /// How many commands were clamped.
    pub fn clamp_count(&self) -> u64 {
        self.clamp_count
    }

    /// How many commands were sent (zero commands included).
    pub fn command_count(&self) -> u64 {
        self.commands
    }

    /// The wrapped device.
    pub fn inner(&self) -> &D {
        &self.inner
    }

    /// The wrapped device, mutably.
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.inner
    }

    /// Unwraps the device.
    pub fn into_inner(self) -> D {
        self.inner
    }
}

impl<D: Device> Device for SaturatingDevice<D> {
    type Error = D::Error;

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, D::Error> {
        self.inner.read(now_s)
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), D::Error> {
        let (w, clamped) = self.inner.limits().saturate(wrench);
        if clamped {
            self.clamp_count += 1;
        }
        self.commands += 1;
        self.inner.command(&w)
    }

    fn command_zero(&mut self) -> Result<(), D::Error> {
        self.commands += 1;
        self.inner.command_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scripted::ScriptedDevice;
    use approx::assert_relative_eq;
    use haptic_core::{Pose, Vec3};

    /// A device that keeps whatever it is sent, unclamped, to see what reaches it.
    struct Raw {
        last: Wrench,
        limits: DeviceLimits,
    }

    impl Device for Raw {
        type Error = std::convert::Infallible;
        fn name(&self) -> &str {
            "raw"
        }
        fn limits(&self) -> DeviceLimits {
            self.limits
        }
        fn read(&mut self, now_s: Real) -> Result<DeviceState, Self::Error> {
            Ok(DeviceState::at_rest(Pose::identity(), now_s))
        }
        fn command(&mut self, wrench: &Wrench) -> Result<(), Self::Error> {
            self.last = *wrench;
            Ok(())
        }
    }

    fn limits() -> DeviceLimits {
        DeviceLimits::new(3.0, 0.3, Vec3::repeat(-0.1), Vec3::repeat(0.1), 1000.0).unwrap()
    }

    #[test]
    fn clamps_before_sending_and_counts() {
        let mut d = SaturatingDevice::new(Raw {
            last: Wrench::zero(),
            limits: limits(),
        });
        let inside = Wrench::new(Vec3::new(1.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 0.2));
        d.command(&inside).unwrap();
        assert_eq!(d.inner().last, inside);
        assert_eq!(d.clamp_count(), 0);
        let f = Vec3::new(6.0, 8.0, 0.0);
        d.command(&Wrench::new(f, Vec3::zeros())).unwrap();
        let sent = d.inner().last;
        assert_relative_eq!(sent.force, f * 0.3, epsilon = 1e-12);
        assert!(limits().admits(&sent));
        assert_eq!(d.clamp_count(), 1);
        // Torque alone, then NaN.
        d.command(&Wrench::new(Vec3::zeros(), Vec3::new(0.0, -1.0, 0.0)))
            .unwrap();
        assert_relative_eq!(d.inner().last.torque.y, -0.3, epsilon = 1e-12);
        d.command(&Wrench::new(Vec3::new(Real::NAN, 0.0, 0.0), Vec3::zeros()))
            .unwrap();
        assert_eq!(d.inner().last, Wrench::zero());
        assert_eq!(d.clamp_count(), 3);
        d.command_zero().unwrap();
        assert_eq!((d.clamp_count(), d.command_count()), (3, 5));
        assert_eq!(d.name(), "raw");
        assert_eq!(d.read(0.5).unwrap().timestamp_s, 0.5);
        let _ = d.inner_mut();
        assert_eq!(d.into_inner().last, Wrench::zero());
    }

    #[test]
    fn an_input_only_device_gets_zero() {
        let zero =
            DeviceLimits::new(0.0, 0.0, Vec3::repeat(-0.1), Vec3::repeat(0.1), 60.0).unwrap();
        let mut d =
            SaturatingDevice::new(ScriptedDevice::stationary(Pose::identity(), zero).unwrap());
        d.command(&Wrench::new(Vec3::x(), Vec3::y())).unwrap();
        assert_eq!(d.inner().last_command(), Wrench::zero());
        assert_eq!(d.clamp_count(), 1);
    }
}
