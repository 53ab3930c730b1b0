//! What a Python run is assembled from: `haptic.Scene`, the back-end and device chosen at run
//! time (one enum each, matched per call: static dispatch inside, no `dyn` in the haptic loop),
//! and the integrator by name.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use haptic_collision::{LodBackend, ParryBackend};
use haptic_core::device::{Error as DeviceErrorTrait, ErrorKind};
use haptic_core::{
    CollisionBackend, ContactSet, Device, DeviceLimits, DeviceState, Pose, QueryParams, QueryStats,
    Real, Twist, Wrench,
};
use haptic_device::{HandDevice, ScriptedDevice, Waypoint};
use haptic_runtime::scene::{
    ContactSpec, CouplingSpec, DeviceSpec, ObstacleSpec, PoseSpec, RateSpec, ToolSpec, WaypointSpec,
};
use haptic_runtime::{SceneParts, scene::Scene as SceneSpec};
use pyo3::prelude::*;

use crate::convert;
use crate::errors::{from_scene, input};
use crate::mesh::PyMesh;

/// A scene ready to run: the tool (recentred on its centre of mass), the obstacles, the
/// parameters and the simulated hand's trajectory. `Scene.load(path)` reads a scene file;
/// `Scene.from_parts(...)` builds one from meshes and keywords, with a scene file's defaults.
#[pyclass(module = "haptic", name = "Scene", frozen)]
pub struct PyScene {
    pub(crate) name: String,
    pub(crate) parts: SceneParts,
}

fn scene_of(spec: &SceneSpec, parts: SceneParts) -> PyScene {
    PyScene {
        name: spec.name.clone(),
        parts,
    }
}

/// `[x, y, z, qw, qx, qy, qz]` as a scene file's pose (position and rotation vector).
fn pose_spec(p: &Pose) -> PoseSpec {
    let r = p.orientation.scaled_axis();
    PoseSpec::new(p.position.into(), [r.x, r.y, r.z])
}

