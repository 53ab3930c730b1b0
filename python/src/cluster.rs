//! `haptic.Clusterer`, `haptic.RigidBody` and `haptic.PenaltyModel`: contact clustering with
//! warm start (eqs. 28–32) and the penalty wrench of a contact set (eq. 33).

use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{ContactModel, ContactSet, Kinematics, RigidBody, ToolState};
use haptic_dynamics::{PenaltyModel, PenaltyParams};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert;
use crate::errors::{Class, error, from_cluster, from_core, from_dynamics};
use crate::mesh::PyMassProperties;
use crate::query::PyContacts;

/// Reduces contacts to at most `max_clusters` clusters (weighted k-means, weights
/// `area (depth + δ)`), warm-started from the previous call's clusters when `warm_start`, each
/// written as a torque pair of two springs (`torque_pairs`, the default) or as one.
#[pyclass(module = "haptic", name = "Clusterer", frozen)]
pub struct PyClusterer {
    inner: std::sync::Mutex<(Clusterer, ContactSet)>,
}

impl PyClusterer {
    fn lock(&self) -> std::sync::MutexGuard<'_, (Clusterer, ContactSet)> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[pymethods]
impl PyClusterer {
    #[new]
    #[pyo3(signature = (max_clusters = None, max_iterations = None, warm_start = None,
        torque_pairs = None))]
    fn new(
        max_clusters: Option<usize>,
        max_iterations: Option<usize>,
        warm_start: Option<bool>,
        torque_pairs: Option<bool>,
    ) -> PyResult<Self> {
        let d = ClusterParams::default();
        let params = ClusterParams {
            max_clusters: max_clusters.unwrap_or(d.max_clusters),
            max_iterations: max_iterations.unwrap_or(d.max_iterations),
            warm_start: warm_start.unwrap_or(d.warm_start),
            torque_pairs: torque_pairs.unwrap_or(d.torque_pairs),
        };
        let clusterer = Clusterer::new(params).map_err(|e| from_cluster(&e))?;
        Ok(Self {
            inner: std::sync::Mutex::new((clusterer, ContactSet::new())),
        })
    }

    /// The representatives of `contacts` queried with tolerance `delta` (m). The GIL is
    /// released while clustering (the clusterer's lock is taken after it is released).
    fn cluster(
        &self,
        py: Python<'_>,
        contacts: PyRef<'_, PyContacts>,
        delta: f64,
    ) -> PyResult<PyContacts> {
        let input = &contacts.contacts;
        let reps = py.detach(|| {
            let mut guard = self.lock();
            let (clusterer, out) = &mut *guard;
            clusterer
                .cluster(input, delta, out)
                .map(|_| out.as_slice().to_vec())
        });
        Ok(PyContacts {
            contacts: reps.map_err(|e| from_cluster(&e))?,
        })
    }

    /// The weight of each representative of the last call (m³ with areas, m without): the sum
    /// of its contacts' `area (depth + δ)`, half each for a torque pair's two springs.
    #[getter]
    fn representative_weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let weights = self.lock().0.representative_weights().to_vec();
        convert::array1(py, weights)
    }

    /// Forgets the warm-start history.
    fn reset(&self) {
        self.lock().0.reset();
    }

    /// Most clusters (K).
    #[getter]
    fn max_clusters(&self) -> usize {
        self.lock().0.params().max_clusters
    }

    /// Whether each cluster is written as a torque pair of two springs.
    #[getter]
    fn torque_pairs(&self) -> bool {
        self.lock().0.params().torque_pairs
    }
}

/// A rigid body: mass (kg) and body-frame inertia about the centre of mass (kg m², 3×3,
/// symmetric positive definite and physical).
#[pyclass(module = "haptic", name = "RigidBody", frozen)]
#[derive(Clone, Copy)]
pub struct PyRigidBody {
    pub(crate) body: RigidBody,
}

