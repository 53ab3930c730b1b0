//! Benchmark `collision`: query time against wrench error, `ParryBackend` and `LodBackend` at the
//! paper's error thresholds, on one replayed sequence of tool poses near contact.
//!
//! `cargo xtask bench collision [--scene jaws|spoon-cup|FILE_A,FILE_B] [--scale S] [--out DIR]
//! [--quick]`
//!
//! - Scenes: `jaws` (upper jaw as the tool over the lower one, in millimetres), `spoon-cup`
//!   (Newell teaspoon in the teacup, metres), or two mesh files (tool, obstacle) with a unit
//!   scale. The tool's body frame is its centre of mass (bounding-box centre if the mass
//!   properties are refused).
//! - Poses: 200 along one smooth closed path near contact (see [`jaws_poses`] and
//!   [`approach_poses`]), replayed in order by every run; `--quick` replays them once, the full
//!   run three times (times pooled).
//! - Runs: the reference (`all-pairs`: LOD at threshold 0 writing every contact it finds,
//!   `with_max_contacts(None)`), parry, then LOD as users get it (compact contacts, at most
//!   256 a query) at thresholds 0, 0.4 %, 1 %, 2.5 % and 5 % of the tool's bounding radius.
//! - Wrench: contacts → `haptic_cluster::Clusterer` (K = 5, weights `a (d + δ)`, `a` the area
//!   each contact stands for) →
//!   `haptic_dynamics::penalty::PenaltyModel` at the representatives (`k_c`, no damping: the tool
//!   is at rest at each pose), torque about the tool origin. Error: per pose, `|W − W₀| / |W₀|`
//!   with `W = (F, T / r)`, `r` the tool's bounding radius and `W₀` the all-pairs wrench; the
//!   median over the poses is reported.
//! - Clustering: the reference warm-starts from its previous pose, as the runtime does. Every
//!   other run clusters each pose from the reference's representatives of that pose
//!   ([`Clusterer::warm_start_from`]), so both land in the same basin of Lloyd's method when the
//!   contacts allow: the headline error measures the collision back-end, not which local minimum
//!   a chain of warm starts reached. The error with each run's own chain (`_chained`) and the
//!   clustering's own variability (the reference's contacts clustered cold against its warm
//!   chain, `clustering_variability_rel_*`) are reported beside it, and so is the error of the
//!   penalty integrated over the contacts themselves, unclustered
//!   (`wrench_error_rel_unclustered_*`, see
//!   [`super::wrench::integrated_wrench`]): the back-end's own error,
//!   apart from the clustering's. Beside them, `force_cancellation_median`: how many times the
//!   reference's net force is smaller than its contacts' forces
//!   ([`super::wrench::force_cancellation`]), the factor by which the contacts' own relative
//!   errors can grow in the net wrench's.
//! - Output: `DIR/collision.json` and `DIR/collision_work_precision.svg`; each row has the mean
//!   and the most contacts a query wrote (`contacts_mean`, `contacts_max`) and the most it found
//!   before compaction (`raw_contacts_max`).
//! - `--suite`: every scene of the generalization suite (see `suite.rs`); `--suite --only
//!   NAME[,NAME…]` runs the scenes named (`boxes-coarse,fork-in-mug`, say), to iterate on a few.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, bail};
use haptic_cluster::{ClusterParams, Clusterer};
use haptic_collision::{LoadOptions, LodBackend, ParryBackend, TriMesh};
use haptic_core::{
    CollisionBackend, ContactModel, ContactSet, Kinematics, Pose, QueryParams, Real, RigidBody,
    ToolState, Vec3,
};
use haptic_dynamics::penalty::{PenaltyModel, PenaltyParams};
use nalgebra::UnitQuaternion;
use serde::Serialize;

use super::wrench::{force_cancellation, integrated_wrench, pose_errors, relative_error};
use crate::common;

/// LOD error thresholds, fractions of the tool's bounding radius.
/// The reference run's `backend` in the rows: LOD at threshold 0 writing every contact.
pub(super) const REFERENCE: &str = "all-pairs";

