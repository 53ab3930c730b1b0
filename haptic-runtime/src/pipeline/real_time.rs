//! The real-time run: the haptic thread at its fixed rate (with real-time scheduling where it is
//! granted), the contact thread as fast as it can, lock-free buffers between them.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use haptic_core::{CollisionBackend, ContactModel, Device, Integrator, Real};

use crate::error::RuntimeError;
use crate::recording::{Frame, RunRecorder, UpdateRecord};
use crate::stages::{
    ContactStage, ContactUpdate, DeviceFailure, HapticStage, ToolMessage, panic_message,
};
use crate::telemetry::{LiveTelemetry, RunMode, Snapshot, Summary};

use super::{ContactStats, Pipeline, finish};

/// Pins the current thread to `core`, if given, and, if `realtime`, asks for real-time
/// scheduling (`SCHED_FIFO` at priority [`REALTIME_PRIORITY`] on Linux; the highest priority of
/// the current policy elsewhere). Returns whether real-time scheduling was granted, and what
/// happened in words.
fn apply_scheduling(core: Option<usize>, realtime: bool) -> (bool, String) {
    let mut notes = Vec::new();
    if let Some(core) = core {
        let pinned = core_affinity::get_core_ids()
            .and_then(|ids| ids.get(core).copied())
            .map(core_affinity::set_for_current)
            .unwrap_or(false);
        notes.push(if pinned {
            format!("pinned to core {core}")
        } else {
            format!("could not pin to core {core}")
        });
    }
    let mut granted = false;
    if realtime {
        match request_realtime() {
            Ok(what) => {
                granted = true;
                notes.push(what);
            }
            Err(why) => notes.push(format!("real-time scheduling not granted ({why})")),
        }
    }
    (granted, notes.join(", "))
}

/// The `SCHED_FIFO` priority the haptic thread asks for (1–99): above the kernel's threaded
/// interrupt handlers' default of 50, below the watchdogs at 99.
pub const REALTIME_PRIORITY: u8 = 80;

#[cfg(target_os = "linux")]
fn request_realtime() -> Result<String, String> {
    use thread_priority::{
        RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
        set_thread_priority_and_policy, thread_native_id,
    };
    let value = ThreadPriorityValue::try_from(REALTIME_PRIORITY)?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map(|()| format!("real-time SCHED_FIFO priority {REALTIME_PRIORITY}"))
    .map_err(|e| format!("{e:?}"))
}

#[cfg(not(target_os = "linux"))]
fn request_realtime() -> Result<String, String> {
    thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Max)
        .map(|()| "highest thread priority".to_string())
        .map_err(|e| format!("{e:?}"))
}

/// How the real-time haptic thread waits for its deadlines: in the periods it sleeps (one in
/// `sleep_every`), it sleeps until `spin` before the deadline and spins from there; in the
/// others it spins from the end of its step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct WaitPlan {
    spin: Duration,
    sleep_every: u64,
}

impl WaitPlan {
    /// The plan for a period of `period`.
    ///
    /// A thread without real-time scheduling has 50 µs of timer slack and is woken late under
    /// load: it sleeps every period and spins for the last 200 µs. A real-time thread has no
    /// slack and usually wakes within tens of microseconds, but not always (on a virtual machine,
    /// a few wake-ups in a thousand take over 60 µs), so it sleeps as seldom as it may. It must
    /// sleep: the kernel stops a real-time thread that runs more than `sched_rt_runtime_us` of
    /// every `sched_rt_period_us` (950 ms of each second by default) for the rest of that
    /// second. It sleeps in enough periods to stay off the CPU for twice the kernel's reserve
    /// (10 % by default), and spins for the last 60 µs of those periods. Where the administrator
    /// has turned the throttling off (`sched_rt_runtime_us = -1`), it never sleeps.
    fn new(realtime_granted: bool, period: Duration) -> Self {
        if !realtime_granted {
            return Self {
                spin: Duration::from_micros(200),
                sleep_every: 1,
            };
        }
        let Some(reserve) = realtime_reserve() else {
            return Self {
                spin: period,
                sleep_every: u64::MAX,
            };
        };
        let spin = Duration::from_micros(60).min(period.mul_f64(0.6));
        let sleep_fraction = (period - spin).as_secs_f64() / period.as_secs_f64();
        let periods = (sleep_fraction / (2.0 * reserve)).floor();
        Self {
            spin,
            sleep_every: if periods >= 1.0 { periods as u64 } else { 1 },
        }
    }

