//! Telemetry that does not slow the loop: fixed-size histograms and counters owned by each
//! thread, published to a shared snapshot with relaxed atomic stores (no lock, no allocation).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use haptic_core::Real;
use serde::{Deserialize, Serialize};

/// Lower edge of the first histogram bin (s).
const HIST_MIN_S: Real = 1e-8;
/// Bins per decade: about 6 % resolution.
const BINS_PER_DECADE: usize = 40;
/// Decades covered: 10 ns to 100 s.
const DECADES: usize = 10;
const BINS: usize = BINS_PER_DECADE * DECADES;

/// A log-binned histogram of durations, allocated once.
#[derive(Debug, Clone)]
pub struct DurationHistogram {
    counts: Box<[u64; BINS]>,
    total: u64,
    max_s: Real,
    sum_s: Real,
}

impl Default for DurationHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl DurationHistogram {
    /// An empty histogram.
    pub fn new() -> Self {
        Self {
            counts: Box::new([0; BINS]),
            total: 0,
            max_s: 0.0,
            sum_s: 0.0,
        }
    }

    /// Records one duration (s). Constant time, no allocation.
    #[inline]
    pub fn record(&mut self, seconds: Real) {
        if !seconds.is_finite() {
            return;
        }
        let bin = if seconds <= HIST_MIN_S {
            0
        } else {
            (((seconds / HIST_MIN_S).log10() * BINS_PER_DECADE as Real) as usize).min(BINS - 1)
        };
        self.counts[bin] += 1;
        self.total += 1;
        self.sum_s += seconds;
        if seconds > self.max_s {
            self.max_s = seconds;
        }
    }

    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// Largest sample (s).
    pub fn max_s(&self) -> Real {
        self.max_s
    }

    /// Mean (s), 0 when empty.
    pub fn mean_s(&self) -> Real {
        if self.total == 0 {
            0.0
        } else {
            self.sum_s / self.total as Real
        }
    }

    /// The `p`-quantile (`p` in [0, 1]) as the upper edge of its bin (s), capped at the maximum;
    /// 0 when empty.
    pub fn quantile_s(&self, p: Real) -> Real {
        if self.total == 0 {
            return 0.0;
        }
        let target = ((p.clamp(0.0, 1.0) * self.total as Real).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= target {
                let upper = HIST_MIN_S * 10f64.powf((i + 1) as Real / BINS_PER_DECADE as Real);
                return upper.min(self.max_s);
            }
        }
        self.max_s
    }
}

/// A shared `f64` written by one thread and read by others, lock-free.
#[derive(Debug, Default)]
pub struct AtomicReal(AtomicU64);

impl AtomicReal {
    /// Stores a value (relaxed).
    #[inline]
    pub fn store(&self, v: Real) {
        self.0.store(v.to_bits(), Ordering::Relaxed);
    }
    /// Loads the value (relaxed).
    #[inline]
    pub fn load(&self) -> Real {
        Real::from_bits(self.0.load(Ordering::Relaxed))
    }
}

/// A pose shared by one writer (the haptic thread) with readers, lock-free: a sequence lock. The
/// writer never waits; a reader retries while a write is under way, so it never sees half of
/// one pose and half of another.
#[derive(Debug, Default)]
pub struct AtomicPose {
    seq: AtomicU64,
    values: [AtomicU64; 7],
}

impl AtomicPose {
    /// Stores `[x, y, z, qw, qx, qy, qz]` (one writer only).
    #[inline]
    pub fn store(&self, pose: &[Real; 7]) {
        let seq = self.seq.load(Ordering::Relaxed);
        self.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
        std::sync::atomic::fence(Ordering::Release);
        for (cell, v) in self.values.iter().zip(pose) {
            cell.store(v.to_bits(), Ordering::Relaxed);
        }
        self.seq.store(seq.wrapping_add(2), Ordering::Release);
    }

    /// Loads the last pose stored whole (all zeros before the first).
    pub fn load(&self) -> [Real; 7] {
        loop {
            let before = self.seq.load(Ordering::Acquire);
            if before % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let mut out = [0.0; 7];
            for (o, cell) in out.iter_mut().zip(&self.values) {
                *o = Real::from_bits(cell.load(Ordering::Relaxed));
            }
            std::sync::atomic::fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == before {
                return out;
            }
        }
    }
}

