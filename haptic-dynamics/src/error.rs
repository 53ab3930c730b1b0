//! The error type of this crate's constructors.

use haptic_core::CoreError;

/// Bad input to a constructor or setter of `haptic-dynamics`.
///
/// Parameters are checked with [`haptic_core::check`]: a bad one is
/// [`DynamicsError::Core`] holding [`CoreError::NonFinite`] or [`CoreError::OutOfRange`],
/// named by its field path (`"coupling.stiffness_n_per_m"`). Integration failures are reported
/// as [`haptic_core::IntegrationError`] by the integrators;
/// this enum covers parameters, grasps and device readings. Tests check the variant.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DynamicsError {
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
