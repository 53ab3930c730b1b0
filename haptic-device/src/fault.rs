//! [`FaultInjector`]: makes any device fail on cue, for tests of the runtime's safety paths.

use haptic_core::{Device, DeviceLimits, DeviceState, Real, Vec3, Wrench};

use crate::error::{DeviceError, finite_time};
use crate::scripted::check_state;

/// Which failure to inject. Read calls are counted from 0, whether they succeed or not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// No fault: everything passes through.
    None,
    /// The first `reads` reads succeed; then the device is unplugged for good: every read and
    /// every command (zero included) fails with [`DeviceError::Disconnected`].
    DisconnectAfter {
        /// Reads that succeed first.
        reads: u64,
    },
    /// The first `reads` reads succeed; every later reading has a NaN position, so it fails
    /// with [`DeviceError::NonFinite`] (kind `InvalidData`), as `Device::read` requires.
    /// Commands still work.
    NanAfter {
        /// Reads that succeed first.
        reads: u64,
    },
    /// Reads number `after_reads .. after_reads + reads` are NaN (as in
    /// [`Fault::NanAfter`]); the device then recovers.
    NanBurst {
        /// Reads that succeed first.
        after_reads: u64,
        /// How many NaN readings follow.
        reads: u64,
    },
    /// Read number `reads` starts a stall: for `duration_s` of the caller's clock from that
    /// read's `now_s`, reads and commands fail with [`DeviceError::Timeout`]; the device then
    /// answers again.
    StallAfter {
        /// Reads that succeed first.
        reads: u64,
        /// How long the device stays silent (s).
        duration_s: Real,
    },
}

/// Wraps any device and injects a [`Fault`]. Errors of the wrapped device pass through with
/// their kind (as [`DeviceError::from_device`]).
#[derive(Debug)]
pub struct FaultInjector<D> {
    inner: D,
    fault: Fault,
    reads: u64,
    stall_from_s: Option<Real>,
    stall_done: bool,
    unplugged: bool,
}

impl<D: Device> FaultInjector<D> {
    /// Wraps `inner` with `fault`.
    pub fn new(inner: D, fault: Fault) -> Self {
        Self {
            inner,
            fault,
            reads: 0,
            stall_from_s: None,
            stall_done: false,
            unplugged: false,
        }
    }

    /// The fault.
    pub fn fault(&self) -> Fault {
        self.fault
    }

    /// Read calls so far.
    pub fn reads(&self) -> u64 {
        self.reads
    }

    /// Whether the injected disconnection has happened.
    pub fn is_disconnected(&self) -> bool {
        self.unplugged
    }

    /// The wrapped device.
    pub fn inner(&self) -> &D {
        &self.inner
    }

