//! `cargo xtask bench [--out DIR] [--quick]`: the performance report, `DIR/perf.json`.
//!
//! Everything is timed one call at a time with [`Instant`] (its own cost, about 20–40 ns on this
//! kind of machine, is included) and summarized by quantiles:
//!
//! - `haptic_step.<integrator>.{free,contacts5}`: one haptic step = `set_device` + integrator step
//!   with [`HapticForces`] + `device_reaction` at the new state. The spoon of the work-precision
//!   study (100 g) on the default coupling, the hand motion of the free-space study at 1 kHz; with
//!   `contacts5`, the penalty wrench of five representatives (the work-precision table contact)
//!   on their fixed frames, the runtime's default contact model, with the contacts' yield and
//!   the Jacobian each integrator asks for, as the runtime's haptic stage takes a step. Each step
//!   starts from the state of a backward-Euler run along the same hand motion (so that every
//!   integrator is timed at the same, bounded states even where it would itself go unstable).
//!   On the paper's tangents, held for the whole 2.5 s run, the backward-Euler run itself was
//!   thrown off the table late in the motion after an ulp-level change of the bounds' arithmetic
//!   (a stale tangent can give energy, `docs/stability.md`), and Newton then failed on its
//!   states.
//! - `cluster_50_to_5_median_s`: `Clusterer` (defaults: K = 5, warm start) on 50 contacts of a
//!   drifting patch, as in `haptic-cluster/benches/cluster.rs`.
//! - `collision_jaws`: `ParryBackend`, `LodBackend` exact and at 2.5 % of the tool's bounding
//!   radius, on the same 200 jaws poses (the collision benchmark's path: the upper jaw in
//!   occlusion, moved by up to 0.5 mm and 0.3°), δ = 1 mm, interleaved pose by pose in one run.
//! - `contact_stage_jaws`: the whole contact stage of the runtime (`ContactStage::update`: the
//!   LOD query, clustering and the linearized model) on the same poses at 2.5 % and 0.4 %,
//!   beside parry's query of the same run (`parry_median_s` and the ratios).
//! - `build_jaws_s`, `build_jaws_bytes`: `LodBackend::new` on the jaws, and its heap memory;
//!   `load_jaws_s`: the same hierarchies read back from their saved files.
//! - `free_space_contact_step_median_s`: the contact stage in free space: the runtime's
//!   `ContactStage::update_into` (as the real-time contact thread calls it, writing into the
//!   buffer it publishes) with the upper jaw 1 m above the lower one: the LOD query, whose broad
//!   phase rejects the pair, and the stage's free-space handling (the representatives and the
//!   model cleared in place).
//! - `receive_contact_update_median_s`: `HapticStage::receive_contact` of a new update with the
//!   five table contacts of `contacts5`: what the haptic thread does on top of its step when
//!   an update arrives (the copy of the contacts in use into the stage).
//! - `suite_worst`: the worst figure over the generalization suite's scenes for each of issue
//!   15's goals (`cargo xtask bench collision --suite`, run last, `--quick` with this report;
//!   its `suite.json` lands beside `perf.json` with `--out`).

use std::collections::BTreeMap;
use std::hint::black_box;
use std::time::Instant;

use haptic_cluster::{ClusterParams, Clusterer};
use haptic_collision::{LoadOptions, LodBackend, ParryBackend, TriMesh};
use haptic_core::{
    CollisionBackend, Contact, ContactSet, DeviceLimits, DeviceState, Integrator, Kinematics,
    LinearizationMode, Pose, QueryParams, Real, ToolState, Vec3,
};
use haptic_device::ScriptedDevice;
use haptic_dynamics::{HapticForces, IntegratorKind, LinearizedBackwardEuler};
use haptic_runtime::{ContactUpdate, HapticStage, SafetyConfig};
use nalgebra::UnitQuaternion;
use serde::Serialize;

use crate::common;
use crate::study::work_precision::{Setup, hand_device, setup};

