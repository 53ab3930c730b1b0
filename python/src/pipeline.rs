//! `haptic.run_virtual` and `haptic.run_realtime`: the pipeline of a scene, with the
//! integrator and back-end chosen by name, its telemetry as numpy arrays and its summary as the
//! demo prints it.

use std::str::FromStr;

use haptic_core::{Integrator, Real};
use haptic_device::ScriptedDevice;
use haptic_dynamics::{
    ForwardEuler, IntegratorKind, LinearizedBackwardEuler, NewtonBackwardEuler, PenaltyModel, Rk4,
};
use haptic_runtime::{ContactLatency, Pipeline, PipelineBuilder, RuntimeError, Summary};
use numpy::{PyArray1, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::convert;
use crate::errors::{Class, error, from_dynamics, from_runtime, from_scene, input};
use crate::parts::{AnyBackend, PyDevice, PyScene, Source, take_python_error, waypoint_list};

/// The pipeline of a Python run.
pub type PyPipeline<I> = Pipeline<I, AnyBackend, PenaltyModel, PyDevice>;

/// The summary as a dict (the demo's `--json`).
pub fn summary_dict<'py>(py: Python<'py>, s: &Summary) -> PyResult<Bound<'py, PyAny>> {
    let json = serde_json::to_string(s)
        .map_err(|e| error(Class::Pipeline, e.to_string(), None, "summary"))?;
    py.import("json")?.call_method1("loads", (json,))
}

/// The integrator named `name`.
pub fn integrator_kind(name: &str) -> PyResult<IntegratorKind> {
    IntegratorKind::from_str(name).map_err(|e| input("integrator", e))
}

/// The pipeline of `scene` with `integrator`, `backend` and `device`.
pub fn build<I: Integrator>(
    scene: &PyScene,
    integrator: I,
    backend: AnyBackend,
    device: PyDevice,
) -> Result<PyPipeline<I>, PyErr> {
    let p = &scene.parts;
    PipelineBuilder::new(p.body, p.tool_pose)
        .integrator(integrator)
        .backend(backend)
        .contact_model(PenaltyModel::new(p.penalty).map_err(|e| from_dynamics(&e))?)
        .device(device)
        .coupling(p.coupling)
        .config(p.config)
        .build()
        .map_err(|e| from_runtime(&e))
}

/// Calls `$body` with `$pipeline` bound to the pipeline of the integrator `$kind`: one
/// monomorphised run per integrator.
macro_rules! with_integrator {
    ($kind:expr, $scene:expr, $backend:expr, $device:expr, |$pipeline:ident| $body:expr) => {
        match $kind {
            IntegratorKind::LinearizedBackwardEuler => {
                let mut $pipeline = build($scene, LinearizedBackwardEuler, $backend, $device)?;
                $body
            }
            IntegratorKind::NewtonBackwardEuler => {
                let mut $pipeline =
                    build($scene, NewtonBackwardEuler::default(), $backend, $device)?;
                $body
            }
            IntegratorKind::Rk4 => {
                let mut $pipeline = build($scene, Rk4, $backend, $device)?;
                $body
            }
            IntegratorKind::ForwardEuler => {
                let mut $pipeline = build($scene, ForwardEuler, $backend, $device)?;
                $body
            }
        }
    };
}
pub(crate) use with_integrator;

/// One row per haptic step.
#[derive(Default)]
struct Series {
    t: Vec<f64>,
    tool: Vec<[f64; 7]>,
    device: Vec<[f64; 7]>,
    force: Vec<[f64; 3]>,
    torque: Vec<[f64; 3]>,
    raw: Vec<i64>,
    clusters: Vec<i64>,
    penetration: Vec<f64>,
}

impl Series {
    fn with_capacity(n: usize) -> Self {
        Self {
            t: Vec::with_capacity(n),
            tool: Vec::with_capacity(n),
            device: Vec::with_capacity(n),
            force: Vec::with_capacity(n),
            torque: Vec::with_capacity(n),
            raw: Vec::with_capacity(n),
            clusters: Vec::with_capacity(n),
            penetration: Vec::with_capacity(n),
        }
    }
}

/// Runs `pipeline` in virtual time, recording the series; the GIL is released (a callable
/// device takes it back for each reading).
fn run_recorded<I: Integrator + Send>(
    py: Python<'_>,
    pipeline: &mut PyPipeline<I>,
    seconds: Real,
    latency: ContactLatency,
) -> (Result<Summary, RuntimeError>, Series) {
    let steps = (seconds * pipeline.config().haptic_rate_hz).round() as usize;
    py.detach(|| {
        let mut s = Series::with_capacity(steps);
        let outcome = pipeline.run_virtual(seconds, latency, |t, h| {
            let w = h.last_wrench();
            let c = h.contact();
            s.t.push(t);
            s.tool.push(convert::pose_array(&h.tool().pose()));
            s.device
                .push(convert::pose_array(&h.forces().coupling.device().pose));
            s.force.push(w.force.into());
            s.torque.push(w.torque.into());
            s.raw.push(c.raw_contact_count as i64);
            s.clusters.push(c.cluster_count as i64);
            s.penetration.push(c.max_penetration_m);
        });
        (outcome, s)
    })
}

