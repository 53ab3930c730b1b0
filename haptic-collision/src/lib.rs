//! # haptic-collision
//!
//! Mesh loading and collision back-ends (being written).

pub mod mesh;

pub use mesh::{DegeneratePolicy, MeshError, TriMesh};
