//! The [`Integrator`] trait and the [`ForceModel`] it evaluates.

use crate::body::RigidBody;
use crate::error::IntegrationError;
use crate::math::{Real, StateVector, WrenchJacobian};
use crate::state::{Kinematics, ToolState, Wrench};

/// Which Jacobian of the forces an integrator wants (see [`Integrator::jacobian_kind`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum JacobianKind {
    /// The exact derivative of the wrench: what an iterative solve (full Newton) converges on.
    #[default]
    Exact,
    /// The derivative without the contacts' geometric stiffness: the torque of a contact force
    /// turning with the tool's point (`−[F]× ∂ρ/∂q`, eqs. 38–41) is left out, so that the
    /// contact stiffness seen by the solve is the material part alone, negative semidefinite.
    /// The geometric part is indefinite: on a light tool with a small inertia it can make one
    /// linearly implicit step turn the tool by a right angle. A one-step linearly implicit
    /// method (a W-method) stays first-order consistent with any Jacobian, so it loses no order
    /// with this one. Only models whose Jacobian has such a term (contacts on
    /// [`crate::LinearizationMode::FixedFrames`]) read it.
    Material,
}

/// The external wrench on the tool as a function of its state: coupling, contacts, gravity.
///
/// An integrator calls [`ForceModel::wrench`] at every state it needs (once for forward Euler,
/// four times for RK4) and [`ForceModel::wrench_and_jacobian`] only when it needs `∂(F, T)/∂y`
/// (backward Euler). Implementations should make the first cheap: explicit integrators never
/// ask for the Jacobian, so a model must not compute it in `wrench`.
///
/// Conventions: the force acts at the centre of mass, the torque is about the centre of mass, both
/// in the world frame (N, N m). `y` is the 13-vector `(x, q, P, L)` and may carry a quaternion
/// that is slightly off unit during a step: evaluate on it as given, so that the Jacobian is the
/// derivative of exactly what `wrench` computes. `kin` holds the rotation, velocities and their
/// derivatives at `y`, already computed by the integrator.
pub trait ForceModel {
    /// The wrench at time `t_s` (s) and state `y`.
    fn wrench(&mut self, body: &RigidBody, t_s: Real, y: &StateVector, kin: &Kinematics) -> Wrench;

    /// The wrench and its Jacobian with respect to `y`, written into `jacobian` (6×13, rows
    /// `(F, T)`, columns `(x, q, P, L)`), which the caller need not zero.
    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench;
}

/// No external force at all: a free rigid body.
impl ForceModel for () {
    fn wrench(&mut self, _: &RigidBody, _: Real, _: &StateVector, _: &Kinematics) -> Wrench {
        Wrench::zero()
    }

    fn wrench_and_jacobian(
        &mut self,
        _: &RigidBody,
        _: Real,
        _: &StateVector,
        _: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        jacobian.fill(0.0);
        Wrench::zero()
    }
}

impl<F: ForceModel + ?Sized> ForceModel for &mut F {
    fn wrench(&mut self, body: &RigidBody, t_s: Real, y: &StateVector, kin: &Kinematics) -> Wrench {
        (**self).wrench(body, t_s, y, kin)
    }

    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        (**self).wrench_and_jacobian(body, t_s, y, kin, jacobian)
    }
}

impl<F: ForceModel + ?Sized> ForceModel for Box<F> {
    fn wrench(&mut self, body: &RigidBody, t_s: Real, y: &StateVector, kin: &Kinematics) -> Wrench {
        (**self).wrench(body, t_s, y, kin)
    }

    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        (**self).wrench_and_jacobian(body, t_s, y, kin, jacobian)
    }
}

/// One time step of the 13-state rigid tool (paper eqs. 2–5).
///
/// Given the body, the state at `t_s` and a [`ForceModel`], return the state at `t_s + dt_s`.
/// The state derivative is `f(y) = (P/m, ½ Q(q) ω, F, T)` with `(F, T)` from the force model.
///
/// Contract for implementers:
/// - Return [`IntegrationError::InvalidStep`] for `dt_s` that is not positive and finite, and
///   [`IntegrationError::NonFiniteInput`] for a state that is not finite, before evaluating
///   anything.
/// - Renormalise the quaternion of the new state.
/// - Never call [`ForceModel::wrench_and_jacobian`] unless [`Integrator::uses_jacobian`] is
///   `true`: explicit methods must not pay for Jacobians.
/// - Return an error, never a non-finite state: [`IntegrationError::NonFiniteForce`] if the
///   model returns NaN, [`IntegrationError::NonFiniteState`] if the result is not finite.
/// - Allocate nothing: this runs in the haptic loop, up to 10 kHz.
///
/// The force model is taken as `&mut dyn ForceModel` so that the trait is object-safe
/// (`Box<dyn Integrator>` for sweeps); the virtual call costs nanoseconds against the 13×13
/// solve of an implicit step.
pub trait Integrator {
    /// A short stable identifier, e.g. `"backward_euler"`.
    fn name(&self) -> &'static str;

    /// Whether `step` asks the force model for its Jacobian (implicit methods).
    fn uses_jacobian(&self) -> bool;

    /// Which Jacobian `step` wants when it asks for one: [`JacobianKind::Exact`] (the default)
    /// for methods that iterate to convergence, [`JacobianKind::Material`] allowed for one-step
    /// linearly implicit methods. The caller that owns the force model reads it once and
    /// configures the model.
    fn jacobian_kind(&self) -> JacobianKind {
        JacobianKind::Exact
    }

    /// Advances `state` by `dt_s` seconds.
    ///
    /// # Errors
    /// See the trait documentation.
    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError>;
}

impl<I: Integrator + ?Sized> Integrator for &mut I {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn uses_jacobian(&self) -> bool {
        (**self).uses_jacobian()
    }
    fn jacobian_kind(&self) -> JacobianKind {
        (**self).jacobian_kind()
    }
    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        (**self).step(body, state, t_s, dt_s, forces)
    }
}

impl<I: Integrator + ?Sized> Integrator for Box<I> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn uses_jacobian(&self) -> bool {
        (**self).uses_jacobian()
    }
    fn jacobian_kind(&self) -> JacobianKind {
        (**self).jacobian_kind()
    }
    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        (**self).step(body, state, t_s, dt_s, forces)
    }
}
