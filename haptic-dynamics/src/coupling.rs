//! Viscoelastic virtual coupling between the haptic device and the tool (paper eqs. 13–27).
//!
//! At grasp the device handle's placement is recorded in the tool's body frame ([`Grasp`],
//! eq. 13). During manipulation a spring-damper pulls the tool's coupling point towards the
//! handle and a rotational spring-damper aligns the tool with the handle (eq. 14):
//!
//! ```text
//! r   = R r_c,              e = x_h - x - r
//! F_c = S(e) + b (v_h - v - ω × r)
//! q_d = q_h ⊗ q_c* ⊗ q*  → φ = θ u  (shortest arc)
//! T_c = r × F_c + S_θ(φ) + b_θ (ω_h - ω)
//! ```
//!
//! `S(e) = k e` below the device's force limit; with [`Saturation`] the spring's force magnitude
//! follows a C¹ spline that levels off at the limit (eqs. 26–27). The Jacobians w.r.t.
//! `(x, q, P, L)` (eqs. 17–25, 27) are analytic, including the derivative of `θ u` near `θ = 0`
//! (series) and near `θ = π`.
//!
//! Conjugates instead of inverses: `q_d` is built with `q*` rather than `q⁻¹`; the two differ by
//! the positive factor `|q|²`, which `θ u` ignores, so the result is the same for the slightly
//! non-unit quaternions met inside a step, and the Jacobian is simpler.

use haptic_core::math::{IL, IP, IQ, IX, skew, state_quat};
use haptic_core::{
    DeviceState, ForceModel, Kinematics, Mat3, Pose, Quat4, Real, RigidBody, StateVector,
    ToolState, Vec3, Wrench, WrenchJacobian,
};
use nalgebra::{Matrix3x4, Matrix4, UnitQuaternion};

use crate::error::DynamicsError;
use haptic_core::check;

/// Device saturation (eqs. 26–27): the largest force and torque the coupling springs produce.
///
/// The spring's force magnitude `f(d)` is `k d` up to `d₁ = α F_max / k`, follows the cubic
/// Hermite curve with `f(d₁) = k d₁`, `f'(d₁) = k`, `f(d₂) = F_max`, `f'(d₂) = 0` on `[d₁, d₂]`,
/// and stays at `F_max` beyond `d₂`. `d₂ = (2 - α) F_max / k` is the only choice that keeps the
/// curve monotone and concave (the Hermite cubic then reduces to a parabola); `α` is
/// [`Saturation::linear_fraction`]. The torque spring does the same with `k_θ` and `τ_max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Saturation {
    /// Largest spring force, N (`F_max`).
    pub max_force_n: Real,
    /// Largest spring torque, N m (`τ_max`).
    pub max_torque_nm: Real,
    /// Fraction `α` of the limit reached linearly before the spline starts, in (0, 1).
    pub linear_fraction: Real,
}

impl Saturation {
    /// Default [`Saturation::linear_fraction`]: linear up to 80 % of the limit.
    pub const DEFAULT_LINEAR_FRACTION: Real = 0.8;

    /// Limits of `max_force_n` (N) and `max_torque_nm` (N m), linear up to 80 % of them.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) for limits that are not
    /// positive and finite.
    pub fn new(max_force_n: Real, max_torque_nm: Real) -> Result<Self, DynamicsError> {
        Self::with_linear_fraction(max_force_n, max_torque_nm, Self::DEFAULT_LINEAR_FRACTION)
    }

    /// As [`Saturation::new`] with an explicit linear fraction `α`.
    ///
    /// # Errors
    /// As [`Saturation::new`], and [`DynamicsError::Core`] unless `0 < α < 1`.
    pub fn with_linear_fraction(
        max_force_n: Real,
        max_torque_nm: Real,
        linear_fraction: Real,
    ) -> Result<Self, DynamicsError> {
        let s = Self {
            max_force_n,
            max_torque_nm,
            linear_fraction,
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks the fields (they are public).
    ///
    /// # Errors
    /// As [`Saturation::with_linear_fraction`].
    pub fn validate(&self) -> Result<(), DynamicsError> {
        check::positive("saturation.max_force_n", self.max_force_n)?;
        check::positive("saturation.max_torque_nm", self.max_torque_nm)?;
        let a = check::finite("saturation.linear_fraction", self.linear_fraction)?;
        if !(a > 0.0 && a < 1.0) {
            return Err(haptic_core::CoreError::OutOfRange {
                what: "saturation.linear_fraction",
                value: a,
                expected: "strictly between 0 and 1",
            }
            .into());
        }
        Ok(())
    }
}

/// A spring `S(e) = f(|e|) e / |e|` whose magnitude is linear, then the saturation spline, then
/// flat (eqs. 26–27). Without a limit it is the linear spring `k e`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplineSpring {
    stiffness: Real,
    d1: Real,
    d2: Real,
    max: Real,
}

impl SplineSpring {
    /// The linear spring `k e` (stiffness in N/m or N m/rad).
    pub fn linear(stiffness: Real) -> Self {
        Self {
            stiffness,
            d1: Real::INFINITY,
            d2: Real::INFINITY,
            max: Real::INFINITY,
        }
    }

