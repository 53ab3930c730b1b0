//! Study `jaws` (the paper's Fig. 6): the upper jaw moved over the lower one through a scaled
//! workspace, at three error thresholds of the multiresolution collision detection, with and
//! without the linearized contact model, the contact thread's latency being the measured cost of
//! each query (scaled).

use haptic_collision::{LoadOptions, LodBackend, TriMesh};
use haptic_core::LinearizationMode;
use haptic_core::{DeviceLimits, Pose, QueryParams, Real, RigidBody, Vec3};
use haptic_device::{ScaledDevice, ScriptedDevice, Waypoint};
use haptic_dynamics::{CouplingParams, LinearizedBackwardEuler, PenaltyParams};
use haptic_runtime::{ContactLatency, PipelineConfig, SceneParts};
use serde::Serialize;

use super::contact_run::{self, points};
use crate::common::{meshes_dir, write_json};
use crate::plot::{Chart, Scale, Series, line_chart};

/// Length of the run (s).
const DURATION_S: Real = 0.9;
/// The paper's workspace scale: 1 m at the device is 0.4 m in the scene.
const WORKSPACE_SCALE: Real = 0.4;
/// Forces felt at the device are the scene's times this.
const FORCE_SCALE: Real = 2.5;
/// The contact rate the 0.4 % runs should see (Hz), as in the paper.
const TARGET_RATE_AT_0_4_HZ: Real = 100.0;
/// The error thresholds (fractions of the tool's radius).
const THRESHOLDS: [Real; 3] = [0.025, 0.01, 0.004];

/// The jaws scene: the upper jaw (tool, body frame at its centre of mass) starting 1.5 mm above
/// its stored place in occlusion, over the lower jaw as stored.
fn parts() -> anyhow::Result<SceneParts> {
    let options = LoadOptions {
        scale_m_per_unit: 1e-3,
        ..LoadOptions::default()
    };
    let (upper, _) = TriMesh::load(meshes_dir().join("jaw_upper_openfulljaw_p26.stl"), &options)?;
    let (lower, _) = TriMesh::load(meshes_dir().join("jaw_lower_openfulljaw_p26.stl"), &options)?;
    let unit = upper.mass_properties(1.0)?;
    let mass_kg = 0.01;
    let body = RigidBody::new(mass_kg, unit.inertia_about_com * (mass_kg / unit.volume_m3))?;
    let tool_mesh = upper.translated(&-unit.centre_of_mass_m)?;
    let stored = unit.centre_of_mass_m;
    let tool_pose = Pose::from_position(stored + Vec3::new(0.0, 0.0, 1.5e-3));
    let coupling = CouplingParams {
        stiffness_n_per_m: 500.0,
        ..CouplingParams::default()
    };
    let penalty = PenaltyParams::new(5000.0, PenaltyParams::default().damping_ns_per_m, 1e-3)?;
    let limits = DeviceLimits::new(
        10.0,
        1.0,
        tool_pose.position - Vec3::repeat(0.5),
        tool_pose.position + Vec3::repeat(0.5),
        1000.0,
    )?;
    Ok(SceneParts {
        body,
        tool_mesh,
        tool_mesh_offset_m: -unit.centre_of_mass_m,
        tool_pose,
        obstacles: vec![(lower, Pose::identity())],
        coupling,
        penalty,
        config: PipelineConfig::default(),
        contact_hz: None,
        limits,
        waypoints: Vec::new(),
        // The paper's study: the paper's rule.
        stopping_rule: haptic_collision::StoppingRule::Deviation,
        load_reports: Vec::new(),
    })
}

/// The hand's motion in device coordinates (about the start, so that the start maps to itself):
/// 100 ms still, down 4.5 mm at the device (1.8 mm in the scene: into occlusion, 0.3 mm past the
/// stored place) by 350 ms, 2.5 mm sideways and back (1 mm in the scene) by 800 ms, held.
fn device(parts: &SceneParts) -> anyhow::Result<ScaledDevice<ScriptedDevice>> {
    let start = parts.tool_pose;
    let s = 1.0 / WORKSPACE_SCALE;
    let at = |dx: Real, dz: Real| Pose {
        position: start.position + Vec3::new(dx * s, 0.0, dz * s),
        orientation: start.orientation,
    };
    let waypoints = vec![
        Waypoint::new(0.0, at(0.0, 0.0)),
        Waypoint::new(0.1, at(0.0, 0.0)),
        Waypoint::new(0.35, at(0.0, -1.8e-3)),
        Waypoint::new(0.575, at(1e-3, -1.8e-3)),
        Waypoint::new(0.8, at(0.0, -1.8e-3)),
        Waypoint::new(DURATION_S, at(0.0, -1.8e-3)),
    ];
    // The scripted device lives in device units; its limits are the scene's, scaled back.
    let device_limits = DeviceLimits::new(
        parts.limits.max_force_n * FORCE_SCALE,
        parts.limits.max_torque_nm * FORCE_SCALE,
        start.position - Vec3::repeat(0.5 * s),
        start.position + Vec3::repeat(0.5 * s),
        1000.0,
    )?;
    let scripted = ScriptedDevice::from_waypoints(waypoints, device_limits)?;
    Ok(ScaledDevice::new(scripted, WORKSPACE_SCALE, FORCE_SCALE)?.with_origin(start.position)?)
}