pub(super) const THRESHOLDS: [Real; 5] = [0.0, 0.004, 0.01, 0.025, 0.05];
/// Poses per sequence.
pub(super) const POSES: usize = 200;

/// A tool (in its body frame), one obstacle (at the identity), the pose sequence and the query
/// parameters.
pub(super) struct Scene {
    pub name: String,
    pub tool: TriMesh,
    pub obstacle: TriMesh,
    pub poses: Vec<Pose>,
    pub delta_m: Real,
    pub k_c: Real,
    pub description: String,
}

/// What one scene measured: a row per back-end and threshold, and the figures around them.
pub(super) struct SceneMeasure {
    /// parry, then LOD at each of [`THRESHOLDS`].
    pub rows: Vec<Row>,
    /// The reference run (LOD at threshold 0): its wrench per pose.
    pub reference: RunResult,
    /// LOD hierarchies' build (s), and their statistics.
    pub lod_build_s: Real,
    lod_build: haptic_collision::lod::BuildStats,
    lod_memory_bytes: usize,
    /// parry's build (s).
    pub parry_build_s: Real,
    /// The tool's bounding radius (m).
    pub radius_m: Real,
    /// parry's median query time over LOD's at 2.5 %.
    pub speedup_2_5: Real,
    /// A query with the tool far away (s).
    pub far_tool_query_s: Real,
}

/// Measures `scene`: builds both back-ends, replays its poses `passes` times with parry and
/// with LOD at each threshold, and prints a line per run.
pub(super) fn measure(
    scene: &Scene,
    passes: usize,
    rule: haptic_collision::StoppingRule,
) -> anyhow::Result<SceneMeasure> {
    println!(
        "collision bench: scene {}, {} + {} triangles, {} poses × {passes}, δ = {} mm",
        scene.name,
        scene.tool.triangles().len(),
        scene.obstacle.triangles().len(),
        scene.poses.len(),
        scene.delta_m * 1e3
    );
    let obstacles = [(scene.obstacle.clone(), Pose::identity())];

    let t = Instant::now();
    let mut lod = LodBackend::new(&scene.tool, &obstacles)?.with_stopping_rule(rule);
    let lod_build_s = t.elapsed().as_secs_f64();
    let bs = lod.build_stats().clone();
    let t = Instant::now();
    let mut parry = ParryBackend::new(&scene.tool, &obstacles)?;
    let parry_build_s = t.elapsed().as_secs_f64();
    println!(
        "build: lod {lod_build_s:.3} s (tool {:.3} s, obstacle {:.3} s, {:.1} MB), parry {parry_build_s:.3} s",
        bs.tool.build_s,
        bs.obstacles[0].build_s,
        lod.memory_bytes() as Real / 1e6
    );
    let radius = lod.tool_bounding_radius_m();

    // Reference run first (every contact at threshold 0), then the others.
    let mut all_pairs = lod.clone().with_max_contacts(None);
    let reference = run_backend(&mut all_pairs, scene, 0.0, passes, radius, None)?;
    drop(all_pairs);
    let mut rows = vec![row(REFERENCE, 0.0, &reference, lod_build_s)];
    let parry_run = run_backend(&mut parry, scene, 0.0, passes, radius, Some(&reference))?;
    rows.push(row("parry", 0.0, &parry_run, parry_build_s));
    for &th in &THRESHOLDS {
        let r = run_backend(&mut lod, scene, th, passes, radius, Some(&reference))?;
        rows.push(row("lod", th, &r, lod_build_s));
    }
    for r in &rows {
        println!(
            "{:>9} {:>6.1} %: median {:>9.1} µs, p99 {:>9.1} µs, contacts {:>8.1} (max {:>7}, raw {:>7}), node pairs {:>9.0}, wrench error median {:.3} (p90 {:.3}; own chain {:.3}; unclustered {:.3}), |F|/|F0| {:.3}",
            r.backend,
            r.threshold * 100.0,
            r.median_s * 1e6,
            r.p99_s * 1e6,
            r.contacts_mean,
            r.contacts_max,
            r.raw_contacts_max,
            r.node_pairs_mean,
            r.wrench_error_rel_median,
            r.wrench_error_rel_p90,
            r.wrench_error_rel_median_chained,
            r.wrench_error_rel_unclustered_median,
            r.force_ratio_median,
        );
    }
    let median_of = |b: &str, th: Real| {
        rows.iter()
            .find(|r| r.backend == b && (r.threshold - th).abs() < 1e-12)
            .map(|r| r.median_s)
    };
    let speedup = match (median_of("parry", 0.0), median_of("lod", 0.025)) {
        (Some(p), Some(l)) if l > 0.0 => p / l,
        _ => Real::NAN,
    };
    println!("LOD at 2.5 % is {speedup:.1}× faster than parry (median query time)");
    println!(
        "clustering variability (reference contacts clustered cold vs its warm chain): median {:.3}, p90 {:.3}",
        quantile(&reference.cold_errors, 0.5),
        quantile(&reference.cold_errors, 0.9)
    );
    println!(
        "force cancellation (reference contacts, sum of |f_i| over |sum of f_i|): median {:.1}",
        quantile(&reference.cancellation, 0.5)
    );

    // A far tool costs the broad phase only.
    let far = Pose::from_position(Vec3::new(10.0, 10.0, 10.0));
    let mut out = ContactSet::new();
    let params = QueryParams::new(scene.delta_m, 0.025)?;
    let t = Instant::now();
    for _ in 0..10_000 {
        lod.query(&far, &params, &mut out)?;
    }
    let far_s = t.elapsed().as_secs_f64() / 10_000.0;
    Ok(SceneMeasure {
        rows,
        reference,
        lod_build_s,
        lod_build: bs,
        lod_memory_bytes: lod.memory_bytes(),
        parry_build_s,
        radius_m: radius,
        speedup_2_5: speedup,
        far_tool_query_s: far_s,
    })
}

