//! [`Recorder`] and [`ReplayDevice`]: any device's readings, and the wrenches it was sent, to and
//! from CSV, bit for bit.
//!
//! # Format (version 1)
//!
//! UTF-8 text. First, metadata lines `# key = value`; then one column-header line; then one row
//! per read. Lines that start with `#` and blank lines are ignored after the header, and so are
//! `#` lines without `=` and unknown keys before it.
//!
//! ```text
//! # haptic-device recording
//! # format_version = 1
//! # device = simulated hand
//! # rate_hz = 1000.0
//! # workspace_scale = 0.4
//! # force_scale = 2.5
//! # nominal_rate_hz = 1000.0
//! # max_force_n = 5.0
//! # max_torque_nm = 0.5
//! # workspace_min_m = -0.2 -0.2 -0.2
//! # workspace_max_m = 0.2 0.2 0.2
//! t_s,stamp_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s,wx_rad_s,wy_rad_s,wz_rad_s,buttons,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm,commands
//! 0.001,0.001,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0,0.0,0.0,0.0,0.0,0.0,0.0,1
//! ```
//!
//! | column | meaning | unit |
//! |---|---|---|
//! | `t_s` | the `now_s` the device was read at; strictly increasing | s |
//! | `stamp_s` | the reading's own time stamp (`DeviceState::timestamp_s`) | s |
//! | `x_m`, `y_m`, `z_m` | handle position, world frame | m |
//! | `qw`, `qx`, `qy`, `qz` | handle orientation, unit quaternion, body to world | – |
//! | `vx_m_s` … `vz_m_s` | linear velocity, world frame | m/s |
//! | `wx_rad_s` … `wz_rad_s` | angular velocity, world frame | rad/s |
//! | `buttons` | button bit mask, decimal | – |
//! | `fx_n` … `fz_n` | force of the last wrench commanded before the next read (zero before any) | N |
//! | `tx_nm` … `tz_nm` | its torque | N m |
//! | `commands` | how many commands came between this read and the next | – |
//!
//! Metadata: `rate_hz` is the rate the recording was taken at (by default the device's nominal
//! rate, `nominal_rate_hz`); `workspace_scale` and `force_scale` say which scaling (see [`crate::ScaledDevice`])
//! lies between the physical handle and the recorded values (1 and 1 when none); the limits are
//! the recorded device's, so that a replay reports the same.
//!
//! Floats are written with Rust's shortest round-trip representation (`{:?}`), so parsing them
//! gives back the same `f64`, bit for bit (`-0.0` included). The wrench is recorded as the
//! recorder received it, before any clamping by the device.
//!
//! The format and its parsing are in `format`, the [`Recorder`] in `recorder`, the
//! [`ReplayDevice`] in `replay`.

mod format;
mod recorder;
mod replay;
#[cfg(test)]
mod tests;

pub use format::{COLUMN_HEADER, COLUMNS, FORMAT_VERSION, RecordedSample, RecordingHeader};
pub use recorder::Recorder;
pub use replay::ReplayDevice;
