//! `cargo xtask bench realtime`: the real-time demo (spoon into cup, semi-implicit backward
//! Euler, LOD back-end) at 1 kHz and 10 kHz, with and without the real-time scheduling the
//! runtime asks for, on an idle machine and with every core busy with other work (one `yes >
//! /dev/null` process per core, started and stopped here). Writes `realtime.json`.

use std::process::{Child, Command, Stdio};

use anyhow::Context;
use haptic_collision::LodBackend;
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel};
use haptic_runtime::{PipelineBuilder, Scene, Summary};
use serde::Serialize;

use crate::common::repo_root;

/// One real-time run.
#[derive(Debug, Serialize)]
struct Row {
    /// Haptic rate asked for (Hz).
    haptic_hz: f64,
    /// Whether the run asked for real-time scheduling and core pinning.
    realtime_scheduling_requested: bool,
    /// Whether the OS granted it.
    realtime_scheduling_granted: bool,
    /// Busy processes running beside the demo.
    load_processes: usize,
    /// Haptic rate reached (Hz).
    haptic_rate_hz: f64,
    /// Haptic steps.
    haptic_steps: u64,
    /// Periods whose step ended after its deadline.
    deadline_misses: u64,
    /// `deadline_misses / haptic_steps`.
    deadline_miss_rel: f64,
    /// Step compute time, 99.9th percentile (s).
    step_p999_s: f64,
    /// Longest step (s).
    step_max_s: f64,
    /// Contact updates per second.
    contact_rate_hz: f64,
    /// What the OS said, in words.
    scheduling: String,
}

/// Busy processes that are killed when this is dropped, whatever happens in between.
struct Load(Vec<Child>);

impl Load {
    fn start(processes: usize) -> anyhow::Result<Self> {
        let mut load = Self(Vec::with_capacity(processes));
        for _ in 0..processes {
            let child = Command::new("yes")
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .context("starting a `yes` load process")?;
            load.0.push(child);
        }
        // Let them reach full speed.
        std::thread::sleep(std::time::Duration::from_millis(200));
        Ok(load)
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

fn run_once(
    scene: &Scene,
    haptic_hz: f64,
    realtime: bool,
    seconds: f64,
) -> anyhow::Result<Summary> {
    let mut parts = scene.assemble()?;
    parts.config.haptic_rate_hz = haptic_hz;
    parts.config.realtime_scheduling = realtime;
    let backend = LodBackend::new(&parts.tool_mesh, &parts.obstacles)?
        .with_stopping_rule(parts.stopping_rule);
    let mut pipeline = PipelineBuilder::new(parts.body, parts.tool_pose)
        .integrator(LinearizedBackwardEuler)
        .backend(backend)
        .contact_model(PenaltyModel::new(parts.penalty)?)
        .device(parts.hand_device()?)
        .coupling(parts.coupling)
        .config(parts.config)
        .build()?;
    Ok(pipeline.run_realtime(seconds, |_| {})?)
}

/// Runs the measurement.
pub fn run(out: &crate::OutArgs) -> anyhow::Result<()> {
    let dir = out.dir("bench")?;
    let seconds = if out.quick { 3.0 } else { 10.0 };
    let cores = std::thread::available_parallelism().map_or(2, usize::from);
    let scene_path = repo_root().join("xtask/scenes/spoon-cup.toml");
    let scene = Scene::load(&scene_path)?;
    let mut rows = Vec::new();
    println!("real-time demo (spoon into cup), {seconds} s per run; load: {cores} `yes` processes");
    println!(
        "{:>7} {:>9} {:>7} {:>5} {:>10} {:>8} {:>9} {:>11} {:>10}",
        "rate",
        "rt asked",
        "granted",
        "load",
        "reached Hz",
        "misses",
        "miss %",
        "p99.9 µs",
        "max µs"
    );
    for haptic_hz in [1000.0, 10_000.0] {
        for load_processes in [0, cores] {
            for realtime in [true, false] {
                let load = Load::start(load_processes)?;
                let s = run_once(&scene, haptic_hz, realtime, seconds)?;
                drop(load);
                let row = Row {
                    haptic_hz,
                    realtime_scheduling_requested: realtime,
                    realtime_scheduling_granted: s.realtime_scheduling_granted,
                    load_processes,
                    haptic_rate_hz: s.haptic_rate_hz,
                    haptic_steps: s.haptic_steps,
                    deadline_misses: s.deadline_misses,
                    deadline_miss_rel: s.deadline_misses as f64 / s.haptic_steps.max(1) as f64,
                    step_p999_s: s.step_p999_s,
                    step_max_s: s.step_max_s,
                    contact_rate_hz: s.contact_rate_hz,
                    scheduling: s.scheduling.clone(),
                };
                println!(
                    "{:>7.0} {:>9} {:>7} {:>5} {:>10.0} {:>8} {:>9.3} {:>11.1} {:>10.1}",
                    row.haptic_hz,
                    row.realtime_scheduling_requested,
                    row.realtime_scheduling_granted,
                    row.load_processes,
                    row.haptic_rate_hz,
                    row.deadline_misses,
                    row.deadline_miss_rel * 100.0,
                    row.step_p999_s * 1e6,
                    row.step_max_s * 1e6
                );
                rows.push(row);
            }
        }
    }
    let path = dir.join("realtime.json");
    std::fs::write(&path, serde_json::to_string_pretty(&rows)?)?;
    println!("wrote {}", path.display());
    Ok(())
}