/// Runs the benchmark on one scene, or the suite (`--suite`).
pub fn run(args: &super::CollisionArgs, out: &crate::OutArgs) -> anyhow::Result<()> {
    if args.suite {
        return super::suite::run(out, args.only.as_deref(), args.stopping_rule).map(|_| ());
    }
    let dir = out.dir("collision")?;
    let scene = load_scene(args, POSES)?;
    let passes = if out.quick { 1 } else { 3 };
    let m = measure(&scene, passes, args.stopping_rule)?;
    let bs = &m.lod_build;
    let report = CollisionReport {
        scene: scene.name.clone(),
        description: scene.description.clone(),
        delta_m: scene.delta_m,
        k_c_n_per_m: scene.k_c,
        poses: scene.poses.len(),
        passes,
        tool_bounding_radius_m: m.radius_m,
        stopping_rule: args.stopping_rule.name(),
        wrench: WRENCH,
        builds: vec![
            Build {
                backend: "lod",
                mesh: "tool",
                triangles: Some(bs.tool.triangles),
                nodes: Some(bs.tool.nodes),
                build_s: bs.tool.build_s,
                memory_bytes: None,
            },
            Build {
                backend: "lod",
                mesh: "obstacle",
                triangles: Some(bs.obstacles[0].triangles),
                nodes: Some(bs.obstacles[0].nodes),
                build_s: bs.obstacles[0].build_s,
                memory_bytes: None,
            },
            Build {
                backend: "lod",
                mesh: "both",
                triangles: None,
                nodes: None,
                build_s: m.lod_build_s,
                memory_bytes: Some(m.lod_memory_bytes),
            },
            Build {
                backend: "parry",
                mesh: "both",
                triangles: None,
                nodes: None,
                build_s: m.parry_build_s,
                memory_bytes: None,
            },
        ],
        lod_build_s: m.lod_build_s,
        parry_build_s: m.parry_build_s,
        far_tool_query_s: m.far_tool_query_s,
        speedup_lod_2_5_percent_vs_parry: m.speedup_2_5,
        clustering_variability_rel_median: quantile(&m.reference.cold_errors, 0.5),
        clustering_variability_rel_p90: quantile(&m.reference.cold_errors, 0.9),
        force_cancellation_median: quantile(&m.reference.cancellation, 0.5),
        rows: &m.rows,
    };
    common::write_json(&dir.join("collision.json"), &report)?;
    super::chart::work_precision_chart(
        &dir.join("collision_work_precision.svg"),
        &scene.name,
        &m.rows,
        args.stopping_rule,
    )
}

