//! haptic-device (being written).
