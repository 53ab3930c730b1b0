//! [`ScriptedDevice`]: an open-loop handle that follows a trajectory, given as waypoints joined by
//! minimum-jerk segments or as a function of time.

use std::fmt;

use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3, Wrench};
use nalgebra::UnitQuaternion;

use crate::error::{DeviceError, finite_time};

/// Tolerance on `| |q| - 1 |` for waypoint orientations.
const UNIT_TOL: Real = 1e-9;

/// Half-width of the central difference that gives the twist of a [`ScriptedDevice::from_fn`]
/// trajectory (s).
pub const FN_TWIST_STEP_S: Real = 1e-5;

/// A pose to pass through at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoint {
    /// When to be there (s).
    pub t_s: Real,
    /// Where to be.
    pub pose: Pose,
}

impl Waypoint {
    /// A waypoint at `t_s` (s).
    pub fn new(t_s: Real, pose: Pose) -> Self {
        Self { t_s, pose }
    }
}

/// The minimum-jerk profile `p(s) = 10 s³ − 15 s⁴ + 6 s⁵` on `s ∈ [0, 1]` and its first two
/// derivatives with respect to `s`. Zero velocity and acceleration at both ends (Flash & Hogan
/// 1985).
#[inline]
pub fn min_jerk(s: Real) -> (Real, Real, Real) {
    let s = s.clamp(0.0, 1.0);
    let s2 = s * s;
    let s3 = s2 * s;
    let p = s3 * (10.0 + s * (-15.0 + 6.0 * s));
    let dp = 30.0 * s2 * (1.0 - s) * (1.0 - s);
    let ddp = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s);
    (p, dp, ddp)
}

/// The largest `|p''(s)|` of [`min_jerk`]: `10/√3`, reached at `s = 1/2 ∓ √3/6`.
pub const MIN_JERK_PEAK_ACCEL: Real = 5.773_502_691_896_258;

/// One segment between two waypoints, with what its evaluation needs precomputed.
#[derive(Debug, Clone, Copy)]
struct Segment {
    t0_s: Real,
    duration_s: Real,
    x0: Vec3,
    dx: Vec3,
    q0: UnitQuaternion<Real>,
    /// Rotation vector from `q0` to `q1`, in `q0`'s frame (shortest arc).
    rot_body: Vec3,
    /// The same in the world frame: `R(q0) rot_body`.
    rot_world: Vec3,
}

impl Segment {
    fn new(a: &Waypoint, b: &Waypoint) -> Self {
        let rel = a.pose.orientation.inverse() * b.pose.orientation;
        let rot_body = rel.scaled_axis();
        Self {
            t0_s: a.t_s,
            duration_s: b.t_s - a.t_s,
            x0: a.pose.position,
            dx: b.pose.position - a.pose.position,
            q0: a.pose.orientation,
            rot_body,
            rot_world: a.pose.orientation * rot_body,
        }
    }

    fn eval(&self, t_s: Real) -> (Pose, Twist) {
        let (p, dp, _) = min_jerk((t_s - self.t0_s) / self.duration_s);
        let rate = dp / self.duration_s;
        let pose = Pose {
            position: self.x0 + self.dx * p,
            orientation: self.q0 * UnitQuaternion::from_scaled_axis(self.rot_body * p),
        };
        let twist = Twist {
            linear: self.dx * rate,
            angular: self.rot_world * rate,
        };
        (pose, twist)
    }
}

