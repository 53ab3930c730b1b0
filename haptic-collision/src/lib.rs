//! # haptic-collision
//!
//! Tool-against-obstacles collision detection for 6-DOF haptic rendering (Otaduy & Lin 2006,
//! Section VI-A), behind `haptic_core::CollisionBackend`.
//!
//! It owns:
//! - [`TriMesh`]: validated triangle meshes, loaded from STL (binary and ASCII), OBJ and PLY with
//!   a unit scale ([`TriMesh::load`], [`LoadOptions`]), and the mass properties of the solid
//!   they bound ([`TriMesh::mass_properties`]);
//! - [`LodBackend`]: the native sensation-preserving multiresolution back-end (ref. \[9\] of the
//!   paper), exact at error threshold 0;
//! - `ParryBackend` (cargo feature `parry`, on by default): parry3d-f64's triangle-mesh contact
//!   manifolds, as a second implementation and a reference; nothing of parry is compiled
//!   without the feature;
//! - [`reference::ReferenceBackend`]: all triangle pairs, for tests on small meshes;
//! - [`compact::Compactor`]: raw contacts merged into a few that keep what the clustering and
//!   the force read; `LodBackend` reports compact contacts by default.
//!
//! It does not own clustering (`haptic-cluster`), contact forces (`haptic-dynamics`) or the
//! pipeline (`haptic-runtime`).
//!
//! Contact convention (docs/formulation.md): `p_a` on the tool, `r_a` the same point in the
//! tool's body frame, `p_b` on the obstacle, `n` unit and out of the tool, `depth_m` positive
//! inside and down to `−δ` when apart, `area_m2` the tool surface the contact stands for (a pair's
//! region in `LodBackend` and the reference, `slab.rs`; a share of its tool triangle in parry). How each back-end measures depth
//! inside an overlap is in its module docs.

#[cfg(feature = "parry")]
mod area;
pub mod compact;
pub mod geometry;
pub mod lod;
pub mod mesh;
#[cfg(feature = "parry")]
pub mod parry;
pub mod reference;
mod slab;

pub use lod::{DEFAULT_MAX_CONTACTS, LodBackend, StoppingRule, UnknownStoppingRule};
pub use mesh::{
    CoincidentTriangles, DegeneratePolicy, LoadOptions, LoadReport, MassProperties, MeshError,
    MeshFormat, TriMesh, WindingPolicy,
};
#[cfg(feature = "parry")]
pub use parry::{ParryBackend, ParryError, ParryOptions};