/// How the wrench and its error are computed (in every report).
pub(super) const WRENCH: &str = "contacts -> haptic_cluster::Clusterer (K = 5, w = a (d + delta), a the tool area a contact stands for) -> haptic_dynamics::penalty::PenaltyModel (k_c times each representative's stiffness share, b_c = 0, tool at rest), torque about the tool origin; error |W - W0| / |W0| with W = (F, T / r), W0 = LOD at threshold 0 with every contact found (all-pairs); a wrench below 1e-9 times the run's median reference wrench counts as none (a pose where both are is skipped, one where only the reference is has error 1). The reference warm-starts from its previous pose; the other runs cluster each pose from the reference's representatives of that pose (wrench_error_rel_*), and along their own chain of warm starts (wrench_error_rel_*_chained). wrench_error_rel_unclustered_*: the same error for the penalty integrated over the contacts themselves, unclustered (F = -sum a (d + delta) n, T = sum rho x F_i), the back-end's own error without the clustering's; null where contacts carry no area";

/// What one run measured.
#[derive(Clone)]
pub(super) struct RunResult {
    times_s: Vec<Real>,
    contacts_mean: Real,
    contacts_max: usize,
    raw_contacts_max: usize,
    node_pairs_mean: Real,
    /// The wrench of each pose `(F, T)` (first pass).
    pub wrenches: Vec<[Real; 6]>,
    /// The clusters' centres and depths of each pose (first pass), which seed the other runs'
    /// clustering.
    cluster_centres: Vec<Vec<(Vec3, Real)>>,
    /// Error per pose, clustered from the reference's representatives of the same pose.
    errors: Vec<Real>,
    /// Error per pose, clustered along this run's own chain of warm starts.
    errors_chained: Vec<Real>,
    /// Reference run only: per pose, its contacts clustered cold against its warm chain.
    pub cold_errors: Vec<Real>,
    /// Per pose with a net force (first pass), the contacts' [`force_cancellation`].
    pub cancellation: Vec<Real>,
    /// The penalty integrated over the contacts' own areas, per pose (first pass); `None` where
    /// a contact has no area (a back-end that does not measure it).
    integrated: Vec<Option<[Real; 6]>>,
    /// Error per pose of `integrated` against the reference's.
    errors_unclustered: Vec<Real>,
    /// `|F| / |F₀|` per pose.
    force_ratios: Vec<Real>,
}

/// The `f`-quantile of `v` (nearest rank), NaN when empty.
pub(super) fn quantile(v: &[Real], f: Real) -> Real {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        Real::NAN
    } else {
        v[((v.len() - 1) as Real * f).round() as usize]
    }
}

fn row(backend: &'static str, threshold: Real, r: &RunResult, build_s: Real) -> Row {
    let (t, e, ec, fr) = (&r.times_s, &r.errors, &r.errors_chained, &r.force_ratios);
    let q = quantile;
    Row {
        backend,
        threshold,
        median_s: q(t, 0.5),
        p99_s: q(t, 0.99),
        contacts_mean: r.contacts_mean,
        contacts_max: r.contacts_max,
        raw_contacts_max: r.raw_contacts_max,
        node_pairs_mean: r.node_pairs_mean,
        wrench_error_rel_median: q(e, 0.5),
        wrench_error_rel_p90: q(e, 0.9),
        wrench_error_rel_max: q(e, 1.0),
        wrench_error_rel_median_chained: q(ec, 0.5),
        wrench_error_rel_p90_chained: q(ec, 0.9),
        wrench_error_rel_unclustered_median: q(&r.errors_unclustered, 0.5),
        wrench_error_rel_unclustered_p90: q(&r.errors_unclustered, 0.9),
        force_ratio_median: q(fr, 0.5),
        build_s,
    }
}