/// Live counters, readable from any thread while the pipeline runs.
#[derive(Debug, Default)]
pub struct LiveTelemetry {
    /// Haptic steps done.
    pub haptic_steps: AtomicU64,
    /// Contact updates published.
    pub contact_updates: AtomicU64,
    /// Simulated or wall time of the haptic thread (s).
    pub time_s: AtomicReal,
    /// Largest force sent so far (N).
    pub max_force_n: AtomicReal,
    /// Largest penetration so far (m).
    pub max_penetration_m: AtomicReal,
    /// Raw contacts of the latest update.
    pub raw_contact_count: AtomicU64,
    /// Clusters of the latest update.
    pub cluster_count: AtomicU64,
    /// Deadline misses so far.
    pub deadline_misses: AtomicU64,
    /// Steps that sent zero force (a NaN reading or state, or a failed solve) so far.
    pub zero_force_steps: AtomicU64,
    /// Set when the contact thread has died.
    pub contact_thread_dead: AtomicBool,
    /// The tool's pose after the latest haptic step, `[x, y, z, qw, qx, qy, qz]`.
    pub tool_pose: AtomicPose,
}

/// A copy of the live counters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Snapshot {
    /// Haptic steps done.
    pub haptic_steps: u64,
    /// Contact updates published.
    pub contact_updates: u64,
    /// Haptic thread time (s).
    pub time_s: Real,
    /// Largest force sent so far (N).
    pub max_force_n: Real,
    /// Largest penetration so far (m).
    pub max_penetration_m: Real,
    /// Raw contacts of the latest update.
    pub raw_contact_count: u64,
    /// Clusters of the latest update.
    pub cluster_count: u64,
    /// Deadline misses so far.
    pub deadline_misses: u64,
    /// Steps that sent zero force (a NaN reading or state, or a failed solve) so far.
    pub zero_force_steps: u64,
    /// The tool's pose after the latest haptic step, `[x, y, z, qw, qx, qy, qz]` (zeros before
    /// the first).
    pub tool_pose: [Real; 7],
}

impl LiveTelemetry {
    /// Reads every counter.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            haptic_steps: self.haptic_steps.load(Ordering::Relaxed),
            contact_updates: self.contact_updates.load(Ordering::Relaxed),
            time_s: self.time_s.load(),
            max_force_n: self.max_force_n.load(),
            max_penetration_m: self.max_penetration_m.load(),
            raw_contact_count: self.raw_contact_count.load(Ordering::Relaxed),
            cluster_count: self.cluster_count.load(Ordering::Relaxed),
            deadline_misses: self.deadline_misses.load(Ordering::Relaxed),
            zero_force_steps: self.zero_force_steps.load(Ordering::Relaxed),
            tool_pose: self.tool_pose.load(),
        }
    }
}

/// How a run was clocked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RunMode {
    /// Haptic and contact threads on the wall clock ([`crate::Pipeline::run_realtime`]);
    /// serialized `"real-time"`.
    RealTime,
    /// One thread, simulated time, deterministic ([`crate::Pipeline::run_virtual`]);
    /// serialized `"virtual-time"`.
    #[default]
    VirtualTime,
}

impl std::fmt::Display for RunMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RunMode::RealTime => "real-time",
            RunMode::VirtualTime => "virtual-time",
        })
    }
}

/// The end-of-run summary. Serialized as the demo's `--json` output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Summary {
    /// How the run was clocked.
    pub mode: RunMode,
    /// Duration of the run (s, wall or simulated).
    pub duration_s: Real,
    /// Haptic steps done.
    pub haptic_steps: u64,
    /// Achieved haptic rate (Hz).
    pub haptic_rate_hz: Real,
    /// Median haptic step compute time (s).
    pub step_p50_s: Real,
    /// 99th percentile of the haptic step time (s).
    pub step_p99_s: Real,
    /// 99.9th percentile of the haptic step time (s).
    pub step_p999_s: Real,
    /// Longest haptic step (s).
    pub step_max_s: Real,
    /// Periods whose step finished after the next deadline.
    pub deadline_misses: u64,
    /// Contact updates published.
    pub contact_updates: u64,
    /// Achieved contact-thread rate (Hz).
    pub contact_rate_hz: Real,
    /// Median contact latency, query start to result available (s).
    pub contact_latency_p50_s: Real,
    /// Longest contact latency (s).
    pub contact_latency_max_s: Real,
    /// Collision queries the broad phase settled (nothing near the tool).
    pub broad_phase_only_queries: u64,
    /// Most raw contacts in one update.
    pub raw_contact_count_max: u64,
    /// Most clusters in one update.
    pub cluster_count_max: u64,
    /// Deepest raw penetration seen (m); 0 without contact.
    pub max_penetration_m: Real,
    /// Largest distance between device handle and grasp point (m).
    pub max_coupling_deviation_m: Real,
    /// Largest force sent to the device (N).
    pub max_force_n: Real,
    /// Commands clamped to the device limits.
    pub saturation_events: u64,
    /// Steps that sent zero force because of a NaN (device or state) or a failed solve.
    pub zero_force_steps: u64,
    /// Integration failures among those.
    pub solver_failures: u64,
    /// Steps whose Newton solve did not converge and that took the semi-implicit step instead
    /// (`SafetyConfig::semi_implicit_fallback`); force stayed on.
    #[serde(default)]
    pub solver_fallbacks: u64,
    /// Contact model or back-end errors (that update was dropped).
    pub contact_errors: u64,
    /// Steps during which the contact model was older than the timeout and faded.
    pub contact_stale_steps: u64,
    /// Contact updates that arrived late: the tool had travelled more than `δ` into a surface
    /// between the query and the update (raise `δ` or the contact rate; `docs/stability.md`).
    #[serde(default)]
    pub late_contact_updates: u64,
    /// Whether the contact thread panicked (the haptic thread went on without it).
    pub contact_thread_panicked: bool,
    /// Median error threshold of the updates with contacts (fraction of the tool's bounding
    /// radius): the scene's, or what a time budget picked.
    #[serde(default)]
    pub error_threshold_median: Real,
    /// Largest error threshold of the updates with contacts.
    #[serde(default)]
    pub error_threshold_max: Real,
    /// The message of a panic that ended the haptic loop (zero force was commanded), if any.
    pub haptic_thread_panic: Option<String>,
    /// What happened to the contact thread or the device, in words; empty when all went well.
    pub incidents: Vec<String>,
    /// Whether the OS granted the haptic thread real-time scheduling (`SCHED_FIFO` on Linux);
    /// always `false` in virtual time and when not requested.
    pub realtime_scheduling_granted: bool,
    /// What the OS allowed for thread priority and affinity, in words.
    pub scheduling: String,
}

