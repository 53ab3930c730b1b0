//! The [`ContactModel`] trait and the [`LinearizedContact`] it publishes to the haptic thread.

use crate::body::RigidBody;
use crate::contact::Contact;
use crate::error::ContactModelError;
use crate::math::{Real, StateVector, WrenchJacobian};
use crate::state::{Kinematics, ToolState, Wrench};

/// Contacts (or cluster representatives) to a wrench on the tool and its Jacobian.
///
/// The contact thread calls [`ContactModel::linearize`] once per collision update, at the tool
/// state `y₀` it queried with, and publishes the resulting [`LinearizedContact`]; the haptic
/// thread evaluates that in constant time each step (paper eq. 42).
///
/// Contract for implementers:
/// - The wrench acts at the tool's centre of mass (force, N) and about it (torque, N m), world
///   frame, as for [`crate::ForceModel`].
/// - Contacts are fixed within one call: their `r_a` (body frame), `p_b`, `n` are constants and
///   the wrench varies with `y` through `p_a = x + R(q) r_a` and the tool's velocity.
/// - When `jacobian` is `Some`, write the full 6×13 derivative `∂(F, T)/∂y` of exactly the wrench
///   you return; when `None`, do not compute it.
/// - Validate the contacts: a NaN field or a non-unit normal is an error, not a NaN force.
pub trait ContactModel {
    /// The contact wrench at state `y` (with its kinematics `kin`), and optionally its Jacobian.
    ///
    /// # Errors
    /// [`ContactModelError`] for non-finite or malformed contacts.
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError>;

    /// Linearizes the model at `state` (paper eq. 42) into `out`, for the haptic thread.
    ///
    /// # Errors
    /// As [`ContactModel::evaluate`], and [`ContactModelError::NonFiniteState`] for a NaN state.
    fn linearize(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        contacts: &[Contact],
        out: &mut LinearizedContact,
    ) -> Result<(), ContactModelError> {
        let y = state.to_vector();
        if y.iter().any(|v| !v.is_finite()) {
            return Err(ContactModelError::NonFiniteState);
        }
        let kin = Kinematics::new(body, &y);
        let mut jac = WrenchJacobian::zeros();
        let w = self.evaluate(body, &y, &kin, contacts, Some(&mut jac))?;
        out.y0 = y;
        out.wrench0 = w;
        out.jacobian = jac;
        out.contacts = contacts.len();
        out.max_depth_m = contacts
            .iter()
            .map(|c| c.depth_m)
            .fold(Real::NEG_INFINITY, Real::max);
        Ok(())
    }
}

impl<M: ContactModel + ?Sized> ContactModel for &mut M {
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError> {
        (**self).evaluate(body, y, kin, contacts, jacobian)
    }
}

impl<M: ContactModel + ?Sized> ContactModel for Box<M> {
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError> {
        (**self).evaluate(body, y, kin, contacts, jacobian)
    }
}

/// How the haptic thread uses a [`LinearizedContact`] between contact updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LinearizationMode {
    /// `F(y) ≈ F(y₀) + ∂F/∂y (y − y₀)`, and the Jacobian enters the implicit solve (the paper's
    /// method).
    #[default]
    Linearized,
    /// `F(y) = F(y₀)` held constant, no Jacobian: the paper's ablation.
    Constant,
}

/// A contact wrench linearized about `y₀` (paper eq. 42): what the contact thread publishes.
///
/// A plain `Copy` value of fixed size, so it can be exchanged through a lock-free single-slot
/// buffer and evaluated in constant time, whatever the number of triangles or raw contacts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearizedContact {
    /// The tool state the contacts were computed at.
    pub y0: StateVector,
    /// `(F(y₀), T(y₀))`.
    pub wrench0: Wrench,
    /// `∂(F, T)/∂y` at `y₀` (6×13).
    pub jacobian: WrenchJacobian,
    /// Number of contacts (representatives) the wrench came from; 0 means no contact.
    pub contacts: usize,
    /// Largest depth among those contacts (m); `-inf` when there is none.
    pub max_depth_m: Real,
}

impl Default for LinearizedContact {
    fn default() -> Self {
        Self::none()
    }
}

impl LinearizedContact {
    /// No contact: zero wrench and zero Jacobian.
    pub fn none() -> Self {
        Self {
            y0: StateVector::zeros(),
            wrench0: Wrench::zero(),
            jacobian: WrenchJacobian::zeros(),
            contacts: 0,
            max_depth_m: Real::NEG_INFINITY,
        }
    }

    /// Whether there is any contact.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.contacts == 0
    }

    /// The wrench at `y` (constant time).
    #[inline]
    pub fn wrench_at(&self, y: &StateVector, mode: LinearizationMode) -> Wrench {
        match mode {
            LinearizationMode::Constant => self.wrench0,
            LinearizationMode::Linearized => {
                if self.contacts == 0 {
                    return Wrench::zero();
                }
                let dw = self.jacobian * (y - self.y0);
                Wrench::new(
                    self.wrench0.force + dw.fixed_rows::<3>(0),
                    self.wrench0.torque + dw.fixed_rows::<3>(3),
                )
            }
        }
    }

    /// The wrench at `y` and, in [`LinearizationMode::Linearized`], its Jacobian added into
    /// `jacobian`; in [`LinearizationMode::Constant`] `jacobian` is left as it is.
    #[inline]
    pub fn add_wrench_and_jacobian(
        &self,
        y: &StateVector,
        mode: LinearizationMode,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        if mode == LinearizationMode::Linearized && self.contacts > 0 {
            *jacobian += self.jacobian;
        }
        self.wrench_at(y, mode)
    }

    /// The same model with every wrench and Jacobian entry scaled by `s` (used to fade contact
    /// forces out when the contact thread stalls).
    pub fn scaled(&self, s: Real) -> Self {
        let mut out = *self;
        out.wrench0.force *= s;
        out.wrench0.torque *= s;
        out.jacobian *= s;
        out
    }
}
