//! [`ScaledDevice`]: workspace and force scaling between a physical handle and the virtual world.

use haptic_core::{Device, DeviceLimits, DeviceState, Real, Vec3, Wrench};

use crate::error::DeviceError;

/// Wraps any device so that its handle moves in a scaled copy of its workspace, and the wrenches
/// the virtual world computes are scaled before they reach it.
///
/// Convention, with `s = workspace_scale`, `f = force_scale`, `τ = torque_scale` (`= f` unless
/// set with [`ScaledDevice::with_torque_scale`]) and `o` the scaling origin (device frame origin
/// by default, [`ScaledDevice::with_origin`]):
///
/// - positions: `x_virtual = o + s (x_device − o)`; linear velocities `v_virtual = s v_device`;
/// - orientations and angular velocities pass unchanged (angles are not scaled);
/// - commands: `F_device = f F_virtual`, `T_device = τ T_virtual`;
/// - limits, in virtual units: workspace `o + s (W_device − o)`, `F_max / f`, `T_max / τ`, the
///   same rate; so a wrench within the scaled limits is within the device's.
///
/// The paper's jaws experiment used `s = 0.4`, `f = 2.5`: 10 cm at the handle move the jaw
/// 4 cm, 1 N on the jaw is felt as 2.5 N. With `f = 1/s` the stiffness felt at the handle is
/// the virtual one (`F_device / x_device = f s k = k`).
#[derive(Debug)]
pub struct ScaledDevice<D> {
    inner: D,
    workspace_scale: Real,
    force_scale: Real,
    torque_scale: Real,
    origin_m: Vec3,
}

impl<D: Device> ScaledDevice<D> {
    /// Scales `inner`'s workspace by `workspace_scale` and wrenches by `force_scale`.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] unless both scales are finite and positive.
    pub fn new(inner: D, workspace_scale: Real, force_scale: Real) -> Result<Self, DeviceError> {
        Ok(Self {
            inner,
            workspace_scale: haptic_core::check::positive(
                "scaled.workspace_scale",
                workspace_scale,
            )?,
            force_scale: haptic_core::check::positive("scaled.force_scale", force_scale)?,
            torque_scale: force_scale,
            origin_m: Vec3::zeros(),
        })
    }

    /// Uses another torque scale than the force scale.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] unless it is finite and positive.
    pub fn with_torque_scale(mut self, torque_scale: Real) -> Result<Self, DeviceError> {
        self.torque_scale = haptic_core::check::positive("scaled.torque_scale", torque_scale)?;
        Ok(self)
    }

    /// Scales positions about `origin_m` (device frame, m) instead of the device's origin.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] for a NaN or infinite origin.
    pub fn with_origin(mut self, origin_m: Vec3) -> Result<Self, DeviceError> {
        haptic_core::check::all_finite("scaled.origin_m", origin_m.iter().copied())?;
        self.origin_m = origin_m;
        Ok(self)
    }

    /// The workspace scale `s`.
    pub fn workspace_scale(&self) -> Real {
        self.workspace_scale
    }

    /// The force scale `f`.
    pub fn force_scale(&self) -> Real {
        self.force_scale
    }

