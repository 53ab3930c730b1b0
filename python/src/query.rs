//! `haptic.Contacts`, `haptic.QueryStats`, `haptic.LodBackend` and `haptic.ParryBackend`:
//! collision queries whose contacts come back as numpy arrays (no Python object per contact).

use std::sync::Mutex;
use std::time::Instant;

use haptic_collision::{LodBackend, ParryBackend, TriMesh};
use haptic_core::{CollisionBackend, Contact, ContactSet, Pose, QueryParams, Vec3};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert;
use crate::errors::{collision, input};
use crate::mesh::PyMesh;

/// A set of contacts as arrays: `p_a`, `r_a`, `p_b`, `n` `(k, 3)` float64, `depth` `(k,)`
/// float64 (m; negative within δ, not touching), `feature_a`, `feature_b` `(k,)` uint32 (the
/// triangle or node that produced each contact; 0xFFFFFFFF for none). Each property is a
/// fresh copy. Build one from arrays with `Contacts(p_a, r_a, p_b, n, depth)`: normals must be
/// unit (within 1e-6).
#[pyclass(module = "haptic", name = "Contacts", frozen)]
pub struct PyContacts {
    pub(crate) contacts: Vec<Contact>,
}

#[pymethods]
impl PyContacts {
    #[new]
    #[pyo3(signature = (p_a, r_a, p_b, n, depth, feature_a = None, feature_b = None, area = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        p_a: &Bound<'_, PyAny>,
        r_a: &Bound<'_, PyAny>,
        p_b: &Bound<'_, PyAny>,
        n: &Bound<'_, PyAny>,
        depth: &Bound<'_, PyAny>,
        feature_a: Option<&Bound<'_, PyAny>>,
        feature_b: Option<&Bound<'_, PyAny>>,
        area: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let p_a = convert::rows::<3>(p_a, "p_a", true)?;
        let k = p_a.len();
        let same = |rows: Vec<[f64; 3]>, field: &str| -> PyResult<Vec<[f64; 3]>> {
            if rows.len() == k {
                Ok(rows)
            } else {
                Err(input(
                    field,
                    format!("has {} rows, p_a has {k}", rows.len()),
                ))
            }
        };
        let r_a = same(convert::rows::<3>(r_a, "r_a", true)?, "r_a")?;
        let p_b = same(convert::rows::<3>(p_b, "p_b", true)?, "p_b")?;
        let n = same(convert::rows::<3>(n, "n", true)?, "n")?;
        let depth = convert::vector(depth, "depth", Some(k))?;
        let features = |f: Option<&Bound<'_, PyAny>>, field: &str| -> PyResult<Vec<u32>> {
            match f {
                None => Ok(vec![haptic_core::NO_FEATURE; k]),
                Some(f) => convert::vector(f, field, Some(k))?
                    .into_iter()
                    .map(|x| {
                        if x.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(&x) {
                            Ok(x as u32)
                        } else {
                            Err(input(field, format!("holds {x}: indices are uint32")))
                        }
                    })
                    .collect(),
            }
        };
        let fa = features(feature_a, "feature_a")?;
        let fb = features(feature_b, "feature_b")?;
        let area = match area {
            None => vec![0.0; k],
            Some(a) => convert::vector(a, "area", Some(k))?,
        };
        let v = |r: &[f64; 3]| Vec3::new(r[0], r[1], r[2]);
        let mut contacts = Vec::with_capacity(k);
        for i in 0..k {
            let c = Contact::new(v(&p_a[i]), v(&r_a[i]), v(&p_b[i]), v(&n[i]), depth[i])
                .map_err(|e| input("n", format!("contact {i}: {e}")))?
                .with_features(fa[i], fb[i])
                .with_area(area[i]);
            c.validate()
                .map_err(|e| input("area", format!("contact {i}: {e}")))?;
            contacts.push(c);
        }
        Ok(Self { contacts })
    }

    /// Points on the tool, world frame (m).
    #[getter]
    fn p_a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        convert::array3(py, self.contacts.iter().map(|c| c.p_a))
    }

    /// Points on the tool, tool body frame (m).
    #[getter]
    fn r_a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        convert::array3(py, self.contacts.iter().map(|c| c.r_a))
    }

    /// Points on the obstacle, world frame (m).
    #[getter]
    fn p_b<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        convert::array3(py, self.contacts.iter().map(|c| c.p_b))
    }

    /// Unit normals, out of the tool.
    #[getter]
    fn n<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        convert::array3(py, self.contacts.iter().map(|c| c.n))
    }

    /// Penetration depths (m): positive inside, negative (down to −δ) within δ.
    #[getter]
    fn depth<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        convert::array1(py, self.contacts.iter().map(|c| c.depth_m).collect())
    }

    /// Area of the tool's surface each contact stands for (m²; 0: not measured). The
    /// clustering weighs contacts by it when every contact has one.
    #[getter]
    fn area<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        convert::array1(py, self.contacts.iter().map(|c| c.area_m2).collect())
    }

    /// Share of the penalty stiffness and damping each contact pushes with: 1 for a contact
    /// from a back-end (or built from arrays); a clustered representative's share is its part
    /// of the `K` clusters' stiffness (`max_clusters` however many are written, where the
    /// contacts carry areas; those written where they do not), in proportion to the penalty its
    /// contacts make, so that the representatives' penalty depends neither on the partition nor
    /// on how many contacts a surface gave.
    #[getter]
    fn stiffness_share<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        convert::array1(
            py,
            self.contacts.iter().map(|c| c.stiffness_share).collect(),
        )
    }

    /// Tool feature of each contact (0xFFFFFFFF: none).
    #[getter]
    fn feature_a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        convert::array1(py, self.contacts.iter().map(|c| c.feature_a).collect())
    }

    /// Obstacle feature of each contact (0xFFFFFFFF: none).
    #[getter]
    fn feature_b<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        convert::array1(py, self.contacts.iter().map(|c| c.feature_b).collect())
    }

    fn __len__(&self) -> usize {
        self.contacts.len()
    }

    fn __repr__(&self) -> String {
        format!("Contacts({} contacts)", self.contacts.len())
    }
}

