//! `haptic.ForceServer`: the real-time pipeline in a thread of its own, its device's pose set
//! from Python (a simulator that runs slower than the hand) and the wrench it sends read back.
//! The haptic thread and Python share the pose and the wrench through triple buffers: the
//! haptic loop takes no lock and never touches the interpreter.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use haptic_core::{Pose, Wrench};
use haptic_runtime::{RuntimeError, Snapshot, Summary};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert;
use crate::errors::{Class, device_kind, error, from_runtime};
use crate::parts::{AnyBackend, AnyDevice, PyScene, SharedLink};
use crate::pipeline::{build, integrator_kind, summary_dict, with_integrator};
use haptic_dynamics::{
    ForwardEuler, IntegratorKind, LinearizedBackwardEuler, NewtonBackwardEuler, Rk4,
};

/// How long a server runs at most unless stopped (s): a day.
const MAX_DURATION_S: f64 = 86_400.0;

/// The Python side of a running server.
struct Running {
    pose: triple_buffer::Input<Pose>,
    wrench: triple_buffer::Output<Wrench>,
    stop: Arc<AtomicBool>,
    snapshot: Arc<Mutex<Snapshot>>,
    thread: JoinHandle<Result<Summary, RuntimeError>>,
}

/// A real-time haptic pipeline for a simulator that runs at its own, slower rate:
/// `ForceServer(scene, integrator="backward_euler", backend="lod")`. `start()` (or `with`)
/// starts the haptic thread at the scene's rate and the contact thread; `set_device_pose(pose)`
/// moves the handle; `wrench()` is the force and torque the haptic thread sends the handle;
/// `stop()` ends the run at zero force and returns its summary.
#[pyclass(module = "haptic", name = "ForceServer")]
pub struct PyForceServer {
    scene: Py<PyScene>,
    integrator: String,
    backend: String,
    running: Option<Running>,
    summary: Option<Summary>,
    last_pose: Pose,
}

fn stopped() -> PyErr {
    error(
        Class::Pipeline,
        "the force server is not running (start it, or use it in a `with` block)",
        None,
        "not_running",
    )
}

#[pymethods]
impl PyForceServer {
    #[new]
    #[pyo3(signature = (scene, integrator = "backward_euler", backend = "lod"))]
    fn new(scene: Bound<'_, PyScene>, integrator: &str, backend: &str) -> PyResult<Self> {
        integrator_kind(integrator)?;
        if !matches!(backend, "lod" | "parry") {
            return Err(crate::errors::input(
                "backend",
                format!("unknown back-end {backend:?}: use \"lod\" or \"parry\""),
            ));
        }
        let last_pose = scene.get().parts.tool_pose;
        Ok(Self {
            scene: scene.unbind(),
            integrator: integrator.to_owned(),
            backend: backend.to_owned(),
            running: None,
            summary: None,
            last_pose,
        })
    }

    /// Starts the haptic and contact threads. The handle starts at the scene's tool pose (the
    /// tool is grasped there) until `set_device_pose` moves it.
    fn start(&mut self, py: Python<'_>) -> PyResult<()> {
        if self.running.is_some() {
            return Err(error(
                Class::Pipeline,
                "the force server is running already",
                None,
                "running",
            ));
        }
        let scene = self.scene.bind(py).get();
        let kind = integrator_kind(&self.integrator)?;
        let parts = &scene.parts;
        let backend_name = self.backend.as_str();
        let backend = py.detach(|| AnyBackend::new(backend_name, parts))?;
        let (pose_in, pose_out) = triple_buffer::triple_buffer(&parts.tool_pose);
        let (wrench_in, wrench_out) = triple_buffer::triple_buffer(&Wrench::zero());
        let stop = Arc::new(AtomicBool::new(false));
        let snapshot = Arc::new(Mutex::new(Snapshot::default()));
        let device = AnyDevice::Shared {
            link: SharedLink {
                pose: pose_out,
                wrench: wrench_in,
                stop: stop.clone(),
            },
            limits: parts.limits,
        };
        let live = snapshot.clone();
        let thread = with_integrator!(kind, scene, backend, device, |p| {
            std::thread::Builder::new()
                .name("haptic force server".into())
                .spawn(move || {
                    p.run_realtime(MAX_DURATION_S, |s| {
                        if let Ok(mut l) = live.lock() {
                            *l = *s;
                        }
                    })
                })
                .map_err(|e| error(Class::Pipeline, e.to_string(), None, "thread"))?
        });
        self.last_pose = parts.tool_pose;
        self.summary = None;
        self.running = Some(Running {
            pose: pose_in,
            wrench: wrench_out,
            stop,
            snapshot,
            thread,
        });
        Ok(())
    }

