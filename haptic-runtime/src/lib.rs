//! haptic-runtime (being written).
