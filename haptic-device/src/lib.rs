//! # haptic-device
//!
//! Implementations of [`haptic_core::Device`]: the handles the runtime reads and commands.
//!
//! It owns:
//! - [`ScriptedDevice`]: open loop, along waypoints (minimum-jerk segments) or a function of time;
//! - [`HandDevice`]: a simulated user, a hand-arm impedance ([`HandParams`]) that tracks a
//!   target trajectory and is moved by the wrench the device renders;
//! - [`Recorder`] and [`ReplayDevice`]: any device's readings and received wrenches to CSV and
//!   back, bit for bit (format in [`record`]);
//! - wrappers for any device: [`ScaledDevice`] (workspace and force scaling),
//!   [`SaturatingDevice`] (clamps and counts), [`FaultInjector`] (disconnection, NaN, stall);
//! - the SpaceMouse report parser and deflection mapping ([`spacemouse`]), and with the `hid`
//!   feature the hidapi driver ([`hid`]), which needs no system library.
//!
//! It does not own the coupling, the dynamics or the loop: the wrench a device is sent comes from
//! `haptic-dynamics` through `haptic-runtime`. It depends on `haptic-core`, nalgebra, thiserror
//! and, optionally, hidapi.
//!
//! Conventions: SI units; poses and wrenches in the world frame of the device's workspace; the
//! commanded wrench acts *on the handle* (what the user feels). Every device here is `Send` and,
//! given the same sequence of calls, deterministic. A reading with NaN or Inf is never returned:
//! it is [`DeviceError::NonFinite`], of kind `InvalidData`.
//!
//! ```
//! use haptic_core::{Device, DeviceLimits, Pose, Vec3, Wrench};
//! use haptic_device::{HandDevice, HandParams, SaturatingDevice, ScaledDevice, ScriptedDevice, Waypoint};
//!
//! let limits = DeviceLimits::new(3.0, 0.3, Vec3::repeat(-0.1), Vec3::repeat(0.1), 1000.0)?;
//! let reach = ScriptedDevice::from_waypoints(
//!     vec![
//!         Waypoint::new(0.0, Pose::identity()),
//!         Waypoint::new(1.0, Pose::from_position(Vec3::new(0.05, 0.0, 0.0))),
//!     ],
//!     limits,
//! )?;
//! let hand = HandDevice::new(HandParams::default(), reach, limits)?;
//! // The paper's jaws set-up: workspace × 0.4, forces × 2.5; clamps counted.
//! let mut device = SaturatingDevice::new(ScaledDevice::new(hand, 0.4, 2.5)?);
//! let state = device.read(0.5)?;
//! assert!((state.pose.position.x - 0.4 * 0.025).abs() < 1e-3);
//! device.command(&Wrench::new(Vec3::new(100.0, 0.0, 0.0), Vec3::zeros()))?;
//! assert_eq!(device.clamp_count(), 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod error;
pub mod fault;
pub mod hand;
#[cfg(feature = "hid")]
pub mod hid;
pub mod record;
pub mod saturating;
pub mod scaled;
pub mod scripted;
pub mod spacemouse;

pub use error::{CsvProblem, DeviceError};
pub use fault::{Fault, FaultInjector};
pub use hand::{HandDevice, HandParams};
#[cfg(feature = "hid")]
pub use hid::{HidDeviceInfo, SpaceMouse, list_hid_devices, list_spacemice};
pub use record::{RecordedSample, Recorder, RecordingHeader, ReplayDevice};
pub use saturating::SaturatingDevice;
pub use scaled::ScaledDevice;
pub use scripted::{ScriptedDevice, Waypoint, min_jerk};
pub use spacemouse::{
    ControlMode, ReportError, SpaceMouseConfig, SpaceMouseReport, SpaceMouseTracker, parse_report,
};

/// The simulated devices of this crate, with a one-line description each (for listings such as
/// `cargo xtask devices`).
pub const SIMULATED_DEVICES: &[(&str, &str)] = &[
    (
        "ScriptedDevice",
        "open loop: waypoints joined by minimum-jerk segments, or a function of time",
    ),
    (
        "HandDevice",
        "closed loop: a hand-arm impedance (m 0.5 kg, k 300 N/m, b 8 N s/m) tracking a target",
    ),
    (
        "ReplayDevice",
        "plays back a CSV recording made by Recorder, bit for bit",
    ),
    (
        "Recorder",
        "wraps any device: its readings and commands to CSV",
    ),
    (
        "ScaledDevice",
        "wraps any device: workspace and force scaling (the paper's jaws: 0.4 and 2.5)",
    ),
    (
        "SaturatingDevice",
        "wraps any device: clamps commands to its limits and counts the clamps",
    ),
    (
        "FaultInjector",
        "wraps any device: disconnection, NaN readings or a stall, on cue",
    ),
];

/// Compile-time check that every device can move to the haptic thread.
const _: () = {
    const fn assert_send<T: Send>() {}
    assert_send::<ScriptedDevice>();
    assert_send::<HandDevice>();
    assert_send::<ReplayDevice>();
    assert_send::<Recorder<HandDevice, std::io::BufWriter<std::fs::File>>>();
    assert_send::<ScaledDevice<HandDevice>>();
    assert_send::<SaturatingDevice<HandDevice>>();
    assert_send::<FaultInjector<HandDevice>>();
    assert_send::<SpaceMouseTracker>();
    assert_send::<DeviceError>();
    #[cfg(feature = "hid")]
    assert_send::<SpaceMouse>();
};