    /// A spring of stiffness `stiffness` saturating at `max` with linear fraction `alpha`.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) unless stiffness and limit are positive
    /// and `0 < alpha < 1`.
    pub fn saturated(stiffness: Real, max: Real, alpha: Real) -> Result<Self, DynamicsError> {
        check::positive("spring.stiffness", stiffness)?;
        check::positive("spring.max", max)?;
        Saturation::with_linear_fraction(max, max, alpha)?;
        let d1 = alpha * max / stiffness;
        let d2 = (2.0 - alpha) * max / stiffness;
        Ok(Self {
            stiffness,
            d1,
            d2,
            max,
        })
    }

    /// Deviation where the spline starts (`d₁`) and where it is flat (`d₂`); infinite when the
    /// spring is linear.
    pub fn knees(&self) -> (Real, Real) {
        (self.d1, self.d2)
    }

    /// The magnitude `f(d)` and its slope `f'(d)` at deviation `d >= 0` (eq. 26).
    #[inline]
    pub fn magnitude(&self, d: Real) -> (Real, Real) {
        let k = self.stiffness;
        if d <= self.d1 {
            (k * d, k)
        } else if d >= self.d2 {
            (self.max, 0.0)
        } else {
            // Cubic Hermite on [d1, d2]: p0 = k d1, m0 = k, p1 = max, m1 = 0.
            let delta = self.d2 - self.d1;
            let s = (d - self.d1) / delta;
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let f = h00 * k * self.d1 + h10 * delta * k + h01 * self.max;
            let dh00 = 6.0 * s2 - 6.0 * s;
            let dh10 = 3.0 * s2 - 4.0 * s + 1.0;
            let dh01 = -6.0 * s2 + 6.0 * s;
            let df = (dh00 * k * self.d1 + dh10 * delta * k + dh01 * self.max) / delta;
            (f, df)
        }
    }

    /// `S(e)` and `∂S/∂e = k(d) I + k'(d) e eᵀ / d` with `k(d) = f(d)/d` (eq. 27).
    #[inline]
    pub fn vector(&self, e: &Vec3) -> (Vec3, Mat3) {
        let d = e.norm();
        if d <= self.d1 {
            return (self.stiffness * e, Mat3::identity() * self.stiffness);
        }
        let (f, df) = self.magnitude(d);
        let kd = f / d;
        let dkd = (df * d - f) / (d * d);
        (
            kd * e,
            Mat3::identity() * kd + (dkd / d) * e * e.transpose(),
        )
    }
}

/// Coupling stiffness and damping, with optional device saturation.
///
/// [`Default`] gives the paper's free-space values `k = 200 N/m`, `k_θ = 0.6 N m/rad` (Section
/// VII-B) and our damping `b = 1 N s/m`, `b_θ = 3·10⁻³ N m s/rad`: one relaxation time
/// `b/k = b_θ/k_θ = 5 ms` for both links, which damps the translational link critically for a
/// 1.25 g tool and exceeds the sampled-data bound `b > k h`, `b_θ > k_θ h` at 1 kHz below which an
/// explicit integrator goes unstable at every mass (see `docs/decisions.md`). No saturation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CouplingParams {
    /// Linear stiffness `k`, N/m.
    pub stiffness_n_per_m: Real,
    /// Linear damping `b`, N s/m.
    pub damping_ns_per_m: Real,
    /// Angular stiffness `k_θ`, N m/rad.
    pub angular_stiffness_nm_per_rad: Real,
    /// Angular damping `b_θ`, N m s/rad.
    pub angular_damping_nms_per_rad: Real,
    /// Device saturation of the springs, if any.
    pub saturation: Option<Saturation>,
}

impl Default for CouplingParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 200.0,
            damping_ns_per_m: 1.0,
            angular_stiffness_nm_per_rad: 0.6,
            angular_damping_nms_per_rad: 3e-3,
            saturation: None,
        }
    }
}

impl CouplingParams {
    /// Validated parameters without saturation.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) unless stiffnesses are
    /// positive and dampings non-negative.
    pub fn new(
        stiffness_n_per_m: Real,
        damping_ns_per_m: Real,
        angular_stiffness_nm_per_rad: Real,
        angular_damping_nms_per_rad: Real,
    ) -> Result<Self, DynamicsError> {
        let p = Self {
            stiffness_n_per_m,
            damping_ns_per_m,
            angular_stiffness_nm_per_rad,
            angular_damping_nms_per_rad,
            saturation: None,
        };
        p.validate()?;
        Ok(p)
    }

    /// The same parameters with `saturation`.
    pub fn with_saturation(mut self, saturation: Option<Saturation>) -> Self {
        self.saturation = saturation;
        self
    }

    /// Checks the fields (they are public).
    ///
    /// # Errors
    /// As [`CouplingParams::new`] and [`Saturation::validate`].
    pub fn validate(&self) -> Result<(), DynamicsError> {
        check::positive("coupling.stiffness_n_per_m", self.stiffness_n_per_m)?;
        check::non_negative("coupling.damping_ns_per_m", self.damping_ns_per_m)?;
        check::positive(
            "coupling.angular_stiffness_nm_per_rad",
            self.angular_stiffness_nm_per_rad,
        )?;
        check::non_negative(
            "coupling.angular_damping_nms_per_rad",
            self.angular_damping_nms_per_rad,
        )?;
        if let Some(s) = &self.saturation {
            s.validate()?;
        }
        Ok(())
    }

