#![no_main]
//! The scene parser never panics.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    if let Ok(text) = std::str::from_utf8(bytes) {
        let _ = haptic_runtime::Scene::from_toml_str(text, std::path::Path::new("."));
    }
});