#[pymethods]
impl PyScene {
    /// Reads a scene file (TOML) and loads its meshes (the GIL is released).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let spec = SceneSpec::load(&path).map_err(|e| from_scene(&e))?;
        let parts = py.detach(|| spec.assemble()).map_err(|e| from_scene(&e))?;
        Ok(scene_of(&spec, parts))
    }

    /// A scene from meshes and parameters, as a scene file would give them (see the README for
    /// every keyword and its default).
    #[staticmethod]
    #[pyo3(signature = (*, tool, mass_kg, tool_pose = None, obstacles = None, name = "scene".to_owned(),
        coupling_stiffness_n_per_m = 200.0, coupling_damping_ns_per_m = None,
        angular_stiffness_nm_per_rad = 0.6, angular_damping_nms_per_rad = None,
        contact_stiffness_n_per_m = 2000.0, contact_damping_ns_per_m = None, delta_m = 1e-3,
        clusters = 5, error_threshold = 0.0, linearized = true, fixed_frames = true,
        haptic_rate_hz = 1000.0,
        contact_rate_hz = None, waypoints = None, max_force_n = 10.0, max_torque_nm = 1.0,
        workspace_half_m = 0.5, time_budget_s = None, stopping_rule = "coherence-budget",
        torque_pairs = true))]
    fn from_parts(
        py: Python<'_>,
        tool: PyRef<'_, PyMesh>,
        mass_kg: f64,
        tool_pose: Option<&Bound<'_, PyAny>>,
        obstacles: Option<&Bound<'_, PyAny>>,
        name: String,
        coupling_stiffness_n_per_m: f64,
        coupling_damping_ns_per_m: Option<f64>,
        angular_stiffness_nm_per_rad: f64,
        angular_damping_nms_per_rad: Option<f64>,
        contact_stiffness_n_per_m: f64,
        contact_damping_ns_per_m: Option<f64>,
        delta_m: f64,
        clusters: usize,
        error_threshold: f64,
        linearized: bool,
        fixed_frames: bool,
        haptic_rate_hz: f64,
        contact_rate_hz: Option<f64>,
        waypoints: Option<&Bound<'_, PyAny>>,
        max_force_n: f64,
        max_torque_nm: f64,
        workspace_half_m: f64,
        time_budget_s: Option<f64>,
        stopping_rule: &str,
        torque_pairs: bool,
    ) -> PyResult<Self> {
        let stopping_rule = convert::stopping_rule(stopping_rule, "stopping_rule")?;
        let tool_pose = match tool_pose {
            Some(p) => convert::pose(p, "tool_pose")?,
            None => Pose::identity(),
        };
        let mut obstacle_specs = Vec::new();
        let mut obstacle_poses = Vec::new();
        let mut obstacle_meshes = Vec::new();
        if let Some(list) = obstacles {
            let items: Vec<Bound<'_, PyAny>> = list
                .try_iter()
                .map_err(|_| input("obstacles", "must be a list of (Mesh, pose) pairs"))?
                .collect::<PyResult<_>>()?;
            for (i, item) in items.iter().enumerate() {
                let field = format!("obstacles[{i}]");
                let (mesh, pose): (PyRef<'_, PyMesh>, Bound<'_, PyAny>) = item
                    .extract()
                    .map_err(|_| input(&field, "must be a (Mesh, pose) pair"))?;
                let pose = convert::pose(&pose, &format!("{field}.pose"))?;
                obstacle_poses.push(pose);
                obstacle_specs.push(ObstacleSpec {
                    mesh: PathBuf::from("<in memory>"),
                    scale_m_per_unit: 1.0,
                    pose: pose_spec(&pose),
                });
                obstacle_meshes.push((*mesh.mesh).clone());
            }
        }
        let waypoints = match waypoints {
            None => Vec::new(),
            Some(w) => waypoint_list(w, "waypoints")?
                .iter()
                .map(|w| {
                    let p = pose_spec(&w.pose);
                    WaypointSpec {
                        time_s: w.t_s,
                        position_m: p.position_m,
                        rotation_axis_angle_rad: p.rotation_axis_angle_rad,
                    }
                })
                .collect(),
        };
        let spec = SceneSpec {
            name,
            tool: ToolSpec {
                mesh: PathBuf::from("<in memory>"),
                scale_m_per_unit: 1.0,
                mass_kg,
                pose: pose_spec(&tool_pose),
            },
            obstacles: obstacle_specs,
            coupling: CouplingSpec {
                stiffness_n_per_m: coupling_stiffness_n_per_m,
                damping_ns_per_m: coupling_damping_ns_per_m,
                angular_stiffness_nm_per_rad,
                angular_damping_nms_per_rad,
            },
            contact: ContactSpec {
                stiffness_n_per_m: contact_stiffness_n_per_m,
                damping_ns_per_m: contact_damping_ns_per_m,
                delta_m,
                clusters,
                torque_pairs,
                error_threshold,
                linearized,
                fixed_frames,
                time_budget_s,
                stopping_rule,
            },
            rates: RateSpec {
                haptic_hz: haptic_rate_hz,
                contact_hz: contact_rate_hz,
            },
            device: DeviceSpec {
                waypoints,
                max_force_n,
                max_torque_nm,
                workspace_half_m,
            },
        };
        let tool_mesh = (*tool.mesh).clone();
        let mut parts = py
            .detach(|| spec.assemble_meshes(tool_mesh, obstacle_meshes))
            .map_err(|e| from_scene(&e))?;
        // The pose specs went through rotation vectors: keep the exact poses given.
        parts.tool_pose = tool_pose;
        for ((_, pose), exact) in parts.obstacles.iter_mut().zip(&obstacle_poses) {
            *pose = *exact;
        }
        Ok(scene_of(&spec, parts))
    }

    /// The scene's name.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The tool mesh in its body frame (origin at its centre of mass).
    #[getter]
    fn tool_mesh(&self) -> PyMesh {
        PyMesh::wrap(self.parts.tool_mesh.clone(), 0)
    }

    /// The tool's initial pose (its centre of mass), `(7,)`.
    #[getter]
    fn tool_pose<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        convert::array1(py, convert::pose_array(&self.parts.tool_pose).to_vec())
    }

    /// The tool's mass (kg).
    #[getter]
    fn mass_kg(&self) -> f64 {
        self.parts.body.mass_kg()
    }

    /// Haptic rate (Hz).
    #[getter]
    fn haptic_rate_hz(&self) -> f64 {
        self.parts.config.haptic_rate_hz
    }

    /// Contact rate in virtual time (Hz), or None (as fast as it runs).
    #[getter]
    fn contact_rate_hz(&self) -> Option<f64> {
        self.parts.contact_hz
    }

    /// The collision query's distance tolerance δ (m).
    #[getter]
    fn delta_m(&self) -> f64 {
        self.parts.config.query.delta_m
    }

    /// The device's largest force (N).
    #[getter]
    fn max_force_n(&self) -> f64 {
        self.parts.limits.max_force_n
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene({:?}: tool of {} triangles, {} obstacles)",
            self.name,
            self.parts.tool_mesh.triangles().len(),
            self.parts.obstacles.len()
        )
    }
}

