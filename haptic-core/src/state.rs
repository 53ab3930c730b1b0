//! Poses, twists, wrenches, the 13-state tool and the device state.

use nalgebra::{Quaternion, UnitQuaternion};

use crate::body::RigidBody;
use crate::error::CoreError;
use crate::math::{
    IL, IP, IQ, IX, Mat3, Quat4, Real, StateVector, Vec3, WrenchVector, rotation_matrix,
    rotation_partials,
};

/// Tolerance on `| |q| - 1 |` accepted by constructors that take a quaternion.
pub const UNIT_QUATERNION_TOL: Real = 1e-9;

fn check_vec(v: &Vec3, what: &'static str) -> Result<(), CoreError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(CoreError::NonFinite { what })
    }
}

fn check_unit(q: &Quaternion<Real>, what: &'static str) -> Result<UnitQuaternion<Real>, CoreError> {
    if !q.coords.iter().all(|c| c.is_finite()) {
        return Err(CoreError::NonFinite { what });
    }
    let norm = q.norm();
    if (norm - 1.0).abs() > UNIT_QUATERNION_TOL {
        return Err(CoreError::NonUnitQuaternion { norm });
    }
    Ok(UnitQuaternion::new_normalize(*q))
}

/// A rigid placement: position (m) and orientation (body to world).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position in metres, world frame.
    pub position: Vec3,
    /// Orientation, mapping body to world.
    pub orientation: UnitQuaternion<Real>,
}

impl Pose {
    /// The identity placement.
    pub fn identity() -> Self {
        Self {
            position: Vec3::zeros(),
            orientation: UnitQuaternion::identity(),
        }
    }

    /// A validated pose.
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] for NaN or Inf, [`CoreError::NonUnitQuaternion`] if
    /// `| |q| - 1 | > 1e-9`.
    pub fn new(position: Vec3, orientation: Quaternion<Real>) -> Result<Self, CoreError> {
        check_vec(&position, "pose position")?;
        let orientation = check_unit(&orientation, "pose orientation")?;
        Ok(Self {
            position,
            orientation,
        })
    }

    /// A pure translation.
    pub fn from_position(position: Vec3) -> Self {
        Self {
            position,
            orientation: UnitQuaternion::identity(),
        }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.position.iter().all(|c| c.is_finite())
            && self.orientation.coords.iter().all(|c| c.is_finite())
    }

    /// Maps a point given in this pose's frame to the world frame.
    #[inline]
    pub fn transform_point(&self, p: &Vec3) -> Vec3 {
        self.orientation * p + self.position
    }

    /// Maps a world point into this pose's frame.
    #[inline]
    pub fn inverse_transform_point(&self, p: &Vec3) -> Vec3 {
        self.orientation.inverse() * (p - self.position)
    }

    /// As an nalgebra isometry.
    pub fn to_isometry(&self) -> nalgebra::Isometry3<Real> {
        nalgebra::Isometry3::from_parts(self.position.into(), self.orientation)
    }
}

impl From<nalgebra::Isometry3<Real>> for Pose {
    fn from(iso: nalgebra::Isometry3<Real>) -> Self {
        Self {
            position: iso.translation.vector,
            orientation: iso.rotation,
        }
    }
}

/// A spatial velocity: linear (m/s) and angular (rad/s), both in the world frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vec3,
    /// Angular velocity, rad/s.
    pub angular: Vec3,
}

impl Twist {
    /// The zero twist.
    pub fn zero() -> Self {
        Self::default()
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.linear
            .iter()
            .chain(self.angular.iter())
            .all(|c| c.is_finite())
    }
}

/// A force (N) and a torque (N m), world frame. Where it acts is said by whoever returns it
/// (about the tool's centre of mass for force models, about the handle for device commands).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Wrench {
    /// Force, N.
    pub force: Vec3,
    /// Torque, N m.
    pub torque: Vec3,
}

impl Wrench {
    /// The zero wrench.
    pub fn zero() -> Self {
        Self::default()
    }

    /// A wrench from its parts.
    pub fn new(force: Vec3, torque: Vec3) -> Self {
        Self { force, torque }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.force
            .iter()
            .chain(self.torque.iter())
            .all(|c| c.is_finite())
    }

    /// As a 6-vector `(F, T)`.
    pub fn to_vector(&self) -> WrenchVector {
        WrenchVector::new(
            self.force.x,
            self.force.y,
            self.force.z,
            self.torque.x,
            self.torque.y,
            self.torque.z,
        )
    }