/// What a query did: whether the bounding volumes overlapped at all, how many node and
/// primitive pairs it tested, and its wall time (s).
#[pyclass(module = "haptic", name = "QueryStats", frozen, get_all)]
pub struct PyQueryStats {
    /// The broad phase found overlapping bounding volumes.
    broad_phase_hit: bool,
    /// Hierarchy node pairs tested.
    node_pairs_tested: u64,
    /// Primitive (triangle or convex piece) pairs tested.
    primitive_pairs_tested: u64,
    /// Contacts found before the back-end compacted them (0: it does not compact).
    raw_contacts: u64,
    /// Wall time of the query (s), measured in Rust.
    time_s: f64,
}

#[pymethods]
impl PyQueryStats {
    fn __repr__(&self) -> String {
        format!(
            "QueryStats(broad_phase_hit={}, node_pairs_tested={}, primitive_pairs_tested={}, raw_contacts={}, time_s={:.3e})",
            if self.broad_phase_hit {
                "True"
            } else {
                "False"
            },
            self.node_pairs_tested,
            self.primitive_pairs_tested,
            self.raw_contacts,
            self.time_s
        )
    }
}

/// `[(Mesh, pose), …]` as the back-ends take them.
fn obstacles(list: &Bound<'_, PyAny>) -> PyResult<Vec<(TriMesh, Pose)>> {
    let items: Vec<Bound<'_, PyAny>> = list
        .try_iter()
        .map_err(|_| input("obstacles", "must be a list of (Mesh, pose) pairs"))?
        .collect::<PyResult<_>>()?;
    let mut out = Vec::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        let field = format!("obstacles[{i}]");
        let (mesh, pose): (PyRef<'_, PyMesh>, Bound<'_, PyAny>) = item
            .extract()
            .map_err(|_| input(&field, "must be a (Mesh, pose) pair"))?;
        out.push((
            (*mesh.mesh).clone(),
            convert::pose(&pose, &format!("{field}.pose"))?,
        ));
    }
    Ok(out)
}

