//! haptic-cluster (being written).
