//! `haptic.ForceServer`: the real-time pipeline in a thread of its own, its device's pose set
//! from Python (a simulator that runs slower than the hand) and the wrench it sends read back.
//! The haptic thread and Python share the handle's state and the wrench through triple buffers
//! and read the live counters lock-free: the haptic loop takes no lock and never touches the
//! interpreter. The Python side is behind a mutex, so that any Python thread may use a server.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Instant;

use haptic_core::{Pose, Twist, Wrench};
use haptic_runtime::telemetry::LiveTelemetry;
use haptic_runtime::{RuntimeError, Summary};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert;
use crate::errors::{Class, device_kind, error, from_runtime};
use crate::parts::{AnyBackend, PyDevice, PyScene, SharedLink, Source, twist_between};
use crate::pipeline::{build, integrator_kind, summary_dict, with_integrator};
use haptic_dynamics::{
    ForwardEuler, IntegratorKind, LinearizedBackwardEuler, NewtonBackwardEuler, Rk4,
};

/// How long a server runs at most unless stopped (s): a day.
const MAX_DURATION_S: f64 = 86_400.0;

/// The Python side of a running server.
struct Running {
    state: triple_buffer::Input<(Pose, Twist)>,
    wrench: triple_buffer::Output<Wrench>,
    stop: Arc<AtomicBool>,
    live: Arc<LiveTelemetry>,
    thread: JoinHandle<Result<Summary, RuntimeError>>,
    /// The handle's last pose and when it was set (for the twist of the next one).
    last: (Pose, Instant),
}

/// Everything a server holds.
struct State {
    running: Option<Running>,
    summary: Option<Summary>,
    last_pose: Pose,
}

/// A real-time haptic pipeline for a simulator that runs at its own, slower rate:
/// `ForceServer(scene, integrator="backward_euler", backend="lod")`. `start()` (or `with`)
/// starts the haptic thread at the scene's rate and the contact thread; `set_device_pose(pose)`
/// moves the handle; `wrench()` is the force and torque the haptic thread sends the handle;
/// `stop()` ends the run at zero force and returns its summary.
#[pyclass(module = "haptic", name = "ForceServer", frozen)]
pub struct PyForceServer {
    scene: Py<PyScene>,
    integrator: String,
    backend: String,
    state: Mutex<State>,
}

fn not_running() -> PyErr {
    error(
        Class::Pipeline,
        "the force server is not running (start it, or use it in a `with` block)",
        None,
        "not_running",
    )
}

