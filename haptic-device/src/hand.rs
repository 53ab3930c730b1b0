//! [`HandDevice`]: a closed-loop simulated user. A hand-and-arm impedance tracks a target
//! trajectory; the wrench the runtime commands acts on the handle and moves it.

use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3, Wrench};
use nalgebra::UnitQuaternion;

use crate::error::{DeviceError, finite_time};
use crate::scripted::{ScriptedDevice, check_state};

/// Mechanical impedance of a human hand and arm grasping a handle, about the grasp point.
///
/// Translation: mass `m`, stiffness `k`, damping `b` (isotropic). Rotation: inertia `I`,
/// stiffness `k_θ`, damping `b_θ` (isotropic). The hand pulls the handle towards the target
/// pose with `k (x_t − x) + b (v_t − v)` and `k_θ θu + b_θ (ω_t − ω)` (`θu` the rotation vector
/// of `q_t q⁻¹`), the equilibrium-point view of arm control.
///
/// [`HandParams::default`] is a relaxed pinch or stylus grasp, with values inside the ranges
/// reported for the hand and arm at the endpoint (docs/decisions.md, "haptic-device"):
///
/// | parameter | default | reported range (sources in docs/decisions.md) |
/// |---|---|---|
/// | `mass_kg` | 0.5 kg | 0.1 – 2 kg effective endpoint mass |
/// | `stiffness_n_per_m` | 300 N/m | 100 – 800 N/m (relaxed to moderate grasp) |
/// | `damping_ns_per_m` | 8 N s/m | 2 – 20 N s/m |
/// | `inertia_kg_m2` | 2·10⁻³ kg m² | 1 – 5·10⁻³ kg m² (hand about the wrist) |
/// | `angular_stiffness_nm_per_rad` | 1.0 N m/rad | 0.3 – 5 N m/rad (wrist, grip dependent) |
/// | `angular_damping_nms_per_rad` | 0.03 N m s/rad | 0.01 – 0.1 N m s/rad |
///
/// Natural frequencies 24.5 rad/s and 22.4 rad/s (3.9 Hz, 3.6 Hz), damping ratios 0.33 and
/// 0.34.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandParams {
    /// Effective mass of hand, arm and handle at the grasp point (kg).
    pub mass_kg: Real,
    /// Translational grasp-and-arm stiffness (N/m).
    pub stiffness_n_per_m: Real,
    /// Translational damping (N s/m).
    pub damping_ns_per_m: Real,
    /// Rotational inertia about the grasp point (kg m²), isotropic.
    pub inertia_kg_m2: Real,
    /// Rotational stiffness (N m/rad).
    pub angular_stiffness_nm_per_rad: Real,
    /// Rotational damping (N m s/rad).
    pub angular_damping_nms_per_rad: Real,
    /// Largest internal integration step (s). A read advances the hand from its previous time
    /// to `now_s` in `⌈Δt / max_substep_s⌉` equal sub-steps.
    pub max_substep_s: Real,
}

impl Default for HandParams {
    fn default() -> Self {
        Self {
            mass_kg: 0.5,
            stiffness_n_per_m: 300.0,
            damping_ns_per_m: 8.0,
            inertia_kg_m2: 2e-3,
            angular_stiffness_nm_per_rad: 1.0,
            angular_damping_nms_per_rad: 0.03,
            max_substep_s: 2.5e-4,
        }
    }
}

/// Largest `ω_n · max_substep_s` admitted, so that the sub-stepping is accurate (the update is
/// stable up to 2).
pub const MAX_OMEGA_DT: Real = 0.2;

