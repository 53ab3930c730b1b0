//! haptic-dynamics (being written).