/// The summary as `cargo xtask demo` prints it: rates and step times of both loops, contacts,
/// forces, safety counters, scheduling (real time) and incidents, one topic a line.
impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self;
        writeln!(f, "--- {} run, {:.2} s ---", s.mode, s.duration_s)?;
        writeln!(
            f,
            "haptic loop   {:>8.0} Hz   step p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs; {} deadline misses",
            s.haptic_rate_hz,
            s.step_p50_s * 1e6,
            s.step_p99_s * 1e6,
            s.step_p999_s * 1e6,
            s.step_max_s * 1e6,
            s.deadline_misses
        )?;
        writeln!(
            f,
            "contact loop  {:>8.0} Hz   latency p50 {:.2} ms, max {:.2} ms; {} updates, {} in free space",
            s.contact_rate_hz,
            s.contact_latency_p50_s * 1e3,
            s.contact_latency_max_s * 1e3,
            s.contact_updates,
            s.broad_phase_only_queries
        )?;
        writeln!(
            f,
            "contacts      {} raw at most, {} clusters at most; max penetration {:.3} mm; error threshold {:.2} % (median; max {:.2} %)",
            s.raw_contact_count_max,
            s.cluster_count_max,
            s.max_penetration_m * 1e3,
            s.error_threshold_median * 100.0,
            s.error_threshold_max * 100.0
        )?;
        writeln!(
            f,
            "forces        max {:.2} N sent, {} saturation events; max coupling deviation {:.2} mm",
            s.max_force_n,
            s.saturation_events,
            s.max_coupling_deviation_m * 1e3
        )?;
        writeln!(
            f,
            "safety        {} zero-force steps (NaN or failed solve), {} solver failures ({} Newton steps fell back to semi-implicit), {} contact errors",
            s.zero_force_steps, s.solver_failures, s.solver_fallbacks, s.contact_errors
        )?;
        if s.mode == RunMode::RealTime {
            writeln!(
                f,
                "scheduling    real-time scheduling {}; {}",
                if s.realtime_scheduling_granted {
                    "granted"
                } else {
                    "NOT granted"
                },
                s.scheduling
            )?;
        }
        for i in &s.incidents {
            writeln!(f, "incident      {i}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod pose_cell_tests {
    use super::*;

    /// A reader racing one writer sees whole poses only: every value of a pose read equal.
    #[test]
    fn a_pose_is_never_read_half_written() {
        let cell = std::sync::Arc::new(AtomicPose::default());
        let writer = {
            let cell = cell.clone();
            std::thread::spawn(move || {
                for k in 1..=200_000u32 {
                    cell.store(&[Real::from(k); 7]);
                }
            })
        };
        let mut reads = 0;
        while !writer.is_finished() || reads == 0 {
            let p = cell.load();
            assert!(p.iter().all(|v| *v == p[0]), "torn read {p:?}");
            reads += 1;
        }
        writer.join().unwrap();
        assert_eq!(cell.load(), [200_000.0; 7]);
    }
}
