//! `cargo xtask devices`: lands with the device issue.

/// Lists the devices.
pub fn run() -> anyhow::Result<()> {
    anyhow::bail!("`cargo xtask devices` lands with haptic-device")
}
