//! haptic-collision (being written).