enum Source {
    Waypoints {
        first: Pose,
        last: Pose,
        t_first_s: Real,
        t_last_s: Real,
        segments: Vec<Segment>,
    },
    Function(Box<dyn FnMut(Real) -> Pose + Send + 'static>),
    FunctionWithTwist(Box<dyn FnMut(Real) -> (Pose, Twist) + Send + 'static>),
}

/// An open-loop device: the handle follows a trajectory whatever force it is commanded.
///
/// - [`ScriptedDevice::from_waypoints`]: poses at given times, joined by minimum-jerk segments
///   (position along the straight line, orientation along the shortest great arc, both with the
///   profile of [`min_jerk`]); the twist is the analytic derivative. Before the first waypoint
///   the handle rests at the first pose, after the last at the last pose.
/// - [`ScriptedDevice::from_fn`]: any `t ↦ pose`; the twist is a central difference with
///   half-width [`FN_TWIST_STEP_S`].
/// - [`ScriptedDevice::from_fn_with_twist`]: any `t ↦ (pose, twist)`.
///
/// Commands are clamped to the limits and kept ([`ScriptedDevice::last_command`]) but move
/// nothing. The pose is not clamped to the workspace: a script is trusted.
///
/// A reading depends only on `now_s` (and, for a stateful function, on the call sequence), so
/// runs are reproducible bit for bit.
pub struct ScriptedDevice {
    source: Source,
    limits: DeviceLimits,
    last_command: Wrench,
    name: String,
}

impl fmt::Debug for ScriptedDevice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match &self.source {
            Source::Waypoints { segments, .. } => format!("{} segments", segments.len()),
            Source::Function(_) => "function".to_owned(),
            Source::FunctionWithTwist(_) => "function with twist".to_owned(),
        };
        f.debug_struct("ScriptedDevice")
            .field("name", &self.name)
            .field("source", &kind)
            .field("limits", &self.limits)
            .finish_non_exhaustive()
    }
}

impl ScriptedDevice {
    /// A handle through `waypoints`, joined by minimum-jerk segments.
    ///
    /// # Errors
    /// [`DeviceError::NoWaypoints`] for an empty list, [`DeviceError::BadWaypoint`] for a NaN or
    /// infinite time or pose or a non-unit orientation, and
    /// [`DeviceError::WaypointTimeNotIncreasing`] when times do not increase strictly.
    pub fn from_waypoints(
        waypoints: Vec<Waypoint>,
        limits: DeviceLimits,
    ) -> Result<Self, DeviceError> {
        let (first, last) = match (waypoints.first(), waypoints.last()) {
            (Some(f), Some(l)) => (*f, *l),
            _ => return Err(DeviceError::NoWaypoints),
        };
        for (index, w) in waypoints.iter().enumerate() {
            let norm = w.pose.orientation.as_ref().norm();
            if !w.t_s.is_finite() || !w.pose.is_finite() || (norm - 1.0).abs() > UNIT_TOL {
                return Err(DeviceError::BadWaypoint { index });
            }
            if index > 0 && w.t_s <= waypoints[index - 1].t_s {
                return Err(DeviceError::WaypointTimeNotIncreasing {
                    index,
                    previous_s: waypoints[index - 1].t_s,
                    t_s: w.t_s,
                });
            }
        }
        let segments = waypoints
            .windows(2)
            .map(|w| Segment::new(&w[0], &w[1]))
            .collect();
        Ok(Self {
            source: Source::Waypoints {
                first: first.pose,
                last: last.pose,
                t_first_s: first.t_s,
                t_last_s: last.t_s,
                segments,
            },
            limits,
            last_command: Wrench::zero(),
            name: "scripted (waypoints)".to_owned(),
        })
    }

    /// A handle that rests at `pose` for ever.
    pub fn stationary(pose: Pose, limits: DeviceLimits) -> Result<Self, DeviceError> {
        Self::from_waypoints(vec![Waypoint::new(0.0, pose)], limits)
    }

    /// A handle at `f(t)`. The twist is the central difference `(f(t+h) − f(t−h)) / 2h` with
    /// `h =` [`FN_TWIST_STEP_S`] (for the orientation, the rotation vector of
    /// `q(t+h) q(t−h)⁻¹` over `2h`), so every read calls `f` three times, in the order `t`,
    /// `t − h`, `t + h`.
    pub fn from_fn(f: impl FnMut(Real) -> Pose + Send + 'static, limits: DeviceLimits) -> Self {
        Self {
            source: Source::Function(Box::new(f)),
            limits,
            last_command: Wrench::zero(),
            name: "scripted (function)".to_owned(),
        }
    }

    /// A handle at `f(t).0` with twist `f(t).1` (one call per read).
    pub fn from_fn_with_twist(
        f: impl FnMut(Real) -> (Pose, Twist) + Send + 'static,
        limits: DeviceLimits,
    ) -> Self {
        Self {
            source: Source::FunctionWithTwist(Box::new(f)),
            limits,
            last_command: Wrench::zero(),
            name: "scripted (function)".to_owned(),
        }
    }