impl HandParams {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] for a non-positive or non-finite value, or for a sub-step too
    /// long for the stiffness (`ω_n · max_substep_s >` [`MAX_OMEGA_DT`]).
    pub fn validate(&self) -> Result<(), DeviceError> {
        haptic_core::check::positive("hand.mass_kg", self.mass_kg)?;
        haptic_core::check::positive("hand.stiffness_n_per_m", self.stiffness_n_per_m)?;
        haptic_core::check::positive("hand.damping_ns_per_m", self.damping_ns_per_m)?;
        haptic_core::check::positive("hand.inertia_kg_m2", self.inertia_kg_m2)?;
        haptic_core::check::positive(
            "hand.angular_stiffness_nm_per_rad",
            self.angular_stiffness_nm_per_rad,
        )?;
        haptic_core::check::positive(
            "hand.angular_damping_nms_per_rad",
            self.angular_damping_nms_per_rad,
        )?;
        haptic_core::check::positive("hand.max_substep_s", self.max_substep_s)?;
        let w = self
            .natural_frequency_rad_s()
            .max(self.rot_natural_frequency_rad_s());
        if w * self.max_substep_s > MAX_OMEGA_DT {
            return Err(DeviceError::Parameter(haptic_core::CoreError::OutOfRange {
                what: "hand.max_substep_s",
                value: self.max_substep_s,
                expected: "<= 0.2 / natural frequency",
            }));
        }
        Ok(())
    }

    /// Translational natural frequency `√(k/m)` (rad/s).
    pub fn natural_frequency_rad_s(&self) -> Real {
        (self.stiffness_n_per_m / self.mass_kg).sqrt()
    }

    /// Rotational natural frequency `√(k_θ/I)` (rad/s).
    pub fn rot_natural_frequency_rad_s(&self) -> Real {
        (self.angular_stiffness_nm_per_rad / self.inertia_kg_m2).sqrt()
    }

    /// Translational damping ratio `b / 2√(k m)`.
    pub fn damping_ratio(&self) -> Real {
        self.damping_ns_per_m / (2.0 * (self.stiffness_n_per_m * self.mass_kg).sqrt())
    }

    /// Rotational damping ratio `b_θ / 2√(k_θ I)`.
    pub fn rot_damping_ratio(&self) -> Real {
        self.angular_damping_nms_per_rad
            / (2.0 * (self.angular_stiffness_nm_per_rad * self.inertia_kg_m2).sqrt())
    }

    /// Steady deflection of the handle under a constant force `f_n` (N): `f / k` (m).
    pub fn deflection_m(&self, f_n: Real) -> Real {
        f_n / self.stiffness_n_per_m
    }

    /// Steady rotation of the handle under a constant torque `t_nm` (N m): `t / k_θ` (rad).
    pub fn rot_deflection_rad(&self, t_nm: Real) -> Real {
        t_nm / self.angular_stiffness_nm_per_rad
    }

    /// Bound on the position tracking error with zero feedback, for a target whose acceleration
    /// never exceeds `max_accel_m_s2` (m/s²), starting on the target (m).
    ///
    /// The error `e = x_t − x` obeys `m ë + b ė + k e = m ẍ_t`, so `|e| ≤ ‖h‖₁ m max|ẍ_t|` with
    /// `h` the impulse response of `1 / (m s² + b s + k)`, whose L1 norm is
    /// `coth(σ/2) / k`, `σ = π ζ / √(1 − ζ²)`, for `ζ < 1` (and `1/k` for `ζ ≥ 1`).
    pub fn tracking_error_bound_m(&self, max_accel_m_s2: Real) -> Real {
        l1_gain(self.damping_ratio()) * self.mass_kg * max_accel_m_s2 / self.stiffness_n_per_m
    }

    /// The rotational counterpart of [`HandParams::tracking_error_bound_m`], for a target whose
    /// angular acceleration never exceeds `max_accel_rad_s2` (rad/s²), in rad. It holds for
    /// rotations about a fixed axis and to first order otherwise.
    pub fn rot_tracking_error_bound_rad(&self, max_accel_rad_s2: Real) -> Real {
        l1_gain(self.rot_damping_ratio()) * self.inertia_kg_m2 * max_accel_rad_s2
            / self.angular_stiffness_nm_per_rad
    }
}

/// `k ‖h‖₁` for a second-order system of damping ratio `zeta`.
fn l1_gain(zeta: Real) -> Real {
    if zeta >= 1.0 {
        1.0
    } else {
        let sigma = std::f64::consts::PI * zeta / (1.0 - zeta * zeta).sqrt();
        1.0 / (sigma / 2.0).tanh()
    }
}

/// The hand's own state.
#[derive(Debug, Clone, Copy)]
struct HandState {
    t_s: Real,
    x: Vec3,
    v: Vec3,
    q: UnitQuaternion<Real>,
    w: Vec3,
}