/// One run: returns the JSON row and the plotted series.
fn run_one(
    base: &SceneParts,
    backend: &LodBackend,
    threshold: Real,
    linearized: bool,
    latency_scale: Real,
    bar: &indicatif::ProgressBar,
    record: Option<&contact_run::Record>,
) -> anyhow::Result<(JawsRow, contact_run::Series, bool)> {
    let mut parts = base.clone();
    parts.config.query = QueryParams::new(parts.penalty.delta_m, threshold)?;
    parts.config.linearization = if linearized {
        LinearizationMode::Linearized
    } else {
        LinearizationMode::Constant
    };
    let latency = ContactLatency::Measured {
        scale: latency_scale,
        min_s: 1e-3,
    };
    let r = contact_run::run(
        &parts,
        LinearizedBackwardEuler,
        backend.clone(),
        device(&parts)?,
        DURATION_S,
        latency,
        Some(bar),
        record,
    )?;
    let s = &r.summary;
    let rate = |latency_s: Real| {
        if latency_s > 0.0 {
            1.0 / latency_s
        } else {
            0.0
        }
    };
    let row = JawsRow {
        threshold,
        linearized,
        stable: r.stable,
        max_penetration_m: s.max_penetration_m,
        contact_rate_hz_min: rate(s.contact_latency_max_s),
        contact_rate_hz_median: rate(s.contact_latency_p50_s),
        raw_contact_count_max: s.raw_contact_count_max,
        cluster_count_max: s.cluster_count_max,
        max_coupling_force_n: s.max_force_n,
        max_coupling_deviation_m: s.max_coupling_deviation_m,
        contact_updates: s.contact_updates,
        zero_force_steps: s.zero_force_steps,
        first_contact_s: r.first_contact_s,
    };
    println!(
        "threshold {:>5.1} %, {:<13} stable {:<5} max penetration {:.3} mm, contact rate median {:.0} Hz (min {:.0}), {} raw contacts, {} clusters, max force {:.2} N",
        threshold * 100.0,
        if linearized {
            "linearized"
        } else {
            "held constant"
        },
        r.stable,
        s.max_penetration_m * 1e3,
        rate(s.contact_latency_p50_s),
        rate(s.contact_latency_max_s),
        s.raw_contact_count_max,
        s.cluster_count_max,
        s.max_force_n
    );
    Ok((row, r.series, r.stable))
}