/// One back-end at one threshold, in `collision.json` and `suite.json`.
#[derive(Serialize, Clone)]
pub(super) struct Row {
    pub backend: &'static str,
    pub threshold: Real,
    pub median_s: Real,
    pub p99_s: Real,
    pub contacts_mean: Real,
    /// Most contacts one query wrote.
    pub contacts_max: usize,
    /// Most contacts one query found before compacting them (`contacts_max` without compaction).
    pub raw_contacts_max: usize,
    pub node_pairs_mean: Real,
    pub wrench_error_rel_median: Real,
    pub wrench_error_rel_p90: Real,
    pub wrench_error_rel_max: Real,
    pub wrench_error_rel_median_chained: Real,
    pub wrench_error_rel_p90_chained: Real,
    /// The error of the penalty integrated over the contacts themselves, unclustered (see
    /// [`super::wrench::integrated_wrench`]): the back-end's own error, without the
    /// clustering's; `null` for a back-end whose contacts carry no area (both of ours do).
    pub wrench_error_rel_unclustered_median: Real,
    /// Its 90th percentile.
    pub wrench_error_rel_unclustered_p90: Real,
    pub force_ratio_median: Real,
    pub build_s: Real,
}

/// One hierarchy (or back-end) build.
#[derive(Serialize)]
struct Build {
    backend: &'static str,
    mesh: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    triangles: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    nodes: Option<usize>,
    build_s: Real,
    #[serde(skip_serializing_if = "Option::is_none")]
    memory_bytes: Option<usize>,
}

/// `collision.json`.
#[derive(Serialize)]
struct CollisionReport<'a> {
    scene: String,
    description: String,
    delta_m: Real,
    k_c_n_per_m: Real,
    poses: usize,
    passes: usize,
    tool_bounding_radius_m: Real,
    /// The LOD walk's stopping rule (`--stopping-rule`).
    stopping_rule: &'static str,
    wrench: &'static str,
    builds: Vec<Build>,
    lod_build_s: Real,
    parry_build_s: Real,
    far_tool_query_s: Real,
    speedup_lod_2_5_percent_vs_parry: Real,
    clustering_variability_rel_median: Real,
    clustering_variability_rel_p90: Real,
    /// The reference's contacts' [`force_cancellation`], median over the poses with a net force.
    force_cancellation_median: Real,
    rows: &'a [Row],
}