/// A virtual-time run: one row per haptic step of the time `t` (s), the tool's and the
/// device's poses `(N, 7)`, the force and torque sent `(N, 3)`, the raw contact and cluster
/// counts and the deepest penetration (m) of the contact update in use; its summary as a dict
/// and as the demo prints it.
#[pyclass(module = "haptic", name = "Run", frozen, get_all)]
pub struct PyRun {
    /// Time after each haptic step (s), `(N,)`.
    t: Py<PyArray1<f64>>,
    /// Tool pose `(N, 7)`.
    tool_pose: Py<PyArray2<f64>>,
    /// Device (handle) pose `(N, 7)`.
    device_pose: Py<PyArray2<f64>>,
    /// Force sent to the device (N), `(N, 3)`.
    force: Py<PyArray2<f64>>,
    /// Torque sent to the device (N m), `(N, 3)`.
    torque: Py<PyArray2<f64>>,
    /// Raw contacts of the update in use, `(N,)` int64.
    raw_contact_count: Py<PyArray1<i64>>,
    /// Clusters of the update in use, `(N,)` int64.
    cluster_count: Py<PyArray1<i64>>,
    /// Deepest penetration of the update in use (m), `(N,)`.
    penetration_m: Py<PyArray1<f64>>,
    /// The run's summary (the demo's `--json`).
    summary: Py<PyAny>,
    /// The summary as `cargo xtask demo` prints it.
    summary_text: String,
}

#[pymethods]
impl PyRun {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!("Run({} steps)", self.t.bind(py).shape()[0])
    }
}

/// The device a run is given: the scene's hand, `(times, poses)`, or a callable. In virtual
/// time (`signal_every > 0`) it checks for Ctrl-C every that many readings.
fn device_of(
    scene: &PyScene,
    device: Option<&Bound<'_, PyAny>>,
    signal_every: u64,
) -> PyResult<PyDevice> {
    let limits = scene.parts.limits;
    let source = match device {
        None => Source::Hand(scene.parts.hand_device().map_err(|e| from_scene(&e))?),
        Some(d) if d.is_callable() => Source::Callable {
            f: d.clone().unbind(),
            last: None,
        },
        Some(d) => {
            let waypoints = waypoint_list(d, "device")?;
            let scripted = ScriptedDevice::from_waypoints(waypoints, limits)
                .map_err(|e| input("device", e))?;
            Source::Scripted(scripted)
        }
    };
    Ok(PyDevice::new(source, limits, signal_every))
}

/// The exception for a run that ended with `e`, or with the device's Python exception `cause`
/// (a callable that raised, Ctrl-C): an `Exception` becomes a `PipelineError` whose
/// `__cause__` it is; a `KeyboardInterrupt` or `SystemExit` is raised as it is.
fn run_error(py: Python<'_>, e: Option<&RuntimeError>, cause: Option<PyErr>) -> PyErr {
    let Some(cause) = cause else {
        return match e {
            Some(e) => from_runtime(e),
            None => error(Class::Pipeline, "the run failed", None, "pipeline"),
        };
    };
    if !cause.is_instance_of::<pyo3::exceptions::PyException>(py) {
        return cause;
    }
    let err = error(
        Class::Pipeline,
        format!("the device callable raised: {cause}"),
        Some("device"),
        "device_callable",
    );
    err.set_cause(py, Some(cause));
    if let Some(s) = e.and_then(RuntimeError::summary) {
        if let Ok(d) = summary_dict(py, s) {
            let _ = err.value(py).setattr("summary", d);
        }
    }
    err
}

/// Most haptic steps a virtual-time run records (its telemetry takes about 190 bytes a step).
pub const MAX_RECORDED_STEPS: f64 = 1e7;