/// A simulated user holding the handle of a device.
///
/// `read(now_s)` integrates the hand from its previous time to `now_s` in equal sub-steps no
/// longer than [`HandParams::max_substep_s`]:
///
/// ```text
/// m v̇ = k (x_t − x) + b (v_t − v) + F_cmd        ẋ = v
/// I ω̇ = k_θ θu(q_t q⁻¹) + b_θ (ω_t − ω) + T_cmd   q̇ = ½ (0, ω) ⊗ q
/// ```
///
/// with the target `(x_t, v_t, q_t, ω_t)` sampled at the end of each sub-step, damping taken
/// implicitly and the position updated with the new velocity (semi-implicit Euler), and
/// `(F_cmd, T_cmd)` the last wrench commanded, saturated to the limits: the wrench the device
/// renders *on the handle* (the coupling's reaction, as the runtime sends it). A constant force
/// `F` therefore displaces the handle by `F / k` along `F`.
///
/// The handle stays in the workspace: a coordinate that would leave it is clamped to the
/// boundary and its outward velocity is zeroed, as at a mechanical stop.
///
/// The first read places the hand on the target at `now_s`. Later reads must not go back in
/// time; reading twice at the same time returns the same state. Everything is deterministic
/// given the sequence of calls.
#[derive(Debug)]
pub struct HandDevice {
    params: HandParams,
    target: ScriptedDevice,
    limits: DeviceLimits,
    state: Option<HandState>,
    command: Wrench,
    clamp_count: u64,
    substeps: u64,
}

impl HandDevice {
    /// A hand with `params` following `target`, on a device with `limits`.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] from [`HandParams::validate`].
    pub fn new(
        params: HandParams,
        target: ScriptedDevice,
        limits: DeviceLimits,
    ) -> Result<Self, DeviceError> {
        params.validate()?;
        Ok(Self {
            params,
            target,
            limits,
            state: None,
            command: Wrench::zero(),
            clamp_count: 0,
            substeps: 0,
        })
    }

    /// The impedance parameters.
    pub fn params(&self) -> &HandParams {
        &self.params
    }

    /// The target trajectory.
    pub fn target_mut(&mut self) -> &mut ScriptedDevice {
        &mut self.target
    }

    /// The wrench acting on the handle now (the last command, saturated).
    pub fn applied_wrench(&self) -> Wrench {
        self.command
    }

    /// How many commands had to be clamped to the limits.
    pub fn clamp_count(&self) -> u64 {
        self.clamp_count
    }

    /// How many internal sub-steps have been taken.
    pub fn substeps(&self) -> u64 {
        self.substeps
    }

    fn clamp_to_workspace(&self, x: &mut Vec3, v: &mut Vec3) {
        let (lo, hi) = (self.limits.workspace_min_m, self.limits.workspace_max_m);
        for k in 0..3 {
            if x[k] < lo[k] {
                x[k] = lo[k];
                v[k] = v[k].max(0.0);
            } else if x[k] > hi[k] {
                x[k] = hi[k];
                v[k] = v[k].min(0.0);
            }
        }
    }

    fn substep(&mut self, s: &mut HandState, dt_s: Real, t1_s: Real) -> Result<(), DeviceError> {
        let p = self.params;
        let (target, target_twist) = self.target.sample(t1_s);
        if !target.is_finite() || !target_twist.is_finite() {
            return Err(DeviceError::NonFinite {
                what: "target pose",
            });
        }
        // Translation: implicit in the damping, then x with the new v.
        let drive = p.stiffness_n_per_m * (target.position - s.x)
            + p.damping_ns_per_m * target_twist.linear
            + self.command.force;
        s.v = (s.v + drive * (dt_s / p.mass_kg)) / (1.0 + dt_s * p.damping_ns_per_m / p.mass_kg);
        s.x += s.v * dt_s;
        let (mut x, mut v) = (s.x, s.v);
        self.clamp_to_workspace(&mut x, &mut v);
        (s.x, s.v) = (x, v);
        // Rotation, the same way, with the world-frame rotation vector as the error.
        let err = (target.orientation * s.q.inverse()).scaled_axis();
        let drive = p.angular_stiffness_nm_per_rad * err
            + p.angular_damping_nms_per_rad * target_twist.angular
            + self.command.torque;
        s.w = (s.w + drive * (dt_s / p.inertia_kg_m2))
            / (1.0 + dt_s * p.angular_damping_nms_per_rad / p.inertia_kg_m2);
        s.q = UnitQuaternion::from_scaled_axis(s.w * dt_s) * s.q;
        s.q.renormalize();
        s.t_s = t1_s;
        Ok(())
    }
}