impl PyForceServer {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while the lock was held cannot leave the state half-written (every update
        // is one assignment): go on with it.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The running server, or an error when it is not running; when its haptic thread has
    /// ended on its own (a device failure, a panic, the time limit), the run's error.
    fn running(state: &mut State) -> PyResult<&mut Running> {
        let ended = match &state.running {
            None => return Err(not_running()),
            Some(r) => r.thread.is_finished(),
        };
        if ended {
            let r = state.running.take().ok_or_else(not_running)?;
            let outcome = r.thread.join();
            return Err(match outcome {
                Ok(Ok(summary)) => {
                    state.summary = Some(summary);
                    error(
                        Class::Pipeline,
                        "the force server's run reached its time limit",
                        None,
                        "ended",
                    )
                }
                Ok(Err(e)) => {
                    state.summary = e.summary().cloned();
                    from_runtime(&e)
                }
                Err(_) => error(
                    Class::Pipeline,
                    "the force server's thread panicked",
                    None,
                    "haptic_panic",
                ),
            });
        }
        state.running.as_mut().ok_or_else(not_running)
    }
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
            state: Mutex::new(State {
                running: None,
                summary: None,
                last_pose,
            }),
        })
    }

    /// Starts the haptic and contact threads (again after a stop, as a new run). The handle
    /// starts at the scene's tool pose (the tool is grasped there) until `set_device_pose`
    /// moves it. Raises `PipelineError` when it is running already.
    fn start(&self, py: Python<'_>) -> PyResult<()> {
        if self.lock().running.is_some() {
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
        let start = parts.tool_pose;
        let (state_in, state_out) = triple_buffer::triple_buffer(&(start, Twist::zero()));
        let (wrench_in, wrench_out) = triple_buffer::triple_buffer(&Wrench::zero());
        let link = SharedLink {
            state: state_out,
            wrench: wrench_in,
        };
        let device = PyDevice::new(Source::Shared(link), parts.limits, 0);
        let stop = device.stop.clone();
        let (thread, live) = with_integrator!(kind, scene, backend, device, |p| {
            let live = p.live_handle();
            let thread = std::thread::Builder::new()
                .name("haptic force server".into())
                .spawn(move || p.run_realtime(MAX_DURATION_S, |_| {}))
                .map_err(|e| error(Class::Pipeline, e.to_string(), None, "thread"))?;
            (thread, live)
        });
        let mut state = self.lock();
        state.last_pose = start;
        state.summary = None;
        state.running = Some(Running {
            state: state_in,
            wrench: wrench_out,
            stop,
            live,
            thread,
            last: (start, Instant::now()),
        });
        Ok(())
    }

    /// Moves the handle to `pose` (7 floats); the haptic thread reads it at its next step. Its
    /// twist (linear and angular velocity, world frame, 6 floats) is `twist` when given, else
    /// the difference from the previous pose over the time between the two calls.
    #[pyo3(signature = (pose, twist = None))]
    fn set_device_pose(
        &self,
        pose: &Bound<'_, PyAny>,
        twist: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let pose = convert::pose(pose, "pose")?;
        let given = match twist {
            Some(t) => {
                let v = convert::vector(t, "twist", Some(6))?;
                Some(Twist {
                    linear: haptic_core::Vec3::new(v[0], v[1], v[2]),
                    angular: haptic_core::Vec3::new(v[3], v[4], v[5]),
                })
            }
            None => None,
        };
        let mut state = self.lock();
        let running = Self::running(&mut state)?;
        let now = Instant::now();
        let (last, at) = running.last;
        let twist = given.unwrap_or_else(|| {
            twist_between(&last, 0.0, &pose, now.duration_since(at).as_secs_f64())
        });
        running.state.write((pose, twist));
        running.last = (pose, now);
        state.last_pose = pose;
        Ok(())
    }

    /// The force (N) and torque (N m) the haptic thread sent the handle last, world frame.
    fn wrench<'py>(&self, py: Python<'py>) -> PyResult<convert::ArrayPair<'py>> {
        let mut state = self.lock();
        let running = Self::running(&mut state)?;
        let w = *running.wrench.read();
        Ok((
            convert::array1(py, vec![w.force.x, w.force.y, w.force.z]),
            convert::array1(py, vec![w.torque.x, w.torque.y, w.torque.z]),
        ))
    }

    /// The virtual tool's pose `(7,)` after the haptic thread's latest step (the scene's tool
    /// pose before the first).
    fn tool_pose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        let mut state = self.lock();
        let running = Self::running(&mut state)?;
        let s = running.live.snapshot();
        let pose = if s.haptic_steps == 0 {
            convert::pose_array(&self.scene.bind(py).get().parts.tool_pose)
        } else {
            s.tool_pose
        };
        Ok(convert::array1(py, pose.to_vec()))
    }

    /// The handle's pose last set, `(7,)`.
    fn device_pose<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        let pose = self.lock().last_pose;
        convert::array1(py, convert::pose_array(&pose).to_vec())
    }

    /// Live figures, read lock-free from the haptic thread's counters: `running`, `steps`,
    /// `time_s`, `haptic_rate_hz`, `contact_updates`, `raw_contact_count`, `cluster_count`,
    /// `max_force_n`, `deadline_misses`, `zero_force_steps`.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let state = self.lock();
        let (s, running) = match &state.running {
            Some(r) => (r.live.snapshot(), !r.thread.is_finished()),
            None => (Default::default(), false),
        };
        let d = PyDict::new(py);
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
    fn stop<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let running = self.lock().running.take().ok_or_else(not_running)?;
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
            Err(e) => {
                self.lock().summary = e.summary().cloned();
                return Err(from_runtime(&e));
            }
        };
        let dict = summary_dict(py, &summary)?;
        self.lock().summary = Some(summary);
        Ok(dict)
    }

    /// The summary of the last run (a dict), once stopped; None before.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let summary = self.lock().summary.clone();
        summary.map(|s| summary_dict(py, &s)).transpose()
    }

    /// The summary of the last run as the demo prints it; None before the first stop.
    #[getter]
    fn summary_text(&self) -> Option<String> {
        self.lock().summary.as_ref().map(ToString::to_string)
    }

    /// Starts the server (raises `PipelineError` if it is running already).
    fn __enter__(slf: Bound<'_, Self>) -> PyResult<Bound<'_, Self>> {
        slf.get().start(slf.py())?;
        Ok(slf)
    }

    /// Stops the server if it is running; exceptions propagate.
    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
        if self.lock().running.is_some() {
            self.stop(py)?;
        }
        Ok(false)
    }
}

impl Drop for PyForceServer {
    fn drop(&mut self) {
        // A server dropped while running stops at zero force.
        let running = self
            .state
            .get_mut()
            .map_or_else(|p| p.into_inner().running.take(), |s| s.running.take());
        if let Some(r) = running {
            r.stop.store(true, Ordering::Release);
            let _ = r.thread.join();
        }
    }
}
