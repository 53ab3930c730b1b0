//! # haptic-core
//!
//! The vocabulary every crate of the `haptic` workspace shares, and the four traits through which
//! the runtime composes them: [`Integrator`], [`CollisionBackend`], [`ContactModel`] and
//! [`Device`]. **This crate is for people who implement back-ends**: a new integrator, a new
//! collision library, a new contact model or a new device driver depends on `haptic-core` alone
//! (nalgebra and thiserror; no parry, no hidapi).
//!
//! It owns: the scalar type [`Real`], mass properties ([`RigidBody`]), the 13-state tool
//! ([`ToolState`], paper eq. 2), poses, twists and wrenches, device readings ([`DeviceState`]),
//! contacts ([`Contact`], [`ContactSet`]), the linearized contact model the haptic thread
//! evaluates ([`LinearizedContact`], eq. 42), the quaternion calculus shared by every force model
//! ([`math`], [`Kinematics`]), and the error types of the traits.
//!
//! It does not own any algorithm: equations of motion, coupling and integrators live in
//! `haptic-dynamics`, collision detection in `haptic-collision`, clustering in `haptic-cluster`,
//! devices in `haptic-device`, and the multirate pipeline in `haptic-runtime`.
//!
//! Conventions (see `docs/decisions.md`): SI units; quaternions `(w, x, y, z)`; `R(q)` maps body
//! to world; contact normals point out of the tool; wrenches on the tool act at (and about) its
//! centre of mass.
//!
//! ## Implementing a device and a collision back-end downstream
//!
//! ```
//! use haptic_core::device::{Error as _, ErrorKind};
//! use haptic_core::{
//!     CollisionBackend, Contact, ContactSet, Device, DeviceFault, DeviceLimits, DeviceState, Pose,
//!     QueryParams, QueryStats, Real, Vec3, Wrench,
//! };
//!
//! /// A handle that sits still, and remembers the last force it was told to render.
//! struct StillHandle {
//!     pose: Pose,
//!     last: Wrench,
//!     unplugged: bool,
//! }
//!
//! impl Device for StillHandle {
//!     type Error = DeviceFault;
//!     fn name(&self) -> &str {
//!         "still handle"
//!     }
//!     fn limits(&self) -> DeviceLimits {
//!         DeviceLimits::new(3.0, 0.3, Vec3::repeat(-0.1), Vec3::repeat(0.1), 1000.0).unwrap()
//!     }
//!     fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceFault> {
//!         if self.unplugged {
//!             return Err(DeviceFault::new(ErrorKind::Disconnected, "cable pulled"));
//!         }
//!         Ok(DeviceState::at_rest(self.pose, now_s))
//!     }
//!     fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceFault> {
//!         let (clamped, _) = self.limits().saturate(wrench);
//!         self.last = clamped;
//!         Ok(())
//!     }
//! }
//!
//! /// A tool that is a single point, above a floor at z = 0.
//! struct PointOnFloor;
//!
//! impl CollisionBackend for PointOnFloor {
//!     type Error = haptic_core::CoreError;
//!     fn name(&self) -> &str {
//!         "point-on-floor"
//!     }
//!     fn tool_bounding_radius_m(&self) -> Real {
//!         0.0
//!     }
//!     fn query(
//!         &mut self,
//!         tool_pose: &Pose,
//!         params: &QueryParams,
//!         out: &mut ContactSet,
//!     ) -> Result<QueryStats, Self::Error> {
//!         out.clear();
//!         let p_a = tool_pose.position;
//!         let depth_m = -p_a.z; // positive below the floor
//!         if depth_m < -params.delta_m {
//!             return Ok(QueryStats::default()); // broad phase: nothing near
//!         }
//!         let p_b = Vec3::new(p_a.x, p_a.y, 0.0);
//!         out.push(Contact::new(p_a, Vec3::zeros(), p_b, -Vec3::z(), depth_m)?);
//!         Ok(QueryStats { broad_phase_hit: true, node_pairs_tested: 1, primitive_pairs_tested: 1, raw_contacts: 0 })
//!     }
//! }
//!
//! let mut handle = StillHandle { pose: Pose::identity(), last: Wrench::zero(), unplugged: false };
//! handle.command(&Wrench::new(Vec3::new(10.0, 0.0, 0.0), Vec3::zeros())).unwrap();
//! assert!((handle.last.force.norm() - 3.0).abs() < 1e-12); // clamped to the limit
//! handle.unplugged = true;
//! let err = handle.read(0.001).unwrap_err();
//! assert_eq!(err.kind(), ErrorKind::Disconnected);
//!
//! let mut floor = PointOnFloor;
//! let mut contacts = ContactSet::new();
//! let params = QueryParams::new(1e-3, 0.0).unwrap();
//! floor.query(&Pose::from_position(Vec3::new(0.0, 0.0, -2e-4)), &params, &mut contacts).unwrap();
//! assert_eq!(contacts.len(), 1);
//! assert!((contacts.as_slice()[0].depth_m - 2e-4).abs() < 1e-15);
//! // The runtime takes back-ends generically or boxed:
//! let mut boxed: Box<dyn CollisionBackend<Error = haptic_core::CoreError>> = Box::new(PointOnFloor);
//! boxed.query(&Pose::from_position(Vec3::new(0.0, 0.0, 1.0)), &params, &mut contacts).unwrap();
//! assert!(contacts.is_empty());
//! ```

pub mod body;
pub mod check;
pub mod collision;
pub mod contact;
pub mod contact_frame;
pub mod contact_model;
pub mod device;
pub mod error;
pub mod integrator;
pub mod math;
pub mod state;

pub use body::RigidBody;
pub use collision::{CollisionBackend, QueryParams, QueryStats};
pub use contact::{Contact, ContactSet, NO_FEATURE, gap_weight_m};
pub use contact_frame::{FixedFrame, YIELD_MARGIN};
pub use contact_model::{
    ContactModel, ContactTangent, LinearizationMode, LinearizedContact, MAX_REPRESENTATIVES,
};
pub use device::{Device, DeviceFault, DeviceLimits};
pub use error::{ContactModelError, CoreError, IntegrationError};
pub use integrator::{ForceModel, Integrator, JacobianKind};
pub use math::{
    Mat3, Quat4, Real, StateVector, SystemJacobian, Vec3, WrenchJacobian, WrenchVector,
};
pub use state::{DeviceState, Kinematics, Pose, ToolState, Twist, Wrench};

/// Compile-time check that the values exchanged between threads are `Send + Sync`.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<ToolState>();
    assert_send_sync::<LinearizedContact>();
    assert_send_sync::<ContactSet>();
    assert_send_sync::<DeviceState>();
    assert_send_sync::<RigidBody>();
};