    /// The wrapped device, mutably.
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.inner
    }

    fn disconnected(&self) -> DeviceError {
        DeviceError::Disconnected {
            detail: match self.fault {
                Fault::DisconnectAfter { reads } => {
                    format!("injected disconnection after {reads} reads")
                }
                _ => "injected disconnection".to_owned(),
            },
        }
    }

    /// The stall error if the device is stalled at `now_s` (`None`: the time of the last read).
    fn stalled(&mut self, now_s: Option<Real>) -> Option<DeviceError> {
        let (Fault::StallAfter { duration_s, .. }, Some(from_s)) = (self.fault, self.stall_from_s)
        else {
            return None;
        };
        let now_s = now_s.unwrap_or(from_s);
        if now_s < from_s + duration_s {
            Some(DeviceError::Timeout {
                stalled_s: now_s - from_s,
            })
        } else {
            self.stall_from_s = None;
            self.stall_done = true;
            None
        }
    }

    fn command_allowed(&mut self) -> Result<(), DeviceError> {
        if self.is_disconnected() {
            return Err(self.disconnected());
        }
        match self.stalled(None) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

impl<D: Device> Device for FaultInjector<D> {
    type Error = DeviceError;

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        let index = self.reads;
        self.reads += 1;
        let nan = match self.fault {
            Fault::None => false,
            Fault::DisconnectAfter { reads } => {
                if index >= reads {
                    self.unplugged = true;
                    return Err(self.disconnected());
                }
                false
            }
            Fault::NanAfter { reads } => index >= reads,
            Fault::NanBurst { after_reads, reads } => {
                index >= after_reads && index - after_reads < reads
            }
            Fault::StallAfter { reads, .. } => {
                if index >= reads && !self.stall_done && self.stall_from_s.is_none() {
                    self.stall_from_s = Some(now_s);
                }
                if let Some(e) = self.stalled(Some(now_s)) {
                    return Err(e);
                }
                false
            }
        };
        let mut state = self.inner.read(now_s).map_err(DeviceError::from_device)?;
        if nan {
            state.pose.position = Vec3::new(Real::NAN, 0.0, 0.0);
        }
        check_state(state)
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        self.command_allowed()?;
        self.inner.command(wrench).map_err(DeviceError::from_device)
    }

    fn command_zero(&mut self) -> Result<(), DeviceError> {
        self.command_allowed()?;
        self.inner.command_zero().map_err(DeviceError::from_device)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scripted::ScriptedDevice;
    use haptic_core::{Pose, device::Error as _, device::ErrorKind};

    fn still() -> ScriptedDevice {
        let l = DeviceLimits::new(3.0, 0.3, Vec3::repeat(-0.1), Vec3::repeat(0.1), 1000.0).unwrap();
        ScriptedDevice::stationary(Pose::identity(), l).unwrap()
    }

    fn kinds(d: &mut FaultInjector<ScriptedDevice>, n: usize) -> Vec<Option<ErrorKind>> {
        (0..n)
            .map(|i| d.read(i as Real * 1e-3).err().map(|e| e.kind()))
            .collect()
    }

    #[test]
    fn no_fault_passes_through() {
        let mut d = FaultInjector::new(still(), Fault::None);
        assert!(kinds(&mut d, 5).iter().all(Option::is_none));
        d.command(&Wrench::new(Vec3::x(), Vec3::zeros())).unwrap();
        assert_eq!(d.inner().last_command().force, Vec3::x());
        assert_eq!((d.fault(), d.reads()), (Fault::None, 5));
    }

    #[test]
    fn disconnect_is_for_good() {
        let mut d = FaultInjector::new(still(), Fault::DisconnectAfter { reads: 3 });
        let k = kinds(&mut d, 6);
        assert_eq!(&k[..3], &[None, None, None]);
        assert!(k[3..].iter().all(|k| *k == Some(ErrorKind::Disconnected)));
        assert!(d.is_disconnected());
        let e = d.command_zero().unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Disconnected);
        assert!(e.to_string().contains("after 3 reads"), "{e}");
        assert!(d.command(&Wrench::zero()).is_err());
    }

    #[test]
    fn nan_is_invalid_data_and_zero_force_still_works() {
        let mut d = FaultInjector::new(still(), Fault::NanAfter { reads: 2 });
        let k = kinds(&mut d, 4);
        assert_eq!(
            k,
            vec![
                None,
                None,
                Some(ErrorKind::InvalidData),
                Some(ErrorKind::InvalidData)
            ]
        );
        assert!(matches!(
            d.read(1.0),
            Err(DeviceError::NonFinite { what: "pose" })
        ));
        d.command_zero().unwrap();
        d.command(&Wrench::new(Vec3::y(), Vec3::zeros())).unwrap();

        let mut b = FaultInjector::new(
            still(),
            Fault::NanBurst {
                after_reads: 1,
                reads: 2,
            },
        );
        let bad = Some(ErrorKind::InvalidData);
        assert_eq!(kinds(&mut b, 5), vec![None, bad, bad, None, None]);
    }

    #[test]
    fn stall_times_out_then_recovers() {
        let mut d = FaultInjector::new(
            still(),
            Fault::StallAfter {
                reads: 2,
                duration_s: 0.0025,
            },
        );
        let to = Some(ErrorKind::Timeout);
        // Reads at 0, 1, 2, 3, 4, 5 ms: silent from 2 ms to 4.5 ms.
        assert_eq!(kinds(&mut d, 6), vec![None, None, to, to, to, None]);
        match d.read(0.0045 - 1e-9) {
            Ok(_) => {}
            Err(e) => panic!("recovered for good, got {e}"),
        }
        d.command_zero().unwrap();
        // During the stall commands time out too.
        let mut d = FaultInjector::new(
            still(),
            Fault::StallAfter {
                reads: 0,
                duration_s: 1.0,
            },
        );
        match d.read(0.5) {
            Err(DeviceError::Timeout { stalled_s }) => assert_eq!(stalled_s, 0.0),
            other => panic!("{other:?}"),
        }
        assert_eq!(d.command_zero().unwrap_err().kind(), ErrorKind::Timeout);
        match d.read(0.75) {
            Err(DeviceError::Timeout { stalled_s }) => assert_eq!(stalled_s, 0.25),
            other => panic!("{other:?}"),
        }
        assert!(d.read(1.5).is_ok());
        d.command_zero().unwrap();
    }

    #[test]
    fn inner_errors_keep_their_kind() {
        let nan = ScriptedDevice::from_fn(
            |_| Pose::from_position(Vec3::new(0.0, Real::NAN, 0.0)),
            still().limits(),
        );
        let mut d = FaultInjector::new(nan, Fault::None);
        assert_eq!(d.read(0.0).unwrap_err().kind(), ErrorKind::InvalidData);
        assert!(matches!(
            d.read(Real::NAN),
            Err(DeviceError::BadTime { .. })
        ));
    }
}