    /// Renames the device (the name shows in listings and recordings).
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// The time span `[first, last]` of a waypoint trajectory (s); `None` for a function.
    pub fn time_span_s(&self) -> Option<(Real, Real)> {
        match &self.source {
            Source::Waypoints {
                t_first_s,
                t_last_s,
                ..
            } => Some((*t_first_s, *t_last_s)),
            _ => None,
        }
    }

    /// The last command received, clamped to the limits.
    pub fn last_command(&self) -> Wrench {
        self.last_command
    }

    /// Pose and twist at `t_s`, without the checks of [`Device::read`].
    pub fn sample(&mut self, t_s: Real) -> (Pose, Twist) {
        match &mut self.source {
            Source::Waypoints {
                first,
                last,
                t_first_s,
                t_last_s,
                segments,
            } => {
                if t_s < *t_first_s || segments.is_empty() {
                    (*first, Twist::zero())
                } else if t_s >= *t_last_s {
                    (*last, Twist::zero())
                } else {
                    // The segment with t0 <= t < t1: the last one starting at or before t.
                    let i = segments.partition_point(|s| s.t0_s <= t_s) - 1;
                    segments[i].eval(t_s)
                }
            }
            Source::Function(f) => {
                let h = FN_TWIST_STEP_S;
                let pose = f(t_s);
                let before = f(t_s - h);
                let after = f(t_s + h);
                let twist = Twist {
                    linear: (after.position - before.position) / (2.0 * h),
                    angular: (after.orientation * before.orientation.inverse()).scaled_axis()
                        / (2.0 * h),
                };
                (pose, twist)
            }
            Source::FunctionWithTwist(f) => f(t_s),
        }
    }
}

/// Checks a reading before it leaves a device: a NaN must be an error, not a value.
pub(crate) fn check_state(state: DeviceState) -> Result<DeviceState, DeviceError> {
    if !state.pose.is_finite() {
        Err(DeviceError::NonFinite { what: "pose" })
    } else if !state.twist.is_finite() {
        Err(DeviceError::NonFinite { what: "twist" })
    } else if !state.timestamp_s.is_finite() {
        Err(DeviceError::NonFinite { what: "time stamp" })
    } else {
        Ok(state)
    }
}

impl Device for ScriptedDevice {
    type Error = DeviceError;

    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        let (pose, twist) = self.sample(now_s);
        check_state(DeviceState {
            pose,
            twist,
            buttons: 0,
            timestamp_s: now_s,
        })
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        self.last_command = self.limits.saturate(wrench).0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    pub(crate) fn limits() -> DeviceLimits {
        DeviceLimits::new(5.0, 0.5, Vec3::repeat(-0.2), Vec3::repeat(0.2), 1000.0).unwrap()
    }

    fn pose(x: Real, y: Real, z: Real, axis: Vec3, angle: Real) -> Pose {
        Pose {
            position: Vec3::new(x, y, z),
            orientation: UnitQuaternion::from_scaled_axis(axis.normalize() * angle),
        }
    }

    fn three() -> Vec<Waypoint> {
        vec![
            Waypoint::new(0.5, pose(0.0, 0.0, 0.0, Vec3::z(), 0.0)),
            Waypoint::new(1.5, pose(0.1, -0.05, 0.02, Vec3::new(1.0, 1.0, 0.0), 0.8)),
            Waypoint::new(2.0, pose(0.1, 0.05, 0.0, Vec3::new(0.0, 1.0, 1.0), -0.4)),
        ]
    }

    #[test]
    fn min_jerk_profile_shape() {
        assert_eq!(min_jerk(0.0), (0.0, 0.0, 0.0));
        let (p, dp, ddp) = min_jerk(1.0);
        assert_relative_eq!(p, 1.0, epsilon = 1e-15);
        assert_eq!((dp, ddp), (0.0, 0.0));
        let (p, dp, ddp) = min_jerk(0.5);
        assert_relative_eq!(p, 0.5, epsilon = 1e-15);
        assert_relative_eq!(dp, 1.875, epsilon = 1e-15);
        assert_relative_eq!(ddp, 0.0, epsilon = 1e-15);
        let s = 0.5 - 3.0_f64.sqrt() / 6.0;
        assert_relative_eq!(min_jerk(s).2, MIN_JERK_PEAK_ACCEL, epsilon = 1e-12);
        // The derivatives are those of the polynomial.
        for i in 1..100 {
            let s = i as Real / 100.0;
            let h = 1e-6;
            let fd = (min_jerk(s + h).0 - min_jerk(s - h).0) / (2.0 * h);
            let fd2 = (min_jerk(s + h).1 - min_jerk(s - h).1) / (2.0 * h);
            assert!((fd - min_jerk(s).1).abs() < 1e-8);
            assert!((fd2 - min_jerk(s).2).abs() < 1e-7);
            assert!(min_jerk(s).2.abs() <= MIN_JERK_PEAK_ACCEL + 1e-12);
        }
    }