    /// From a 6-vector `(F, T)`.
    pub fn from_vector(v: &WrenchVector) -> Self {
        Self {
            force: v.fixed_rows::<3>(0).into_owned(),
            torque: v.fixed_rows::<3>(3).into_owned(),
        }
    }
}

impl std::ops::Add for Wrench {
    type Output = Wrench;
    fn add(self, rhs: Wrench) -> Wrench {
        Wrench::new(self.force + rhs.force, self.torque + rhs.torque)
    }
}

impl std::ops::AddAssign for Wrench {
    fn add_assign(&mut self, rhs: Wrench) {
        self.force += rhs.force;
        self.torque += rhs.torque;
    }
}

impl std::ops::Neg for Wrench {
    type Output = Wrench;
    fn neg(self) -> Wrench {
        Wrench::new(-self.force, -self.torque)
    }
}

/// The state of the virtual tool, `y = (x, q, P, L)` (paper eq. 2): centre-of-mass position (m),
/// orientation (body to world), linear momentum (kg m/s) and angular momentum (kg m²/s), all in
/// the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolState {
    /// Centre-of-mass position, m.
    pub x: Vec3,
    /// Orientation, body to world.
    pub q: UnitQuaternion<Real>,
    /// Linear momentum, kg m/s.
    pub p: Vec3,
    /// Angular momentum about the centre of mass, kg m²/s.
    pub l: Vec3,
}

impl ToolState {
    /// A validated state.
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] for NaN or Inf, [`CoreError::NonUnitQuaternion`] if the
    /// quaternion's norm differs from 1 by more than 1e-9.
    pub fn new(x: Vec3, q: Quaternion<Real>, p: Vec3, l: Vec3) -> Result<Self, CoreError> {
        check_vec(&x, "tool position")?;
        check_vec(&p, "linear momentum")?;
        check_vec(&l, "angular momentum")?;
        let q = check_unit(&q, "tool orientation")?;
        Ok(Self { x, q, p, l })
    }

    /// A tool at rest at `pose`.
    pub fn at_rest(pose: &Pose) -> Self {
        Self {
            x: pose.position,
            q: pose.orientation,
            p: Vec3::zeros(),
            l: Vec3::zeros(),
        }
    }

    /// The pose of the centre-of-mass frame.
    pub fn pose(&self) -> Pose {
        Pose {
            position: self.x,
            orientation: self.q,
        }
    }

    /// The quaternion as `(w, x, y, z)`.
    #[inline]
    pub fn quat4(&self) -> Quat4 {
        Quat4::new(self.q.w, self.q.i, self.q.j, self.q.k)
    }

    /// The 13-vector `(x, q, P, L)`.
    pub fn to_vector(&self) -> StateVector {
        let mut y = StateVector::zeros();
        y.fixed_rows_mut::<3>(IX).copy_from(&self.x);
        y.fixed_rows_mut::<4>(IQ).copy_from(&self.quat4());
        y.fixed_rows_mut::<3>(IP).copy_from(&self.p);
        y.fixed_rows_mut::<3>(IL).copy_from(&self.l);
        y
    }

    /// A state from a 13-vector, renormalising its quaternion (what every integrator does after
    /// a step).
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] if any entry is NaN or Inf, [`CoreError::NonUnitQuaternion`] if
    /// the quaternion part is (nearly) zero and cannot be normalised.
    pub fn from_vector_normalized(y: &StateVector) -> Result<Self, CoreError> {
        if y.iter().any(|v| !v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "state vector",
            });
        }
        let mut q = Quaternion::new(y[IQ], y[IQ + 1], y[IQ + 2], y[IQ + 3]);
        let mut norm = q.norm();
        if !norm.is_finite() {
            // Components so large that the norm overflows (a diverging explicit step): scale by
            // the largest first, which is exact in direction.
            q /= q.coords.amax();
            norm = q.norm();
        }
        if norm < 1e-6 {
            return Err(CoreError::NonUnitQuaternion { norm });
        }
        Ok(Self {
            x: y.fixed_rows::<3>(IX).into_owned(),
            q: UnitQuaternion::new_unchecked(q / norm),
            p: y.fixed_rows::<3>(IP).into_owned(),
            l: y.fixed_rows::<3>(IL).into_owned(),
        })
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.to_vector().iter().all(|v| v.is_finite())
    }

    /// Linear velocity `v = P / m` (m/s).
    #[inline]
    pub fn velocity(&self, body: &RigidBody) -> Vec3 {
        self.p / body.mass_kg()
    }

    /// Angular velocity `ω = R I_b⁻¹ Rᵀ L` (rad/s, world frame).
    #[inline]
    pub fn angular_velocity(&self, body: &RigidBody) -> Vec3 {
        let r = self.q.to_rotation_matrix().into_inner();
        r * (body.inertia_body_inv() * (r.transpose() * self.l))
    }

    /// The tool's twist `(v, ω)`.
    pub fn twist(&self, body: &RigidBody) -> Twist {
        Twist {
            linear: self.velocity(body),
            angular: self.angular_velocity(body),
        }
    }

    /// Kinetic energy `½ P²/m + ½ L·ω` (J).
    pub fn kinetic_energy_j(&self, body: &RigidBody) -> Real {
        0.5 * self.p.norm_squared() / body.mass_kg()
            + 0.5 * self.l.dot(&self.angular_velocity(body))
    }
}