impl Device for HandDevice {
    type Error = DeviceError;

    fn name(&self) -> &str {
        "simulated hand"
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        let mut s = match self.state {
            None => {
                let (pose, twist) = self.target.sample(now_s);
                let mut s = HandState {
                    t_s: now_s,
                    x: pose.position,
                    v: twist.linear,
                    q: pose.orientation,
                    w: twist.angular,
                };
                let (mut x, mut v) = (s.x, s.v);
                self.clamp_to_workspace(&mut x, &mut v);
                (s.x, s.v) = (x, v);
                s
            }
            Some(s) if now_s < s.t_s => {
                return Err(DeviceError::TimeWentBack {
                    previous_s: s.t_s,
                    now_s,
                });
            }
            Some(s) => s,
        };
        let span_s = now_s - s.t_s;
        if span_s > 0.0 {
            // The 1e-9 keeps a span of exactly k sub-steps, up to rounding, at k.
            let n = (span_s / self.params.max_substep_s - 1e-9).ceil().max(1.0) as u64;
            let t0_s = s.t_s;
            let dt_s = span_s / n as Real;
            for i in 1..=n {
                // The last sub-step ends exactly at now_s.
                let t1_s = if i == n {
                    now_s
                } else {
                    t0_s + i as Real * dt_s
                };
                self.substep(&mut s, dt_s, t1_s)?;
                self.substeps += 1;
            }
        }
        self.state = Some(s);
        check_state(DeviceState {
            pose: Pose {
                position: s.x,
                orientation: s.q,
            },
            twist: Twist {
                linear: s.v,
                angular: s.w,
            },
            buttons: 0,
            timestamp_s: now_s,
        })
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        let (w, clamped) = self.limits.saturate(wrench);
        if clamped {
            self.clamp_count += 1;
        }
        self.command = w;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scripted::{MIN_JERK_PEAK_ACCEL, Waypoint};
    use approx::assert_relative_eq;

    fn limits() -> DeviceLimits {
        DeviceLimits::new(5.0, 0.5, Vec3::repeat(-0.2), Vec3::repeat(0.2), 1000.0).unwrap()
    }

    /// A 10 cm reach with a 1 rad turn in 1 s, then a way back in 0.8 s.
    fn reach() -> (Vec<Waypoint>, Real, Real) {
        let a = Pose::identity();
        let b = Pose {
            position: Vec3::new(0.06, -0.08, 0.0),
            orientation: UnitQuaternion::from_scaled_axis(Vec3::new(0.0, 0.6, 0.8)),
        };
        let c = Pose::from_position(Vec3::new(0.0, 0.0, 0.05));
        let w = vec![
            Waypoint::new(0.2, a),
            Waypoint::new(1.2, b),
            Waypoint::new(2.0, c),
        ];
        // Peak accelerations of the two segments: 10/√3 · distance / duration².
        let peak =
            |distance: Real, duration_s: Real| MIN_JERK_PEAK_ACCEL * distance / duration_s.powi(2);
        let lin = peak((b.position - a.position).norm(), 1.0)
            .max(peak((c.position - b.position).norm(), 0.8));
        let rot = peak(a.orientation.angle_to(&b.orientation), 1.0)
            .max(peak(b.orientation.angle_to(&c.orientation), 0.8));
        (w, lin, rot)
    }

    fn hand(w: Vec<Waypoint>) -> HandDevice {
        let target = ScriptedDevice::from_waypoints(w, limits()).unwrap();
        HandDevice::new(HandParams::default(), target, limits()).unwrap()
    }

    #[test]
    fn default_params_are_valid_and_as_documented() {
        let p = HandParams::default();
        p.validate().unwrap();
        assert_relative_eq!(
            p.natural_frequency_rad_s(),
            24.494_897_427_831_78,
            epsilon = 1e-12
        );
        assert_relative_eq!(p.damping_ratio(), 0.326_598_632_371_090_4, epsilon = 1e-12);
        assert_relative_eq!(
            p.rot_natural_frequency_rad_s(),
            22.360_679_774_997_9,
            epsilon = 1e-12
        );
        assert_relative_eq!(
            p.rot_damping_ratio(),
            0.335_410_196_624_968_5,
            epsilon = 1e-12
        );
        // The L1 gain is at least 1 and decreases with damping.
        assert!(l1_gain(0.1) > l1_gain(0.3) && l1_gain(0.3) > l1_gain(0.9));
        assert_eq!(l1_gain(1.5), 1.0);
    }

    #[test]
    fn bad_params_are_rejected() {
        for p in [
            HandParams {
                mass_kg: 0.0,
                ..HandParams::default()
            },
            HandParams {
                angular_damping_nms_per_rad: Real::NAN,
                ..HandParams::default()
            },
            HandParams {
                stiffness_n_per_m: 1e9,
                ..HandParams::default()
            },
        ] {
            let target = ScriptedDevice::stationary(Pose::identity(), limits()).unwrap();
            assert!(matches!(
                HandDevice::new(p, target, limits()),
                Err(DeviceError::Parameter(_))
            ));
        }
    }

    /// Runs the hand at 1 kHz with zero feedback; returns the largest position and angle errors.
    fn track(w: Vec<Waypoint>, until_s: Real) -> (Real, Real) {
        let mut target = ScriptedDevice::from_waypoints(w.clone(), limits()).unwrap();
        let mut h = hand(w);
        let (mut e_x, mut e_q) = (0.0_f64, 0.0_f64);
        let steps = (until_s * 1000.0).round() as usize;
        for n in 0..=steps {
            let t = n as Real * 1e-3;
            let s = h.read(t).unwrap();
            h.command_zero().unwrap();
            let g = target.read(t).unwrap();
            e_x = e_x.max((s.pose.position - g.pose.position).norm());
            e_q = e_q.max(s.pose.orientation.angle_to(&g.pose.orientation));
        }
        (e_x, e_q)
    }

    #[test]
    fn tracks_the_target_within_the_documented_bound() {
        let (w, a_lin, a_rot) = reach();
        let p = HandParams::default();
        let (e_x, e_q) = track(w, 3.0);
        let bound_x = p.tracking_error_bound_m(a_lin);
        let bound_q = p.rot_tracking_error_bound_rad(a_rot);
        eprintln!(
            "tracking: max position error {:.3} mm (bound {:.3} mm), max angle error {:.4} rad \
             (bound {:.4} rad)",
            e_x * 1e3,
            bound_x * 1e3,
            e_q,
            bound_q
        );
        assert!(e_x <= bound_x, "{e_x} > {bound_x}");
        assert!(e_q <= bound_q, "{e_q} > {bound_q}");
        // The bound is not vacuous: the error is a sizeable part of it.
        assert!(e_x > 0.2 * bound_x && e_q > 0.2 * bound_q);
        // The documented figure for this motion: within 2.5 mm and 0.03 rad.
        assert!(e_x < 2.5e-3 && e_q < 0.03);
    }

    #[test]
    fn settles_on_the_target_when_it_stops() {
        let (w, _, _) = reach();
        let end = w[2].pose;
        let mut h = hand(w);
        for n in 0..=5000 {
            h.read(n as Real * 1e-3).unwrap();
        }
        let s = h.read(5.0).unwrap();
        assert!((s.pose.position - end.position).norm() < 1e-9);
        assert!(s.pose.orientation.angle_to(&end.orientation) < 1e-9);
        assert!(s.twist.linear.norm() < 1e-8 && s.twist.angular.norm() < 1e-7);
    }

    #[test]
    fn constant_force_deflects_by_f_over_k() {
        let rest = Pose::from_position(Vec3::new(0.01, 0.02, -0.03));
        let mut h = hand(vec![Waypoint::new(0.0, rest)]);
        let f = Vec3::new(1.5, -0.9, 0.6);
        let t = Vec3::new(0.0, 0.05, -0.02);
        h.read(0.0).unwrap();
        h.command(&Wrench::new(f, t)).unwrap();
        for n in 1..=4000 {
            h.read(n as Real * 1e-3).unwrap();
        }
        let s = h.read(4.0).unwrap();
        let p = HandParams::default();
        let deflection = s.pose.position - rest.position;
        let expected = f / p.stiffness_n_per_m;
        eprintln!(
            "deflection {:.6} mm, F/k = {:.6} mm; rotation {:.6} rad, T/k_θ = {:.6} rad",
            deflection.norm() * 1e3,
            expected.norm() * 1e3,
            s.pose.orientation.angle(),
            t.norm() / p.angular_stiffness_nm_per_rad
        );
        assert!((deflection - expected).norm() <= 1e-9 * expected.norm());
        assert_relative_eq!(
            deflection.norm(),
            p.deflection_m(f.norm()),
            max_relative = 1e-9
        );
        let rot = s.pose.orientation.scaled_axis();
        let expected_rot = t / p.angular_stiffness_nm_per_rad;
        assert!((rot - expected_rot).norm() <= 1e-9 * expected_rot.norm());
        assert_relative_eq!(
            rot.norm(),
            p.rot_deflection_rad(t.norm()),
            max_relative = 1e-9
        );
        assert_eq!(h.clamp_count(), 0);
    }

    #[test]
    fn commands_are_saturated_before_they_act() {
        let mut h = hand(vec![Waypoint::new(0.0, Pose::identity())]);
        h.read(0.0).unwrap();
        // 50 N asked, 5 N allowed: the deflection is 5/k, not 50/k.
        h.command(&Wrench::new(Vec3::new(50.0, 0.0, 0.0), Vec3::zeros()))
            .unwrap();
        assert_eq!(h.clamp_count(), 1);
        assert_relative_eq!(h.applied_wrench().force.x, 5.0, epsilon = 1e-12);
        let s = h.read(4.0).unwrap();
        assert_relative_eq!(s.pose.position.x, 5.0 / 300.0, max_relative = 1e-6);
        // A NaN command is zero force.
        h.command(&Wrench::new(Vec3::new(Real::NAN, 0.0, 0.0), Vec3::zeros()))
            .unwrap();
        assert_eq!(h.clamp_count(), 2);
        assert_eq!(h.applied_wrench(), Wrench::zero());
    }

    #[test]
    fn the_handle_stays_in_the_workspace() {
        // The target lies 10 cm beyond the +x wall.
        let outside = Pose::from_position(Vec3::new(0.3, 0.0, 0.0));
        let mut h = hand(vec![
            Waypoint::new(0.0, Pose::identity()),
            Waypoint::new(0.5, outside),
        ]);
        let mut max_x = Real::MIN;
        for n in 0..=2000 {
            let s = h.read(n as Real * 1e-3).unwrap();
            max_x = max_x.max(s.pose.position.x);
        }
        let s = h.read(2.0).unwrap();
        assert_eq!(max_x, 0.2);
        assert_eq!(s.pose.position.x, 0.2);
        assert_eq!(s.twist.linear.x, 0.0);
    }

    #[test]
    fn deterministic_substepping_and_time_rules() {
        let (w, _, _) = reach();
        let mut a = hand(w.clone());
        let mut b = hand(w);
        for n in 0..700 {
            let t = 0.1 + n as Real * 1e-3;
            let sa = a.read(t).unwrap();
            let sb = b.read(t).unwrap();
            assert_eq!(sa, sb);
            let f = Wrench::new(sa.pose.position * -40.0, Vec3::new(0.0, 0.0, 0.01));
            a.command(&f).unwrap();
            b.command(&f).unwrap();
        }
        // 1 ms spans take 4 sub-steps of 0.25 ms.
        assert_eq!(a.substeps(), 699 * 4);
        let last = a.read(0.799).unwrap();
        assert_eq!(
            a.read(0.799).unwrap(),
            last,
            "a repeated read changes nothing"
        );
        assert!(matches!(a.read(0.5), Err(DeviceError::TimeWentBack { .. })));
        assert!(matches!(
            a.read(Real::INFINITY),
            Err(DeviceError::BadTime { .. })
        ));
    }

    #[test]
    fn a_nan_target_is_invalid_data() {
        let target = ScriptedDevice::from_fn(
            |t| Pose::from_position(Vec3::new(if t > 0.5 { Real::NAN } else { 0.0 }, 0.0, 0.0)),
            limits(),
        );
        let mut h = HandDevice::new(HandParams::default(), target, limits()).unwrap();
        h.read(0.0).unwrap();
        let e = h.read(1.0).unwrap_err();
        assert_eq!(
            haptic_core::device::Error::kind(&e),
            haptic_core::device::ErrorKind::InvalidData
        );
    }
}