    fn springs(&self) -> Result<(SplineSpring, SplineSpring), DynamicsError> {
        self.validate()?;
        Ok(match &self.saturation {
            None => (
                SplineSpring::linear(self.stiffness_n_per_m),
                SplineSpring::linear(self.angular_stiffness_nm_per_rad),
            ),
            Some(s) => (
                SplineSpring::saturated(self.stiffness_n_per_m, s.max_force_n, s.linear_fraction)?,
                SplineSpring::saturated(
                    self.angular_stiffness_nm_per_rad,
                    s.max_torque_nm,
                    s.linear_fraction,
                )?,
            ),
        })
    }
}

/// Where the handle holds the tool, in the tool's body frame (eq. 13).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grasp {
    /// Coupling point relative to the centre of mass, body frame, m: `r_c = Rᵀ (x_h - x)`.
    pub r_c: Vec3,
    /// Coupling orientation relative to the tool: `q_c = q⁻¹ ⊗ q_h`.
    pub q_c: UnitQuaternion<Real>,
}

impl Grasp {
    /// Records the handle's placement relative to the tool at the moment of grasping (eq. 13).
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::CoreError::NonFinite`]) if the tool state or the handle pose is not finite.
    pub fn new(tool: &ToolState, handle: &Pose) -> Result<Self, DynamicsError> {
        if !tool.is_finite() {
            return Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "tool state",
            }));
        }
        if !handle.is_finite() {
            return Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device pose",
            }));
        }
        let inv = tool.q.inverse();
        Ok(Self {
            r_c: inv * (handle.position - tool.x),
            q_c: inv * handle.orientation,
        })
    }

    /// A grasp from its parts (`r_c` in m, body frame).
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::CoreError::NonFinite`]) for NaN or Inf.
    pub fn from_parts(r_c: Vec3, q_c: UnitQuaternion<Real>) -> Result<Self, DynamicsError> {
        if !r_c.iter().chain(q_c.coords.iter()).all(|v| v.is_finite()) {
            return Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "grasp",
            }));
        }
        Ok(Self { r_c, q_c })
    }
}

/// How far the tool lags behind the handle: what telemetry and the studies plot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CouplingDeviation {
    /// `|x_h - x - R r_c|`, m.
    pub translation_m: Real,
    /// Rotation angle `θ` between handle and coupled tool orientation, rad, in `[0, π]`.
    pub angle_rad: Real,
}

/// `θ u` of the rotation `p` (any non-zero scale), shortest arc, and its derivative w.r.t. the
/// four components of `p` (3×4; eqs. 24–25).
///
/// With `p = ±(w, v)` flipped so that `w >= 0`: `θ u = g v` with `g = 2 atan2(|v|, w) / |v|`,
/// `∂(θu)/∂w = -2 v / |p|²`, `∂(θu)/∂v = g I + h v vᵀ`, `h = (∂g/∂|v|)/|v|`. For
/// `|v| < 10⁻² w` (θ below about 1.1°) `g` and `h` use their series in `t = |v|²/w²`, which
/// avoids `0/0` at `θ = 0`. Near `θ = π` (`w → 0`) the closed forms are regular; `θ u` itself
/// jumps from `π u` to `-π u` when `w` changes sign, as any shortest-arc map must.
pub fn rotation_vector(p: &Quat4) -> (Vec3, Matrix3x4<Real>) {
    let sign = if p[0] < 0.0 { -1.0 } else { 1.0 };
    let w = sign * p[0];
    let v = sign * Vec3::new(p[1], p[2], p[3]);
    let n2 = v.norm_squared();
    let s = n2 + w * w;
    if !(s > 0.0 && s.is_finite()) {
        return (Vec3::zeros(), Matrix3x4::zeros());
    }
    let n = n2.sqrt();
    let (g, h) = if n < 1e-2 * w {
        let t = n2 / (w * w);
        let g = (2.0 / w) * (1.0 + t * (-1.0 / 3.0 + t * (1.0 / 5.0 + t * (-1.0 / 7.0 + t / 9.0))));
        let h = (2.0 / (w * w * w))
            * (-2.0 / 3.0 + t * (4.0 / 5.0 + t * (-6.0 / 7.0 + t * (8.0 / 9.0 - t * 10.0 / 11.0))));
        (g, h)
    } else {
        let a = n.atan2(w);
        (2.0 * a / n, 2.0 * (w / (n2 * s) - a / (n2 * n)))
    };
    let phi = g * v;
    let mut jac = Matrix3x4::zeros();
    jac.set_column(0, &(v * (-2.0 * sign / s)));
    let dv = (Mat3::identity() * g + h * v * v.transpose()) * sign;
    jac.fixed_view_mut::<3, 3>(0, 1).copy_from(&dv);
    (phi, jac)
}

