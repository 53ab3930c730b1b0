//! The Python exceptions: one class per typed error of the Rust crates, all under
//! `haptic.HapticError`, each instance with `.field` (what was wrong, or `None`) and `.kind` (a
//! short word). `InputError` is also a `ValueError`. The classes are made when the module is
//! imported and kept for the interpreter's lifetime.

use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

/// The exception classes, by the name they have in Python.
pub struct Exceptions {
    base: Py<PyType>,
    classes: Vec<(&'static str, Py<PyType>)>,
}

static EXCEPTIONS: PyOnceLock<Exceptions> = PyOnceLock::new();

/// Every class below `HapticError`, with its docstring.
const CLASSES: [(&str, &str); 8] = [
    (
        "InputError",
        "An argument from Python with a wrong shape, dtype or value (NaN, empty, out of range).",
    ),
    (
        "MeshError",
        "A mesh file that cannot be read or parsed, or an invalid mesh.",
    ),
    ("SceneError", "A scene file or a scene field."),
    (
        "CollisionError",
        "A collision back-end that cannot be built or queried.",
    ),
    ("ClusterError", "Clustering parameters or contacts."),
    (
        "DynamicsError",
        "Penalty, coupling or rigid-body parameters.",
    ),
    ("DeviceError", "A device that failed; `.kind` says how."),
    (
        "PipelineError",
        "A run that stopped before its end; `.summary` holds the run up to the stop.",
    ),
];

fn make(py: Python<'_>) -> PyResult<Exceptions> {
    let builtins = py.import("builtins")?;
    let type_ = builtins.getattr("type")?;
    let new_class = |name: &str, bases: Bound<'_, PyTuple>, doc: &str| -> PyResult<Py<PyType>> {
        let ns = PyDict::new(py);
        ns.set_item("__doc__", doc)?;
        ns.set_item("__module__", "haptic")?;
        ns.set_item("field", py.None())?;
        ns.set_item("kind", "error")?;
        ns.set_item("summary", py.None())?;
        Ok(type_
            .call1((name, bases, ns))?
            .cast_into::<PyType>()?
            .unbind())
    };
    let base = new_class(
        "HapticError",
        PyTuple::new(py, [py.get_type::<PyException>()])?,
        "The base of every error of haptic. `.field`: the argument or field that was wrong \
         (or None); `.kind`: a short machine-readable word.",
    )?;
    let mut classes = Vec::new();
    for (name, doc) in CLASSES {
        let bases = if name == "InputError" {
            PyTuple::new(
                py,
                [
                    base.bind(py).clone().into_any(),
                    py.get_type::<PyValueError>().into_any(),
                ],
            )?
        } else {
            PyTuple::new(py, [base.bind(py).clone()])?
        };
        classes.push((name, new_class(name, bases, doc)?));
    }
    Ok(Exceptions { base, classes })
}

/// Adds the classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let e = EXCEPTIONS.get_or_try_init(py, || make(py))?;
    m.add("HapticError", e.base.bind(py))?;
    for (name, class) in &e.classes {
        m.add(*name, class.bind(py))?;
    }
    Ok(())
}

/// Which exception.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// `InputError`.
    Input,
    /// `MeshError`.
    Mesh,
    /// `SceneError`.
    Scene,
    /// `CollisionError`.
    Collision,
    /// `ClusterError`.
    Cluster,
    /// `DynamicsError`.
    Dynamics,
    /// `DeviceError`.
    Device,
    /// `PipelineError`.
    Pipeline,
}

impl Class {
    fn name(self) -> &'static str {
        match self {
            Class::Input => "InputError",
            Class::Mesh => "MeshError",
            Class::Scene => "SceneError",
            Class::Collision => "CollisionError",
            Class::Cluster => "ClusterError",
            Class::Dynamics => "DynamicsError",
            Class::Device => "DeviceError",
            Class::Pipeline => "PipelineError",
        }
    }
}

/// An exception of `class` with its message, field and kind.
pub fn error(class: Class, message: impl Into<String>, field: Option<&str>, kind: &str) -> PyErr {
    Python::attach(|py| {
        let made = EXCEPTIONS.get_or_try_init(py, || make(py));
        let e = match made {
            Ok(e) => e,
            Err(err) => return err,
        };
        let Some((_, ty)) = e.classes.iter().find(|(n, _)| *n == class.name()) else {
            return PyValueError::new_err(message.into());
        };
        let err = PyErr::from_type(ty.bind(py).clone(), message.into());
        let value = err.value(py);
        let set = value
            .setattr("field", field)
            .and_then(|()| value.setattr("kind", kind));
        match set {
            Ok(()) => err,
            Err(e) => e,
        }
    })
}

/// An `InputError` for the argument `field`.
pub fn input(field: &str, message: impl std::fmt::Display) -> PyErr {
    error(
        Class::Input,
        format!("{field}: {message}"),
        Some(field),
        "invalid_input",
    )
}

