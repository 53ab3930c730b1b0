//! # haptic-dynamics (being written)
//!
//! The rigid-body tool, the virtual coupling with device saturation, the penalty contact model and
//! the integrators.

pub mod penalty;
