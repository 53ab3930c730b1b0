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

mod spring;
#[cfg(test)]
mod tests;

use haptic_core::check;
use haptic_core::math::{
    IL, IP, IQ, IX, left_product_matrix, quat4, rotation_vector, skew, state_quat,
};
use haptic_core::{
    DeviceState, ForceModel, Kinematics, Mat3, Pose, Quat4, Real, RigidBody, StateVector,
    ToolState, Vec3, Wrench, WrenchJacobian,
};
use nalgebra::{Matrix3x4, Matrix4, UnitQuaternion};

use crate::error::DynamicsError;
pub use spring::{Saturation, SplineSpring};

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