    /// Whether period `k` sleeps.
    fn sleeps(&self, k: u64) -> bool {
        k % self.sleep_every == 0
    }
}

/// The fraction of each second the kernel keeps from real-time threads (Linux:
/// `1 − sched_rt_runtime_us / sched_rt_period_us`, 5 % by default); `None` where it keeps none
/// (`sched_rt_runtime_us = -1`). Read once per run, before the loop; the default where the files
/// cannot be read.
fn realtime_reserve() -> Option<Real> {
    let read = |name: &str| -> Option<Real> {
        std::fs::read_to_string(format!("/proc/sys/kernel/{name}"))
            .ok()?
            .trim()
            .parse()
            .ok()
    };
    match (read("sched_rt_runtime_us"), read("sched_rt_period_us")) {
        (Some(runtime), _) if runtime < 0.0 => None,
        (Some(runtime), Some(period)) if period > 0.0 && runtime <= period => {
            Some((1.0 - runtime / period).max(0.01))
        }
        _ => Some(0.05),
    }
}

/// The channels and flags the real-time haptic thread shares with the others.
struct HapticThreadLinks<'a> {
    tool_in: triple_buffer::Input<ToolMessage>,
    contact_out: triple_buffer::Output<(ContactUpdate, Real)>,
    live: &'a LiveTelemetry,
    stop: &'a AtomicBool,
    /// Frames to record, into a buffer allocated before the loop (never grown in it).
    frames: Option<FrameBuffer<'a>>,
}

/// The haptic thread's recording buffer: frames every `period_s`, up to its capacity.
struct FrameBuffer<'a> {
    frames: &'a mut Vec<Frame>,
    period_s: Real,
    next_s: Real,
}

/// The recording buffers of a real-time run.
struct RecordBuffers<'a> {
    frames: FrameBuffer<'a>,
    updates: UpdateBuffer<'a>,
}

/// The contact thread's recording: one record per update.
struct UpdateBuffer<'a> {
    updates: &'a mut Vec<UpdateRecord>,
    cap: usize,
    scratch: Vec<haptic_core::Contact>,
}