#[pymethods]
impl PyRigidBody {
    #[new]
    fn new(mass_kg: f64, inertia_kg_m2: &Bound<'_, PyAny>) -> PyResult<Self> {
        if !mass_kg.is_finite() {
            return Err(crate::errors::input(
                "mass_kg",
                format!("must be finite, got {mass_kg}"),
            ));
        }
        let inertia = convert::mat3(inertia_kg_m2, "inertia_kg_m2")?;
        let body = RigidBody::new(mass_kg, inertia).map_err(|e| from_core(Class::Dynamics, &e))?;
        Ok(Self { body })
    }

    /// The body of a mesh's mass properties (body frame at the centre of mass, mesh axes).
    #[staticmethod]
    fn from_mass_properties(mp: PyRef<'_, PyMassProperties>) -> PyResult<Self> {
        let body = mp
            .mp
            .rigid_body()
            .map_err(|e| from_core(Class::Dynamics, &e))?;
        Ok(Self { body })
    }

    /// Mass (kg).
    #[getter]
    fn mass_kg(&self) -> f64 {
        self.body.mass_kg()
    }

    /// Body-frame inertia (kg m²), `(3, 3)`.
    #[getter]
    fn inertia_kg_m2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let m = self.body.inertia_body();
        let rows: Vec<[f64; 3]> = (0..3).map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]).collect();
        convert::array_rows(py, &rows)
    }
}

/// The penalty contact model: per contact a spring `stiffness_n_per_m` and damper
/// `damping_ns_per_m` along its normal, pushing from `delta_m` before the surfaces touch.
#[pyclass(module = "haptic", name = "PenaltyModel")]
pub struct PyPenaltyModel {
    model: PenaltyModel,
}

#[pymethods]
impl PyPenaltyModel {
    #[new]
    #[pyo3(signature = (stiffness_n_per_m = 2000.0, damping_ns_per_m = 2.0, delta_m = 1e-3))]
    fn new(stiffness_n_per_m: f64, damping_ns_per_m: f64, delta_m: f64) -> PyResult<Self> {
        let params = PenaltyParams::new(stiffness_n_per_m, damping_ns_per_m, delta_m)
            .map_err(|e| from_dynamics(&e))?;
        let model = PenaltyModel::new(params).map_err(|e| from_dynamics(&e))?;
        Ok(Self { model })
    }

    /// The contact wrench on the tool `(force (3,), torque (3,))` (N, N m about its centre of
    /// mass, world frame) of `contacts` with the tool `body` at `pose`, moving at `velocity`
    /// (m/s) and `angular_velocity` (rad/s, world frame); at rest by default.
    #[pyo3(signature = (body, pose, contacts, velocity = None, angular_velocity = None))]
    fn wrench<'py>(
        &mut self,
        py: Python<'py>,
        body: PyRef<'_, PyRigidBody>,
        pose: &Bound<'_, PyAny>,
        contacts: PyRef<'_, PyContacts>,
        velocity: Option<&Bound<'_, PyAny>>,
        angular_velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<convert::ArrayPair<'py>> {
        let pose = convert::pose(pose, "pose")?;
        let body = body.body;
        let v = match velocity {
            Some(v) => convert::vec3(v, "velocity")?,
            None => haptic_core::Vec3::zeros(),
        };
        let w = match angular_velocity {
            Some(w) => convert::vec3(w, "angular_velocity")?,
            None => haptic_core::Vec3::zeros(),
        };
        let r = pose.orientation.to_rotation_matrix();
        let inertia_world = r.matrix() * body.inertia_body() * r.matrix().transpose();
        let state = ToolState {
            p: v * body.mass_kg(),
            l: inertia_world * w,
            ..ToolState::at_rest(&pose)
        };
        let y = state.to_vector();
        let kin = Kinematics::new(&body, &y);
        let wrench = self
            .model
            .evaluate(&body, &y, &kin, &contacts.contacts, None)
            .map_err(|e| {
                error(
                    Class::Dynamics,
                    e.to_string(),
                    Some("contacts"),
                    "invalid_contact",
                )
            })?;
        let f = wrench.force;
        let t = wrench.torque;
        Ok((
            convert::array1(py, vec![f.x, f.y, f.z]),
            convert::array1(py, vec![t.x, t.y, t.z]),
        ))
    }
}