/// The matrix `M(a)` of left multiplication, `a ⊗ b = M(a) b`, quaternions `(w, x, y, z)`.
fn left_product_matrix(a: &Quat4) -> Matrix4<Real> {
    let (w, x, y, z) = (a[0], a[1], a[2], a[3]);
    Matrix4::new(w, -x, -y, -z, x, w, -z, y, y, z, w, -x, z, -y, x, w)
}

fn quat4(q: &UnitQuaternion<Real>) -> Quat4 {
    Quat4::new(q.w, q.i, q.j, q.k)
}

/// Intermediate values of one coupling evaluation.
struct Parts {
    r: Vec3,
    e: Vec3,
    k_e: Mat3,
    force: Vec3,
    phi: Vec3,
    dphi_dp: Matrix3x4<Real>,
    k_phi: Mat3,
    torque_rot: Vec3,
}

/// The virtual coupling: parameters, grasp and the latest device reading. A [`ForceModel`] for
/// the integrators (the wrench on the tool, at and about its centre of mass, world frame), and the
/// source of the reaction sent to the device.
///
/// The device state is held constant over a step (set it with [`VirtualCoupling::set_device`]
/// before each step), as the haptic loop does.
#[derive(Debug, Clone, Copy)]
pub struct VirtualCoupling {
    params: CouplingParams,
    grasp: Grasp,
    device: DeviceState,
    linear: SplineSpring,
    angular: SplineSpring,
    /// `∂q_d/∂q = M(q_h ⊗ q_c*) diag(1, -1, -1, -1)`, so that `q_d = dqd_dq q`.
    dqd_dq: Matrix4<Real>,
}

impl VirtualCoupling {
    /// A coupling with `params`, `grasp` and the first device reading.
    ///
    /// # Errors
    /// Invalid parameters ([`CouplingParams::validate`]), or a device state that is not finite
    /// ([`VirtualCoupling::set_device`]).
    pub fn new(
        params: CouplingParams,
        grasp: Grasp,
        device: &DeviceState,
    ) -> Result<Self, DynamicsError> {
        let (linear, angular) = params.springs()?;
        let mut c = Self {
            params,
            grasp,
            device: DeviceState::at_rest(Pose::identity(), 0.0),
            linear,
            angular,
            dqd_dq: Matrix4::identity(),
        };
        c.set_device(device)?;
        Ok(c)
    }

    /// Grasps `tool` with the handle where `device` is now (eq. 13) and couples them.
    ///
    /// # Errors
    /// As [`Grasp::new`] and [`VirtualCoupling::new`].
    pub fn grasping(
        params: CouplingParams,
        tool: &ToolState,
        device: &DeviceState,
    ) -> Result<Self, DynamicsError> {
        let grasp = Grasp::new(tool, &device.pose)?;
        Self::new(params, grasp, device)
    }