/// Haptic rate, Hz.
const RATE_HZ: Real = 1000.0;
/// Distance tolerance of the jaws queries, m.
const DELTA_M: Real = 1e-3;

/// Median, p99 and p99.9 of `v` (sorted in place).
fn quantiles(v: &mut [Real]) -> (Real, Real, Real) {
    v.sort_by(Real::total_cmp);
    let q = |f: Real| v[((v.len() - 1) as Real * f).round() as usize];
    (q(0.5), q(0.99), q(0.999))
}

fn median(v: &mut [Real]) -> Real {
    quantiles(v).0
}

/// The forces of one haptic step as the runtime sets them up for `integ`: the coupling, and with
/// `contact` the table contact on its fixed frames (the runtime's default model), with the
/// contact Jacobian the integrator asks for.
fn haptic_forces(s: &Setup, contact: bool, integ: &dyn Integrator) -> HapticForces {
    let mut forces = HapticForces::new(s.coupling);
    forces.mode = LinearizationMode::FixedFrames;
    forces.jacobian_kind = integ.jacobian_kind();
    if contact {
        forces.contact = s.table;
    }
    forces
}

/// One haptic step as the runtime's haptic stage takes it: the device reading, the contacts
/// pressed beyond their reach yielding (fixed frames), the integrator's step.
fn haptic_step(
    s: &Setup,
    integ: &mut dyn Integrator,
    forces: &mut HapticForces,
    (device, tool): (&DeviceState, &ToolState),
    t_s: Real,
) -> anyhow::Result<ToolState> {
    forces.coupling.set_device(device)?;
    if !forces.contact.is_empty() {
        let y = tool.to_vector();
        forces
            .contact
            .yield_beyond_reach(&y, &Kinematics::new(&s.body, &y));
    }
    Ok(integ.step(&s.body, tool, t_s, 1.0 / RATE_HZ, forces)?)
}

/// The device readings and the backward-Euler states along the hand motion, one per haptic step.
fn reference_states(
    s: &Setup,
    contact: bool,
    steps: usize,
) -> anyhow::Result<Vec<(DeviceState, ToolState)>> {
    let h = 1.0 / RATE_HZ;
    let mut integ = IntegratorKind::LinearizedBackwardEuler.boxed();
    let mut forces = haptic_forces(s, contact, &*integ);
    let mut tool = s.start;
    let mut out = Vec::with_capacity(steps);
    for n in 0..steps {
        let t = n as Real * h;
        let device = hand_device(t);
        out.push((device, tool));
        tool = haptic_step(s, &mut *integ, &mut forces, (&device, &tool), t)?;
    }
    Ok(out)
}

/// Times `samples` haptic steps of `kind`, cycling over `states`; returns median, p99, p99.9.
fn time_haptic_step(
    kind: IntegratorKind,
    s: &Setup,
    contact: bool,
    states: &[(DeviceState, ToolState)],
    samples: usize,
) -> anyhow::Result<(Real, Real, Real)> {
    let h = 1.0 / RATE_HZ;
    let mut integ: Box<dyn Integrator + Send> = kind.boxed();
    let mut forces = haptic_forces(s, contact, &*integ);
    let mut times = Vec::with_capacity(samples);
    // One unmeasured pass to warm caches and branch predictors.
    for (i, (device, tool)) in states.iter().enumerate() {
        let next = haptic_step(s, &mut *integ, &mut forces, (device, tool), i as Real * h)?;
        black_box(forces.coupling.device_reaction(&s.body, &next));
    }
    for k in 0..samples {
        let i = k % states.len();
        let (device, tool) = &states[i];
        let t = i as Real * h;
        let clock = Instant::now();
        let next = haptic_step(
            s,
            &mut *integ,
            &mut forces,
            (black_box(device), black_box(tool)),
            t,
        )?;
        let reaction = forces.coupling.device_reaction(&s.body, &next);
        times.push(clock.elapsed().as_secs_f64());
        black_box(reaction);
    }
    Ok(quantiles(&mut times))
}

