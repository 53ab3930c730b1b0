//! `cargo xtask stress`: randomized long runs in virtual time over the spoon-in-cup scene, that
//! count what must never happen (a NaN or over-limit force sent to the device) and map which
//! (integrator, mass, stiffness, contact rate) configurations are stable.
//!
//! Every run drives the full pipeline (LOD collision at 2.5 %, clustering, linearized penalty
//! model, virtual coupling, integrator) through a [`Probe`] device that checks every wrench the
//! pipeline sends, independently of the pipeline's own saturation, and runs a passivity observer
//! (Hannaford & Ryu 2002): the energy that has flowed from the device port into the simulation,
//! `E(t) = −Σ (F·v + T·ω) Δt`. A passive simulation keeps `E ≥ 0`; its minimum is reported.

use std::sync::atomic::{AtomicU64, Ordering};

use haptic_collision::LodBackend;
use haptic_core::{Device, DeviceLimits, DeviceState, Pose, QueryParams, Real, Vec3, Wrench};
use haptic_device::{Fault, FaultInjector, ScriptedDevice, Waypoint};
use haptic_dynamics::{
    CouplingParams, ForwardEuler, LinearizedBackwardEuler, NewtonBackwardEuler, PenaltyModel,
    PenaltyParams, Rk4,
};
use haptic_runtime::{ContactLatency, PipelineBuilder, Scene, SceneParts};
use nalgebra::UnitQuaternion;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use crate::common::{repo_root, write_json};

/// Arguments of the stress runs.
#[derive(clap::Args, Debug)]
pub struct StressArgs {
    /// Output options.
    #[command(flatten)]
    pub out: crate::OutArgs,
    /// Total haptic steps over all runs (default 1,000,000; 100,000 with `--quick`).
    #[arg(long)]
    pub steps: Option<u64>,
}

/// Simulated seconds per run.
const RUN_S: Real = 2.0;

/// The integrators, in the order the runs cycle through them.
const INTEGRATORS: [&str; 4] = [
    "backward_euler",
    "newton_backward_euler",
    "rk4",
    "forward_euler",
];

/// What the hand does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
enum Motion {
    /// Into the cup and against the wall, smoothly.
    Smooth,
    /// Jumps of 10 cm every 0.3 s.
    Teleports,
    /// Spinning at 50 rad/s about the vertical.
    Spin,
    /// The smooth motion with a burst of 50 NaN readings.
    NanBurst,
}

/// One randomized configuration.
#[derive(Debug, Clone, Serialize)]
struct Config {
    seed: u64,
    integrator: &'static str,
    mass_kg: Real,
    coupling_n_per_m: Real,
    contact_n_per_m: Real,
    contact_rate_hz: Real,
    motion: Motion,
}

/// What one run counted.
#[derive(Debug, Clone, Serialize)]
struct Outcome {
    config: Config,
    steps: u64,
    nan_forces_sent: u64,
    over_limit_forces_sent: u64,
    max_quat_norm_error: Real,
    divergent: bool,
    /// Tool resets after the coupling stretched past the divergence bound.
    resets: u64,
    /// Integration steps that failed (zero force sent).
    solver_failures: u64,
    /// Newton steps that did not converge and took the semi-implicit step instead.
    solver_fallbacks: u64,
    /// Largest coupling deviation (m).
    max_coupling_deviation_m: Real,
    stable: bool,
    passivity_min_energy_j: Real,
    max_force_n: Real,
    max_penetration_m: Real,
}

/// A device wrapper that checks every wrench sent (finite, within the limits) and observes the
/// energy through the port.
struct Probe<D> {
    inner: D,
    limits: DeviceLimits,
    last: Option<(Real, DeviceState)>,
    now_s: Real,
    energy_j: Real,
    min_energy_j: Real,
    nan_sent: u64,
    over_limit_sent: u64,
}

impl<D: Device> Probe<D> {
    fn new(inner: D) -> Self {
        let limits = inner.limits();
        Self {
            inner,
            limits,
            last: None,
            now_s: 0.0,
            energy_j: 0.0,
            min_energy_j: 0.0,
            nan_sent: 0,
            over_limit_sent: 0,
        }
    }
}

impl<D: Device> Device for Probe<D> {
    type Error = D::Error;