/// `(times (k,), poses (k, 7))` as waypoints.
pub fn waypoint_list(obj: &Bound<'_, PyAny>, field: &str) -> PyResult<Vec<Waypoint>> {
    let (times, poses): (Bound<'_, PyAny>, Bound<'_, PyAny>) = obj
        .extract()
        .map_err(|_| input(field, "must be a pair (times (k,), poses (k, 7))"))?;
    let t = convert::vector(&times, &format!("{field}.times"), None)?;
    let p = convert::rows::<7>(&poses, &format!("{field}.poses"), false)?;
    if t.len() != p.len() {
        return Err(input(
            field,
            format!("{} times for {} poses", t.len(), p.len()),
        ));
    }
    t.iter()
        .zip(&p)
        .map(|(t, p)| {
            Ok(Waypoint::new(
                *t,
                convert::pose_from(p, &format!("{field}.poses"))?,
            ))
        })
        .collect()
}

/// The collision back-end chosen by name.
// One value per run, matched in each query: boxing the larger variant would only add a pointer
// chase.
#[allow(clippy::large_enum_variant)]
pub enum AnyBackend {
    /// The LOD back-end.
    Lod(LodBackend),
    /// parry3d.
    Parry(ParryBackend),
}

/// The error of [`AnyBackend`].
#[derive(Debug)]
pub struct AnyBackendError(String);

impl std::fmt::Display for AnyBackendError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for AnyBackendError {}

impl AnyBackend {
    /// The back-end `name` (`lod` or `parry`) for `parts`.
    pub fn new(name: &str, parts: &SceneParts) -> PyResult<Self> {
        match name {
            "lod" => LodBackend::new(&parts.tool_mesh, &parts.obstacles)
                .map(|b| AnyBackend::Lod(b.with_stopping_rule(parts.stopping_rule)))
                .map_err(|e| crate::errors::collision(&e)),
            // A time budget picks LOD thresholds: parry has none to pick.
            "parry" if parts.config.query_budget.is_some() => Err(input(
                "backend",
                "the scene sets a time budget, which picks the LOD back-end's error threshold; parry has none",
            )),
            "parry" => ParryBackend::new(&parts.tool_mesh, &parts.obstacles)
                .map(AnyBackend::Parry)
                .map_err(|e| crate::errors::collision(&e)),
            other => Err(input(
                "backend",
                format!("unknown back-end {other:?}: use \"lod\" or \"parry\""),
            )),
        }
    }
}