/// Runs one query of `backend` with the GIL released; the back-end's lock is taken after the
/// GIL is released, so that other Python threads wait for it without holding the GIL.
fn query<B: CollisionBackend + Send>(
    py: Python<'_>,
    inner: &Mutex<(B, ContactSet)>,
    pose: &Bound<'_, PyAny>,
    delta: f64,
    threshold: f64,
) -> PyResult<(PyContacts, PyQueryStats)> {
    let pose = convert::pose(pose, "pose")?;
    convert::positive(delta, "delta")?;
    convert::non_negative(threshold, "threshold")?;
    let params = QueryParams::new(delta, threshold).map_err(|e| input("threshold", e))?;
    let (result, contacts, time_s) = py.detach(|| {
        let mut guard = inner.lock().unwrap_or_else(|p| p.into_inner());
        let (backend, scratch) = &mut *guard;
        let start = Instant::now();
        let r = backend.query(&pose, &params, scratch);
        let time_s = start.elapsed().as_secs_f64();
        (r, scratch.as_slice().to_vec(), time_s)
    });
    let stats = result.map_err(|e| collision(&e))?;
    Ok((
        PyContacts { contacts },
        PyQueryStats {
            broad_phase_hit: stats.broad_phase_hit,
            node_pairs_tested: stats.node_pairs_tested,
            primitive_pairs_tested: stats.primitive_pairs_tested,
            raw_contacts: stats.raw_contacts,
            time_s,
        },
    ))
}

/// The native sensation-preserving multiresolution back-end: `LodBackend(tool, obstacles,
/// cache_dir=None, max_contacts=256, stopping_rule="coherence-budget")`, the tool mesh in its body
/// frame and `[(Mesh, pose), …]` the obstacles with their world poses. With `cache_dir`, each
/// hierarchy is read back from that folder when it was saved there for the same mesh, and built
/// and saved there otherwise (a file that cannot be used is rebuilt, never used).
/// `stopping_rule="coherence-budget"` (the default) is
/// `haptic_collision::StoppingRule::CoherenceBudget`, `"deviation"` the paper's
/// `StoppingRule::Deviation`, `"coherence"` `StoppingRule::DeviationAndCoherence`.
/// Building the hierarchies and querying release the GIL; one back-end may be used from several
/// Python threads (their queries take turns).
#[pyclass(module = "haptic", name = "LodBackend", frozen)]
pub struct PyLodBackend {
    inner: Mutex<(LodBackend, ContactSet)>,
    node_count: usize,
    radius_m: f64,
    cache: Vec<(String, String)>,
}

#[pymethods]
impl PyLodBackend {
    #[new]
    #[pyo3(signature = (tool, obstacles, cache_dir = None, max_contacts = Some(haptic_collision::DEFAULT_MAX_CONTACTS), stopping_rule = "coherence-budget"))]
    fn new(
        py: Python<'_>,
        tool: PyRef<'_, PyMesh>,
        obstacles: &Bound<'_, PyAny>,
        cache_dir: Option<std::path::PathBuf>,
        max_contacts: Option<usize>,
        stopping_rule: &str,
    ) -> PyResult<Self> {
        use haptic_collision::lod::CacheOutcome;
        let rule = convert::stopping_rule(stopping_rule, "stopping_rule")?;
        let obstacles = self::obstacles(obstacles)?;
        let tool = tool.mesh.clone();
        let (backend, cache) = py
            .detach(|| match &cache_dir {
                None => LodBackend::new(&tool, &obstacles).map(|b| (b, Vec::new())),
                Some(dir) => LodBackend::with_cache(&tool, &obstacles, dir),
            })
            .map_err(|e| collision(&e))?;
        let backend = backend
            .with_max_contacts(max_contacts)
            .with_stopping_rule(rule);
        let cache = cache
            .into_iter()
            .map(|o| match o {
                CacheOutcome::Loaded(p) => ("loaded".to_owned(), p.display().to_string()),
                CacheOutcome::Built(p) => ("built".to_owned(), p.display().to_string()),
                CacheOutcome::Rebuilt(p, why) => {
                    (format!("rebuilt: {why}"), p.display().to_string())
                }
                CacheOutcome::NotSaved(p, why) => {
                    (format!("not saved: {why}"), p.display().to_string())
                }
            })
            .collect();
        Ok(Self {
            node_count: backend.node_count(),
            radius_m: backend.tool_bounding_radius_m(),
            inner: Mutex::new((backend, ContactSet::with_capacity(256))),
            cache,
        })
    }