    /// Takes a new device reading. On error the previous reading is kept.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::CoreError::NonFinite`]) with `what = "device pose"`, `"device twist"` or
    /// `"device time stamp"` for NaN or Inf; [`DynamicsError::Core`] with
    /// [`haptic_core::CoreError::NonUnitQuaternion`] for an orientation off unit by more than 1e-6.
    pub fn set_device(&mut self, device: &DeviceState) -> Result<(), DynamicsError> {
        if !device.pose.is_finite() {
            return Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device pose",
            }));
        }
        if !device.twist.is_finite() {
            return Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device twist",
            }));
        }
        if !device.timestamp_s.is_finite() {
            return Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device time stamp",
            }));
        }
        let norm = device.pose.orientation.coords.norm();
        if (norm - 1.0).abs() > 1e-6 {
            return Err(haptic_core::CoreError::NonUnitQuaternion { norm }.into());
        }
        let a = quat4(&(device.pose.orientation * self.grasp.q_c.inverse()));
        let conj = Matrix4::from_diagonal(&Quat4::new(1.0, -1.0, -1.0, -1.0));
        self.dqd_dq = left_product_matrix(&a) * conj;
        self.device = *device;
        Ok(())
    }

    /// The parameters.
    pub fn params(&self) -> &CouplingParams {
        &self.params
    }

    /// The grasp.
    pub fn grasp(&self) -> &Grasp {
        &self.grasp
    }

    /// The latest device reading.
    pub fn device(&self) -> &DeviceState {
        &self.device
    }

    fn parts(&self, y: &StateVector, kin: &Kinematics) -> Parts {
        let p = &self.params;
        let x: Vec3 = y.fixed_rows::<3>(IX).into_owned();
        let r = kin.r * self.grasp.r_c;
        let e = self.device.pose.position - x - r; // eq. 14, spring stretch
        let (f_spring, k_e) = self.linear.vector(&e); // eq. 26
        let v_rel = self.device.twist.linear - kin.v - kin.omega.cross(&r);
        let force = f_spring + p.damping_ns_per_m * v_rel; // eq. 14
        let qd = self.dqd_dq * state_quat(y); // eq. 15
        let (phi, dphi_dp) = rotation_vector(&qd); // eq. 16
        let (t_spring, k_phi) = self.angular.vector(&phi);
        let torque_rot =
            t_spring + p.angular_damping_nms_per_rad * (self.device.twist.angular - kin.omega);
        Parts {
            r,
            e,
            k_e,
            force,
            phi,
            dphi_dp,
            k_phi,
            torque_rot,
        }
    }

    /// The coupling wrench on the tool at `y` (force at the centre of mass, torque about it,
    /// world frame; eq. 14) and, if asked, its 6×13 Jacobian (eqs. 17–25, 27; every entry set).
    pub fn evaluate(
        &self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Wrench {
        let c = self.parts(y, kin);
        let torque = c.r.cross(&c.force) + c.torque_rot;
        if let Some(j) = jacobian {
            self.jacobian(body, kin, &c, j);
        }
        Wrench::new(c.force, torque)
    }

    fn jacobian(&self, body: &RigidBody, kin: &Kinematics, c: &Parts, j: &mut WrenchJacobian) {
        let b = self.params.damping_ns_per_m;
        let bt = self.params.angular_damping_nms_per_rad;
        let skew_r = skew(&c.r);
        let skew_f = skew(&c.force);
        // x columns (eq. 17): ∂F/∂x = -∂S/∂e, ∂T/∂x = [r]× ∂F/∂x.
        let df_dx = -c.k_e;
        j.fixed_view_mut::<3, 3>(0, IX).copy_from(&df_dx);
        j.fixed_view_mut::<3, 3>(3, IX).copy_from(&(skew_r * df_dx));
        // q columns, one component at a time (eqs. 18, 21, 24-25).
        let dphi_dq = c.dphi_dp * self.dqd_dq;
        for k in 0..4 {
            let dr = kin.r_partials[k] * self.grasp.r_c;
            let dw: Vec3 = kin.omega_q.column(k).into_owned();
            let df = -(c.k_e * dr) - b * (dw.cross(&c.r) + kin.omega.cross(&dr));
            let dphi: Vec3 = dphi_dq.column(k).into_owned();
            let dt = skew_r * df - skew_f * dr + c.k_phi * dphi - bt * dw;
            j.fixed_view_mut::<3, 1>(0, IQ + k).copy_from(&df);
            j.fixed_view_mut::<3, 1>(3, IQ + k).copy_from(&dt);
        }
        // P columns (eqs. 19, 22).
        let df_dp = Mat3::identity() * (-b / body.mass_kg());
        j.fixed_view_mut::<3, 3>(0, IP).copy_from(&df_dp);
        j.fixed_view_mut::<3, 3>(3, IP).copy_from(&(skew_r * df_dp));
        // L columns (eqs. 20, 23): -b ω × r = b [r]× I_w⁻¹ L.
        let df_dl = b * skew_r * kin.inertia_world_inv;
        j.fixed_view_mut::<3, 3>(0, IL).copy_from(&df_dl);
        j.fixed_view_mut::<3, 3>(3, IL)
            .copy_from(&(skew_r * df_dl - bt * kin.inertia_world_inv));
    }

    /// The coupling wrench on the tool in state `tool` (telemetry; no Jacobian).
    pub fn wrench_on_tool(&self, body: &RigidBody, tool: &ToolState) -> Wrench {
        let y = tool.to_vector();
        let kin = Kinematics::new(body, &y);
        self.evaluate(body, &y, &kin, None)
    }

    /// The wrench to send to the device, acting at the handle (eq. 14 with the new tool state):
    /// force `-F_c` and torque `-(S_θ(θu) + b_θ (ω_h - ω))`. The lever term `r × F_c` acts about
    /// the tool's centre of mass, not about the handle, and is not part of it.
    pub fn device_reaction(&self, body: &RigidBody, tool: &ToolState) -> Wrench {
        let y = tool.to_vector();
        let kin = Kinematics::new(body, &y);
        let c = self.parts(&y, &kin);
        Wrench::new(-c.force, -c.torque_rot)
    }

    /// The coupling deviation of the tool in state `tool` (distance and angle).
    pub fn deviation(&self, tool: &ToolState) -> CouplingDeviation {
        let r = tool.q * self.grasp.r_c;
        let e = self.device.pose.position - tool.x - r;
        let qd = self.dqd_dq * tool.quat4();
        let (phi, _) = rotation_vector(&qd);
        CouplingDeviation {
            translation_m: e.norm(),
            angle_rad: phi.norm(),
        }
    }

    /// The tool state at rest at which the coupling deviation is zero: `q = q_h ⊗ q_c⁻¹`,
    /// `x = x_h - R(q) r_c`, no momentum. For re-placing the tool at the handle (after a fault,
    /// or to start a scene).
    pub fn tool_at_handle(&self) -> ToolState {
        let q = self.device.pose.orientation * self.grasp.q_c.inverse();
        ToolState::at_rest(&Pose {
            position: self.device.pose.position - q * self.grasp.r_c,
            orientation: q,
        })
    }

    /// The spring stretch `e = x_h - x - R r_c` (m) and rotation vector `θ u` (rad) at `y`.
    pub fn stretch(&self, y: &StateVector, kin: &Kinematics) -> (Vec3, Vec3) {
        let c = self.parts(y, kin);
        (c.e, c.phi)
    }
}

