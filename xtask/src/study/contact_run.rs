//! One contact run of the studies: a scene's parts with overrides, driven open loop by a device,
//! stepped in virtual time, with the series the paper plots recorded at every haptic step.

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

use haptic_core::{CollisionBackend, ContactSet, Device, Integrator, LinearizationMode, Real};
use haptic_dynamics::PenaltyModel;
use haptic_runtime::recording::RecordingHeader;
use haptic_runtime::{
    ContactLatency, ContactUpdate, HapticStage, PipelineBuilder, RunObserver, RunRecorder,
    SceneParts, Summary,
};
use serde::Serialize;

/// Where to record a run (for `cargo xtask view`), and its header.
pub struct Record {
    /// The recording file.
    pub path: PathBuf,
    /// Its header.
    pub header: RecordingHeader,
}

/// Collects the series and forwards to a recorder, if any.
struct Collector<'a> {
    series: Series,
    first_contact_s: Option<f64>,
    mode: LinearizationMode,
    progress: Option<&'a indicatif::ProgressBar>,
    recorder: Option<RunRecorder<BufWriter<File>>>,
}

impl<I: Integrator, D: Device> RunObserver<I, D> for Collector<'_> {
    fn haptic_step(&mut self, t: Real, h: &HapticStage<I, D>) {
        let tool = h.tool();
        let y = tool.to_vector();
        let kin = haptic_core::Kinematics::new(h.body(), &y);
        let contact = h.contact();
        if contact.raw_contact_count > 0 && self.first_contact_s.is_none() {
            self.first_contact_s = Some(t);
        }
        if let Some(bar) = self.progress {
            if self.series.t_s.len() % 10 == 0 {
                bar.set_position((t * 1e3) as u64);
            }
        }
        let series = &mut self.series;
        series.t_s.push(t);
        series.penetration_m.push(contact.max_penetration_m);
        series
            .deviation_m
            .push(h.forces().coupling.deviation(tool).translation_m);
        series.contact_force_n.push(
            h.forces()
                .contact
                .wrench_at(&y, &kin, self.mode)
                .force
                .norm(),
        );
        series.coupling_force_n.push(h.last_wrench().force.norm());
        if let Some(r) = &mut self.recorder {
            RunObserver::<I, D>::haptic_step(r, t, h);
        }
    }

    fn contact_update(
        &mut self,
        t: Real,
        available: Real,
        update: &ContactUpdate,
        raw: &ContactSet,
        representatives: &ContactSet,
        representative_weights_m: &[Real],
        query_time_s: Real,
    ) {
        if let Some(r) = &mut self.recorder {
            RunObserver::<I, D>::contact_update(
                r,
                t,
                available,
                update,
                raw,
                representatives,
                representative_weights_m,
                query_time_s,
            );
        }
    }
}

/// The series of one run, one sample per haptic step.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Series {
    /// Time (s).
    pub t_s: Vec<f64>,
    /// Deepest raw penetration of the contact update in use (m).
    pub penetration_m: Vec<f64>,
    /// Coupling deviation |x_h − x − R r_c| (m).
    pub deviation_m: Vec<f64>,
    /// Contact force magnitude on the tool, as the haptic thread evaluates it (N).
    pub contact_force_n: Vec<f64>,
    /// Coupling force magnitude sent to the device (N).
    pub coupling_force_n: Vec<f64>,
}

/// What a run gives.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// The telemetry summary.
    pub summary: Summary,
    /// The series.
    pub series: Series,
    /// Whether the run is stable (see [`is_stable`]).
    pub stable: bool,
    /// Time of the first contact update with contacts (s), if any.
    pub first_contact_s: Option<f64>,
}

/// Runs `parts` with `integrator`, `backend` and `device` for `seconds` of virtual time.
pub fn run<I, B, D>(
    parts: &SceneParts,
    integrator: I,
    backend: B,
    device: D,
    seconds: f64,
    latency: ContactLatency,
    progress: Option<&indicatif::ProgressBar>,
    record: Option<&Record>,
) -> anyhow::Result<RunResult>
where
    I: Integrator,
    B: CollisionBackend,
    D: Device,
{
    let mut pipeline = PipelineBuilder::new(parts.body, parts.tool_pose)
        .integrator(integrator)
        .backend(backend)
        .contact_model(PenaltyModel::new(parts.penalty)?)
        .device(device)
        .coupling(parts.coupling)
        .config(parts.config)
        .build()?;
    let recorder = match record {
        Some(r) => Some(RunRecorder::new(
            BufWriter::new(File::create(&r.path)?),
            &r.header,
            parts.config.query.error_threshold,
        )?),
        None => None,
    };
    let mut collector = Collector {
        series: Series::default(),
        first_contact_s: None,
        mode: parts.config.linearization,
        progress,
        recorder,
    };
    let outcome = pipeline.run_virtual_observed(seconds, latency, &mut collector);
    let summary = match (collector.recorder.take(), record) {
        (Some(r), Some(rec)) => crate::recording::finish_recording(outcome, r, &rec.path)?,
        _ => outcome?,
    };
    let (series, first_contact_s) = (collector.series, collector.first_contact_s);
    if let Some(bar) = progress {
        bar.finish();
    }
    let stable = is_stable(&summary, &series);
    Ok(RunResult {
        summary,
        series,
        stable,
        first_contact_s,
    })
}

/// A run is stable when nothing went wrong (no NaN, no failed solve, no force reaching the
/// device's limit, which these scenes never need), the
/// coupling deviation stays under 5 cm, and the coupling force settles: over the last 20 % of the
/// run its peak-to-peak variation is under half its mean plus 0.1 N (sustained oscillation or
/// growth fails this).
pub fn is_stable(summary: &Summary, series: &Series) -> bool {
    if summary.zero_force_steps > 0 || summary.solver_failures > 0 || summary.saturation_events > 0
    {
        return false;
    }
    if series
        .deviation_m
        .iter()
        .any(|d| !d.is_finite() || *d > 0.05)
    {
        return false;
    }
    let n = series.coupling_force_n.len();
    if n < 10 {
        return true;
    }
    let tail = &series.coupling_force_n[n - n / 5..];
    let mean = tail.iter().sum::<f64>() / tail.len() as f64;
    let (lo, hi) = tail
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    hi - lo < 0.5 * mean + 0.1
}

/// RMS of `values` over the samples whose time is in `[from, to)`.
pub fn rms_between(t: &[f64], values: &[f64], from: f64, to: f64) -> f64 {
    let (sum, n) = t
        .iter()
        .zip(values)
        .filter(|(t, _)| **t >= from && **t < to)
        .fold((0.0, 0usize), |(s, n), (_, v)| (s + v * v, n + 1));
    if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
}

/// Every `k`-th point of a series, as (t, v) pairs for a plot.
pub fn points(t: &[f64], v: &[f64], k: usize) -> Vec<(f64, f64)> {
    t.iter()
        .zip(v)
        .step_by(k.max(1))
        .map(|(t, v)| (*t, *v))
        .collect()
}

/// A progress bar for one run of `seconds`, in simulated milliseconds, labelled `name`.
pub fn bar(multi: &indicatif::MultiProgress, name: &str, seconds: f64) -> indicatif::ProgressBar {
    let bar = multi.add(indicatif::ProgressBar::new((seconds * 1e3) as u64));
    if let Ok(style) = indicatif::ProgressStyle::with_template("{bar:30} {pos:>4}/{len} ms  {msg}")
    {
        bar.set_style(style);
    }
    bar.set_message(name.to_owned());
    bar
}