    /// The torque scale `τ`.
    pub fn torque_scale(&self) -> Real {
        self.torque_scale
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

    /// A device-frame point in the virtual world.
    pub fn to_virtual_m(&self, device_m: &Vec3) -> Vec3 {
        self.origin_m + (device_m - self.origin_m) * self.workspace_scale
    }

    /// The wrench the device is sent for a virtual wrench.
    pub fn to_device_wrench(&self, w: &Wrench) -> Wrench {
        Wrench::new(w.force * self.force_scale, w.torque * self.torque_scale)
    }
}

impl<D: Device> Device for ScaledDevice<D> {
    type Error = D::Error;

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn limits(&self) -> DeviceLimits {
        let l = self.inner.limits();
        DeviceLimits {
            max_force_n: l.max_force_n / self.force_scale,
            max_torque_nm: l.max_torque_nm / self.torque_scale,
            workspace_min_m: self.to_virtual_m(&l.workspace_min_m),
            workspace_max_m: self.to_virtual_m(&l.workspace_max_m),
            nominal_rate_hz: l.nominal_rate_hz,
        }
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, D::Error> {
        let mut s = self.inner.read(now_s)?;
        s.pose.position = self.to_virtual_m(&s.pose.position);
        s.twist.linear *= self.workspace_scale;
        Ok(s)
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), D::Error> {
        self.inner.command(&self.to_device_wrench(wrench))
    }

    fn command_zero(&mut self) -> Result<(), D::Error> {
        self.inner.command_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hand::{HandDevice, HandParams};
    use crate::scripted::{ScriptedDevice, Waypoint};
    use approx::assert_relative_eq;
    use haptic_core::{Pose, Twist};
    use nalgebra::UnitQuaternion;

    fn limits() -> DeviceLimits {
        DeviceLimits::new(
            4.0,
            0.4,
            Vec3::repeat(-0.1),
            Vec3::new(0.1, 0.1, 0.3),
            1000.0,
        )
        .unwrap()
    }

    fn line() -> ScriptedDevice {
        ScriptedDevice::from_fn_with_twist(
            |t| {
                (
                    Pose {
                        position: Vec3::new(0.1 * t, 0.02, -0.05),
                        orientation: UnitQuaternion::from_scaled_axis(Vec3::new(0.0, 0.0, t)),
                    },
                    Twist {
                        linear: Vec3::new(0.1, 0.0, 0.0),
                        angular: Vec3::new(0.0, 0.0, 1.0),
                    },
                )
            },
            limits(),
        )
    }

    #[test]
    fn poses_velocities_and_limits_scale_consistently() {
        let mut d = ScaledDevice::new(line(), 0.4, 2.5).unwrap();
        let s = d.read(0.5).unwrap();
        assert_relative_eq!(
            s.pose.position,
            Vec3::new(0.02, 0.008, -0.02),
            epsilon = 1e-15
        );
        assert_relative_eq!(s.twist.linear, Vec3::new(0.04, 0.0, 0.0), epsilon = 1e-15);
        assert_relative_eq!(s.pose.orientation.angle(), 0.5, epsilon = 1e-15);
        assert_eq!(s.twist.angular, Vec3::new(0.0, 0.0, 1.0));
        let l = d.limits();
        assert_relative_eq!(l.max_force_n, 1.6, epsilon = 1e-15);
        assert_relative_eq!(l.max_torque_nm, 0.16, epsilon = 1e-15);
        assert_relative_eq!(l.workspace_min_m, Vec3::repeat(-0.04), epsilon = 1e-15);
        assert_relative_eq!(
            l.workspace_max_m,
            Vec3::new(0.04, 0.04, 0.12),
            epsilon = 1e-15
        );
        // A virtual wrench at the scaled limit is at the device's limit.
        d.command(&Wrench::new(
            Vec3::new(1.6, 0.0, 0.0),
            Vec3::new(0.0, 0.16, 0.0),
        ))
        .unwrap();
        let sent = d.inner().last_command();
        assert_relative_eq!(sent.force.x, 4.0, epsilon = 1e-12);
        assert_relative_eq!(sent.torque.y, 0.4, epsilon = 1e-12);
        assert_eq!(
            (d.workspace_scale(), d.force_scale(), d.torque_scale()),
            (0.4, 2.5, 2.5)
        );
    }

    #[test]
    fn origin_and_torque_scale() {
        let o = Vec3::new(0.0, 0.0, 0.1);
        let mut d = ScaledDevice::new(line(), 0.5, 2.0)
            .unwrap()
            .with_origin(o)
            .unwrap()
            .with_torque_scale(1.0)
            .unwrap();
        let s = d.read(0.0).unwrap();
        // (0, 0.02, -0.05) about (0, 0, 0.1) by 0.5: (0, 0.01, 0.025).
        assert_relative_eq!(
            s.pose.position,
            Vec3::new(0.0, 0.01, 0.025),
            epsilon = 1e-15
        );
        assert_eq!(d.to_virtual_m(&o), o);
        d.command(&Wrench::new(Vec3::x(), Vec3::y() * 0.1)).unwrap();
        assert_relative_eq!(d.inner().last_command().force.x, 2.0);
        assert_relative_eq!(d.inner().last_command().torque.y, 0.1);
        assert!(d.with_origin(Vec3::new(Real::NAN, 0.0, 0.0)).is_err());
        for (s, f) in [
            (0.0, 1.0),
            (1.0, -2.0),
            (Real::NAN, 1.0),
            (1.0, Real::INFINITY),
        ] {
            assert!(matches!(
                ScaledDevice::new(line(), s, f),
                Err(DeviceError::Parameter(_))
            ));
        }
        assert!(
            ScaledDevice::new(line(), 1.0, 1.0)
                .unwrap()
                .with_torque_scale(0.0)
                .is_err()
        );
    }

    #[test]
    fn felt_stiffness_is_preserved_with_reciprocal_scales() {
        // A virtual spring k_v = 200 N/m towards the origin, rendered through s = 0.4, f = 2.5
        // on a simulated hand pushed by a constant target offset: the hand settles where the
        // device spring (k_v as seen at the handle) balances its own.
        let rest = Pose::from_position(Vec3::new(0.02, 0.0, 0.0));
        let target =
            ScriptedDevice::from_waypoints(vec![Waypoint::new(0.0, rest)], limits()).unwrap();
        let hand = HandDevice::new(HandParams::default(), target, limits()).unwrap();
        let mut d = ScaledDevice::new(hand, 0.4, 2.5).unwrap();
        let k_v = 200.0;
        let mut s = d.read(0.0).unwrap();
        for n in 1..=5000 {
            d.command(&Wrench::new(-s.pose.position * k_v, Vec3::zeros()))
                .unwrap();
            s = d.read(n as Real * 1e-3).unwrap();
        }
        let k_h = HandParams::default().stiffness_n_per_m;
        let x_device = d.inner_mut().read(5.0).unwrap().pose.position.x;
        // k_h (0.02 − x) = k_v x  ⇒  x = 0.02 k_h / (k_h + k_v), in device units.
        assert_relative_eq!(x_device, 0.02 * k_h / (k_h + k_v), max_relative = 1e-3);
    }
}
