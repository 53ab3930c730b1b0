//! The SpaceMouse-class HID driver (feature `hid`): enumeration, opening, and a [`Device`] that
//! drains the device's reports into a [`SpaceMouseTracker`] at each read.
//!
//! hidapi is built with its pure-Rust Linux backend (`linux-native-basic-udev`): hidraw nodes,
//! no libudev, no system library at build time. The device has no force output: its limits say
//! zero force and torque, and commands are accepted and dropped.

use std::ffi::CString;

use haptic_core::{Device, DeviceLimits, DeviceState, Real, Wrench};

use crate::error::DeviceError;
use crate::spacemouse::{SpaceMouseConfig, SpaceMouseTracker};

/// USB vendor id of 3Dconnexion.
pub const VENDOR_3DCONNEXION: u16 = 0x256f;
/// USB vendor id of Logitech, under which 3Dconnexion's older devices enumerate.
pub const VENDOR_LOGITECH: u16 = 0x046d;

/// Known 6-DOF devices: `(vendor, product, model)`. 3Dconnexion mice (CadMouse) and keyboards
/// are not listed.
pub const KNOWN_DEVICES: &[(u16, u16, &str)] = &[
    (VENDOR_LOGITECH, 0xc603, "SpaceMouse Plus XT"),
    (VENDOR_LOGITECH, 0xc605, "CADman"),
    (VENDOR_LOGITECH, 0xc606, "SpaceMouse Classic"),
    (VENDOR_LOGITECH, 0xc621, "SpaceBall 5000"),
    (VENDOR_LOGITECH, 0xc623, "SpaceTraveler"),
    (VENDOR_LOGITECH, 0xc625, "SpacePilot"),
    (VENDOR_LOGITECH, 0xc626, "SpaceNavigator"),
    (VENDOR_LOGITECH, 0xc627, "SpaceExplorer"),
    (VENDOR_LOGITECH, 0xc628, "SpaceNavigator for Notebooks"),
    (VENDOR_LOGITECH, 0xc629, "SpacePilot Pro"),
    (VENDOR_LOGITECH, 0xc62b, "SpaceMouse Pro"),
    (VENDOR_3DCONNEXION, 0xc62e, "SpaceMouse Wireless (cable)"),
    (VENDOR_3DCONNEXION, 0xc62f, "SpaceMouse Wireless (receiver)"),
    (
        VENDOR_3DCONNEXION,
        0xc631,
        "SpaceMouse Pro Wireless (cable)",
    ),
    (
        VENDOR_3DCONNEXION,
        0xc632,
        "SpaceMouse Pro Wireless (receiver)",
    ),
    (VENDOR_3DCONNEXION, 0xc633, "SpaceMouse Enterprise"),
    (VENDOR_3DCONNEXION, 0xc635, "SpaceMouse Compact"),
    (VENDOR_3DCONNEXION, 0xc636, "SpaceMouse Module"),
    (VENDOR_3DCONNEXION, 0xc652, "Universal Receiver"),
];

/// The model name of a known 6-DOF device.
pub fn known_model(vendor_id: u16, product_id: u16) -> Option<&'static str> {
    KNOWN_DEVICES
        .iter()
        .find(|(v, p, _)| *v == vendor_id && *p == product_id)
        .map(|(_, _, m)| *m)
}

/// A HID device found by enumeration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HidDeviceInfo {
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
    /// Product string reported by the device (empty if none).
    pub product: String,
    /// Manufacturer string reported by the device (empty if none).
    pub manufacturer: String,
    /// Platform path (a hidraw node on Linux).
    pub path: String,
    /// The model, when the vendor and product ids are in [`KNOWN_DEVICES`].
    pub model: Option<&'static str>,
}

impl HidDeviceInfo {
    /// Whether this is a known 6-DOF device.
    pub fn is_spacemouse(&self) -> bool {
        self.model.is_some()
    }
}

fn hid_error(operation: &'static str) -> impl Fn(hidapi::HidError) -> DeviceError {
    move |e| DeviceError::Hid {
        operation,
        message: e.to_string(),
    }
}

/// Every HID device visible to this process.
///
/// # Errors
/// [`DeviceError::Hid`] if hidapi cannot start or enumerate (no hidraw support, say).
pub fn list_hid_devices() -> Result<Vec<HidDeviceInfo>, DeviceError> {
    let api = hidapi::HidApi::new().map_err(hid_error("enumerating HID devices"))?;
    let mut out: Vec<HidDeviceInfo> = api
        .device_list()
        .map(|d| HidDeviceInfo {
            vendor_id: d.vendor_id(),
            product_id: d.product_id(),
            product: d.product_string().unwrap_or_default().to_owned(),
            manufacturer: d.manufacturer_string().unwrap_or_default().to_owned(),
            path: d.path().to_string_lossy().into_owned(),
            model: known_model(d.vendor_id(), d.product_id()),
        })
        .collect();
    // One entry per node (a device with several interfaces or usages may repeat).
    out.sort_by(|a, b| a.path.cmp(&b.path));
    out.dedup_by(|a, b| a.path == b.path);
    Ok(out)
}