impl ForceModel for VirtualCoupling {
    fn wrench(
        &mut self,
        body: &RigidBody,
        _t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
    ) -> Wrench {
        self.evaluate(body, y, kin, None)
    }

    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        _t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        self.evaluate(body, y, kin, Some(jacobian))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{FD_RTOL, arb_body, arb_raw_state, column_check, random_unit};
    use haptic_core::Twist;
    use nalgebra::Vector3;
    use proptest::prelude::*;

    /// Which range the coupling angle is drawn from.
    #[derive(Debug, Clone, Copy)]
    enum Angle {
        Any,
        NearZero,
        NearPi,
    }

    /// A random coupling around a random tool: grasp offset up to 5 cm, device displaced by up
    /// to 5 cm from the coupling point, rotated by an angle from `angle`, moving at up to 1 m/s
    /// and 10 rad/s; saturation (1..10 N, 0.05..0.5 N m) in half of the cases.
    fn arb_case(
        angle: Angle,
    ) -> impl Strategy<Value = (RigidBody, StateVector, VirtualCoupling, ToolState)> {
        (
            arb_body(),
            arb_raw_state(),
            (
                prop::array::uniform3(-0.05..0.05f64),
                prop::array::uniform4(-1.0..1.0f64),
                prop::array::uniform3(-0.05..0.05f64),
                prop::array::uniform3(-1.0..1.0f64),
                0.0..1.0f64,
            ),
            (
                prop::array::uniform3(-1.0..1.0f64),
                prop::array::uniform3(-10.0..10.0f64),
                any::<bool>(),
                1.0..10.0f64,
                0.05..0.5f64,
                0.1..0.9f64,
            ),
        )
            .prop_map(
                move |(body, raw, (rc, qc, dx, axis, a), (vh, wh, sat, fmax, tmax, alpha))| {
                    let y = raw.state_vector(&body);
                    let tool = ToolState::from_vector_normalized(&y).expect("finite");
                    let grasp =
                        Grasp::from_parts(Vector3::from(rc), random_unit(&qc)).expect("finite");
                    let axis = Vector3::from(axis);
                    let axis = if axis.norm() < 1e-3 {
                        Vec3::x()
                    } else {
                        axis.normalize()
                    };
                    let theta = match angle {
                        Angle::Any => a * (std::f64::consts::PI - 2e-3),
                        // 0 in 10 % of the cases, else log-uniform in [1e-8, 3e-2] rad: both
                        // sides of the switch between series and closed form (θ ≈ 0.02 rad).
                        Angle::NearZero => {
                            if a < 0.1 {
                                0.0
                            } else {
                                10f64.powf(-8.0 + 6.5 * (a - 0.1) / 0.9)
                            }
                        }
                        Angle::NearPi => std::f64::consts::PI - 1e-3 - a * 1e-2,
                    };
                    let coupled = tool.q * grasp.q_c;
                    let q_h = UnitQuaternion::from_scaled_axis(axis * theta) * coupled;
                    let x_h = tool.x + tool.q * grasp.r_c + Vector3::from(dx);
                    let device = DeviceState {
                        pose: Pose {
                            position: x_h,
                            orientation: q_h,
                        },
                        twist: Twist {
                            linear: Vector3::from(vh),
                            angular: Vector3::from(wh),
                        },
                        buttons: 0,
                        timestamp_s: 0.0,
                    };
                    let saturation = sat.then(|| {
                        Saturation::with_linear_fraction(fmax, tmax, alpha).expect("valid")
                    });
                    let params = CouplingParams::default().with_saturation(saturation);
                    let coupling = VirtualCoupling::new(params, grasp, &device).expect("valid");
                    (body, y, coupling, tool)
                },
            )
    }

    fn check_coupling(
        body: &RigidBody,
        y: &StateVector,
        coupling: &VirtualCoupling,
    ) -> Result<(), String> {
        let kin = Kinematics::new(body, y);
        let mut j = WrenchJacobian::zeros();
        coupling.evaluate(body, y, &kin, Some(&mut j));
        let m = body.mass_kg();
        let eval = |yy: &StateVector| {
            let k = Kinematics::new(body, yy);
            coupling.evaluate(body, yy, &k, None)
        };
        let jf = j.fixed_rows::<3>(0).into_owned();
        column_check(&jf, y, m, |yy| eval(yy).force).map_err(|e| format!("force: {e}"))?;
        let jt = j.fixed_rows::<3>(3).into_owned();
        column_check(&jt, y, m, |yy| eval(yy).torque).map_err(|e| format!("torque: {e}"))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]

        /// Force and torque Jacobians (eqs. 17–25, 27) at any coupling angle.
        #[test]
        fn coupling_jacobian_matches_fd((body, y, c, _) in arb_case(Angle::Any)) {
            let r = check_coupling(&body, &y, &c);
            prop_assert!(r.is_ok(), "{}", r.unwrap_err());
        }

        /// θu near θ = 0 (including exactly 0), where the series form is used.
        #[test]
        fn coupling_jacobian_matches_fd_near_zero((body, y, c, _) in arb_case(Angle::NearZero)) {
            let r = check_coupling(&body, &y, &c);
            prop_assert!(r.is_ok(), "{}", r.unwrap_err());
        }