    fn name(&self) -> &str {
        "probe"
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, D::Error> {
        let s = self.inner.read(now_s)?;
        self.now_s = now_s;
        self.last = Some((now_s, s));
        Ok(s)
    }

    fn command(&mut self, w: &Wrench) -> Result<(), D::Error> {
        if !w.force.iter().chain(w.torque.iter()).all(|v| v.is_finite()) {
            self.nan_sent += 1;
        } else if w.force.norm() > self.limits.max_force_n * (1.0 + 1e-9)
            || w.torque.norm() > self.limits.max_torque_nm * (1.0 + 1e-9)
        {
            self.over_limit_sent += 1;
        }
        if let Some((_, s)) = &self.last {
            // Held until the next reading: one haptic period (1 ms).
            let p = w.force.dot(&s.twist.linear) + w.torque.dot(&s.twist.angular);
            if p.is_finite() {
                self.energy_j -= p * 1e-3;
                self.min_energy_j = self.min_energy_j.min(self.energy_j);
            }
        }
        self.inner.command(w)
    }

    fn command_zero(&mut self) -> Result<(), D::Error> {
        self.inner.command_zero()
    }
}

/// The hand's target for a motion, about the start pose.
fn device_for(
    motion: Motion,
    start: Pose,
    limits: DeviceLimits,
) -> anyhow::Result<FaultInjector<ScriptedDevice>> {
    let smooth = |limits| -> anyhow::Result<ScriptedDevice> {
        let at = |dx: Real, dy: Real| Pose {
            position: start.position + Vec3::new(dx, dy, 0.0),
            orientation: start.orientation,
        };
        Ok(ScriptedDevice::from_waypoints(
            vec![
                Waypoint::new(0.0, at(0.0, 0.0)),
                Waypoint::new(0.6, at(0.0, -0.07)),
                Waypoint::new(1.2, at(0.04, -0.07)),
                Waypoint::new(1.6, at(-0.04, -0.07)),
                Waypoint::new(RUN_S, at(0.04, -0.07)),
            ],
            limits,
        )?)
    };
    let (device, fault) = match motion {
        Motion::Smooth => (smooth(limits)?, Fault::None),
        Motion::NanBurst => (
            smooth(limits)?,
            Fault::NanBurst {
                after_reads: 900,
                reads: 50,
            },
        ),
        Motion::Teleports => (
            ScriptedDevice::from_fn(
                move |t| {
                    let k = (t / 0.3).floor() as i64;
                    let dx = if k % 2 == 0 { 0.0 } else { 0.1 };
                    let dy = if k % 4 < 2 { -0.07 } else { 0.0 };
                    Pose {
                        position: start.position + Vec3::new(dx, dy, 0.0),
                        orientation: start.orientation,
                    }
                },
                limits,
            ),
            Fault::None,
        ),
        Motion::Spin => (
            ScriptedDevice::from_fn(
                move |t| Pose {
                    position: start.position + Vec3::new(0.0, -0.07 * (t / RUN_S).min(1.0), 0.0),
                    orientation: UnitQuaternion::from_scaled_axis(Vec3::new(0.0, 50.0 * t, 0.0))
                        * start.orientation,
                },
                limits,
            ),
            Fault::None,
        ),
    };
    Ok(FaultInjector::new(device, fault))
}

fn log_uniform(rng: &mut impl Rng, lo: Real, hi: Real) -> Real {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

fn config(seed: u64) -> Config {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let motion = match rng.random_range(0..10) {
        0..=5 => Motion::Smooth,
        6 => Motion::Teleports,
        7 => Motion::Spin,
        _ => Motion::NanBurst,
    };
    Config {
        seed,
        integrator: INTEGRATORS[(seed % 4) as usize],
        mass_kg: log_uniform(&mut rng, 5e-4, 1.0),
        coupling_n_per_m: log_uniform(&mut rng, 50.0, 5000.0),
        contact_n_per_m: log_uniform(&mut rng, 500.0, 50_000.0),
        contact_rate_hz: log_uniform(&mut rng, 10.0, 1000.0),
        motion,
    }
}

/// Runs one configuration.
fn run_one(
    base: &SceneParts,
    backend: &LodBackend,
    c: &Config,
    passivity_controller: bool,
) -> anyhow::Result<Outcome> {
    let mut parts = base.clone();
    parts.body = base.body.with_mass(c.mass_kg)?;
    // The coupling's damping scales with its stiffness (the free-space study's ratios).
    let d = CouplingParams::default();
    let ratio = c.coupling_n_per_m / d.stiffness_n_per_m;
    parts.coupling = CouplingParams {
        stiffness_n_per_m: c.coupling_n_per_m,
        damping_ns_per_m: d.damping_ns_per_m * ratio,
        angular_stiffness_nm_per_rad: d.angular_stiffness_nm_per_rad * ratio,
        angular_damping_nms_per_rad: d.angular_damping_nms_per_rad * ratio,
        saturation: None,
    };
    parts.penalty = PenaltyParams::new(
        c.contact_n_per_m,
        base.penalty.damping_ns_per_m * c.contact_n_per_m / base.penalty.stiffness_n_per_m,
        base.penalty.delta_m,
    )?;
    parts.config.query = QueryParams::new(base.penalty.delta_m, 0.025)?;
    parts.config.safety.passivity_controller = passivity_controller;
    let device = Probe::new(device_for(c.motion, parts.tool_pose, parts.limits)?);
    let latency = ContactLatency::FixedRate {
        rate_hz: c.contact_rate_hz,
    };
    macro_rules! go {
        ($integrator:expr) => {{
            let mut p = PipelineBuilder::new(parts.body, parts.tool_pose)
                .integrator($integrator)
                .backend(backend.clone())
                .contact_model(PenaltyModel::new(parts.penalty)?)
                .device(device)
                .coupling(parts.coupling)
                .config(parts.config)
                .build()?;
            let summary = p.run_virtual(RUN_S, latency, |_, _| {})?;
            let stats = p.haptic().stats.clone();
            let probe = p.haptic().device();
            (
                summary,
                stats,
                probe.nan_sent,
                probe.over_limit_sent,
                probe.min_energy_j,
            )
        }};
    }
    let (summary, stats, nan_sent, over_sent, min_energy) = match c.integrator {
        "backward_euler" => go!(LinearizedBackwardEuler),
        "newton_backward_euler" => go!(NewtonBackwardEuler::default()),
        "rk4" => go!(Rk4),
        _ => go!(ForwardEuler),
    };
    let divergent = stats.divergences > 0 || stats.solver_failures > 0;
    // Stable: no divergence or failed step; the coupling stretches less than 10 cm (the smooth
    // motion pushes the handle at most about 4 cm past the cup wall; the force may saturate,
    // which is the device's limit, not an instability); the tool does not sink more than 5 mm
    // into the cup. Teleports and spins are judged on divergence only.
    let violent = matches!(c.motion, Motion::Teleports | Motion::Spin);
    let stable = !divergent
        && (violent || (stats.max_coupling_deviation_m < 0.1 && summary.max_penetration_m < 5e-3));
    Ok(Outcome {
        config: c.clone(),
        steps: stats.steps,
        nan_forces_sent: nan_sent,
        over_limit_forces_sent: over_sent,
        max_quat_norm_error: stats.max_quat_norm_error,
        divergent,
        resets: stats.divergences,
        solver_failures: stats.solver_failures,
        solver_fallbacks: stats.solver_fallbacks,
        max_coupling_deviation_m: stats.max_coupling_deviation_m,
        stable,
        passivity_min_energy_j: min_energy,
        max_force_n: summary.max_force_n,
        max_penetration_m: summary.max_penetration_m,
    })
}

/// Runs the stress tests.
pub fn run(args: &StressArgs) -> anyhow::Result<()> {
    let dir = args.out.dir("stress")?;
    let total = args
        .steps
        .unwrap_or(if args.out.quick { 100_000 } else { 1_000_000 });
    let steps_per_run = (RUN_S * 1000.0) as u64;
    let runs = total.div_ceil(steps_per_run).max(4);
    let scene = Scene::load(&repo_root().join("xtask/scenes/spoon-cup.toml"))?;
    let base = scene.assemble()?;
    let backend =
        LodBackend::new(&base.tool_mesh, &base.obstacles)?.with_stopping_rule(base.stopping_rule);
    println!(
        "stress: {runs} runs of {RUN_S} s ({} steps) over the spoon in the cup",
        runs * steps_per_run
    );
    let done = AtomicU64::new(0);
    let bar = indicatif::ProgressBar::new(runs);
    let outcomes: Vec<anyhow::Result<Outcome>> = (0..runs)
        .into_par_iter()
        .map(|seed| {
            let r = run_one(&base, &backend, &config(seed), false);
            done.fetch_add(1, Ordering::Relaxed);
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    let outcomes: Vec<Outcome> = outcomes.into_iter().collect::<Result<_, _>>()?;

    let steps_total: u64 = outcomes.iter().map(|o| o.steps).sum();
    let nan_sent: u64 = outcomes.iter().map(|o| o.nan_forces_sent).sum();
    let over_sent: u64 = outcomes.iter().map(|o| o.over_limit_forces_sent).sum();
    let quat = outcomes
        .iter()
        .map(|o| o.max_quat_norm_error)
        .fold(0.0, Real::max);
    let divergent = outcomes.iter().filter(|o| o.divergent).count();
    let mut per_integrator = std::collections::BTreeMap::new();
    for name in INTEGRATORS {
        let mine: Vec<&Outcome> = outcomes
            .iter()
            .filter(|o| o.config.integrator == name)
            .collect();
        per_integrator.insert(
            name,
            IntegratorTotals {
                runs: mine.len(),
                divergent_runs: mine.iter().filter(|o| o.divergent).count(),
                stable_runs: mine.iter().filter(|o| o.stable).count(),
                passivity_min_energy_j: mine
                    .iter()
                    .map(|o| o.passivity_min_energy_j)
                    .fold(0.0, Real::min),
            },
        );
    }
    // The passivity controller, measured on the smooth-motion runs that are unstable without it.
    let unstable: Vec<&Outcome> = outcomes
        .iter()
        .filter(|o| !o.stable && matches!(o.config.motion, Motion::Smooth | Motion::NanBurst))
        .collect();
    let with_pc: Vec<Outcome> = unstable
        .par_iter()
        .map(|o| run_one(&base, &backend, &o.config, true))
        .collect::<Result<_, _>>()?;
    let pc_stable = with_pc.iter().filter(|o| o.stable).count();
    let pc_min_energy = with_pc
        .iter()
        .map(|o| o.passivity_min_energy_j)
        .fold(0.0, Real::min);
    let before_min_energy = unstable
        .iter()
        .map(|o| o.passivity_min_energy_j)
        .fold(0.0, Real::min);
    println!(
        "passivity controller on the {} unstable smooth-motion runs: {pc_stable} become stable; lowest port energy {before_min_energy:.3} J without, {pc_min_energy:.3} J with",
        unstable.len()
    );
    let map = stability_map(&outcomes);
    let corner = Corner::of(&outcomes);
    println!(
        "stiff, slow-update corner (contact rate < {:.0} Hz, k_c > {:.0} kN/m, implicit integrators, smooth and NaN-burst motions): {}/{} stable, {} ejected (reset, or coupling past 10 cm), {} with a failed step",
        CORNER_RATE_HZ,
        CORNER_STIFFNESS_N_PER_M / 1e3,
        corner.stable,
        corner.runs,
        corner.ejected,
        corner.failed_steps
    );
    let report = StressReport {
        steps_total,
        configurations: outcomes.len(),
        nan_forces_sent: nan_sent,
        over_limit_forces_sent: over_sent,
        max_quat_norm_error: quat,
        divergent_runs: divergent,
        integrators: per_integrator,
        stability_map: &map.1,
        corner,
        passivity_controller: PassivityReport {
            rerun_unstable_smooth_runs: unstable.len(),
            stable_with_controller: pc_stable,
            min_port_energy_without_j: before_min_energy,
            min_port_energy_with_j: pc_min_energy,
            nan_forces_sent: with_pc.iter().map(|o| o.nan_forces_sent).sum::<u64>(),
            over_limit_forces_sent: with_pc
                .iter()
                .map(|o| o.over_limit_forces_sent)
                .sum::<u64>(),
        },
        runs: &outcomes,
    };
    write_json(&dir.join("stress.json"), &report)?;
    std::fs::write(dir.join("stability.md"), &map.0)?;
    println!(
        "{steps_total} steps, {} configurations: {nan_sent} NaN forces sent, {over_sent} over-limit forces sent, max |q| error {quat:.1e}, {divergent} divergent runs",
        outcomes.len()
    );
    println!("{}", map.0);
    Ok(())
}

/// The stability map: for each integrator, the fraction of smooth-motion runs that are stable,
/// by decade of mass and by the coupling-stiffness-to-mass ratio. Returns Markdown and JSON.
fn stability_map(outcomes: &[Outcome]) -> (String, Vec<MapCell>) {
    let mass_bins: [(Real, Real); 4] = [(5e-4, 5e-3), (5e-3, 5e-2), (5e-2, 0.5), (0.5, 1.0 + 1e-9)];
    let rate_bins: [(Real, Real); 2] = [(10.0, 100.0), (100.0, 1000.0 + 1e-9)];
    let mut md = String::from(
        "| integrator | contact rate | 0.5–5 g | 5–50 g | 50–500 g | 0.5–1 kg |\n|---|---|---|---|---|---|\n",
    );
    let mut cells = Vec::new();
    for name in INTEGRATORS {
        for (rlo, rhi) in rate_bins {
            let mut row = format!("| {name} | {rlo:.0}–{:.0} Hz |", rhi.floor());
            for (mlo, mhi) in mass_bins {
                let runs: Vec<&Outcome> = outcomes
                    .iter()
                    .filter(|o| {
                        o.config.integrator == name
                            && matches!(o.config.motion, Motion::Smooth | Motion::NanBurst)
                            && o.config.mass_kg >= mlo
                            && o.config.mass_kg < mhi
                            && o.config.contact_rate_hz >= rlo
                            && o.config.contact_rate_hz < rhi
                    })
                    .collect();
                let stable = runs.iter().filter(|o| o.stable).count();
                if runs.is_empty() {
                    row.push_str(" – |");
                } else {
                    row.push_str(&format!(" {stable}/{} |", runs.len()));
                }
                cells.push(MapCell {
                    integrator: name,
                    contact_rate_hz: [rlo, rhi],
                    mass_kg: [mlo, mhi],
                    runs: runs.len(),
                    stable,
                });
            }
            md.push_str(&row);
            md.push('\n');
        }
    }
    (md, cells)
}

/// Contact rates below this (Hz), with [`CORNER_STIFFNESS_N_PER_M`], make the corner where stale
/// contact models used to throw light tools out (`docs/stability.md`).
const CORNER_RATE_HZ: Real = 100.0;
/// Contact stiffnesses above this (N/m) make the corner, with [`CORNER_RATE_HZ`].
const CORNER_STIFFNESS_N_PER_M: Real = 15_000.0;

/// The stiff, slow-update corner of the map: implicit integrators, smooth and NaN-burst
/// motions, contact rate below [`CORNER_RATE_HZ`], contact stiffness above
/// [`CORNER_STIFFNESS_N_PER_M`].
#[derive(Serialize)]
struct Corner {
    runs: usize,
    stable: usize,
    /// Runs with a tool reset or the coupling stretched past 10 cm.
    ejected: usize,
    /// Runs with an integration step that failed.
    failed_steps: usize,
}

impl Corner {
    fn of(outcomes: &[Outcome]) -> Self {
        let runs: Vec<&Outcome> = outcomes
            .iter()
            .filter(|o| {
                let c = &o.config;
                matches!(c.integrator, "backward_euler" | "newton_backward_euler")
                    && matches!(c.motion, Motion::Smooth | Motion::NanBurst)
                    && c.contact_rate_hz < CORNER_RATE_HZ
                    && c.contact_n_per_m > CORNER_STIFFNESS_N_PER_M
            })
            .collect();
        Self {
            runs: runs.len(),
            stable: runs.iter().filter(|o| o.stable).count(),
            ejected: runs
                .iter()
                .filter(|o| o.resets > 0 || o.max_coupling_deviation_m >= 0.1)
                .count(),
            failed_steps: runs.iter().filter(|o| o.solver_failures > 0).count(),
        }
    }
}

/// Per-integrator totals of `stress.json`.
#[derive(Serialize)]
struct IntegratorTotals {
    runs: usize,
    divergent_runs: usize,
    stable_runs: usize,
    passivity_min_energy_j: Real,
}

/// One cell of the stability map.
#[derive(Serialize)]
struct MapCell {
    integrator: &'static str,
    contact_rate_hz: [Real; 2],
    mass_kg: [Real; 2],
    runs: usize,
    stable: usize,
}

/// The passivity controller's reruns.
#[derive(Serialize)]
struct PassivityReport {
    rerun_unstable_smooth_runs: usize,
    stable_with_controller: usize,
    min_port_energy_without_j: Real,
    min_port_energy_with_j: Real,
    nan_forces_sent: u64,
    over_limit_forces_sent: u64,
}

/// `stress.json`.
#[derive(Serialize)]
struct StressReport<'a> {
    steps_total: u64,
    configurations: usize,
    nan_forces_sent: u64,
    over_limit_forces_sent: u64,
    max_quat_norm_error: Real,
    divergent_runs: usize,
    integrators: std::collections::BTreeMap<&'static str, IntegratorTotals>,
    stability_map: &'a [MapCell],
    corner: Corner,
    passivity_controller: PassivityReport,
    runs: &'a [Outcome],
}
