//! The error type of this crate's constructors.

use haptic_core::{CoreError, Real};

/// Bad input to a constructor or setter of `haptic-dynamics`.
///
/// Integration failures are reported as [`haptic_core::IntegrationError`] by the integrators;
/// this enum covers parameters, grasps and device readings. Tests check the variant.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DynamicsError {
    /// A value that must be finite was NaN or infinite.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which quantity was not finite.
        what: &'static str,
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
    /// An integrator name that [`crate::IntegratorKind`] does not know.
    #[error("unknown integrator {name:?} (expected be, newton-be, rk4 or fe)")]
    UnknownIntegrator {
        /// The name given.
        name: String,
    },
    /// A core type rejected a value (mass properties, a pose, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// `Ok` if `v` is finite, else [`DynamicsError::NonFinite`].
pub(crate) fn finite(v: Real, what: &'static str) -> Result<Real, DynamicsError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(DynamicsError::NonFinite { what })
    }
}