/// The attached SpaceMouse-class devices.
///
/// # Errors
/// As [`list_hid_devices`].
pub fn list_spacemice() -> Result<Vec<HidDeviceInfo>, DeviceError> {
    Ok(list_hid_devices()?
        .into_iter()
        .filter(HidDeviceInfo::is_spacemouse)
        .collect())
}

/// Most reports drained in one read (the device sends at most a few per millisecond).
const MAX_REPORTS_PER_READ: usize = 64;

/// A 3Dconnexion SpaceMouse-class device as a [`Device`]: a 6-DOF input with buttons and no
/// force output.
pub struct SpaceMouse {
    device: hidapi::HidDevice,
    tracker: SpaceMouseTracker,
    name: String,
    buf: [u8; 64],
}

impl std::fmt::Debug for SpaceMouse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SpaceMouse")
            .field("name", &self.name)
            .field("tracker", &self.tracker)
            .finish_non_exhaustive()
    }
}

impl SpaceMouse {
    /// Opens the first attached SpaceMouse-class device.
    ///
    /// # Errors
    /// [`DeviceError::NotFound`] when none is attached (or none is readable);
    /// [`DeviceError::Hid`] if enumeration or opening fails; a configuration error from
    /// [`SpaceMouseTracker::new`].
    pub fn open_first(config: SpaceMouseConfig) -> Result<Self, DeviceError> {
        let found = list_spacemice()?;
        let Some(info) = found.first() else {
            return Err(DeviceError::NotFound {
                detail: "no 3Dconnexion SpaceMouse-class HID device is attached (or readable: \
                         check the permissions of /dev/hidraw*)"
                    .to_owned(),
            });
        };
        Self::open(info, config)
    }

    /// Opens the device `info` describes.
    ///
    /// # Errors
    /// [`DeviceError::Hid`] if it cannot be opened; a configuration error from
    /// [`SpaceMouseTracker::new`].
    pub fn open(info: &HidDeviceInfo, config: SpaceMouseConfig) -> Result<Self, DeviceError> {
        let tracker = SpaceMouseTracker::new(config)?;
        let api = hidapi::HidApi::new().map_err(hid_error("starting hidapi"))?;
        let path = CString::new(info.path.as_bytes()).map_err(|_| DeviceError::Hid {
            operation: "opening a HID device",
            message: format!("path {:?} contains a NUL byte", info.path),
        })?;
        let device = api
            .open_path(&path)
            .map_err(hid_error("opening a HID device"))?;
        device
            .set_blocking_mode(false)
            .map_err(hid_error("setting non-blocking mode"))?;
        let name = format!(
            "{} ({:04x}:{:04x})",
            info.model.unwrap_or(if info.product.is_empty() {
                "HID 6-DOF device"
            } else {
                &info.product
            }),
            info.vendor_id,
            info.product_id
        );
        Ok(Self {
            device,
            tracker,
            name,
            buf: [0; 64],
        })
    }

    /// The report tracker (counts, deflections).
    pub fn tracker(&self) -> &SpaceMouseTracker {
        &self.tracker
    }
}

impl Device for SpaceMouse {
    type Error = DeviceError;

    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.tracker.limits()
    }

    /// Drains the reports waiting (without blocking), then maps the deflection to a pose.
    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        for _ in 0..MAX_REPORTS_PER_READ {
            match self.device.read_timeout(&mut self.buf, 0) {
                Ok(0) => break,
                Ok(n) => self.tracker.feed(&self.buf[..n])?,
                Err(e) => {
                    return Err(DeviceError::Disconnected {
                        detail: e.to_string(),
                    });
                }
            }
        }
        self.tracker.state(now_s)
    }

    /// No force output: accepted and dropped.
    fn command(&mut self, _wrench: &Wrench) -> Result<(), DeviceError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_models() {
        assert_eq!(known_model(0x046d, 0xc626), Some("SpaceNavigator"));
        assert_eq!(known_model(0x256f, 0xc635), Some("SpaceMouse Compact"));
        assert_eq!(known_model(0x256f, 0xc650), None); // a CadMouse
        assert_eq!(known_model(0x1234, 0xc626), None);
    }

    /// Off hardware, opening fails with `NotFound` naming the SpaceMouse, or (no hidraw support
    /// at all) with the HID error itself, never another kind; with one attached, it opens as a
    /// device that renders no force. The listing is consistent with the enumeration.
    #[test]
    fn enumeration_never_panics_and_open_first_says_not_found() {
        match SpaceMouse::open_first(SpaceMouseConfig::default()) {
            Ok(d) => assert_eq!(d.limits().max_force_n, 0.0),
            Err(e) => {
                let kind = haptic_core::device::Error::kind(&e);
                assert!(
                    matches!(
                        kind,
                        haptic_core::device::ErrorKind::NotFound
                            | haptic_core::device::ErrorKind::Other
                    ),
                    "{e}"
                );
                if kind == haptic_core::device::ErrorKind::NotFound {
                    assert!(e.to_string().contains("SpaceMouse"));
                } else {
                    assert!(matches!(e, DeviceError::Hid { .. }), "{e}");
                }
            }
        }
        if let Ok(all) = list_hid_devices() {
            let mice = list_spacemice().unwrap_or_default();
            assert!(mice.len() <= all.len());
            assert!(mice.iter().all(HidDeviceInfo::is_spacemouse));
        }
    }
}