/// The body of the real-time haptic thread: `steps` periods of `dt`, each against its own
/// deadline `t0 + (k + 1) dt` (`t0`: the haptic clock's origin), waited for as `wait` says. Stops early when `stop` is raised. Returns a device failure that ended the run,
/// and the loop's own duration (s), from its start to the end of its last period.
fn realtime_haptic_loop<I: Integrator, D: Device>(
    haptic: &mut HapticStage<I, D>,
    links: &mut HapticThreadLinks<'_>,
    steps: u64,
    dt: Real,
    wait: WaitPlan,
    t0: Instant,
) -> (Option<DeviceFailure>, Real) {
    let live = links.live;
    for k in 0..steps {
        if links.stop.load(Ordering::Relaxed) {
            break;
        }
        // From the start, not accumulated: no drift, and no narrowing of `k`.
        let deadline = t0 + Duration::from_secs_f64((k + 1) as Real * dt);
        let now_s = t0.elapsed().as_secs_f64();
        if links.contact_out.update() {
            // Read in place: the update is 15 kB, and `receive_contact` copies only the
            // contacts in use.
            let (update, _) = links.contact_out.output_buffer();
            haptic.receive_contact(update, now_s);
        }
        let started = Instant::now();
        let outcome = haptic.step(now_s, dt);
        haptic
            .stats
            .step_time
            .record(started.elapsed().as_secs_f64());
        if let Err(f) = outcome {
            return (Some(f), t0.elapsed().as_secs_f64());
        }
        links.tool_in.write(ToolMessage {
            seq: k + 1,
            time_s: now_s,
            state: *haptic.tool(),
        });
        if let Some(fb) = &mut links.frames {
            // Within the capacity reserved before the loop: no allocation.
            // Frames on a fixed grid of period_s (the step's clock jitters).
            if now_s + dt + 1e-6 >= fb.next_s && fb.frames.len() < fb.frames.capacity() {
                fb.frames.push(Frame::of(now_s + dt, haptic));
                while fb.next_s <= now_s + dt + 1e-6 {
                    fb.next_s += fb.period_s;
                }
            }
        }
        live.haptic_steps.store(k + 1, Ordering::Relaxed);
        live.time_s.store(now_s);
        live.tool_pose
            .store(&crate::recording::pose_array(&haptic.tool().pose()));
        live.max_force_n.store(haptic.stats.max_force_n);
        live.zero_force_steps
            .store(haptic.stats.zero_force_steps, Ordering::Relaxed);
        let after = Instant::now();
        if after > deadline {
            live.deadline_misses.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let remaining = deadline - after;
        if wait.sleeps(k) && remaining > wait.spin {
            std::thread::sleep(remaining - wait.spin);
        }
        while Instant::now() < deadline {
            std::hint::spin_loop();
        }
    }
    (None, t0.elapsed().as_secs_f64())
}

/// The body of the real-time contact thread: an update for every new tool state, until `stop`.
/// A panic of the stage ends the thread and is reported; the haptic thread fades the contact
/// forces out.
fn contact_thread_loop<B: CollisionBackend, C: ContactModel>(
    contact: &mut ContactStage<B, C>,
    mut tool_out: triple_buffer::Output<ToolMessage>,
    mut contact_in: triple_buffer::Input<(ContactUpdate, Real)>,
    live: &LiveTelemetry,
    stop: &AtomicBool,
    start: Instant,
    haptic_origin_ns: &AtomicU64,
    mut record: Option<UpdateBuffer<'_>>,
) -> ContactStats {
    let mut stats = ContactStats::default();
    let mut last_seq = 0;
    // The published update is no longer readable from this side: a copy for the recording.
    let mut recorded = ContactUpdate::none();
    while !stop.load(Ordering::Acquire) {
        tool_out.update();
        let msg = *tool_out.output_buffer();
        if msg.seq == last_seq {
            std::thread::sleep(Duration::from_micros(20));
            continue;
        }
        last_seq = msg.seq;
        let started = Instant::now();
        // Written in place into the buffer's back slot, published only when whole: a failed
        // or panicking update leaves the haptic thread's model as it was.
        let slot = contact_in.input_buffer_mut();
        match catch_unwind(AssertUnwindSafe(|| {
            contact.update_into(&msg.state, msg.time_s, &mut slot.0)
        })) {
            Ok(Ok(())) => {
                let latency = started.elapsed().as_secs_f64();
                // On the haptic clock (its origin is set before its first message), so that
                // an update's time and the query's time compare.
                let now = start.elapsed().as_secs_f64()
                    - haptic_origin_ns.load(Ordering::Acquire) as Real * 1e-9;
                slot.1 = latency;
                let update = &slot.0;
                stats.record(update, latency, now);
                let (raw_count, cluster_count) = (update.raw_contact_count, update.cluster_count);
                if record.is_some() {
                    recorded.copy_from(update);
                }
                contact_in.publish();
                if let Some(r) = &mut record {
                    r.updates.push(UpdateRecord::of(
                        msg.time_s,
                        now,
                        &recorded,
                        contact.raw_contacts(),
                        contact.representatives(),
                        contact.representative_weights(),
                        latency,
                        r.cap,
                        &mut r.scratch,
                    ));
                }
                live.contact_updates.fetch_add(1, Ordering::Relaxed);
                live.raw_contact_count
                    .store(raw_count as u64, Ordering::Relaxed);
                live.cluster_count
                    .store(cluster_count as u64, Ordering::Relaxed);
                live.max_penetration_m.store(stats.max_penetration_m);
            }
            Ok(Err(e)) => {
                stats.errors += 1;
                stats.first_error.get_or_insert_with(|| e.to_string());
            }
            Err(payload) => {
                stats.panicked = Some(panic_message(&*payload));
                live.contact_thread_dead.store(true, Ordering::Release);
                break;
            }
        }
    }
    stats
}

/// Raises a flag when dropped: the watcher's way of stopping the other threads on every exit,
/// its own panics (in a progress callback) included.
struct RaiseOnDrop<'a>(&'a AtomicBool);