    /// Moves the handle to `pose` (7 floats); the haptic thread reads it at its next step.
    fn set_device_pose(&mut self, pose: &Bound<'_, PyAny>) -> PyResult<()> {
        let pose = convert::pose(pose, "pose")?;
        let running = self.running.as_mut().ok_or_else(stopped)?;
        running.pose.write(pose);
        self.last_pose = pose;
        Ok(())
    }

    /// The force (N) and torque (N m) the haptic thread sent the handle last, world frame.
    fn wrench<'py>(&mut self, py: Python<'py>) -> PyResult<convert::ArrayPair<'py>> {
        let running = self.running.as_mut().ok_or_else(stopped)?;
        let w = *running.wrench.read();
        Ok((
            convert::array1(py, vec![w.force.x, w.force.y, w.force.z]),
            convert::array1(py, vec![w.torque.x, w.torque.y, w.torque.z]),
        ))
    }

    /// The virtual tool's pose `(7,)` as of the last live update (ten a second; all zeros
    /// before the first).
    fn tool_pose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let running = self.running.as_ref().ok_or_else(stopped)?;
        let s = running.snapshot.lock().map(|s| *s).unwrap_or_default();
        Ok(convert::array1(py, s.tool_pose.to_vec()))
    }

    /// The handle's pose last set, `(7,)`.
    fn device_pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        convert::array1(py, convert::pose_array(&self.last_pose).to_vec())
    }

    /// Live figures, updated ten times a second: `steps`, `time_s`, `haptic_rate_hz`,
    /// `contact_updates`, `raw_contact_count`, `cluster_count`, `max_force_n`,
    /// `deadline_misses`, `zero_force_steps`, and `running`.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let s = match &self.running {
            Some(r) => r.snapshot.lock().map(|s| *s).unwrap_or_default(),
            None => Snapshot::default(),
        };
        let running = self
            .running
            .as_ref()
            .is_some_and(|r| !r.thread.is_finished());
        d.set_item("running", running)?;
        d.set_item("steps", s.haptic_steps)?;
        d.set_item("time_s", s.time_s)?;
        d.set_item(
            "haptic_rate_hz",
            if s.time_s > 0.0 {
                s.haptic_steps as f64 / s.time_s
            } else {
                0.0
            },
        )?;
        d.set_item("contact_updates", s.contact_updates)?;
        d.set_item("raw_contact_count", s.raw_contact_count)?;
        d.set_item("cluster_count", s.cluster_count)?;
        d.set_item("max_force_n", s.max_force_n)?;
        d.set_item("deadline_misses", s.deadline_misses)?;
        d.set_item("zero_force_steps", s.zero_force_steps)?;
        Ok(d)
    }

    /// Ends the run (zero force is sent) and returns its summary as a dict. The GIL is released
    /// while the threads stop.
    fn stop<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let running = self.running.take().ok_or_else(stopped)?;
        running.stop.store(true, Ordering::Release);
        let joined = py.detach(|| running.thread.join());
        let outcome = joined.map_err(|_| {
            error(
                Class::Pipeline,
                "the force server's thread panicked",
                None,
                "haptic_panic",
            )
        })?;
        let summary = match outcome {
            Ok(s) => s,
            // Stopping is the device saying it is disconnected: the run ended as asked.
            Err(RuntimeError::Device { kind, summary, .. })
                if device_kind(kind) == "disconnected" =>
            {
                *summary
            }
            Err(e) => return Err(from_runtime(&e)),
        };
        let dict = summary_dict(py, &summary)?;
        self.summary = Some(summary);
        Ok(dict)
    }

    /// The summary of the last run (a dict), once stopped; None before.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.summary
            .as_ref()
            .map(|s| summary_dict(py, s))
            .transpose()
    }

    /// The summary of the last run as the demo prints it (empty before the first stop).
    #[getter]
    fn summary_text(&self) -> String {
        self.summary
            .as_ref()
            .map(ToString::to_string)
            .unwrap_or_default()
    }

    fn __enter__<'py>(
        mut slf: PyRefMut<'py, Self>,
        py: Python<'py>,
    ) -> PyResult<PyRefMut<'py, Self>> {
        slf.start(py)?;
        Ok(slf)
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(
        &mut self,
        py: Python<'_>,
        _args: &Bound<'_, pyo3::types::PyTuple>,
    ) -> PyResult<bool> {
        if self.running.is_some() {
            self.stop(py)?;
        }
        Ok(false)
    }
}

impl Drop for PyForceServer {
    fn drop(&mut self) {
        // A server dropped while running stops at zero force.
        if let Some(r) = self.running.take() {
            r.stop.store(true, Ordering::Release);
            let _ = r.thread.join();
        }
    }
}
