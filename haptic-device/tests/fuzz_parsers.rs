//! Short fuzzing of the device-side parsers in the default test run: the HID report parser and
//! the recording CSV reader never panic, on arbitrary bytes and on mutated valid input.

use haptic_device::{ReplayDevice, parse_report};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn hid_reports_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..40)) {
        let _ = parse_report(&bytes);
    }

    #[test]
    fn csv_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..800)) {
        let _ = ReplayDevice::from_reader(std::io::Cursor::new(bytes));
    }

    #[test]
    fn csv_text_lines_never_panic(lines in prop::collection::vec("[-0-9.,eE# a-z_:=]{0,60}", 0..12)) {
        let text = lines.join("\n");
        let _ = ReplayDevice::from_reader(std::io::Cursor::new(text.into_bytes()));
    }
}
