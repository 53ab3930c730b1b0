#![no_main]
//! The SpaceMouse HID report parser never panics.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let _ = haptic_device::parse_report(bytes);
});