/// Replays the sequence `passes` times; the wrench of each pose comes from the first pass.
fn run_backend<B: CollisionBackend>(
    backend: &mut B,
    scene: &Scene,
    threshold: Real,
    passes: usize,
    radius: Real,
    reference: Option<&RunResult>,
) -> anyhow::Result<RunResult>
where
    B::Error: Send + Sync + 'static,
{
    let params = QueryParams::new(scene.delta_m, threshold)?;
    let mut out = ContactSet::new();
    let mut times_s = Vec::with_capacity(passes * scene.poses.len());
    let mut wrenches = Vec::with_capacity(scene.poses.len());
    let mut chained_wrenches = Vec::with_capacity(scene.poses.len());
    let mut cluster_centres = Vec::with_capacity(scene.poses.len());
    // Two clusterers: one seeded from the reference's representatives of the same pose (the
    // headline error), one along this run's own chain of warm starts, as a runtime would run.
    let mut seeded = WrenchPipeline::new(scene, radius)?;
    let mut chained = WrenchPipeline::new(scene, radius)?;
    let (mut contacts, mut node_pairs, mut contacts_max) = (0usize, 0u64, 0usize);
    let mut raw_contacts_max = 0usize;
    let mut cold_errors = Vec::new();
    let mut integrated = Vec::with_capacity(scene.poses.len());
    let mut cancellation = Vec::with_capacity(scene.poses.len());
    for pass in 0..passes {
        for (i, pose) in scene.poses.iter().enumerate() {
            let t = Instant::now();
            let st = backend.query(pose, &params, &mut out)?;
            times_s.push(t.elapsed().as_secs_f64());
            if pass > 0 {
                continue;
            }
            contacts += out.len();
            contacts_max = contacts_max.max(out.len());
            // A back-end that does not compact reports 0 raw contacts: all it found it wrote.
            raw_contacts_max = raw_contacts_max.max((st.raw_contacts as usize).max(out.len()));
            node_pairs += st.node_pairs_tested;
            integrated.push(integrated_wrench(out.as_slice(), pose, scene.delta_m));
            cancellation.extend(force_cancellation(out.as_slice(), scene.delta_m));
            let w = chained.wrench(&out, pose, scene.delta_m)?;
            chained_wrenches.push(w);
            match reference {
                Some(r) => {
                    seeded
                        .clusterer
                        .warm_start_from_centres(&r.cluster_centres[i]);
                    wrenches.push(seeded.wrench(&out, pose, scene.delta_m)?);
                }
                None => {
                    // The reference: its own contacts clustered cold, to measure how far two
                    // clusterings of the same contacts can differ.
                    seeded.clusterer.reset();
                    let cold = seeded.wrench(&out, pose, scene.delta_m)?;
                    cold_errors.extend(relative_error(&cold, &w, radius, 0.0));
                    wrenches.push(w);
                }
            }
            cluster_centres.push(chained.clusterer.cluster_centres().to_vec());
        }
    }
    let n = scene.poses.len().max(1) as Real;
    let errors_against = |ws: &[[Real; 6]]| match reference {
        Some(r) => pose_errors(ws.iter().map(Some), r.wrenches.iter().map(Some), radius),
        None => Ok(vec![0.0; ws.len()]),
    };
    let force = |w: &[Real; 6]| Vec3::new(w[0], w[1], w[2]).norm();
    let force_ratios = match reference {
        Some(r) => wrenches
            .iter()
            .zip(&r.wrenches)
            .filter(|(_, w0)| force(w0) > 0.0)
            .map(|(w, w0)| force(w) / force(w0))
            .collect(),
        None => vec![1.0; wrenches.len()],
    };
    let errors_unclustered = match reference {
        // A back-end whose contacts carry no area has no figure (`null` in the report).
        Some(_) if integrated.iter().any(Option::is_none) => Vec::new(),
        Some(r) => pose_errors(
            integrated.iter().map(Option::as_ref),
            r.integrated.iter().map(Option::as_ref),
            radius,
        )?,
        None => vec![0.0; integrated.len()],
    };
    Ok(RunResult {
        force_ratios,
        integrated,
        errors_unclustered,
        times_s,
        contacts_mean: contacts as Real / n,
        contacts_max,
        raw_contacts_max,
        node_pairs_mean: node_pairs as Real / n,
        errors: errors_against(&wrenches)?,
        errors_chained: errors_against(&chained_wrenches)?,
        cold_errors,
        cancellation,
        wrenches,
        cluster_centres,
    })
}

/// The contact wrench of one pose: contacts → `haptic_cluster::Clusterer` (K = 5, warm start
/// from this run's previous pose) → `haptic_dynamics::penalty::PenaltyModel` at the
/// representatives, with the tool at rest at `pose` (so damping plays no part). `(F, T)`, the
/// torque about the tool origin.
struct WrenchPipeline {
    clusterer: Clusterer,
    model: PenaltyModel,
    body: RigidBody,
    reps: ContactSet,
}

impl WrenchPipeline {
    fn new(scene: &Scene, radius: Real) -> anyhow::Result<Self> {
        Ok(Self {
            clusterer: Clusterer::new(ClusterParams::default())?,
            model: PenaltyModel::new(PenaltyParams {
                stiffness_n_per_m: scene.k_c,
                damping_ns_per_m: 0.0,
                delta_m: scene.delta_m,
            })?,
            body: RigidBody::sphere(0.01, radius)?,
            reps: ContactSet::new(),
        })
    }

    fn wrench(
        &mut self,
        contacts: &ContactSet,
        pose: &Pose,
        delta: Real,
    ) -> anyhow::Result<[Real; 6]> {
        self.clusterer
            .cluster(contacts.as_slice(), delta, &mut self.reps)?;
        let y = ToolState::at_rest(pose).to_vector();
        let kin = Kinematics::new(&self.body, &y);
        let w = self
            .model
            .evaluate(&self.body, &y, &kin, self.reps.as_slice(), None)?;
        Ok([
            w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z,
        ])
    }
}

