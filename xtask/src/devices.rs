//! `cargo xtask devices`: lists the simulated devices, and the SpaceMouse-class HID devices
//! attached. Exits 0 when there is none (or when HID enumeration is unavailable), saying so.
//! Writes the listing to `target/xtask/devices/devices.json`.

use haptic_core::{Device, DeviceLimits, Pose, Vec3};
use haptic_device::{
    HandDevice, HandParams, SIMULATED_DEVICES, ScriptedDevice, SpaceMouseConfig, Waypoint,
};
use serde::Serialize;

use crate::common;

/// A quick check that the simulated hand runs: one second of a 5 cm reach, zero feedback.
fn hand_check() -> anyhow::Result<(f64, f64)> {
    let limits = DeviceLimits::new(5.0, 0.5, Vec3::repeat(-0.2), Vec3::repeat(0.2), 1000.0)?;
    let end = Pose::from_position(Vec3::new(0.05, 0.0, 0.0));
    let waypoints = vec![
        Waypoint::new(0.0, Pose::identity()),
        Waypoint::new(1.0, end),
    ];
    let mut target = ScriptedDevice::from_waypoints(waypoints.clone(), limits)?;
    let mut hand = HandDevice::new(
        HandParams::default(),
        ScriptedDevice::from_waypoints(waypoints, limits)?,
        limits,
    )?;
    let mut max_err_m: f64 = 0.0;
    let mut last_x = 0.0;
    for n in 0..=1500 {
        let t = n as f64 * 1e-3;
        let s = hand.read(t)?;
        hand.command_zero()?;
        max_err_m = max_err_m.max((s.pose.position - target.read(t)?.pose.position).norm());
        last_x = s.pose.position.x;
    }
    Ok((max_err_m, last_x))
}

/// Lists the devices.
pub fn run() -> anyhow::Result<()> {
    println!("Simulated devices (haptic-device):");
    for (name, what) in SIMULATED_DEVICES {
        println!("  {name:<17} {what}");
    }
    let (err_m, x_m) = hand_check()?;
    println!(
        "  self-check: simulated hand on a 5 cm, 1 s reach: max tracking error {:.2} mm, at \
         {:.2} mm after 1.5 s",
        err_m * 1e3,
        x_m * 1e3
    );

    println!("\nHID devices (3Dconnexion SpaceMouse class, hidapi without system libraries):");
    let limits = SpaceMouseConfig::default().limits()?;
    let (hid_status, hid_list) = match haptic_device::list_hid_devices() {
        Err(e) => {
            println!("  HID enumeration is not available here ({e}); simulated devices only.");
            ("unavailable".to_owned(), Vec::new())
        }
        Ok(all) => {
            let mice: Vec<_> = all.iter().filter(|d| d.is_spacemouse()).collect();
            if mice.is_empty() {
                println!(
                    "  No SpaceMouse-class device found ({} other HID device(s) visible). Plug \
                     one in (and make /dev/hidraw* readable) to use it; simulated devices work \
                     without.",
                    all.len()
                );
            }
            for d in &mice {
                println!(
                    "  {} [{:04x}:{:04x}] {} {} at {} (input only: max force {} N)",
                    d.model.unwrap_or("6-DOF device"),
                    d.vendor_id,
                    d.product_id,
                    d.manufacturer,
                    d.product,
                    d.path,
                    limits.max_force_n
                );
            }
            let list = mice
                .iter()
                .map(|d| HidEntry {
                    model: d.model,
                    vendor_id: d.vendor_id,
                    product_id: d.product_id,
                    product: d.product.clone(),
                    manufacturer: d.manufacturer.clone(),
                    path: d.path.clone(),
                })
                .collect();
            (format!("{} found", mice.len()), list)
        }
    };

    let dir = common::repo_root()
        .join("target")
        .join("xtask")
        .join("devices");
    std::fs::create_dir_all(&dir)?;
    let simulated = SIMULATED_DEVICES
        .iter()
        .map(|&(name, description)| Simulated { name, description })
        .collect();
    common::write_json(
        &dir.join("devices.json"),
        &DevicesReport {
            simulated,
            hand_self_check: HandCheck {
                max_tracking_error_m: err_m,
                final_x_m: x_m,
            },
            hid_status,
            hid: hid_list,
        },
    )?;
    Ok(())
}

/// A simulated device of `devices.json`.
#[derive(Serialize)]
struct Simulated {
    name: &'static str,
    description: &'static str,
}

/// A HID device found.
#[derive(Serialize)]
struct HidEntry {
    model: Option<&'static str>,
    vendor_id: u16,
    product_id: u16,
    product: String,
    manufacturer: String,
    path: String,
}

/// The simulated hand's self-check.
#[derive(Serialize)]
struct HandCheck {
    max_tracking_error_m: f64,
    final_x_m: f64,
}

/// `devices.json`.
#[derive(Serialize)]
struct DevicesReport {
    simulated: Vec<Simulated>,
    hand_self_check: HandCheck,
    hid_status: String,
    hid: Vec<HidEntry>,
}