/// Everything a force model needs to know about the tool at one state vector, evaluated on the
/// raw (not renormalised) quaternion so that finite differences and analytic Jacobians see the
/// same function.
///
/// Holds `R`, its partials `R_k`, `I_w⁻¹ = R I_b⁻¹ Rᵀ`, `v`, `ω` and `∂ω/∂q` (3×4, paper eq. 11).
#[derive(Debug, Clone, Copy)]
pub struct Kinematics {
    /// Rotation matrix `R(q)`, body to world.
    pub r: Mat3,
    /// `∂R/∂q_k`, `k = w, x, y, z`.
    pub r_partials: [Mat3; 4],
    /// World-frame inverse inertia `R I_b⁻¹ Rᵀ`.
    pub inertia_world_inv: Mat3,
    /// Linear velocity, m/s.
    pub v: Vec3,
    /// Angular velocity, rad/s.
    pub omega: Vec3,
    /// `∂ω/∂q` (3×4): column k is `(R_k I_b⁻¹ Rᵀ + R I_b⁻¹ R_kᵀ) L`.
    pub omega_q: nalgebra::Matrix3x4<Real>,
}

impl Kinematics {
    /// Evaluates the kinematics of `body` at the state vector `y`.
    pub fn new(body: &RigidBody, y: &StateVector) -> Self {
        let q = crate::math::state_quat(y);
        let r = rotation_matrix(&q);
        let r_partials = rotation_partials(&q);
        let ib_inv = body.inertia_body_inv();
        let r_ib_inv = r * ib_inv;
        let inertia_world_inv = r_ib_inv * r.transpose();
        let l: Vec3 = y.fixed_rows::<3>(IL).into_owned();
        let p: Vec3 = y.fixed_rows::<3>(IP).into_owned();
        let omega = inertia_world_inv * l;
        // eq. 11, column k: `(R_k I_b⁻¹ Rᵀ + R I_b⁻¹ R_kᵀ) L`, as matrix-vector products (the
        // 3×3 products would cost four times as much, on every haptic step).
        let body_l = ib_inv * (r.transpose() * l);
        let mut omega_q = nalgebra::Matrix3x4::zeros();
        for k in 0..4 {
            let rk = &r_partials[k];
            omega_q.set_column(k, &(rk * body_l + r_ib_inv * (rk.transpose() * l)));
        }
        Self {
            r,
            r_partials,
            inertia_world_inv,
            v: p / body.mass_kg(),
            omega,
            omega_q,
        }
    }
}

/// What a device reports each period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceState {
    /// Pose of the handle in the (scaled) workspace, world frame.
    pub pose: Pose,
    /// Velocity of the handle, world frame.
    pub twist: Twist,
    /// Button bit mask (bit i = button i pressed).
    pub buttons: u32,
    /// Time stamp of the reading, seconds since the device was opened.
    pub timestamp_s: Real,
}

impl DeviceState {
    /// A handle at rest at `pose`, no buttons, at time `timestamp_s`.
    pub fn at_rest(pose: Pose, timestamp_s: Real) -> Self {
        Self {
            pose,
            twist: Twist::zero(),
            buttons: 0,
            timestamp_s,
        }
    }

