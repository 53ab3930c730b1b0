//! Errors of the runtime.

use haptic_core::device::ErrorKind;

use crate::telemetry::Summary;

/// What can stop or prevent a run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RuntimeError {
    /// The device failed (disconnected, timed out): zero force was commanded and the run stopped.
    /// The telemetry of the run up to that point is attached.
    #[error("device error ({kind:?}): {message}")]
    Device {
        /// Kind of the failure.
        kind: ErrorKind,
        /// The device's own message.
        message: String,
        /// Telemetry up to the failure.
        summary: Box<Summary>,
    },
    /// The haptic loop panicked (in the device, the integrator or the contact model): zero force
    /// was commanded and the run stopped. The telemetry up to the panic is attached; its
    /// `haptic_thread_panic` holds the same message.
    #[error("the haptic loop panicked: {message}; zero force was commanded")]
    HapticPanic {
        /// The panic's message.
        message: String,
        /// Telemetry up to the panic.
        summary: Box<Summary>,
    },
    /// A configuration value is out of range.
    #[error("invalid configuration `{field}`: {reason}")]
    Config {
        /// The field, as named in the scene file or the config struct.
        field: String,
        /// Why it is invalid.
        reason: String,
    },
    /// The scene could not be loaded.
    #[cfg(feature = "scene")]
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// The device's first reading, where the tool is grasped, is not finite.
    #[error("the first device reading is not finite: the tool cannot be grasped")]
    NonFiniteFirstReading,
    /// The tool could not be grasped or coupled (a bad coupling parameter or pose).
    #[error("the tool could not be grasped: {0}")]
    Grasp(#[from] haptic_dynamics::DynamicsError),
    /// A thread could not be spawned or joined.
    #[error("thread failure: {0}")]
    Thread(String),
}

impl RuntimeError {
    /// The telemetry of a run that stopped on this error (a device failure or a panic of the
    /// haptic loop), if it had started.
    pub fn summary(&self) -> Option<&Summary> {
        match self {
            Self::Device { summary, .. } | Self::HapticPanic { summary, .. } => Some(summary),
            _ => None,
        }
    }

    /// A configuration error naming its field.
    pub fn config(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Config {
            field: field.into(),
            reason: reason.into(),
        }
    }
}
