//! # haptic-collision
//!
//! Mesh loading and collision back-ends (being written).

pub mod geometry;
pub mod lod;
pub mod mesh;
pub mod reference;

pub use lod::LodBackend;
pub use mesh::{DegeneratePolicy, MeshError, TriMesh};
