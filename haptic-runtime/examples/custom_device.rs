//! A device of your own: time-stamped handle poses that arrive over a channel (as from a network
//! socket or a tracker's driver thread), with an error type that says its [`ErrorKind`].
//!
//! The [`Device`] contract in practice: `read` never blocks (it takes the newest sample due by
//! `now_s`, or keeps the last one), a NaN pose is an `InvalidData` error and not a value, a
//! closed channel is `Disconnected`, and `command` never renders beyond the limits. The runtime sends
//! zero force for an `InvalidData` reading and stops cleanly, at zero force, when the device is
//! disconnected.
//!
//! Run it with `cargo run -p haptic-runtime --example custom_device`.

use std::sync::mpsc::{Receiver, TryRecvError, channel};

use haptic_core::device::{Error, ErrorKind};
use haptic_core::{
    CollisionBackend, ContactSet, CoreError, Device, DeviceLimits, DeviceState, Pose, QueryParams,
    QueryStats, Real, RigidBody, Twist, Vec3, Wrench,
};
use haptic_dynamics::{NewtonBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::{ContactLatency, PipelineBuilder, RuntimeError};

/// What can go wrong with the channel device.
#[derive(Debug, thiserror::Error)]
enum ChannelDeviceError {
    /// The sender is gone.
    #[error("the pose channel is closed")]
    Closed,
    /// A pose that is not finite.
    #[error("received a non-finite pose")]
    NonFinitePose,
}

impl Error for ChannelDeviceError {
    fn kind(&self) -> ErrorKind {
        match self {
            ChannelDeviceError::Closed => ErrorKind::Disconnected,
            ChannelDeviceError::NonFinitePose => ErrorKind::InvalidData,
        }
    }
}

/// An input device fed by a channel of `(time_s, pose)` samples; it records the last wrench
/// commanded.
struct ChannelDevice {
    samples: Receiver<(Real, Pose)>,
    /// A sample received but not yet due.
    pending: Option<(Real, Pose)>,
    last_pose: Pose,
    last_wrench: Wrench,
    limits: DeviceLimits,
}

impl Device for ChannelDevice {
    type Error = ChannelDeviceError;

    fn name(&self) -> &str {
        "channel"
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, ChannelDeviceError> {
        // Take every sample due by now, without blocking; keep the newest.
        loop {
            let (t_s, pose) = match self.pending.take() {
                Some(sample) => sample,
                None => match self.samples.try_recv() {
                    Ok(sample) => sample,
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return Err(ChannelDeviceError::Closed),
                },
            };
            if t_s > now_s {
                self.pending = Some((t_s, pose)); // not yet
                break;
            }
            if !pose.is_finite() {
                return Err(ChannelDeviceError::NonFinitePose);
            }
            self.last_pose = pose;
        }
        Ok(DeviceState {
            pose: self.last_pose,
            twist: Twist::zero(), // the channel carries poses only; the coupling damps anyway
            buttons: 0,
            timestamp_s: now_s,
        })
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), ChannelDeviceError> {
        self.last_wrench = self.limits.saturate(wrench).0; // never beyond the limits
        Ok(())
    }
}

/// Free space: a back-end with nothing to collide with.
struct Nothing;

impl CollisionBackend for Nothing {
    type Error = CoreError;
    fn name(&self) -> &str {
        "nothing"
    }
    fn tool_bounding_radius_m(&self) -> Real {
        0.05
    }
    fn query(
        &mut self,
        _: &Pose,
        _: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, CoreError> {
        out.clear();
        Ok(QueryStats::default())
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let limits = DeviceLimits::new(5.0, 0.5, Vec3::repeat(-0.3), Vec3::repeat(0.3), 1000.0)?;
    let (send, samples) = channel();
    // The "driver": a pose every 1 ms for 0.3 s, moving 2 cm along x; at 0.1 s one NaN pose
    // (a glitch); then it hangs up.
    for k in 0..300 {
        let t_s = 1e-3 * k as Real;
        let x_m = if k == 100 {
            Real::NAN
        } else {
            0.02 * t_s / 0.3
        };
        send.send((t_s, Pose::from_position(Vec3::new(x_m, 0.0, 0.0))))?;
    }
    drop(send);
    let device = ChannelDevice {
        samples,
        pending: None,
        last_pose: Pose::identity(),
        last_wrench: Wrench::zero(),
        limits,
    };

    let mut pipeline = PipelineBuilder::new(RigidBody::sphere(0.05, 0.02)?, Pose::identity())
        .integrator(NewtonBackwardEuler::default())
        .backend(Nothing)
        .contact_model(PenaltyModel::new(PenaltyParams::default())?)
        .device(device)
        .build()?;
    // The tool follows the handle; the NaN sample gives one zero-force step; the closed
    // channel ends the run, at zero force.
    let outcome =
        pipeline.run_virtual(1.0, ContactLatency::FixedRate { rate_hz: 100.0 }, |_, _| {});
    match outcome {
        Err(RuntimeError::Device {
            kind,
            message,
            summary,
        }) => {
            let d = pipeline.haptic().device();
            println!(
                "the device ended the run at t = {:.3} s: {kind:?} ({message}); {} zero-force \
                 step for the NaN sample; handle at x = {:.1} mm, tool at x = {:.1} mm, last \
                 wrench sent {:.3} N",
                summary.duration_s,
                summary.zero_force_steps,
                d.last_pose.position.x * 1e3,
                pipeline.haptic().tool().x.x * 1e3,
                d.last_wrench.force.norm()
            );
            assert_eq!(kind, ErrorKind::Disconnected);
            assert_eq!(summary.zero_force_steps, 1);
            assert_eq!(
                d.last_wrench,
                Wrench::zero(),
                "every way out ends at zero force"
            );
            Ok(())
        }
        other => Err(format!("expected the device to disconnect, got {other:?}").into()),
    }
}