/// Runs `scene` for `seconds` of simulated time, single-threaded and deterministic.
#[pyfunction]
#[pyo3(signature = (scene, seconds, device = None, integrator = "backward_euler", backend = "lod", contact_rate_hz = None))]
pub fn run_virtual(
    py: Python<'_>,
    scene: PyRef<'_, PyScene>,
    seconds: f64,
    device: Option<&Bound<'_, PyAny>>,
    integrator: &str,
    backend: &str,
    contact_rate_hz: Option<f64>,
) -> PyResult<PyRun> {
    convert::non_negative(seconds, "seconds")?;
    let steps = seconds * scene.parts.config.haptic_rate_hz;
    if steps > MAX_RECORDED_STEPS {
        return Err(input(
            "seconds",
            format!(
                "{seconds} s at {} Hz is {steps:.3e} steps; a run records at most {MAX_RECORDED_STEPS:e}",
                scene.parts.config.haptic_rate_hz
            ),
        ));
    }
    let kind = integrator_kind(integrator)?;
    let rate_hz = contact_rate_hz.or(scene.parts.contact_hz).unwrap_or(250.0);
    convert::positive(rate_hz, "contact_rate_hz")?;
    let device = device_of(&scene, device, 1000)?;
    let python_error = device.python_error.clone();
    let parts = &scene.parts;
    let backend = py.detach(|| AnyBackend::new(backend, parts))?;
    let latency = ContactLatency::FixedRate { rate_hz };
    let built: PyResult<(Result<Summary, RuntimeError>, Series)> = (|| {
        Ok(with_integrator!(kind, &scene, backend, device, |p| {
            run_recorded(py, &mut p, seconds, latency)
        }))
    })();
    let (outcome, series) = match built {
        Ok(r) => r,
        // The first reading happens while the pipeline is built: a callable that raised there.
        Err(e) => {
            return Err(
                take_python_error(&python_error).map_or(e, |c| run_error(py, None, Some(c)))
            );
        }
    };
    let summary = match outcome {
        Ok(s) => s,
        Err(e) => return Err(run_error(py, Some(&e), take_python_error(&python_error))),
    };
    // Ctrl-C ends a run through its device like a disconnection: raise it.
    if let Some(e) = take_python_error(&python_error) {
        return Err(run_error(py, None, Some(e)));
    }
    Ok(PyRun {
        t: convert::array1(py, series.t).unbind(),
        tool_pose: convert::array_rows(py, &series.tool).unbind(),
        device_pose: convert::array_rows(py, &series.device).unbind(),
        force: convert::array_rows(py, &series.force).unbind(),
        torque: convert::array_rows(py, &series.torque).unbind(),
        raw_contact_count: convert::array1(py, series.raw).unbind(),
        cluster_count: convert::array1(py, series.clusters).unbind(),
        penetration_m: convert::array1(py, series.penetration).unbind(),
        summary: summary_dict(py, &summary)?.unbind(),
        summary_text: summary.to_string(),
    })
}

/// A real-time run's summary, as a dict and as the demo prints it.
#[pyclass(module = "haptic", name = "RealtimeResult", frozen, get_all)]
pub struct PyRealtimeResult {
    /// The summary (the demo's `--json`).
    summary: Py<PyAny>,
    /// The summary as `cargo xtask demo` prints it.
    summary_text: String,
}

/// Runs `scene` for `seconds` of wall time with its simulated hand: the haptic thread at the
/// scene's rate and the contact thread as fast as it goes, as `cargo xtask demo` does. The GIL
/// is released for the run.
#[pyfunction]
#[pyo3(signature = (scene, seconds, integrator = "backward_euler", backend = "lod"))]
pub fn run_realtime(
    py: Python<'_>,
    scene: PyRef<'_, PyScene>,
    seconds: f64,
    integrator: &str,
    backend: &str,
) -> PyResult<PyRealtimeResult> {
    convert::non_negative(seconds, "seconds")?;
    let kind = integrator_kind(integrator)?;
    let device = device_of(&scene, None, 0)?;
    let stop = device.stop.clone();
    let parts = &scene.parts;
    let backend = py.detach(|| AnyBackend::new(backend, parts))?;
    let mut interrupt = None;
    let outcome = with_integrator!(kind, &scene, backend, device, |p| {
        py.detach(|| {
            p.run_realtime(seconds, |_| {
                // Ten times a second, on the calling thread: Ctrl-C stops the run (at zero
                // force) through its device.
                if interrupt.is_none() {
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        interrupt = Some(e);
                        stop.store(true, std::sync::atomic::Ordering::Release);
                    }
                }
            })
        })
    });
    if let Some(e) = interrupt {
        return Err(e);
    }
    let summary = outcome.map_err(|e| from_runtime(&e))?;
    Ok(PyRealtimeResult {
        summary: summary_dict(py, &summary)?.unbind(),
        summary_text: summary.to_string(),
    })
}

/// Registers the functions and classes of this file.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRun>()?;
    m.add_class::<PyRealtimeResult>()?;
    m.add_function(wrap_pyfunction!(run_virtual, m)?)?;
    m.add_function(wrap_pyfunction!(run_realtime, m)?)?;
    Ok(())
}