/// Times `HapticStage::receive_contact` of `samples` new updates holding the five table contacts
/// (each with a new sequence number, so that each is taken), on a stage at the start state.
fn time_receive_contact(s: &Setup, samples: usize) -> anyhow::Result<Real> {
    let integ = LinearizedBackwardEuler;
    let forces = haptic_forces(s, false, &integ);
    let limits = DeviceLimits::new(10.0, 1.0, Vec3::repeat(-10.0), Vec3::repeat(10.0), RATE_HZ)?;
    let device = ScriptedDevice::stationary(hand_device(0.0).pose, limits)?;
    let mut stage = HapticStage::new(
        integ,
        device,
        s.body,
        forces,
        s.start,
        SafetyConfig::default(),
    );
    let mut update = ContactUpdate::none();
    update.model = s.table;
    update.raw_contact_count = s.table.contact_count;
    update.cluster_count = s.table.contact_count;
    update.broad_phase_only = false;
    let mut times = Vec::with_capacity(samples);
    for k in 0..samples + 1000 {
        update.seq = k as u64 + 1;
        let clock = Instant::now();
        stage.receive_contact(black_box(&update), k as Real * 1e-3);
        let dt = clock.elapsed().as_secs_f64();
        black_box(stage.forces());
        if k >= 1000 {
            times.push(dt);
        }
    }
    anyhow::ensure!(
        stage.forces().contact.contact_count == s.table.contact_count,
        "the haptic stage did not take the update"
    );
    Ok(median(&mut times))
}

/// Times one query.
fn time_query<B: CollisionBackend>(
    backend: &mut B,
    pose: &Pose,
    params: &QueryParams,
    out: &mut ContactSet,
) -> anyhow::Result<Real>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    let clock = Instant::now();
    backend.query(pose, params, out)?;
    Ok(clock.elapsed().as_secs_f64())
}

/// The CPU model, from `/proc/cpuinfo`.
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".to_owned())
}