impl CollisionBackend for AnyBackend {
    type Error = AnyBackendError;
    fn name(&self) -> &str {
        match self {
            AnyBackend::Lod(b) => b.name(),
            AnyBackend::Parry(b) => b.name(),
        }
    }
    fn tool_bounding_radius_m(&self) -> Real {
        match self {
            AnyBackend::Lod(b) => b.tool_bounding_radius_m(),
            AnyBackend::Parry(b) => b.tool_bounding_radius_m(),
        }
    }
    fn query(
        &mut self,
        pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, AnyBackendError> {
        match self {
            AnyBackend::Lod(b) => b
                .query(pose, params, out)
                .map_err(|e| AnyBackendError(e.to_string())),
            AnyBackend::Parry(b) => b
                .query(pose, params, out)
                .map_err(|e| AnyBackendError(e.to_string())),
        }
    }
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        match self {
            AnyBackend::Lod(b) => b.threshold_reached(params),
            AnyBackend::Parry(b) => b.threshold_reached(params),
        }
    }
}

/// The twist that takes `a` at `t_a` to `b` at `t_b` (world frame; zero for a non-positive
/// interval): a backward difference, as a device estimates its handle's velocity.
pub fn twist_between(a: &Pose, t_a: Real, b: &Pose, t_b: Real) -> Twist {
    let dt = t_b - t_a;
    if !dt.is_finite() || dt <= 0.0 {
        return Twist::zero();
    }
    let turn = b.orientation * a.orientation.inverse();
    Twist {
        linear: (b.position - a.position) / dt,
        angular: turn.scaled_axis() / dt,
    }
}

/// The handle state a Python force server publishes for the haptic thread (a triple buffer),
/// and the wrench the haptic thread commanded.
pub struct SharedLink {
    /// The newest handle pose and twist.
    pub state: triple_buffer::Output<(Pose, Twist)>,
    /// The wrench commanded last.
    pub wrench: triple_buffer::Input<Wrench>,
}

/// Where a Python run's device gets its handle from.
// One value per run, read at every haptic step: kept inline rather than boxed.
#[allow(clippy::large_enum_variant)]
pub enum Source {
    /// The scene's simulated hand.
    Hand(HandDevice),
    /// A handle through given poses.
    Scripted(ScriptedDevice),
    /// A Python callable `t -> pose`, its twist a backward difference of its readings.
    Callable {
        /// The callable.
        f: Py<PyAny>,
        /// The previous reading `(t, pose)`.
        last: Option<(Real, Pose)>,
    },
    /// A pose (and twist) set from Python while the run goes (the force server).
    Shared(SharedLink),
}

/// The device of a Python run: its source, the scene's limits, and a stop flag that ends the
/// run at the next reading (raised by `ForceServer.stop` or by Ctrl-C).
pub struct PyDevice {
    /// Where the handle comes from.
    pub source: Source,
    /// The device limits (the scene's).
    pub limits: DeviceLimits,
    /// Raised to end the run: the next reading says the device is disconnected.
    pub stop: Arc<AtomicBool>,
    /// In virtual time, on the calling thread: check for Ctrl-C every this many readings
    /// (0: never; the haptic thread of a real-time run never takes the GIL).
    pub signal_every: u64,
    reads: u64,
    /// The callable's first exception or a signal's (KeyboardInterrupt), kept to be raised when
    /// the run ends; shared, so that an error during the pipeline's build (its first reading)
    /// is not lost with the device. Locked only when an error is stored.
    pub python_error: Arc<Mutex<Option<PyErr>>>,
}

impl PyDevice {
    /// A device reading `source`.
    pub fn new(source: Source, limits: DeviceLimits, signal_every: u64) -> Self {
        Self {
            source,
            limits,
            stop: Arc::new(AtomicBool::new(false)),
            signal_every,
            reads: 0,
            python_error: Arc::new(Mutex::new(None)),
        }
    }
}

/// Keeps `e` in `slot` unless an earlier exception is there.
fn keep(slot: &Mutex<Option<PyErr>>, e: PyErr) {
    if let Ok(mut slot) = slot.lock() {
        slot.get_or_insert(e);
    }
}

/// The Python exception a run's device kept, if any.
pub fn take_python_error(slot: &Mutex<Option<PyErr>>) -> Option<PyErr> {
    slot.lock().ok().and_then(|mut s| s.take())
}

