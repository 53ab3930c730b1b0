//! Error types shared by every crate that implements or drives the core traits.

use crate::Real;

/// Bad input to a constructor of a core type.
///
/// Every validated constructor in this crate returns this error; tests check the variant.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CoreError {
    /// A value that must be finite was NaN or infinite.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which quantity was not finite.
        what: &'static str,
    },
    /// A mass was zero or negative.
    #[error("mass must be positive, got {mass_kg} kg")]
    NonPositiveMass {
        /// The offending mass in kilograms.
        mass_kg: Real,
    },
    /// An inertia tensor was not symmetric.
    #[error("inertia tensor is not symmetric (largest asymmetry {asymmetry:e} kg m^2)")]
    InertiaNotSymmetric {
        /// Largest absolute difference `|I_ij - I_ji|`.
        asymmetry: Real,
    },
    /// An inertia tensor was not positive definite.
    #[error(
        "inertia tensor is not positive definite (smallest eigenvalue {min_eigenvalue:e} kg m^2)"
    )]
    InertiaNotPositiveDefinite {
        /// Smallest eigenvalue found.
        min_eigenvalue: Real,
    },
    /// Principal moments that no mass distribution can have (`I_1 + I_2 < I_3`).
    #[error("inertia tensor violates the triangle inequality of principal moments")]
    InertiaNotPhysical,
    /// A quaternion that must be unit was not.
    #[error("quaternion is not unit (norm {norm})")]
    NonUnitQuaternion {
        /// The norm that was found.
        norm: Real,
    },
    /// A contact normal had (near) zero length or was not unit.
    #[error("contact normal is not a unit vector (norm {norm})")]
    BadNormal {
        /// The norm of the given normal.
        norm: Real,
    },
    /// A parameter had a value outside its admissible range.
    #[error("{what} = {value} is out of range: {expected}")]
    OutOfRange {
        /// Which parameter.
        what: &'static str,
        /// The value given.
        value: Real,
        /// What was expected, in words.
        expected: &'static str,
    },
}

/// Failure of one integration step.
///
/// Returned by [`crate::Integrator::step`]. The state passed in is left untouched, so a caller can
/// retry with another step size or fall back to zero force.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IntegrationError {
    /// The step size was zero, negative or not finite.
    #[error("step size must be positive and finite, got {dt_s} s")]
    InvalidStep {
        /// The step size in seconds.
        dt_s: Real,
    },
    /// The state handed to the integrator, or an input of the force model (a device pose, say),
    /// contained NaN or Inf.
    #[error("non-finite {what} in integration input")]
    NonFiniteInput {
        /// Which input.
        what: &'static str,
    },
    /// The force model returned a NaN or Inf wrench or Jacobian.
    #[error("force model returned a non-finite {what}")]
    NonFiniteForce {
        /// `"wrench"` or `"jacobian"`.
        what: &'static str,
    },
    /// The linear system `(I - h J) Δy = h f` could not be solved.
    #[error("singular linear system in implicit step")]
    SingularSystem,
    /// Newton's method did not reach its tolerance.
    #[error("Newton iteration did not converge in {iterations} iterations (residual {residual:e})")]
    NotConverged {
        /// Iterations performed.
        iterations: usize,
        /// Final residual norm.
        residual: Real,
    },
    /// The new state was not finite.
    #[error("integration produced a non-finite state")]
    NonFiniteState,
}

/// Failure of a contact model evaluation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ContactModelError {
    /// A contact had a NaN or Inf field.
    #[error("contact {index} has a non-finite {what}")]
    NonFiniteContact {
        /// Index of the contact in the slice.
        index: usize,
        /// Which field.
        what: &'static str,
    },
    /// A contact normal was not unit length.
    #[error("contact {index} has a normal of norm {norm}, expected 1")]
    BadNormal {
        /// Index of the contact in the slice.
        index: usize,
        /// The norm found.
        norm: Real,
    },
    /// The tool state was not finite.
    #[error("tool state is not finite")]
    NonFiniteState,
    /// A parameter was outside its admissible range.
    #[error(transparent)]
    Parameter(#[from] CoreError),
    /// More contacts than a [`crate::LinearizedContact`] holds.
    #[error("{count} contacts to linearize, at most {max}: cluster them first")]
    TooManyContacts {
        /// Contacts given.
        count: usize,
        /// [`crate::MAX_REPRESENTATIVES`].
        max: usize,
    },
}

impl ContactModelError {
    /// The same error about the contact at `index` of a longer slice (for an error found in a
    /// one-contact slice).
    pub fn at_index(self, index: usize) -> Self {
        match self {
            Self::NonFiniteContact { what, .. } => Self::NonFiniteContact { index, what },
            Self::BadNormal { norm, .. } => Self::BadNormal { index, norm },
            other => other,
        }
    }
}