/// Runs the performance report.
pub fn run(out: &crate::OutArgs) -> anyhow::Result<()> {
    let out_args = out;
    let quick = out.quick;
    let dir = out.dir("bench")?;
    let step_samples = if quick { 50_000 } else { 500_000 };
    let cluster_samples = if quick { 5_000 } else { 50_000 };
    let free_samples = if quick { 20_000 } else { 200_000 };
    let passes = if quick { 1 } else { 3 };

    // Haptic step.
    let s = setup()?;
    let trajectory_steps = (2.5 * RATE_HZ) as usize;
    let mut haptic = BTreeMap::new();
    let mut states = Vec::new();
    for contact in [false, true] {
        states.push(reference_states(&s, contact, trajectory_steps)?);
    }
    for kind in IntegratorKind::ALL {
        let mut entry = BTreeMap::new();
        for (contact, st) in [false, true].into_iter().zip(&states) {
            let (med, p99, p999) = time_haptic_step(kind, &s, contact, st, step_samples)?;
            let key = if contact { "contacts5" } else { "free" };
            println!(
                "haptic step {:<22} {:<9} median {:6.3} µs  p99 {:6.3} µs  p99.9 {:6.3} µs",
                kind.name(),
                key,
                med * 1e6,
                p99 * 1e6,
                p999 * 1e6
            );
            entry.insert(
                key,
                StepTimes {
                    median_s: med,
                    p99_s: p99,
                    p999_s: p999,
                },
            );
        }
        haptic.insert(kind.name(), entry);
    }

    let receive_med = time_receive_contact(&s, free_samples)?;
    println!(
        "haptic stage receiving a 5-contact update: median {:.1} ns",
        receive_med * 1e9
    );

    // Clustering 50 → 5, warm.
    let frames: Vec<Vec<Contact>> = (0..64)
        .map(|t| crate::fixture_contacts::drifting_patch(t, 50))
        .collect();
    let mut clusterer = Clusterer::new(ClusterParams::default())?;
    let mut reps = ContactSet::with_capacity(8);
    for f in &frames {
        clusterer.cluster(f, DELTA_M, &mut reps)?;
    }
    let mut cluster_times = Vec::with_capacity(cluster_samples);
    for k in 0..cluster_samples {
        let f = &frames[k % frames.len()];
        let clock = Instant::now();
        clusterer.cluster(black_box(f), DELTA_M, &mut reps)?;
        cluster_times.push(clock.elapsed().as_secs_f64());
    }
    let cluster_median = median(&mut cluster_times);
    println!(
        "cluster 50 → 5 (warm): median {:.3} µs",
        cluster_median * 1e6
    );

    // Jaws: build, queries.
    let meshes = common::meshes_dir();
    let (tool, com) =
        super::collision::load_tool(&meshes.join("jaw_upper_openfulljaw_p26.stl"), 1e-3)?;
    let (lower, _) = TriMesh::load(
        meshes.join("jaw_lower_openfulljaw_p26.stl"),
        &LoadOptions::with_scale(1e-3),
    )?;
    let obstacles = [(lower, Pose::identity())];
    let clock = Instant::now();
    let mut lod = LodBackend::new(&tool, &obstacles)?;
    let build_s = clock.elapsed().as_secs_f64();
    let build_bytes = lod.memory_bytes();
    let clock = Instant::now();
    let mut parry = ParryBackend::new(&tool, &obstacles)?;
    let parry_build_s = clock.elapsed().as_secs_f64();
    // The saved hierarchies: written once into a fresh folder, then loaded (best of three).
    let cache = dir.join("lod-cache");
    let _ = std::fs::remove_dir_all(&cache);
    LodBackend::with_cache(&tool, &obstacles, &cache)?;
    let mut load_s = Real::INFINITY;
    for _ in 0..3 {
        let clock = Instant::now();
        let (_, outcomes) = LodBackend::with_cache(&tool, &obstacles, &cache)?;
        load_s = load_s.min(clock.elapsed().as_secs_f64());
        anyhow::ensure!(
            outcomes
                .iter()
                .all(|o| matches!(o, haptic_collision::lod::CacheOutcome::Loaded(_))),
            "the saved jaws hierarchies were not loaded: {outcomes:?}"
        );
    }
    println!(
        "jaws: LOD build {build_s:.3} s, {:.1} MB, loaded from its files in {load_s:.3} s; parry build {parry_build_s:.3} s",
        build_bytes as Real / 1e6
    );
    let poses = super::collision::jaws_poses(&com);
    let exact = QueryParams::new(DELTA_M, 0.0)?;
    let lod25 = QueryParams::new(DELTA_M, 0.025)?;
    let mut out = ContactSet::new();
    let (mut t_parry, mut t_exact, mut t_25) = (Vec::new(), Vec::new(), Vec::new());
    let (mut n_parry, mut n_exact, mut n_25) = (0usize, 0usize, 0usize);
    for pass in 0..passes {
        for pose in &poses {
            t_parry.push(time_query(&mut parry, pose, &exact, &mut out)?);
            if pass == 0 {
                n_parry += out.len();
            }
            t_exact.push(time_query(&mut lod, pose, &exact, &mut out)?);
            if pass == 0 {
                n_exact += out.len();
            }
            t_25.push(time_query(&mut lod, pose, &lod25, &mut out)?);
            if pass == 0 {
                n_25 += out.len();
            }
        }
    }
    let (parry_med, parry_p99, _) = quantiles(&mut t_parry);
    let (exact_med, exact_p99, _) = quantiles(&mut t_exact);
    let (lod25_med, lod25_p99, _) = quantiles(&mut t_25);
    let speedup = parry_med / lod25_med;
    let np = poses.len() as Real;
    println!(
        "jaws queries (median): parry {:.3} ms, LOD exact {:.3} ms, LOD 2.5 % {:.3} ms → {speedup:.1}× parry; mean contacts {:.1} / {:.1} / {:.1}",
        parry_med * 1e3,
        exact_med * 1e3,
        lod25_med * 1e3,
        n_parry as Real / np,
        n_exact as Real / np,
        n_25 as Real / np
    );

    // The whole contact stage (query, clustering, linearization) at 2.5 % and 0.4 %, with the
    // hierarchies read back from the files saved above.
    let mass = tool.mass_properties(1.0)?;
    let body = tool.mass_properties(0.1 / mass.volume_m3)?.rigid_body()?;
    let contact_stage = |threshold: Real| -> anyhow::Result<_> {
        let (backend, _) = LodBackend::with_cache(&tool, &obstacles, &cache)?;
        Ok(haptic_runtime::ContactStage::new(
            backend,
            haptic_dynamics::PenaltyModel::new(haptic_dynamics::PenaltyParams::new(
                5000.0, 2.0, DELTA_M,
            )?)?,
            Clusterer::new(ClusterParams::default())?,
            body,
            QueryParams::new(DELTA_M, threshold)?,
        ))
    };
    let stage_times = |threshold: Real| -> anyhow::Result<Vec<Real>> {
        let mut stage = contact_stage(threshold)?;
        // One pass untimed: the stage's buffers grow to their size on the first updates.
        for (k, pose) in poses.iter().enumerate() {
            black_box(stage.update(&ToolState::at_rest(pose), k as Real * 1e-3)?);
        }
        let mut times = Vec::with_capacity(passes * poses.len());
        for _ in 0..passes {
            for (k, pose) in poses.iter().enumerate() {
                let state = ToolState::at_rest(pose);
                let clock = Instant::now();
                black_box(stage.update(&state, k as Real * 1e-3)?);
                times.push(clock.elapsed().as_secs_f64());
            }
        }
        Ok(times)
    };
    let (stage25_med, _, _) = quantiles(&mut stage_times(0.025)?);
    let (stage04_med, _, _) = quantiles(&mut stage_times(0.004)?);
    println!(
        "jaws contact stage (median): {:.3} ms at 2.5 % ({:.1}× parry's query), {:.3} ms at 0.4 % ({:.1}×)",
        stage25_med * 1e3,
        parry_med / stage25_med,
        stage04_med * 1e3,
        parry_med / stage04_med
    );

    // Free-space contact step: the runtime's contact stage with the tool 1 m away (the broad
    // phase rejects it), written in place as the real-time contact thread writes it.
    let far = ToolState::at_rest(&Pose {
        position: com + Vec3::new(0.0, 0.0, 1.0),
        orientation: UnitQuaternion::identity(),
    });
    let mut stage = contact_stage(0.025)?;
    let mut update = ContactUpdate::none();
    let mut free_times = Vec::with_capacity(free_samples);
    for k in 0..free_samples + 1000 {
        let clock = Instant::now();
        stage.update_into(black_box(&far), k as Real * 1e-3, &mut update)?;
        let dt = clock.elapsed().as_secs_f64();
        black_box(&update);
        if k >= 1000 {
            free_times.push(dt);
        }
    }
    if !update.broad_phase_only {
        anyhow::bail!(
            "the tool 1 m away still has {} contacts",
            update.raw_contact_count
        );
    }
    let free_med = median(&mut free_times);
    println!("free-space contact step: median {:.1} ns", free_med * 1e9);

    // The generalization suite, last: its worst figures are issue 15's goals.
    println!(
        "generalization suite ({}):",
        if quick { "quick" } else { "full" }
    );
    let suite_worst = super::suite::run(out_args, None, haptic_collision::StoppingRule::default())?;

    let report = PerfReport {
        haptic_step: haptic,
        cluster_50_to_5_median_s: cluster_median,
        collision_jaws: CollisionJaws {
            parry_median_s: parry_med,
            lod_exact_median_s: exact_med,
            lod_2_5_median_s: lod25_med,
            speedup_lod_2_5_vs_parry: speedup,
            parry_p99_s: parry_p99,
            lod_exact_p99_s: exact_p99,
            lod_2_5_p99_s: lod25_p99,
            speedup_lod_exact_vs_parry: parry_med / exact_med,
            contacts_mean: ContactsMean {
                parry: n_parry as Real / np,
                lod_exact: n_exact as Real / np,
                lod_2_5: n_25 as Real / np,
            },
            poses: poses.len(),
            passes,
            delta_m: DELTA_M,
        },
        contact_stage_jaws: ContactStageJaws {
            lod_2_5_median_s: stage25_med,
            lod_0_4_median_s: stage04_med,
            parry_median_s: parry_med,
            ratio_parry_to_lod_2_5: parry_med / stage25_med,
            ratio_parry_to_lod_0_4: parry_med / stage04_med,
        },
        build_jaws_s: build_s,
        load_jaws_s: load_s,
        build_jaws_bytes: build_bytes,
        build_jaws_parry_s: parry_build_s,
        free_space_contact_step_median_s: free_med,
        receive_contact_update_median_s: receive_med,
        suite_worst,
        setup: PerfSetup {
            cpu: cpu_model(),
            cpus: std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1),
            quick,
            haptic_step_samples: step_samples,
            haptic_step: "set_device + integrator step (HapticForces) + device_reaction, 1 kHz, 100 g spoon, default coupling; states from a backward-Euler run along the free-space hand motion; contacts5: linearized penalty wrench of 5 representatives",
            cluster_samples,
            free_space_samples: free_samples,
            timer: "std::time::Instant around each call (its overhead included)",
        },
    };
    common::write_json(&dir.join("perf.json"), &report)?;
    Ok(())
}