pub(super) fn load_scene(args: &super::CollisionArgs, n_poses: usize) -> anyhow::Result<Scene> {
    let meshes = common::meshes_dir();
    if args.delta_mm.is_some() && ["jaws", "spoon-cup"].contains(&args.scene.as_str()) {
        bail!(
            "--delta-mm is for FILE_A,FILE_B scenes; `{}` keeps the paper's δ",
            args.scene
        );
    }
    match args.scene.as_str() {
        "jaws" => {
            let scale = args.scale.unwrap_or(1e-3);
            let (tool, com) = load_tool(&meshes.join("jaw_upper_openfulljaw_p26.stl"), scale)?;
            let (obstacle, _) = TriMesh::load(
                meshes.join("jaw_lower_openfulljaw_p26.stl"),
                &LoadOptions::with_scale(scale),
            )?;
            Ok(Scene {
                name: "jaws".into(),
                poses: crate::fixture_poses::jaws_poses(&com, n_poses),
                tool,
                obstacle,
                delta_m: 1e-3,
                k_c: 5000.0,
                description: "upper jaw (47,332 triangles, tool, body frame at its centre of mass) over the lower jaw (40,174), in occlusion as stored, moved along a closed path by up to 0.5 mm sideways, -0.1..+0.5 mm vertically and 0.3 degrees".into(),
            })
        }
        "spoon-cup" => {
            let scale = args.scale.unwrap_or(1.0);
            let (tool, _) = load_tool(&meshes.join("newell_teaspoon.stl"), scale)?;
            let (obstacle, _) = TriMesh::load(
                meshes.join("newell_teacup.stl"),
                &LoadOptions::with_scale(scale),
            )?;
            // Bowl down into the cup (cup axis +y): the spoon turned upside down, tilted 20°.
            let orientation =
                UnitQuaternion::from_scaled_axis(Vec3::new(0.0, 0.0, 1.0) * std::f64::consts::PI)
                    * UnitQuaternion::from_scaled_axis(Vec3::new(0.35, 0.0, 0.0));
            let delta = 1e-3;
            let poses = approach_poses(&tool, &obstacle, orientation, Vec3::y(), delta, n_poses)?;
            Ok(Scene {
                name: "spoon-cup".into(),
                tool,
                obstacle,
                poses,
                delta_m: delta,
                k_c: 2000.0,
                description: "Newell teaspoon (1,344 triangles, tool) lowered bowl first into the Newell teacup (4,004) until it touches, then moved around that pose".into(),
            })
        }
        pair => {
            let Some((a, b)) = pair.split_once(',') else {
                bail!("unknown scene `{pair}`: use jaws, spoon-cup or FILE_A,FILE_B");
            };
            let scale = args.scale.unwrap_or(1.0);
            let (tool, _) = load_tool(Path::new(a), scale)?;
            let (obstacle, report) = TriMesh::load(b, &LoadOptions::with_scale(scale))
                .with_context(|| format!("loading {b}"))?;
            if let Some(repairs) = crate::common::mesh_repairs(&report) {
                println!("{b}: {repairs}");
            }
            let (lo, hi) = tool.bounding_box();
            let delta = match args.delta_mm {
                None => 0.01 * (hi - lo).norm(),
                Some(mm) if mm.is_finite() && mm > 0.0 => mm * 1e-3,
                Some(mm) => bail!("--delta-mm must be a positive length, not {mm}"),
            };
            let poses = approach_poses(
                &tool,
                &obstacle,
                UnitQuaternion::identity(),
                Vec3::z(),
                delta,
                n_poses,
            )?;
            Ok(Scene {
                name: format!("{}+{}", file_name(Path::new(a)), file_name(Path::new(b))),
                tool,
                obstacle,
                poses,
                delta_m: delta,
                k_c: 2000.0,
                description: format!(
                    "{a} (tool) lowered along -z onto {b} until it touches, then moved around that pose; delta = {}",
                    if args.delta_mm.is_some() {
                        "as given (--delta-mm)"
                    } else {
                        "1 % of the tool's diagonal"
                    }
                ),
            })
        }
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Loads a tool and moves its body frame to its centre of mass (or, if the mass properties are
/// refused, e.g. for an open mesh, to its bounding-box centre). Returns the mesh in its body
/// frame and where that origin was in the file's frame (m); says what loading repaired, if anything.
pub(super) fn load_tool(path: &Path, scale: Real) -> anyhow::Result<(TriMesh, Vec3)> {
    let (mesh, report) = TriMesh::load(path, &LoadOptions::with_scale(scale))
        .with_context(|| format!("loading {}", path.display()))?;
    if let Some(repairs) = crate::common::mesh_repairs(&report) {
        println!("{}: {repairs}", path.display());
    }
    let origin = match mesh.mass_properties(1000.0) {
        Ok(mp) => mp.centre_of_mass_m,
        Err(_) => {
            let (lo, hi) = mesh.bounding_box();
            (lo + hi) * 0.5
        }
    };
    Ok((mesh.translated(&-origin)?, origin))
}

/// The jaws' pose path (the shared fixture).
pub(super) fn jaws_poses(com: &Vec3) -> Vec<Pose> {
    crate::fixture_poses::jaws_poses(com, POSES)
}

/// A tool approaching an obstacle along `−up` with a fixed orientation: the first offset with a
/// contact within `δ` (LOD at threshold 0; a march, then bisection), then `n_poses` poses around it: ±`δ` along
/// `up`, ±2δ sideways, ±0.3° of tilt.
pub(super) fn approach_poses(
    tool: &TriMesh,
    obstacle: &TriMesh,
    orientation: UnitQuaternion<Real>,
    up: Vec3,
    delta: Real,
    n_poses: usize,
) -> anyhow::Result<Vec<Pose>> {
    let mut lod = LodBackend::new(tool, &[(obstacle.clone(), Pose::identity())])?;
    let (lo, hi) = obstacle.bounding_box();
    let centre = (lo + hi) * 0.5;
    let reach = (hi - lo).norm() + 2.0 * lod.tool_bounding_radius_m();
    let params = QueryParams::new(delta, 0.0)?;
    let mut out = ContactSet::new();
    let mut touches = |t: Real| -> anyhow::Result<bool> {
        let pose = Pose {
            position: centre + up * (reach - t),
            orientation,
        };
        lod.query(&pose, &params, &mut out)?;
        Ok(!out.is_empty())
    };
    // March in 400 steps to the first pose with a contact (a hollow obstacle may let the tool
    // pass through an opening further on), then bisect.
    let end = reach + 0.5 * (hi - lo).dot(&up).abs();
    if touches(0.0)? {
        bail!("the tool touches the obstacle from the start of the approach");
    }
    let steps = 400;
    let mut first = None;
    for k in 1..=steps {
        let t = end * k as Real / steps as Real;
        if touches(t)? {
            first = Some(t);
            break;
        }
    }
    let Some(hit) = first else {
        bail!("the tool never comes within δ of the obstacle along the approach direction");
    };
    let (mut a, mut b) = (hit - end / steps as Real, hit);
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if touches(m)? {
            b = m;
        } else {
            a = m;
        }
    }
    // At `b` the closest approach is just below δ: the surfaces touch about δ further in.
    let touch = centre + up * (reach - b - delta);
    let side = {
        let s = if up.x.abs() < 0.9 {
            Vec3::x()
        } else {
            Vec3::y()
        };
        let s1 = (s - up * up.dot(&s)).normalize();
        (s1, up.cross(&s1))
    };
    Ok((0..n_poses)
        .map(|i| {
            let s = i as Real / n_poses as Real * std::f64::consts::TAU;
            let dp = up * (delta * (3.0 * s).sin())
                + side.0 * (2.0 * delta * s.sin())
                + side.1 * (2.0 * delta * (2.0 * s).cos());
            let tilt =
                UnitQuaternion::from_scaled_axis((side.0 * s.cos() + side.1 * s.sin()) * 0.005);
            Pose {
                position: touch + dp,
                orientation: tilt * orientation,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests;
