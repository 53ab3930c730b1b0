//! Gravity, and the force model the haptic thread integrates every step: coupling + linearized
//! contact + optional gravity.

use haptic_core::{
    ForceModel, JacobianKind, Kinematics, LinearizationMode, LinearizedContact, Real, RigidBody,
    StateVector, Vec3, Wrench, WrenchJacobian,
};

use crate::coupling::VirtualCoupling;
use crate::error::DynamicsError;

/// Standard gravity, m/s², pointing down the world's `-z` axis.
pub const STANDARD_GRAVITY_M_S2: Real = 9.81;

/// Uniform gravity `m g` at the centre of mass (no torque, zero Jacobian).
///
/// Haptic tools are usually gravity-compensated, so gravity is off unless asked for:
/// [`HapticForces::gravity`] defaults to `None`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gravity {
    /// Acceleration of gravity, m/s², world frame.
    pub g_m_s2: Vec3,
}

impl Gravity {
    /// `g = (0, 0, -9.81) m/s²`.
    pub fn earth() -> Self {
        Self {
            g_m_s2: Vec3::new(0.0, 0.0, -STANDARD_GRAVITY_M_S2),
        }
    }

    /// A validated acceleration (m/s²).
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::CoreError::NonFinite`]) for NaN or Inf.
    pub fn new(g_m_s2: Vec3) -> Result<Self, DynamicsError> {
        haptic_core::check::all_finite("gravity", g_m_s2.iter().copied())?;
        Ok(Self { g_m_s2 })
    }
}

impl ForceModel for Gravity {
    fn wrench(&mut self, body: &RigidBody, _: Real, _: &StateVector, _: &Kinematics) -> Wrench {
        Wrench::new(body.mass_kg() * self.g_m_s2, Vec3::zeros())
    }

    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        jacobian.fill(0.0);
        self.wrench(body, t_s, y, kin)
    }
}

/// Everything acting on the tool in the haptic loop: the virtual coupling, the linearized contact
/// model published by the contact thread (eq. 42) and, optionally, gravity.
///
/// Evaluating it allocates nothing and costs the same whatever the number of contacts.
#[derive(Debug, Clone, Copy)]
pub struct HapticForces {
    /// The virtual coupling (set its device reading before each step).
    pub coupling: VirtualCoupling,
    /// The latest linearized contact model; [`LinearizedContact::none`] in free space.
    pub contact: LinearizedContact,
    /// The model before it, blended out while `contact` is blended in (see
    /// [`HapticForces::blend`]).
    pub previous_contact: LinearizedContact,
    /// Weight of `contact` against `previous_contact`, in `[0, 1]`: the contact wrench is
    /// `blend · W(y) + (1 − blend) · W_previous(y)`, and so its Jacobian. 1 uses `contact` alone.
    pub blend: Real,
    /// How the contact model is used between updates.
    pub mode: LinearizationMode,
    /// Which contact Jacobian the integrator wants ([`haptic_core::Integrator::jacobian_kind`]);
    /// the haptic stage sets it from its integrator.
    pub jacobian_kind: JacobianKind,
    /// Gravitational acceleration (m/s²), `None` for a gravity-compensated tool (the default).
    pub gravity: Option<Vec3>,
}

impl HapticForces {
    /// Coupling only: no contact, no gravity, and the paper's tangents
    /// ([`LinearizationMode::Linearized`]: a model set by hand is then affine in the state, as
    /// the work-precision study wants); the runtime sets the mode from its configuration.
    pub fn new(coupling: VirtualCoupling) -> Self {
        Self {
            coupling,
            contact: LinearizedContact::none(),
            previous_contact: LinearizedContact::none(),
            blend: 1.0,
            mode: LinearizationMode::Linearized,
            jacobian_kind: JacobianKind::Exact,
            gravity: None,
        }
    }

    /// The contact wrench at `y` (blended), and its Jacobian added into `jacobian` if given.
    fn contact_wrench(
        &self,
        y: &StateVector,
        kin: &Kinematics,
        mut jacobian: Option<&mut WrenchJacobian>,
    ) -> Wrench {
        let b = self.blend.clamp(0.0, 1.0);
        let kind = self.jacobian_kind;
        let mut w = self.contact.weighted(
            y,
            kin,
            self.mode,
            b,
            jacobian.as_deref_mut().map(|j| (j, kind)),
        );
        if b < 1.0 {
            w += self.previous_contact.weighted(
                y,
                kin,
                self.mode,
                1.0 - b,
                jacobian.map(|j| (j, kind)),
            );
        }
        w
    }

    fn gravity_force(&self, body: &RigidBody) -> Vec3 {
        self.gravity
            .map_or_else(Vec3::zeros, |g| body.mass_kg() * g)
    }
}

impl ForceModel for HapticForces {
    fn wrench(
        &mut self,
        body: &RigidBody,
        _t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
    ) -> Wrench {
        let mut w = self.coupling.evaluate(body, y, kin, None);
        w += self.contact_wrench(y, kin, None);
        w.force += self.gravity_force(body);
        w
    }

    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        _t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        let mut w = self.coupling.evaluate(body, y, kin, Some(jacobian));
        w += self.contact_wrench(y, kin, Some(jacobian));
        w.force += self.gravity_force(body);
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coupling::CouplingParams;
    use haptic_core::{ContactTangent, DeviceState, Pose, ToolState};

    fn setup() -> (RigidBody, ToolState, HapticForces) {
        let body = RigidBody::from_principal(0.02, [1e-6, 2e-6, 2.5e-6]).unwrap();
        let tool = ToolState::at_rest(&Pose::from_position(Vec3::new(0.0, 0.0, 0.1)));
        let device = DeviceState::at_rest(Pose::from_position(Vec3::new(0.0, 0.02, 0.1)), 0.0);
        let coupling =
            VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
        (body, tool, HapticForces::new(coupling))
    }

    #[test]
    fn sums_coupling_contact_and_gravity() {
        let (body, tool, mut forces) = setup();
        let y = tool.to_vector();
        let kin = Kinematics::new(&body, &y);
        let mut j0 = WrenchJacobian::zeros();
        let w0 = forces.wrench_and_jacobian(&body, 0.0, &y, &kin, &mut j0);
        assert!(w0.force.norm() < 1e-15, "grasped in place: no force");
        // Add gravity and a contact pushing up with 1.5 N and stiffness 1000 N/m in z.
        forces.gravity = Some(Gravity::earth().g_m_s2);
        let mut contact = LinearizedContact::none();
        contact.y0 = y;
        let mut jc = WrenchJacobian::zeros();
        jc[(2, 2)] = -1000.0;
        let w = Wrench::new(Vec3::new(0.0, 0.0, 1.5), Vec3::zeros());
        contact
            .push(ContactTangent::new(-Vec3::z(), w, jc, 2e-3).unwrap())
            .unwrap();
        forces.contact = contact;
        let mut y1 = y;
        y1[2] -= 1e-3;
        let kin1 = Kinematics::new(&body, &y1);
        let mut j = WrenchJacobian::zeros();
        let w = forces.wrench_and_jacobian(&body, 0.0, &y1, &kin1, &mut j);
        let coupling_z = 200.0 * 1e-3; // the coupling pulls back up too
        let expected = 1.5 + 1.0 + coupling_z - 0.02 * 9.81;
        assert!(
            (w.force.z - expected).abs() < 1e-12,
            "{} vs {expected}",
            w.force.z
        );
        assert!((j[(2, 2)] - (-1000.0 - 200.0)).abs() < 1e-9);
        let w_only = forces.wrench(&body, 0.0, &y1, &kin1);
        assert_eq!(w_only, w);
        forces.mode = LinearizationMode::Constant;
        let mut jc = WrenchJacobian::zeros();
        let wc = forces.wrench_and_jacobian(&body, 0.0, &y1, &kin1, &mut jc);
        assert!((wc.force.z - (1.5 + coupling_z - 0.02 * 9.81)).abs() < 1e-12);
        assert!((jc[(2, 2)] + 200.0).abs() < 1e-9);
    }

    #[test]
    fn gravity_is_validated_and_has_no_jacobian() {
        assert!(matches!(
            Gravity::new(Vec3::new(0.0, Real::NAN, 0.0)),
            Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
                what: "gravity"
            }))
        ));
        let body = RigidBody::sphere(2.0, 0.1).unwrap();
        let mut g = Gravity::earth();
        let y = ToolState::at_rest(&Pose::identity()).to_vector();
        let kin = Kinematics::new(&body, &y);
        let mut j = WrenchJacobian::repeat(1.0);
        let w = g.wrench_and_jacobian(&body, 0.0, &y, &kin, &mut j);
        assert_eq!(w.force, Vec3::new(0.0, 0.0, -19.62));
        assert_eq!(j, WrenchJacobian::zeros());
    }

    #[test]
    fn a_blend_weighs_the_two_models_and_their_jacobians() {
        let (body, tool, mut forces) = setup();
        let y = tool.to_vector();
        let model = |f: Real, k: Real| {
            let mut m = LinearizedContact::none();
            m.y0 = y;
            let mut j = WrenchJacobian::zeros();
            j[(2, 2)] = -k;
            j[(3, 1)] = 0.1 * k;
            m.push(
                ContactTangent::new(
                    -Vec3::z(),
                    Wrench::new(Vec3::new(0.0, 0.0, f), Vec3::new(0.01, 0.0, 0.0)),
                    j,
                    1e-3,
                )
                .unwrap(),
            )
            .unwrap();
            m
        };
        forces.previous_contact = model(1.0, 1000.0);
        forces.contact = model(3.0, 4000.0);
        forces.blend = 0.3;
        let mut y1 = y;
        y1[2] -= 1e-4;
        let kin1 = Kinematics::new(&body, &y1);
        let mut j = WrenchJacobian::zeros();
        let w = forces.wrench_and_jacobian(&body, 0.0, &y1, &kin1, &mut j);
        let coupling_z = 200.0 * 1e-4;
        let expected = 0.3 * (3.0 + 0.4) + 0.7 * (1.0 + 0.1) + coupling_z;
        assert!(
            (w.force.z - expected).abs() < 1e-9,
            "{} vs {expected}",
            w.force.z
        );
        assert!((j[(2, 2)] - (-(0.3 * 4000.0 + 0.7 * 1000.0) - 200.0)).abs() < 1e-6);
        // Blend 1: the new model alone; the previous one is not evaluated.
        forces.blend = 1.0;
        let w1 = forces.wrench(&body, 0.0, &y1, &kin1);
        assert!((w1.force.z - (3.4 + coupling_z)).abs() < 1e-9);
    }
}
