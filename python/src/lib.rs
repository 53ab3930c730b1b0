//! `haptic._haptic`: the extension module behind the `haptic` Python package (see
//! `python/README.md` for the API and `python/python/haptic/__init__.pyi` for its types). Meshes,
//! back-ends, clustering, the penalty model, scenes, virtual- and real-time runs, and a force
//! server for a simulator that runs slower than the hand. Arrays are numpy's; every error is an
//! exception under `haptic.HapticError` naming what was wrong; long calls release the GIL.

mod cluster;
mod convert;
mod errors;
mod mesh;
mod parts;
mod pipeline;
mod query;
mod server;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _haptic(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<mesh::PyMesh>()?;
    m.add_class::<mesh::PyMassProperties>()?;
    m.add_class::<query::PyContacts>()?;
    m.add_class::<query::PyQueryStats>()?;
    m.add_class::<query::PyLodBackend>()?;
    m.add_class::<query::PyParryBackend>()?;
    m.add_class::<cluster::PyClusterer>()?;
    m.add_class::<cluster::PyRigidBody>()?;
    m.add_class::<cluster::PyPenaltyModel>()?;
    m.add_class::<parts::PyScene>()?;
    m.add_class::<server::PyForceServer>()?;
    pipeline::register(m)?;
    Ok(())
}