/// The error of [`PyDevice`].
#[derive(Debug)]
pub enum PyDeviceError {
    /// From a library device.
    Device(haptic_device::DeviceError),
    /// The callable raised or returned something that is not a pose.
    Callable(String),
    /// The callable returned a pose with a NaN or infinity.
    NonFinite,
    /// The run was stopped (`ForceServer.stop`, Ctrl-C).
    Stopped,
}

impl std::fmt::Display for PyDeviceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PyDeviceError::Device(e) => write!(f, "{e}"),
            PyDeviceError::Callable(m) => write!(f, "the device callable failed: {m}"),
            PyDeviceError::NonFinite => {
                f.write_str("the device callable returned a non-finite pose")
            }
            PyDeviceError::Stopped => f.write_str("the run was stopped"),
        }
    }
}

impl std::error::Error for PyDeviceError {}

impl DeviceErrorTrait for PyDeviceError {
    fn kind(&self) -> ErrorKind {
        match self {
            PyDeviceError::Device(e) => e.kind(),
            PyDeviceError::Callable(_) => ErrorKind::Other,
            PyDeviceError::NonFinite => ErrorKind::InvalidData,
            PyDeviceError::Stopped => ErrorKind::Disconnected,
        }
    }
}

/// Calls the device callable at `t_s` and reads a pose out of its result: `Err(None)` for a
/// pose with a NaN or an infinity (a reading the runtime turns into a zero-force step),
/// `Err(Some(e))` when the callable raised or returned something that is not a pose.
fn call_pose(f: &Py<PyAny>, t_s: Real) -> Result<Pose, Option<PyErr>> {
    Python::attach(|py| {
        let r = f.call1(py, (t_s,)).map_err(Some)?;
        let v = convert::vector_unchecked(r.bind(py), "device", Some(7)).map_err(Some)?;
        if v.iter().any(|x| !x.is_finite()) {
            return Err(None);
        }
        convert::pose_from(&v, "device").map_err(Some)
    })
}

impl Device for PyDevice {
    type Error = PyDeviceError;

    fn name(&self) -> &str {
        match &self.source {
            Source::Hand(d) => d.name(),
            Source::Scripted(d) => d.name(),
            Source::Callable { .. } => "python callable",
            Source::Shared(_) => "python force server",
        }
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, PyDeviceError> {
        if self.stop.load(Ordering::Acquire) {
            return Err(PyDeviceError::Stopped);
        }
        self.reads += 1;
        if self.signal_every > 0 && self.reads % self.signal_every == 0 {
            if let Err(e) = Python::attach(|py| py.check_signals()) {
                keep(&self.python_error, e);
                return Err(PyDeviceError::Stopped);
            }
        }
        let slot = &self.python_error;
        let (pose, twist) = match &mut self.source {
            Source::Hand(d) => return d.read(now_s).map_err(PyDeviceError::Device),
            Source::Scripted(d) => return d.read(now_s).map_err(PyDeviceError::Device),
            Source::Callable { f, last } => match call_pose(f, now_s) {
                Ok(p) => {
                    let twist =
                        last.map_or(Twist::zero(), |(t, q)| twist_between(&q, t, &p, now_s));
                    *last = Some((now_s, p));
                    (p, twist)
                }
                Err(None) => return Err(PyDeviceError::NonFinite),
                Err(Some(e)) => {
                    let message = e.to_string();
                    keep(slot, e);
                    return Err(PyDeviceError::Callable(message));
                }
            },
            Source::Shared(link) => *link.state.read(),
        };
        Ok(DeviceState {
            pose,
            twist,
            buttons: 0,
            timestamp_s: now_s,
        })
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), PyDeviceError> {
        match &mut self.source {
            Source::Hand(d) => d.command(wrench).map_err(PyDeviceError::Device),
            Source::Scripted(d) => d.command(wrench).map_err(PyDeviceError::Device),
            Source::Callable { .. } => Ok(()),
            Source::Shared(link) => {
                link.wrench.write(self.limits.saturate(wrench).0);
                Ok(())
            }
        }
    }
}
