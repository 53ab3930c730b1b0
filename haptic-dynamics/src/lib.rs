//! # haptic-dynamics
//!
//! The rigid-body virtual tool and what moves it (Otaduy & Lin 2006, Sections IV–V):
//!
//! - [`eom`]: the equations of motion of the 13-state tool (eqs. 2–3) and their analytic
//!   Jacobian (eqs. 6–12);
//! - [`coupling`]: the viscoelastic virtual coupling to the haptic device, with device saturation,
//!   its analytic Jacobians and the reaction wrench sent to the device (eqs. 13–27);
//! - [`penalty`]: the penalty contact model (eqs. 33–41);
//! - [`forces`]: gravity (off by default) and [`HapticForces`], the force model the haptic thread
//!   integrates (coupling + linearized contact, eq. 42, + gravity);
//! - [`integrators`]: forward Euler, RK4, semi-implicit backward Euler (eq. 5) and full-Newton
//!   backward Euler behind [`haptic_core::Integrator`], and [`IntegratorKind`] to pick one by name.
//!
//! It does not own collision detection, clustering, devices or threads (see `haptic-collision`,
//! `haptic-cluster`, `haptic-device`, `haptic-runtime`). Shared types and the traits come from
//! `haptic-core`; conventions (SI units, `R(q)` body to world, wrenches at the centre of mass)
//! are in `docs/decisions.md`.
//!
//! ```
//! use haptic_core::{DeviceState, Integrator, Pose, RigidBody, ToolState, Vec3};
//! use haptic_dynamics::{LinearizedBackwardEuler, CouplingParams, HapticForces, VirtualCoupling};
//!
//! let body = RigidBody::from_principal(0.001, [4e-6, 1e-7, 4e-6]).unwrap(); // a 1 g spoon
//! let mut tool = ToolState::at_rest(&Pose::identity());
//! let mut device = DeviceState::at_rest(Pose::from_position(Vec3::new(0.0, -0.03, 0.0)), 0.0);
//! let coupling = VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
//! let mut forces = HapticForces::new(coupling);
//! let mut be = LinearizedBackwardEuler;
//! for i in 0..1000 {
//!     let t = i as f64 * 1e-3;
//!     device.pose.position.x = 0.05 * (2.0 * t).sin(); // the hand moves
//!     device.twist.linear.x = 0.1 * (2.0 * t).cos();
//!     forces.coupling.set_device(&device).unwrap();
//!     tool = be.step(&body, &tool, t, 1e-3, &mut forces).unwrap();
//!     let _feedback = forces.coupling.device_reaction(&body, &tool); // to the device
//! }
//! assert!(forces.coupling.deviation(&tool).translation_m < 1e-3);
//! ```

pub mod coupling;
pub mod eom;
pub mod error;
pub mod forces;
pub mod integrators;
pub mod penalty;
#[cfg(test)]
mod testutil;

pub use coupling::{
    CouplingDeviation, CouplingParams, Grasp, Saturation, SplineSpring, VirtualCoupling,
};
pub use eom::{
    add_wrench_jacobian, free_jacobian, quaternion_jacobian_blocks, state_derivative,
    system_jacobian,
};
pub use error::DynamicsError;
pub use forces::{Gravity, HapticForces};
pub use integrators::{
    ForwardEuler, IntegratorKind, LinearizedBackwardEuler, NewtonBackwardEuler, Rk4,
};
pub use penalty::{PenaltyModel, PenaltyParams};

/// Compile-time check that the force model and integrators can move to the haptic thread.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<HapticForces>();
    assert_send_sync::<VirtualCoupling>();
    assert_send_sync::<LinearizedBackwardEuler>();
    assert_send_sync::<NewtonBackwardEuler>();
};