        /// θu near θ = π (π - 1.1e-2 .. π - 1e-3).
        #[test]
        fn coupling_jacobian_matches_fd_near_pi((body, y, c, _) in arb_case(Angle::NearPi)) {
            let r = check_coupling(&body, &y, &c);
            prop_assert!(r.is_ok(), "{}", r.unwrap_err());
        }

        /// The saturation spline (eqs. 26–27): magnitude slope and vector Jacobian.
        #[test]
        fn saturation_spline_matches_fd(
            k in 1.0..1000.0f64,
            max in 0.1..10.0f64,
            alpha in 0.05..0.95f64,
            u in 0.0..3.0f64,
            dir in prop::array::uniform3(-1.0..1.0f64),
        ) {
            let s = SplineSpring::saturated(k, max, alpha).unwrap();
            let (_, d2) = s.knees();
            let d = u * d2;
            let h = 1e-6 * d2;
            prop_assume!(d > h);
            let (f, df) = s.magnitude(d);
            let fd = (s.magnitude(d + h).0 - s.magnitude(d - h).0) / (2.0 * h);
            prop_assert!((df - fd).abs() <= FD_RTOL * k + 1e-12, "{df} vs {fd}");
            prop_assert!(f <= max * (1.0 + 1e-12) && f >= 0.0);
            let dir = Vector3::from(dir);
            prop_assume!(dir.norm() > 1e-2);
            let e = dir.normalize() * d;
            let (_, jac) = s.vector(&e);
            for c in 0..3 {
                let mut ep = e;
                let mut em = e;
                ep[c] += h;
                em[c] -= h;
                let fdc = (s.vector(&ep).0 - s.vector(&em).0) / (2.0 * h);
                let an = jac.column(c).into_owned();
                prop_assert!((an - fdc).norm() <= FD_RTOL * k + 1e-12, "col {c}: {an} vs {fdc}");
            }
        }
    }

    #[test]
    fn spline_is_c1_monotone_and_flat() {
        let s = SplineSpring::saturated(200.0, 3.0, 0.8).unwrap();
        let (d1, d2) = s.knees();
        assert!((d1 - 0.012).abs() < 1e-15 && (d2 - 0.018).abs() < 1e-15);
        for d in [d1, d2] {
            let (fl, dl) = s.magnitude(d - 1e-12);
            let (fr, dr) = s.magnitude(d + 1e-12);
            assert!(
                (fl - fr).abs() < 1e-9 && (dl - dr).abs() < 1e-6,
                "{d}: {fl} {fr} {dl} {dr}"
            );
        }
        let mut last = 0.0;
        for i in 0..=400 {
            let (f, df) = s.magnitude(i as f64 * 1e-4);
            assert!(f >= last - 1e-15 && df >= -1e-12 && f <= 3.0 + 1e-12);
            last = f;
        }
        assert_eq!(s.magnitude(1.0), (3.0, 0.0));
        // Linear region is exactly k e.
        let (v, _) = s.vector(&Vec3::new(0.001, 0.0, 0.0));
        assert!((v.x - 0.2).abs() < 1e-15);
    }

    #[test]
    fn rotation_vector_matches_nalgebra_and_takes_the_short_arc() {
        for (axis, angle) in [
            (Vec3::new(1.0, 2.0, -0.5), 0.3),
            (Vec3::new(0.0, 0.0, 1.0), 3.0),
            (Vec3::new(-1.0, 0.2, 0.1), 1e-7),
        ] {
            let q = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
            let (phi, _) = rotation_vector(&quat4(&q));
            assert!(
                (phi - q.scaled_axis()).norm() < 1e-14,
                "{phi} vs {}",
                q.scaled_axis()
            );
            // -q is the same rotation: same vector, and a scaled quaternion too.
            let (phi2, _) = rotation_vector(&(-quat4(&q) * 1.7));
            assert!((phi2 - phi).norm() < 1e-14);
        }
        // A rotation by 350° about z is -10° about z.
        let q = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 350f64.to_radians());
        let (phi, _) = rotation_vector(&quat4(&q));
        assert!((phi - Vec3::new(0.0, 0.0, -10f64.to_radians())).norm() < 1e-12);
        assert_eq!(rotation_vector(&Quat4::zeros()).0, Vec3::zeros());
    }

    fn still_tool() -> (RigidBody, ToolState, DeviceState) {
        let body = RigidBody::from_principal(0.05, [1e-5, 2e-5, 2.5e-5]).unwrap();
        let tool = ToolState::at_rest(&Pose {
            position: Vec3::new(0.1, 0.0, 0.2),
            orientation: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
        });
        let handle = Pose {
            position: Vec3::new(0.1, -0.03, 0.21),
            orientation: UnitQuaternion::from_euler_angles(0.0, 0.5, 0.0),
        };
        (body, tool, DeviceState::at_rest(handle, 0.0))
    }

    #[test]
    fn grasp_gives_zero_wrench_and_reaction_opposes_the_pull() {
        let (body, tool, device) = still_tool();
        let mut c = VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
        let w = c.wrench_on_tool(&body, &tool);
        assert!(w.force.norm() < 1e-12 && w.torque.norm() < 1e-12, "{w:?}");
        let dev = c.deviation(&tool);
        assert!(dev.translation_m < 1e-15 && dev.angle_rad < 1e-7);
        // Move the handle 1 cm along +x and turn it 0.1 rad about z.
        let mut moved = device;
        moved.pose.position.x += 0.01;
        moved.pose.orientation =
            UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 0.1) * moved.pose.orientation;
        c.set_device(&moved).unwrap();
        let w = c.wrench_on_tool(&body, &tool);
        assert!(
            (w.force - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-12,
            "{:?}",
            w.force
        );
        let r = tool.q * c.grasp().r_c;
        let rot = w.torque - r.cross(&w.force);
        assert!((rot - Vec3::new(0.0, 0.0, 0.06)).norm() < 1e-12, "{rot}");
        let react = c.device_reaction(&body, &tool);
        assert!((react.force + w.force).norm() < 1e-15);
        assert!((react.torque + rot).norm() < 1e-15);
        let dev = c.deviation(&tool);
        assert!((dev.translation_m - 0.01).abs() < 1e-15 && (dev.angle_rad - 0.1).abs() < 1e-12);
        let placed = c.tool_at_handle();
        let dev = c.deviation(&placed);
        assert!(dev.translation_m < 1e-15 && dev.angle_rad < 1e-7, "{dev:?}");
        assert!(c.wrench_on_tool(&body, &placed).force.norm() < 1e-12);
    }

    #[test]
    fn saturated_coupling_caps_the_force() {
        let (body, tool, device) = still_tool();
        let sat = Saturation::new(3.0, 0.2).unwrap();
        let params = CouplingParams::default().with_saturation(Some(sat));
        let mut c = VirtualCoupling::grasping(params, &tool, &device).unwrap();
        let mut far = device;
        far.pose.position.y += 0.5;
        far.pose.orientation =
            UnitQuaternion::from_axis_angle(&Vec3::x_axis(), 2.0) * far.pose.orientation;
        c.set_device(&far).unwrap();
        let react = c.device_reaction(&body, &tool);
        assert!((react.force.norm() - 3.0).abs() < 1e-12);
        assert!((react.torque.norm() - 0.2).abs() < 1e-12);
    }

    #[test]
    fn bad_device_input_is_a_typed_error_and_keeps_the_old_reading() {
        let (_, tool, device) = still_tool();
        let mut c = VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
        let mut bad = device;
        bad.pose.position.y = Real::NAN;
        assert!(matches!(
            c.set_device(&bad),
            Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device pose"
            }))
        ));
        assert_eq!(c.device(), &device);
        let mut bad = device;
        bad.twist.angular.z = Real::INFINITY;
        assert!(matches!(
            c.set_device(&bad),
            Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device twist"
            }))
        ));
        let mut bad = device;
        bad.pose.orientation =
            UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0));
        assert!(matches!(
            c.set_device(&bad),
            Err(DynamicsError::Core(
                haptic_core::CoreError::NonUnitQuaternion { .. }
            ))
        ));
        let mut bad = device;
        bad.pose.orientation =
            UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(Real::NAN, 0.0, 0.0, 0.0));
        assert!(matches!(
            VirtualCoupling::grasping(CouplingParams::default(), &tool, &bad),
            Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "device pose"
            }))
        ));
    }

    #[test]
    fn parameters_are_validated() {
        assert!(matches!(
            CouplingParams::new(0.0, 1.0, 0.6, 0.0),
            Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
                what: "coupling.stiffness_n_per_m",
                ..
            }))
        ));
        assert!(matches!(
            CouplingParams::new(200.0, -1.0, 0.6, 0.0),
            Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
                what: "coupling.damping_ns_per_m",
                ..
            }))
        ));
        assert!(matches!(
            CouplingParams::new(200.0, 1.0, Real::NAN, 0.0),
            Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "coupling.angular_stiffness_nm_per_rad"
            }))
        ));
        assert!(matches!(
            CouplingParams::new(200.0, 1.0, 0.6, -1e-3),
            Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
                what: "coupling.angular_damping_nms_per_rad",
                ..
            }))
        ));
        assert!(matches!(
            Saturation::new(0.0, 1.0),
            Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
                what: "saturation.max_force_n",
                ..
            }))
        ));
        assert!(matches!(
            Saturation::with_linear_fraction(1.0, 1.0, 1.0),
            Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
                what: "saturation.linear_fraction",
                ..
            }))
        ));
        let p = CouplingParams::default().with_saturation(Some(Saturation {
            max_force_n: 1.0,
            max_torque_nm: -1.0,
            linear_fraction: 0.5,
        }));
        let (_, tool, device) = still_tool();
        assert!(matches!(
            VirtualCoupling::grasping(p, &tool, &device),
            Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
                what: "saturation.max_torque_nm",
                ..
            }))
        ));
        let d = CouplingParams::default();
        assert_eq!(
            (d.stiffness_n_per_m, d.angular_stiffness_nm_per_rad),
            (200.0, 0.6)
        );
        assert!(d.validate().is_ok());
    }
}
