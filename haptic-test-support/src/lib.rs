//! Fixtures shared by the workspace's tests and benchmarks, in one place: a counting global
//! allocator, an analytic box-on-floor back-end and its hand, the drifting contact patch the
//! clustering benches use, the jaws' pose path, and a deterministic random generator. Not published (`publish = false`); a
//! dev-dependency only.

pub mod alloc;
pub mod box_on_floor;
pub mod contacts;
pub mod poses;
pub mod rng;