    #[test]
    fn waypoints_are_hit_exactly_and_held_outside() {
        let w = three();
        let mut d = ScriptedDevice::from_waypoints(w.clone(), limits()).unwrap();
        assert_eq!(d.time_span_s(), Some((0.5, 2.0)));
        for (t, expected) in [(0.0, &w[0]), (0.5, &w[0]), (2.0, &w[2]), (9.0, &w[2])] {
            let s = d.read(t).unwrap();
            assert_eq!(s.pose, expected.pose, "t = {t}");
            assert_eq!(s.twist, Twist::zero());
            assert_eq!(s.timestamp_s, t);
        }
        // Interior waypoint: exact start of the next segment, zero twist.
        let s = d.read(1.5).unwrap();
        assert_eq!(s.pose.position, w[1].pose.position);
        assert!(s.pose.orientation.angle_to(&w[1].pose.orientation) < 1e-15);
        assert_eq!(s.twist, Twist::zero());
        // Approaching the interior waypoint from the left ends there too.
        let s = d.read(1.5 - 1e-9).unwrap();
        assert!((s.pose.position - w[1].pose.position).norm() < 1e-12);
        assert!(s.pose.orientation.angle_to(&w[1].pose.orientation) < 1e-9);
    }

    #[test]
    fn twist_is_the_derivative_of_the_pose() {
        let mut d = ScriptedDevice::from_waypoints(three(), limits()).unwrap();
        let h = 1e-6;
        for i in 0..=40 {
            let t = 0.45 + i as Real * 0.04;
            let s = d.read(t).unwrap();
            let a = d.read(t - h).unwrap().pose;
            let b = d.read(t + h).unwrap().pose;
            let v = (b.position - a.position) / (2.0 * h);
            let w = (b.orientation * a.orientation.inverse()).scaled_axis() / (2.0 * h);
            assert!(
                (v - s.twist.linear).norm() < 1e-6,
                "t={t}: {v} vs {}",
                s.twist.linear
            );
            assert!(
                (w - s.twist.angular).norm() < 1e-6,
                "t={t}: {w} vs {}",
                s.twist.angular
            );
        }
    }

    #[test]
    fn orientation_takes_the_short_way() {
        // 350° about z is -10°: the handle must turn 10°, not 350°.
        let a = pose(0.0, 0.0, 0.0, Vec3::z(), 0.0);
        let b = pose(0.0, 0.0, 0.0, Vec3::z(), 350.0_f64.to_radians());
        let mut d = ScriptedDevice::from_waypoints(
            vec![Waypoint::new(0.0, a), Waypoint::new(1.0, b)],
            limits(),
        )
        .unwrap();
        let mid = d.read(0.5).unwrap();
        assert_relative_eq!(
            mid.pose.orientation.angle(),
            5.0_f64.to_radians(),
            epsilon = 1e-12
        );
        // 180°: still well defined (no panic), and arrives.
        let c = pose(0.0, 0.0, 0.0, Vec3::x(), std::f64::consts::PI);
        let mut d = ScriptedDevice::from_waypoints(
            vec![Waypoint::new(0.0, a), Waypoint::new(1.0, c)],
            limits(),
        )
        .unwrap();
        let end = d.read(1.0 - 1e-12).unwrap();
        assert!(end.pose.orientation.angle_to(&c.orientation) < 1e-9);
    }