    /// With `cache_dir`: for the tool, then each obstacle, `(what happened, file)`, what being
    /// `"loaded"`, `"built"`, `"rebuilt: why"` or `"not saved: why"`; empty without.
    #[getter]
    fn cache_report(&self) -> Vec<(String, String)> {
        self.cache.clone()
    }

    /// The contacts of the tool at `pose` within `delta` (m), at the error `threshold` (a
    /// fraction of the tool's bounding radius; 0 is exact), and the query's statistics. The GIL
    /// is released during the query.
    #[pyo3(signature = (pose, delta, threshold = 0.0))]
    fn query(
        &self,
        py: Python<'_>,
        pose: &Bound<'_, PyAny>,
        delta: f64,
        threshold: f64,
    ) -> PyResult<(PyContacts, PyQueryStats)> {
        query(py, &self.inner, pose, delta, threshold)
    }

    /// Nodes in the hierarchies.
    #[getter]
    fn node_count(&self) -> usize {
        self.node_count
    }

    /// The tool's bounding radius about its body origin (m): the unit of `threshold`.
    #[getter]
    fn tool_bounding_radius_m(&self) -> f64 {
        self.radius_m
    }

    /// The error threshold a query within `delta` (m) at `threshold` holds: `threshold`, or at
    /// most `delta` over the tool's bounding radius under the rules that cap a piece's
    /// deviation at `delta` (`"coherence-budget"`, the default, and `"coherence"`)
    /// (`CollisionBackend::threshold_reached`).
    fn threshold_reached(&self, py: Python<'_>, delta: f64, threshold: f64) -> PyResult<f64> {
        let params = QueryParams::new(delta, threshold).map_err(|e| input("threshold", e))?;
        // Without the GIL while another thread's query holds the back-end, as `query` waits.
        Ok(py.detach(|| {
            let guard = self.inner.lock().unwrap_or_else(|p| p.into_inner());
            guard.0.threshold_reached(&params)
        }))
    }
}

/// The parry3d back-end (exact triangle-mesh contacts; the threshold is ignored), built like
/// `LodBackend`.
#[pyclass(module = "haptic", name = "ParryBackend", frozen)]
pub struct PyParryBackend {
    inner: Mutex<(ParryBackend, ContactSet)>,
    radius_m: f64,
}

#[pymethods]
impl PyParryBackend {
    #[new]
    fn new(
        py: Python<'_>,
        tool: PyRef<'_, PyMesh>,
        obstacles: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let obstacles = self::obstacles(obstacles)?;
        let tool = tool.mesh.clone();
        let backend = py
            .detach(|| ParryBackend::new(&tool, &obstacles))
            .map_err(|e| collision(&e))?;
        Ok(Self {
            radius_m: backend.tool_bounding_radius_m(),
            inner: Mutex::new((backend, ContactSet::with_capacity(256))),
        })
    }

    /// As `LodBackend.query`; `threshold` is accepted and ignored (parry is exact).
    #[pyo3(signature = (pose, delta, threshold = 0.0))]
    fn query(
        &self,
        py: Python<'_>,
        pose: &Bound<'_, PyAny>,
        delta: f64,
        threshold: f64,
    ) -> PyResult<(PyContacts, PyQueryStats)> {
        query(py, &self.inner, pose, delta, threshold)
    }

    /// The tool's bounding radius about its body origin (m).
    #[getter]
    fn tool_bounding_radius_m(&self) -> f64 {
        self.radius_m
    }
}
