//! Every way out of the haptic loop ends at zero force: a device or an integrator that panics
//! mid-run, in virtual time and in real time, stops the run with a typed error that carries the
//! panic's message, and the last command the device received is zero.

mod common;

use common::{BoxOnFloor, FaultyIntegrator, HALF_M, IntegratorFault, box_body, pressing_hand};
use haptic_core::{Device, DeviceLimits, DeviceState, Integrator, Pose, Real, Vec3, Wrench};
use haptic_device::HandDevice;
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::{ContactLatency, Pipeline, PipelineBuilder, PipelineConfig, RuntimeError};

/// The haptic step at which the faulty part panics: the box is pressed on the floor by then, so
/// the device is rendering a real force.
const PANIC_AT_STEP: u64 = 600;

/// Wraps a device: remembers every command it receives, and panics on its `panic_at`-th read.
struct RecordingDevice<D> {
    inner: D,
    reads: u64,
    panic_at: Option<u64>,
    last_command: Option<Wrench>,
    largest_force_n: Real,
}

impl<D> RecordingDevice<D> {
    fn new(inner: D, panic_at: Option<u64>) -> Self {
        Self {
            inner,
            reads: 0,
            panic_at,
            last_command: None,
            largest_force_n: 0.0,
        }
    }
}

impl<D: Device> Device for RecordingDevice<D> {
    type Error = D::Error;
    fn name(&self) -> &str {
        "recording"
    }
    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }
    fn read(&mut self, now_s: Real) -> Result<DeviceState, D::Error> {
        self.reads += 1;
        if self.panic_at == Some(self.reads) {
            panic!("injected device panic");
        }
        self.inner.read(now_s)
    }
    fn command(&mut self, wrench: &Wrench) -> Result<(), D::Error> {
        self.last_command = Some(*wrench);
        self.largest_force_n = self.largest_force_n.max(wrench.force.norm());
        self.inner.command(wrench)
    }
}

fn pipeline<I: Integrator>(
    integrator: I,
    device: RecordingDevice<HandDevice>,
) -> Pipeline<I, BoxOnFloor, PenaltyModel, RecordingDevice<HandDevice>> {
    PipelineBuilder::new(
        box_body(),
        Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.01)),
    )
    .integrator(integrator)
    .backend(BoxOnFloor::new(HALF_M))
    .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
    .device(device)
    .config(PipelineConfig {
        realtime_scheduling: false,
        ..PipelineConfig::default()
    })
    .build()
    .unwrap()
}

/// Checks the error of a run that panicked: typed, with the message in the error and in the
/// summary, the run stopped at the panic, and the device left at zero force after rendering a
/// real one.
fn assert_stopped_at_zero_force<I: Integrator>(
    result: Result<haptic_runtime::Summary, RuntimeError>,
    p: &Pipeline<I, BoxOnFloor, PenaltyModel, RecordingDevice<HandDevice>>,
    expected_message: &str,
) {
    let err = result.expect_err("a panic must not end in Ok");
    let RuntimeError::HapticPanic { message, summary } = &err else {
        panic!("expected RuntimeError::HapticPanic, got {err}");
    };
    assert!(message.contains(expected_message), "{message}");
    assert!(err.to_string().contains("zero force"), "{err}");
    assert_eq!(
        summary.haptic_thread_panic.as_deref(),
        Some(message.as_str())
    );
    assert!(
        summary
            .incidents
            .iter()
            .any(|i| i.contains(expected_message)),
        "{:?}",
        summary.incidents
    );
    // The run stopped at the panic, not at its planned end.
    assert!(
        summary.haptic_steps <= PANIC_AT_STEP,
        "{} steps after a panic at step {PANIC_AT_STEP}",
        summary.haptic_steps
    );
    let device = p.haptic().device();
    assert!(
        device.largest_force_n > 0.5,
        "the device never rendered a force ({} N): the test checks nothing",
        device.largest_force_n
    );
    assert_eq!(
        device.last_command,
        Some(Wrench::zero()),
        "the device was left with a force"
    );
    assert_eq!(*p.haptic().last_wrench(), Wrench::zero());
}

#[test]
fn a_device_panic_in_virtual_time_ends_at_zero_force() {
    let device = RecordingDevice::new(pressing_hand(), Some(PANIC_AT_STEP));
    let mut p = pipeline(LinearizedBackwardEuler, device);
    let result = p.run_virtual(2.0, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, _| {});
    assert_stopped_at_zero_force(result, &p, "injected device panic");
}

#[test]
fn an_integrator_panic_in_virtual_time_ends_at_zero_force() {
    let integrator = FaultyIntegrator::new(IntegratorFault::PanicAt(PANIC_AT_STEP));
    let mut p = pipeline(integrator, RecordingDevice::new(pressing_hand(), None));
    let result = p.run_virtual(2.0, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, _| {});
    assert_stopped_at_zero_force(result, &p, "injected integrator panic");
}

#[test]
fn a_device_panic_in_real_time_ends_at_zero_force() {
    let device = RecordingDevice::new(pressing_hand(), Some(PANIC_AT_STEP));
    let mut p = pipeline(LinearizedBackwardEuler, device);
    let result = p.run_realtime(2.0, |_| {});
    assert_stopped_at_zero_force(result, &p, "injected device panic");
}

#[test]
fn an_integrator_panic_in_real_time_ends_at_zero_force() {
    let integrator = FaultyIntegrator::new(IntegratorFault::PanicAt(PANIC_AT_STEP));
    let mut p = pipeline(integrator, RecordingDevice::new(pressing_hand(), None));
    let result = p.run_realtime(2.0, |_| {});
    assert_stopped_at_zero_force(result, &p, "injected integrator panic");
}

/// A panic in the caller's `progress` callback stops the haptic thread too, at zero force.
#[test]
fn a_progress_callback_panic_stops_the_run_at_zero_force() {
    let mut p = pipeline(
        LinearizedBackwardEuler,
        RecordingDevice::new(pressing_hand(), None),
    );
    let started = std::time::Instant::now();
    let mut calls = 0;
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        p.run_realtime(30.0, |_| {
            calls += 1;
            if calls == 8 {
                panic!("injected progress panic");
            }
        })
    }));
    assert!(
        caught.is_err(),
        "the callback's panic must reach the caller"
    );
    assert!(
        started.elapsed().as_secs_f64() < 10.0,
        "the haptic thread ran on after the caller panicked"
    );
    let device = p.haptic().device();
    assert!(device.largest_force_n > 0.5, "{} N", device.largest_force_n);
    assert_eq!(device.last_command, Some(Wrench::zero()));
}
