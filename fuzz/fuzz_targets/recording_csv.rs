#![no_main]
//! The recording CSV reader never panics.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let _ = haptic_device::ReplayDevice::from_reader(std::io::Cursor::new(bytes));
});
