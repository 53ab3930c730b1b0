//! # haptic-runtime
//!
//! The multirate pipeline of Otaduy & Lin (2006, Section III-A), composed from any
//! [`haptic_core::Integrator`], [`haptic_core::CollisionBackend`], [`haptic_core::ContactModel`]
//! (with k-means clustering) and [`haptic_core::Device`]:
//!
//! - the **haptic thread**, at a fixed rate (1 kHz by default, up to 10 kHz): read device →
//!   linearise coupling → linearised contact → solve the 13×13 system → coupling force with the
//!   new state → send to device. No allocation, no lock, no I/O per step.
//! - the **contact thread**, as fast as it can: fetch tool state → collision query → cluster →
//!   penalty forces and Jacobians at the representatives → publish the linearized model.
//!
//! They exchange the latest tool state and the latest [`haptic_core::LinearizedContact`] through
//! lock-free single-slot (triple) buffers. The same stages also run single-threaded in
//! **virtual time** ([`Pipeline::run_virtual`]), deterministically, for studies.
//!
//! It owns: the builder, scenes (code or TOML), both run modes, telemetry and the safety rules
//! (finite, saturated forces; zero force on NaN or failed solves; fade-out when the contact thread
//! stalls or dies; clean stop on device failure). It does not own any physics or geometry.
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use haptic_runtime::{ContactLatency, PipelineBuilder};
//! # let (body, pose, integrator, backend, model, device) = todo_parts();
//! let mut pipeline = PipelineBuilder::new(body, pose)
//!     .integrator(integrator)
//!     .backend(backend)
//!     .contact_model(model)
//!     .device(device)
//!     .build()?;
//! let summary = pipeline.run_virtual(1.0, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, _| {})?;
//! println!("max penetration {:.3} mm", summary.max_penetration_m * 1e3);
//! # Ok(()) }
//! # fn todo_parts() -> (haptic_core::RigidBody, haptic_core::Pose,
//! #   haptic_dynamics::integrators::BackwardEuler, haptic_collision::LodBackend,
//! #   haptic_dynamics::penalty::PenaltyModel, haptic_device::ScriptedDevice) { unreachable!() }
//! ```

pub mod error;
pub mod pipeline;
#[cfg(feature = "scene")]
pub mod scene;
pub mod stages;
pub mod telemetry;

pub use error::RuntimeError;
pub use pipeline::{ContactLatency, Pipeline, PipelineBuilder, PipelineConfig, REALTIME_PRIORITY};
#[cfg(feature = "scene")]
pub use scene::{Scene, SceneError, SceneParts};
pub use stages::{
    ContactStage, ContactUpdate, DeviceFailure, HapticStage, SafetyConfig, StepOutcome,
    ToolMessage, ZeroForceGuard,
};
pub use telemetry::{Snapshot, Summary};