    /// Whether pose, twist and time stamp are all finite.
    pub fn is_finite(&self) -> bool {
        self.pose.is_finite() && self.twist.is_finite() && self.timestamp_s.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_quaternions_normalise_without_overflow() {
        let mut y = ToolState::at_rest(&Pose::identity()).to_vector();
        y[crate::math::IQ] = 1e300;
        y[crate::math::IQ + 1] = 1e300;
        let s = ToolState::from_vector_normalized(&y).unwrap();
        assert!((s.q.coords.norm() - 1.0).abs() < 1e-15);
        assert!((s.q.w - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-15);
    }

    #[test]
    fn pose_rejects_bad_input() {
        assert!(matches!(
            Pose::new(Vec3::new(Real::NAN, 0.0, 0.0), Quaternion::identity()),
            Err(CoreError::NonFinite {
                what: "pose position"
            })
        ));
        assert!(matches!(
            Pose::new(Vec3::zeros(), Quaternion::new(1.0, 0.1, 0.0, 0.0)),
            Err(CoreError::NonUnitQuaternion { .. })
        ));
        assert!(matches!(
            Pose::new(
                Vec3::zeros(),
                Quaternion::new(Real::INFINITY, 0.0, 0.0, 0.0)
            ),
            Err(CoreError::NonFinite {
                what: "pose orientation"
            })
        ));
    }

    #[test]
    fn tool_state_rejects_bad_input() {
        let z = Vec3::zeros();
        let id = Quaternion::identity();
        assert!(matches!(
            ToolState::new(Vec3::new(0.0, Real::NAN, 0.0), id, z, z),
            Err(CoreError::NonFinite {
                what: "tool position"
            })
        ));
        assert!(matches!(
            ToolState::new(z, id, Vec3::new(Real::INFINITY, 0.0, 0.0), z),
            Err(CoreError::NonFinite {
                what: "linear momentum"
            })
        ));
        assert!(matches!(
            ToolState::new(z, id, z, Vec3::new(0.0, 0.0, Real::NEG_INFINITY)),
            Err(CoreError::NonFinite {
                what: "angular momentum"
            })
        ));
        assert!(matches!(
            ToolState::new(z, Quaternion::new(0.5, 0.0, 0.0, 0.0), z, z),
            Err(CoreError::NonUnitQuaternion { .. })
        ));
        let mut y = StateVector::zeros();
        assert!(matches!(
            ToolState::from_vector_normalized(&y),
            Err(CoreError::NonUnitQuaternion { .. })
        ));
        y[IQ] = 1.0;
        y[IP] = Real::NAN;
        assert!(matches!(
            ToolState::from_vector_normalized(&y),
            Err(CoreError::NonFinite { .. })
        ));
    }

    #[test]
    fn vector_round_trip_and_velocities() {
        let body = RigidBody::from_principal(2.0, [1.0, 2.0, 2.5]).unwrap();
        let q = Quaternion::new(0.5, 0.5, -0.5, 0.5);
        let s = ToolState::new(
            Vec3::new(1.0, 2.0, 3.0),
            q,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        )
        .unwrap();
        let back = ToolState::from_vector_normalized(&s.to_vector()).unwrap();
        assert!((back.to_vector() - s.to_vector()).norm() < 1e-15);
        assert!((s.velocity(&body) - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-15);
        let k = Kinematics::new(&body, &s.to_vector());
        assert!((k.omega - s.angular_velocity(&body)).norm() < 1e-14);
        assert!((k.v - s.velocity(&body)).norm() < 1e-15);
    }

    #[test]
    fn omega_q_matches_central_differences() {
        let body = RigidBody::from_principal(0.3, [1e-3, 2e-3, 2.5e-3]).unwrap();
        let s = ToolState::new(
            Vec3::zeros(),
            Quaternion::new(0.9, 0.1, -0.3, 0.2).normalize(),
            Vec3::zeros(),
            Vec3::new(0.01, -0.02, 0.03),
        )
        .unwrap();
        let y = s.to_vector();
        let k = Kinematics::new(&body, &y);
        for c in 0..4 {
            let h = 1e-7;
            let mut yp = y;
            let mut ym = y;
            yp[IQ + c] += h;
            ym[IQ + c] -= h;
            let fd =
                (Kinematics::new(&body, &yp).omega - Kinematics::new(&body, &ym).omega) / (2.0 * h);
            let an = k.omega_q.column(c).into_owned();
            assert!(
                (fd - an).norm() <= 1e-6 * an.norm().max(1e-3),
                "{c}: {fd} vs {an}"
            );
        }
    }
}
