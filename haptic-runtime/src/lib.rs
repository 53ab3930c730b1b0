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
//! The pipeline from its four parts (here a back-end with nothing to collide with, so the tool
//! simply follows the hand; `examples/` has an analytic back-end, a device of your own and the
//! spoon in the cup):
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use haptic_core::{
//!     CollisionBackend, ContactSet, CoreError, DeviceLimits, Pose, QueryParams, QueryStats, Real,
//!     RigidBody, Vec3,
//! };
//! use haptic_device::{ScriptedDevice, Waypoint};
//! use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
//! use haptic_runtime::{ContactLatency, PipelineBuilder};
//!
//! struct Nothing;
//! impl CollisionBackend for Nothing {
//!     type Error = CoreError;
//!     fn name(&self) -> &str { "nothing" }
//!     fn tool_bounding_radius_m(&self) -> Real { 0.05 }
//!     fn query(&mut self, _: &Pose, _: &QueryParams, out: &mut ContactSet)
//!         -> Result<QueryStats, CoreError> { out.clear(); Ok(QueryStats::default()) }
//! }
//!
//! let limits = DeviceLimits::new(10.0, 1.0, Vec3::repeat(-0.5), Vec3::repeat(0.5), 1000.0)?;
//! let goal = Pose::from_position(Vec3::new(0.05, 0.0, 0.0));
//! let hand = ScriptedDevice::from_waypoints(
//!     vec![Waypoint::new(0.0, Pose::identity()), Waypoint::new(0.5, goal)],
//!     limits,
//! )?;
//! let mut pipeline = PipelineBuilder::new(RigidBody::sphere(0.05, 0.02)?, Pose::identity())
//!     .integrator(LinearizedBackwardEuler)
//!     .backend(Nothing)
//!     .contact_model(PenaltyModel::new(PenaltyParams::default())?)
//!     .device(hand)
//!     .build()?;
//! let summary = pipeline.run_virtual(1.0, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, _| {})?;
//! assert_eq!(summary.haptic_steps, 1000);
//! assert!((pipeline.haptic().tool().x - goal.position).norm() < 1e-3); // it followed the hand
//! # Ok(()) }
//! ```

pub mod budget;
pub mod error;
pub mod pipeline;
pub mod recording;
#[cfg(feature = "scene")]
pub mod scene;
pub mod stages;
pub mod telemetry;

pub use budget::{QueryBudget, ThresholdController};
pub use error::RuntimeError;
pub use pipeline::{ContactLatency, Pipeline, PipelineBuilder, PipelineConfig, REALTIME_PRIORITY};
pub use recording::{RunObserver, RunRecorder, RunRecording};
#[cfg(feature = "scene")]
pub use scene::{Scene, SceneError, SceneParts};
pub use stages::{
    ContactStage, ContactStageError, ContactUpdate, DeviceFailure, HapticStage, SafetyConfig,
    StepOutcome, ToolMessage, ZeroForceGuard,
};
pub use telemetry::{RunMode, Snapshot, Summary};