    #[test]
    fn bad_waypoints_are_typed_errors() {
        assert!(matches!(
            ScriptedDevice::from_waypoints(vec![], limits()),
            Err(DeviceError::NoWaypoints)
        ));
        let mut w = three();
        w[2].t_s = 1.5;
        assert!(matches!(
            ScriptedDevice::from_waypoints(w, limits()),
            Err(DeviceError::WaypointTimeNotIncreasing { index: 2, .. })
        ));
        let mut w = three();
        w[1].t_s = Real::NAN;
        assert!(matches!(
            ScriptedDevice::from_waypoints(w, limits()),
            Err(DeviceError::BadWaypoint { index: 1 })
        ));
        let mut w = three();
        w[0].pose.position.y = Real::INFINITY;
        assert!(matches!(
            ScriptedDevice::from_waypoints(w, limits()),
            Err(DeviceError::BadWaypoint { index: 0 })
        ));
        let mut w = three();
        w[2].pose.orientation =
            UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(1.0, 0.5, 0.0, 0.0));
        assert!(matches!(
            ScriptedDevice::from_waypoints(w, limits()),
            Err(DeviceError::BadWaypoint { index: 2 })
        ));
    }

    #[test]
    fn function_trajectories() {
        let mut d = ScriptedDevice::from_fn(
            |t| Pose {
                position: Vec3::new(0.05 * (3.0 * t).sin(), 0.0, 0.01 * t),
                orientation: UnitQuaternion::from_scaled_axis(Vec3::new(0.0, 0.2 * t, 0.0)),
            },
            limits(),
        );
        let s = d.read(0.3).unwrap();
        assert_relative_eq!(s.pose.position.x, 0.05 * 0.9_f64.sin(), epsilon = 1e-15);
        assert_relative_eq!(s.twist.linear.x, 0.15 * 0.9_f64.cos(), epsilon = 1e-9);
        assert_relative_eq!(s.twist.linear.z, 0.01, epsilon = 1e-9);
        assert!((s.twist.angular - Vec3::new(0.0, 0.2, 0.0)).norm() < 1e-9);

        let mut nan = ScriptedDevice::from_fn(
            |t| Pose::from_position(Vec3::new(if t > 1.0 { Real::NAN } else { 0.0 }, 0.0, 0.0)),
            limits(),
        );
        assert!(nan.read(0.5).is_ok());
        let e = nan.read(2.0).unwrap_err();
        assert_eq!(
            haptic_core::device::Error::kind(&e),
            haptic_core::device::ErrorKind::InvalidData
        );
        assert!(matches!(
            nan.read(Real::NAN),
            Err(DeviceError::BadTime { .. })
        ));

        let mut with = ScriptedDevice::from_fn_with_twist(
            |t| {
                (
                    Pose::from_position(Vec3::new(t, 0.0, 0.0)),
                    Twist {
                        linear: Vec3::x(),
                        angular: Vec3::zeros(),
                    },
                )
            },
            limits(),
        )
        .with_name("line");
        assert_eq!(with.name(), "line");
        assert_eq!(with.read(0.25).unwrap().twist.linear, Vec3::x());
    }

    #[test]
    fn commands_are_clamped_and_kept() {
        let mut d = ScriptedDevice::stationary(Pose::identity(), limits()).unwrap();
        d.command(&Wrench::new(Vec3::new(0.0, 30.0, 0.0), Vec3::zeros()))
            .unwrap();
        assert_relative_eq!(d.last_command().force.y, 5.0, epsilon = 1e-12);
        d.command_zero().unwrap();
        assert_eq!(d.last_command(), Wrench::zero());
    }

    proptest! {
        #[test]
        fn positions_stay_on_the_segment(t in -1.0..3.0_f64) {
            let w = three();
            let mut d = ScriptedDevice::from_waypoints(w.clone(), limits()).unwrap();
            let s = d.read(t).unwrap();
            // Min-jerk is monotone: the position lies between the segment's ends, per axis.
            let (a, b) = if t < 1.5 { (&w[0], &w[1]) } else { (&w[1], &w[2]) };
            for k in 0..3 {
                let lo = a.pose.position[k].min(b.pose.position[k]) - 1e-15;
                let hi = a.pose.position[k].max(b.pose.position[k]) + 1e-15;
                prop_assert!(s.pose.position[k] >= lo && s.pose.position[k] <= hi);
            }
            prop_assert!((s.pose.orientation.as_ref().norm() - 1.0).abs() < 1e-12);
        }
    }
}