/// Runs the study.
pub fn run(args: &crate::OutArgs) -> anyhow::Result<()> {
    let dir = args.dir("jaws")?;
    let base = parts()?;
    println!(
        "jaws: {} + {} triangles",
        base.tool_mesh.triangles().len(),
        base.obstacles[0].0.triangles().len(),
    );
    let backend = crate::common::lod_backend(&base.tool_mesh, &base.obstacles)?;
    // Calibrate the latency scale: the median cost of a 0.4 % query on this machine, so that the
    // 0.4 % runs see about 100 Hz as in the paper.
    // The runs go one after the other, not in parallel: their contact latency is the measured
    // cost of each query, which a concurrent run would inflate.
    let multi = indicatif::MultiProgress::new();
    let (calib, _, _) = run_one(
        &base,
        &backend,
        0.004,
        true,
        1.0,
        &contact_run::bar(&multi, "calibration, 0.4 %", DURATION_S),
        None,
    )?;
    let median_cost_s = 1.0 / calib.contact_rate_hz_median.max(1e-9);
    let latency_scale = (1.0 / TARGET_RATE_AT_0_4_HZ) / median_cost_s;
    println!(
        "median 0.4 % contact update {:.3} ms here; latency scale {:.1} (0.4 % runs at about {} Hz)",
        median_cost_s * 1e3,
        latency_scale,
        TARGET_RATE_AT_0_4_HZ
    );
    let mut rows = Vec::new();
    let mut pen = Vec::new();
    let mut force = Vec::new();
    for linearized in [true, false] {
        for &threshold in &THRESHOLDS {
            let name = format!(
                "{:.1} %{}",
                threshold * 100.0,
                if linearized { "" } else { ", constant" }
            );
            let bar = contact_run::bar(&multi, &name, DURATION_S);
            let record = contact_run::Record {
                path: dir.join(format!(
                    "jaws-{}{}.rec",
                    crate::plot::tick_label(threshold * 100.0),
                    if linearized { "" } else { "-constant" }
                )),
                header: crate::recording::header(
                    "jaws",
                    vec![
                        ("integrator".to_owned(), "backward_euler".to_owned()),
                        ("back-end".to_owned(), "lod".to_owned()),
                        (
                            "error threshold".to_owned(),
                            format!("{} %", threshold * 100.0),
                        ),
                        (
                            "contact model".to_owned(),
                            if linearized {
                                "linearized"
                            } else {
                                "held constant"
                            }
                            .to_owned(),
                        ),
                        (
                            "contact latency".to_owned(),
                            format!("measured cost × {latency_scale:.1}"),
                        ),
                    ],
                    vec![
                        crate::recording::mesh_record(
                            "tool",
                            &meshes_dir().join("jaw_upper_openfulljaw_p26.stl"),
                            1e-3,
                            crate::recording::tool_placement(&base.tool_mesh_offset_m),
                        )?,
                        crate::recording::mesh_record(
                            "obstacle",
                            &meshes_dir().join("jaw_lower_openfulljaw_p26.stl"),
                            1e-3,
                            crate::recording::obstacle_placement(&Pose::identity()),
                        )?,
                    ],
                    1000.0,
                    1000.0,
                ),
            };
            let (row, series, _) = run_one(
                &base,
                &backend,
                threshold,
                linearized,
                latency_scale,
                &bar,
                Some(&record),
            )?;
            let page = record.path.with_extension("html");
            let bytes = crate::view::write_page(&record.path, &page, None)?;
            println!("replay: {} ({:.1} MB)", page.display(), bytes as f64 / 1e6);
            pen.push(Series::new(
                name.clone(),
                points(
                    &series.t_s,
                    &series
                        .penetration_m
                        .iter()
                        .map(|p| p * 1e3)
                        .collect::<Vec<_>>(),
                    2,
                ),
            ));
            force.push(Series::new(
                name,
                points(&series.t_s, &series.coupling_force_n, 2),
            ));
            rows.push(row);
        }
    }
    write_json(
        &dir.join("jaws.json"),
        &JawsReport {
            study: "jaws (Fig. 6)",
            duration_s: DURATION_S,
            workspace_scale: WORKSPACE_SCALE,
            force_scale: FORCE_SCALE,
            mass_kg: base.body.mass_kg(),
            coupling_stiffness_n_per_m: base.coupling.stiffness_n_per_m,
            contact_stiffness_n_per_m: base.penalty.stiffness_n_per_m,
            clusters: base.config.cluster.max_clusters,
            torque_pairs: base.config.cluster.torque_pairs,
            latency: "measured cost of each query times latency_scale, at least 1 ms",
            latency_scale,
            median_query_cost_0_4_s: median_cost_s,
            runs: rows,
        },
    )?;
    for (file, title, y, series) in [
        (
            "jaws-penetration.svg",
            "Maximum local penetration",
            "penetration (mm)",
            &pen,
        ),
        (
            "jaws-coupling-force.svg",
            "Coupling force",
            "|F_c| (N)",
            &force,
        ),
    ] {
        line_chart(
            &dir.join(file),
            &Chart {
                title,
                x_label: "time (s)",
                y_label: y,
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
            },
            series,
        )?;
    }
    Ok(())
}

/// One run of `jaws.json`.
#[derive(Serialize)]
pub(crate) struct JawsRow {
    threshold: Real,
    linearized: bool,
    stable: bool,
    max_penetration_m: Real,
    contact_rate_hz_min: Real,
    contact_rate_hz_median: Real,
    /// JSON `raw_contacts_max` (the name the studies' readers use).
    #[serde(rename = "raw_contacts_max")]
    raw_contact_count_max: u64,
    /// JSON `clusters_max`.
    #[serde(rename = "clusters_max")]
    cluster_count_max: u64,
    max_coupling_force_n: Real,
    max_coupling_deviation_m: Real,
    contact_updates: u64,
    zero_force_steps: u64,
    first_contact_s: Option<Real>,
}

/// `jaws.json`.
#[derive(Serialize)]
struct JawsReport {
    study: &'static str,
    duration_s: Real,
    workspace_scale: Real,
    force_scale: Real,
    mass_kg: Real,
    coupling_stiffness_n_per_m: Real,
    contact_stiffness_n_per_m: Real,
    clusters: usize,
    /// Each cluster written as a torque pair of two springs.
    torque_pairs: bool,
    latency: &'static str,
    latency_scale: Real,
    median_query_cost_0_4_s: Real,
    runs: Vec<JawsRow>,
}