/// Step-time quantiles (s).
#[derive(Serialize)]
struct StepTimes {
    median_s: Real,
    p99_s: Real,
    p999_s: Real,
}

/// Mean contacts per query.
#[derive(Serialize)]
struct ContactsMean {
    parry: Real,
    lod_exact: Real,
    lod_2_5: Real,
}

/// The jaws' collision figures.
#[derive(Serialize)]
struct CollisionJaws {
    parry_median_s: Real,
    lod_exact_median_s: Real,
    lod_2_5_median_s: Real,
    speedup_lod_2_5_vs_parry: Real,
    parry_p99_s: Real,
    lod_exact_p99_s: Real,
    lod_2_5_p99_s: Real,
    speedup_lod_exact_vs_parry: Real,
    contacts_mean: ContactsMean,
    poses: usize,
    passes: usize,
    delta_m: Real,
}

/// The runtime's whole contact stage on the jaws, beside parry's query of the same run.
#[derive(Serialize)]
struct ContactStageJaws {
    lod_2_5_median_s: Real,
    lod_0_4_median_s: Real,
    parry_median_s: Real,
    ratio_parry_to_lod_2_5: Real,
    ratio_parry_to_lod_0_4: Real,
}

/// How the figures were taken.
#[derive(Serialize)]
struct PerfSetup {
    cpu: String,
    cpus: usize,
    quick: bool,
    haptic_step_samples: usize,
    haptic_step: &'static str,
    cluster_samples: usize,
    free_space_samples: usize,
    timer: &'static str,
}

/// `perf.json`. Its field names are a contract: scripts read them (`docs/performance.md` lists
/// them); rename none.
#[derive(Serialize)]
struct PerfReport {
    haptic_step: BTreeMap<&'static str, BTreeMap<&'static str, StepTimes>>,
    cluster_50_to_5_median_s: Real,
    collision_jaws: CollisionJaws,
    contact_stage_jaws: ContactStageJaws,
    build_jaws_s: Real,
    /// `LodBackend::with_cache` on the jaws with both hierarchies saved: reading them back (s).
    load_jaws_s: Real,
    build_jaws_bytes: usize,
    build_jaws_parry_s: Real,
    free_space_contact_step_median_s: Real,
    /// `HapticStage::receive_contact` of a new update with five contacts: what a haptic step
    /// costs on top of the step itself when an update has arrived (s).
    receive_contact_update_median_s: Real,
    /// The worst figure over the scenes of `cargo xtask bench collision --suite` (run as part of
    /// this report, `--quick` with it; its `suite.json` is written beside, or to
    /// `target/xtask/collision` without `--out`).
    suite_worst: super::suite::SuiteWorst,
    setup: PerfSetup,
}