/// The field a `haptic_core::CoreError` names, if it names one.
fn core_field(e: &haptic_core::CoreError) -> Option<String> {
    use haptic_core::CoreError as C;
    match e {
        C::OutOfRange { what, .. } | C::NonFinite { what } => Some((*what).to_owned()),
        C::NonPositiveMass { .. } => Some("mass_kg".to_owned()),
        C::InertiaNotSymmetric { .. }
        | C::InertiaNotPositiveDefinite { .. }
        | C::InertiaNotPhysical => Some("inertia_kg_m2".to_owned()),
        C::BadNormal { .. } => Some("n".to_owned()),
        _ => None,
    }
}

/// A core error (bad parameter, non-finite value) as an exception of `class`.
pub fn from_core(class: Class, e: &haptic_core::CoreError) -> PyErr {
    let field = core_field(e);
    error(class, e.to_string(), field.as_deref(), "invalid_parameter")
}

/// A mesh error.
pub fn from_mesh(e: &haptic_collision::MeshError) -> PyErr {
    use haptic_collision::MeshError as M;
    let kind = match e {
        M::Empty => "empty",
        M::NonFiniteVertex { .. } => "non_finite_vertex",
        M::IndexOutOfRange { .. } => "index_out_of_range",
        M::DegenerateTriangles { .. } => "degenerate_triangles",
        M::NonOrientable { .. } => "non_orientable",
        M::InconsistentWinding { .. } => "inconsistent_winding",
        M::Io { .. } => "io",
        _ => "invalid_mesh",
    };
    let field = match e {
        M::NonFiniteVertex { .. } => Some("vertices"),
        M::Empty
        | M::IndexOutOfRange { .. }
        | M::DegenerateTriangles { .. }
        | M::NonOrientable { .. }
        | M::InconsistentWinding { .. } => Some("triangles"),
        // Unreadable, of an unknown format or unparsable: the file.
        _ => Some("path"),
    };
    error(Class::Mesh, e.to_string(), field, kind)
}

/// A scene error, naming its field.
pub fn from_scene(e: &haptic_runtime::SceneError) -> PyErr {
    use haptic_runtime::SceneError as S;
    match e {
        S::Invalid { field, .. } => {
            error(Class::Scene, e.to_string(), Some(field), "invalid_field")
        }
        _ => error(Class::Scene, e.to_string(), None, "unreadable"),
    }
}

/// A back-end error (LOD or parry) as a `CollisionError`.
pub fn collision(e: &dyn std::error::Error) -> PyErr {
    error(Class::Collision, e.to_string(), None, "collision")
}

/// A clustering error.
pub fn from_cluster(e: &haptic_cluster::ClusterError) -> PyErr {
    use haptic_cluster::ClusterError as C;
    let (field, kind) = match e {
        C::ZeroClusters | C::TooManyClusters { .. } => (Some("max_clusters"), "invalid_parameter"),
        C::ZeroIterations | C::TooManyIterations { .. } => {
            (Some("max_iterations"), "invalid_parameter")
        }
        C::BadDelta { .. } => (Some("delta"), "invalid_parameter"),
        C::NonFiniteContact { .. } | C::BadNormal { .. } => (Some("contacts"), "invalid_contact"),
        _ => (None, "cluster"),
    };
    error(Class::Cluster, e.to_string(), field, kind)
}

/// A dynamics error (parameters of the penalty model, the coupling, a rigid body).
pub fn from_dynamics(e: &haptic_dynamics::DynamicsError) -> PyErr {
    match e {
        haptic_dynamics::DynamicsError::Core(core) => from_core(Class::Dynamics, core),
        _ => error(Class::Dynamics, e.to_string(), None, "dynamics"),
    }
}

/// The word for a device error kind.
pub fn device_kind(kind: haptic_core::device::ErrorKind) -> &'static str {
    use haptic_core::device::ErrorKind as K;
    match kind {
        K::Disconnected => "disconnected",
        K::Timeout => "timeout",
        K::NotFound => "not_found",
        K::InvalidData => "invalid_data",
        K::CommandRejected => "command_rejected",
        _ => "other",
    }
}

/// A runtime error: a configuration error names its field; a run that stopped carries its
/// summary (as a dict) in `.summary`.
pub fn from_runtime(e: &haptic_runtime::RuntimeError) -> PyErr {
    use haptic_runtime::RuntimeError as R;
    let err = match e {
        R::Config { field, .. } => {
            error(Class::Input, e.to_string(), Some(field), "invalid_config")
        }
        R::Scene(s) => from_scene(s),
        R::Grasp(d) => from_dynamics(d),
        R::Device { kind, .. } => error(
            Class::Device,
            e.to_string(),
            Some("device"),
            device_kind(*kind),
        ),
        R::HapticPanic { .. } => error(Class::Pipeline, e.to_string(), None, "haptic_panic"),
        R::NonFiniteFirstReading => {
            error(Class::Device, e.to_string(), Some("device"), "invalid_data")
        }
        _ => error(Class::Pipeline, e.to_string(), None, "pipeline"),
    };
    if let Some(summary) = e.summary() {
        Python::attach(|py| {
            if let Ok(dict) = crate::pipeline::summary_dict(py, summary) {
                let _ = err.value(py).setattr("summary", dict);
            }
        });
    }
    err
}