impl Drop for RaiseOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

impl<I, B, C, D> Pipeline<I, B, C, D>
where
    I: Integrator + Send,
    B: CollisionBackend + Send,
    C: ContactModel + Send,
    D: Device + Send,
{
    /// Runs `duration_s` of wall time: the haptic thread at the fixed haptic rate, the contact
    /// thread as fast as it can, exchanging the latest tool state and the latest linearized
    /// contact model through lock-free single-slot (triple) buffers. The calling thread watches
    /// and calls `progress` about ten times a second with a live snapshot.
    ///
    /// If the contact thread stalls or panics, the haptic thread keeps its rate on the last
    /// model and fades contact forces out after the timeout; the summary says what happened.
    /// Every way out of the haptic loop, a panic included, ends at zero force.
    ///
    /// # Errors
    /// [`RuntimeError::Device`] if the device fails, [`RuntimeError::HapticPanic`] if the haptic
    /// thread panics; zero force has been commanded in both cases.
    pub fn run_realtime(
        &mut self,
        duration_s: Real,
        progress: impl FnMut(&Snapshot),
    ) -> Result<Summary, RuntimeError> {
        self.run_realtime_inner(duration_s, progress, None)
    }

    /// [`Pipeline::run_realtime`], recorded into `recorder`: the haptic thread keeps its frames
    /// in a buffer allocated before its loop (it still allocates nothing, takes no lock and does
    /// no I/O per step), the contact thread its updates; both are written, in time order, after
    /// the threads have stopped.
    ///
    /// # Errors
    /// As [`Pipeline::run_realtime`]; the recording then holds the run up to the failure.
    pub fn run_realtime_recorded<W: std::io::Write>(
        &mut self,
        duration_s: Real,
        progress: impl FnMut(&Snapshot),
        recorder: &mut RunRecorder<W>,
    ) -> Result<Summary, RuntimeError> {
        let period = recorder.frame_period_s();
        let capacity = (duration_s / period).ceil().max(0.0) as usize + 2;
        let mut frames = Vec::with_capacity(capacity);
        let mut updates = Vec::new();
        let buffers = RecordBuffers {
            frames: FrameBuffer {
                frames: &mut frames,
                period_s: period,
                next_s: 0.0,
            },
            updates: UpdateBuffer {
                updates: &mut updates,
                cap: recorder.contact_cap(),
                scratch: Vec::new(),
            },
        };
        let outcome = self.run_realtime_inner(duration_s, progress, Some(buffers));
        let (mut f, mut u) = (frames.iter().peekable(), updates.iter().peekable());
        loop {
            match (f.peek(), u.peek()) {
                (Some(a), Some(b)) if b.t < a.t => recorder.write_update(u.next().expect("peeked")),
                (Some(_), _) => recorder.write_frame(f.next().expect("peeked")),
                (None, Some(_)) => recorder.write_update(u.next().expect("peeked")),
                (None, None) => break,
            }
        }
        outcome
    }

    fn run_realtime_inner(
        &mut self,
        duration_s: Real,
        mut progress: impl FnMut(&Snapshot),
        record: Option<RecordBuffers<'_>>,
    ) -> Result<Summary, RuntimeError> {
        let (frame_buffer, update_buffer) = match record {
            Some(r) => (Some(r.frames), Some(r.updates)),
            None => (None, None),
        };
        let dt = 1.0 / self.config.haptic_rate_hz;
        let steps = (duration_s / dt).round().max(0.0) as u64;
        let (tool_in, tool_out) = triple_buffer::triple_buffer(&ToolMessage {
            seq: 0,
            time_s: 0.0,
            state: *self.haptic.tool(),
        });
        let (contact_in, contact_out) =
            triple_buffer::triple_buffer(&(ContactUpdate::none(), 0.0 as Real));
        let stop = AtomicBool::new(false);
        let scheduling_wanted = self.config.realtime_scheduling;
        let live = &self.live;
        let haptic = &mut self.haptic;
        let contact = &mut self.contact;
        let start = Instant::now();
        // The haptic clock's origin, in ns after `start`.
        let haptic_origin_ns = AtomicU64::new(0);
        let (outcome, loop_s, contact_stats, granted, notes) = std::thread::scope(|s| {
            let stop = &stop;
            let haptic_origin_ns = &haptic_origin_ns;
            let _stop_all = RaiseOnDrop(stop);
            let contact_thread = s.spawn(move || {
                let (_, note) = if scheduling_wanted {
                    apply_scheduling(Some(0), false)
                } else {
                    (false, String::new())
                };
                let stats = contact_thread_loop(
                    contact,
                    tool_out,
                    contact_in,
                    live,
                    stop,
                    start,
                    haptic_origin_ns,
                    update_buffer,
                );
                (stats, note)
            });
            let haptic_thread = s.spawn(move || {
                let mut haptic = haptic.zero_force_guard();
                let (granted, note) = if scheduling_wanted {
                    apply_scheduling(Some(1), true)
                } else {
                    (false, String::new())
                };
                let mut links = HapticThreadLinks {
                    tool_in,
                    contact_out,
                    live,
                    stop,
                    frames: frame_buffer,
                };
                let wait = WaitPlan::new(granted, Duration::from_secs_f64(dt));
                let started = Instant::now();
                let origin_ns =
                    u64::try_from(started.duration_since(start).as_nanos()).unwrap_or(0);
                haptic_origin_ns.store(origin_ns, Ordering::Release);
                let outcome = catch_unwind(AssertUnwindSafe(|| {
                    realtime_haptic_loop(&mut haptic, &mut links, steps, dt, wait, started)
                }))
                .map_err(|payload| panic_message(&*payload));
                drop(haptic);
                stop.store(true, Ordering::Release);
                let loop_s = match &outcome {
                    Ok((_, loop_s)) => *loop_s,
                    Err(_) => started.elapsed().as_secs_f64(),
                };
                (outcome.map(|(failure, _)| failure), loop_s, granted, note)
            });
            while !haptic_thread.is_finished() {
                progress(&live.snapshot());
                std::thread::sleep(Duration::from_millis(100));
            }
            let (outcome, loop_s, granted, haptic_note) =
                haptic_thread.join().unwrap_or_else(|_| {
                    (
                        Err("the haptic thread panicked outside its loop".into()),
                        start.elapsed().as_secs_f64(),
                        false,
                        String::new(),
                    )
                });
            stop.store(true, Ordering::Release);
            let (contact_stats, contact_note) = contact_thread.join().unwrap_or_else(|_| {
                let stats = ContactStats {
                    panicked: Some("contact thread could not be joined".into()),
                    ..ContactStats::default()
                };
                (stats, String::new())
            });
            (
                outcome,
                loop_s,
                contact_stats,
                granted,
                format!("haptic thread: {haptic_note}; contact thread: {contact_note}"),
            )
        });
        progress(&self.live.snapshot());
        // Rates over the haptic loop's own duration: the watcher notices the end up to a
        // tenth of a second late.
        let mut summary = self.summarize(RunMode::RealTime, loop_s, &contact_stats);
        summary.realtime_scheduling_granted = granted;
        summary.scheduling = if scheduling_wanted {
            notes
        } else {
            "not requested".into()
        };
        finish(summary, outcome)
    }
}
