//! Study `cup` (the paper's Fig. 4): the spoon pressed into the cup, three configurations on one
//! trajectory, in virtual time.

use haptic_collision::LodBackend;
use haptic_core::{Pose, Real, Vec3};
use haptic_device::{ScriptedDevice, Waypoint};
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyParams, Rk4};
use haptic_runtime::{ContactLatency, Scene, SceneParts};
use nalgebra::UnitQuaternion;
use serde::Serialize;

use super::contact_run::{self, RunResult, points, rms_between};
use crate::common::{repo_root, write_json};
use crate::plot::{Chart, Scale, Series, line_chart};

/// Length of the trajectory (s).
const DURATION_S: Real = 0.65;
/// Contact updates per second of virtual time.
const CONTACT_HZ: Real = 500.0;

/// The trajectory, as handle poses: 150 ms still with the bowl inside the cup 15 mm from the
/// wall, then 35 mm towards the wall in 250 ms (about 20 mm past it), then held.
fn trajectory(start: &Pose) -> Vec<Waypoint> {
    let at = |dx: Real| Pose {
        position: start.position + Vec3::new(dx, 0.0, 0.0),
        orientation: start.orientation,
    };
    vec![
        Waypoint::new(0.0, at(0.0)),
        Waypoint::new(0.15, at(0.0)),
        Waypoint::new(0.40, at(0.035)),
        Waypoint::new(DURATION_S, at(0.035)),
    ]
}

/// One configuration of Fig. 4.
struct Config {
    name: &'static str,
    integrator: &'static str,
    mass_kg: Real,
    contact_stiffness_n_per_m: Real,
}

const CONFIGS: [Config; 3] = [
    Config {
        name: "BE, 10 g, k_c = 2 kN/m",
        integrator: "backward_euler",
        mass_kg: 0.01,
        contact_stiffness_n_per_m: 2000.0,
    },
    Config {
        name: "RK4, 100 g, k_c = 2 kN/m",
        integrator: "rk4",
        mass_kg: 0.1,
        contact_stiffness_n_per_m: 2000.0,
    },
    Config {
        name: "BE, 10 g, k_c = 10 kN/m",
        integrator: "backward_euler",
        mass_kg: 0.01,
        contact_stiffness_n_per_m: 10000.0,
    },
];

/// The spoon-cup scene with the bowl already inside the cup, and a configuration's mass and
/// contact stiffness.
fn parts_for(base: &SceneParts, c: &Config) -> anyhow::Result<SceneParts> {
    let mut parts = base.clone();
    parts.body = base.body.with_mass(c.mass_kg)?;
    parts.penalty = PenaltyParams::new(
        c.contact_stiffness_n_per_m,
        base.penalty.damping_ns_per_m,
        base.penalty.delta_m,
    )?;
    parts.tool_pose = Pose {
        position: Vec3::new(0.0, 0.115, 0.0),
        orientation: UnitQuaternion::from_scaled_axis(Vec3::new(std::f64::consts::PI, 0.0, 0.0)),
    };
    Ok(parts)
}

/// Runs one configuration.
fn run_config(
    base: &SceneParts,
    c: &Config,
    bar: &indicatif::ProgressBar,
    record: &contact_run::Record,
) -> anyhow::Result<RunResult> {
    let parts = parts_for(base, c)?;
    let device = ScriptedDevice::from_waypoints(trajectory(&parts.tool_pose), parts.limits)?;
    let backend = LodBackend::new(&parts.tool_mesh, &parts.obstacles)?
        .with_stopping_rule(parts.stopping_rule);
    let latency = ContactLatency::FixedRate {
        rate_hz: CONTACT_HZ,
    };
    match c.integrator {
        "rk4" => contact_run::run(
            &parts,
            Rk4,
            backend,
            device,
            DURATION_S,
            latency,
            Some(bar),
            Some(record),
        ),
        _ => contact_run::run(
            &parts,
            LinearizedBackwardEuler,
            backend,
            device,
            DURATION_S,
            latency,
            Some(bar),
            Some(record),
        ),
    }
}

/// Runs the study.
pub fn run(args: &crate::OutArgs) -> anyhow::Result<()> {
    let dir = args.dir("cup")?;
    let scene = Scene::load(&repo_root().join("xtask/scenes/spoon-cup.toml"))?;
    let base = scene.assemble()?;
    let mut rows = Vec::new();
    let mut pen = Vec::new();
    let mut dev = Vec::new();
    let mut fc = Vec::new();
    let mut fk = Vec::new();
    // The configurations run in parallel (virtual time: timing does not affect the results).
    let multi = indicatif::MultiProgress::new();
    let records: Vec<contact_run::Record> = CONFIGS
        .iter()
        .enumerate()
        .map(|(i, c)| {
            Ok(contact_run::Record {
                path: dir.join(format!("cup-{}.rec", i + 1)),
                header: crate::recording::header_for_scene(
                    &scene,
                    &base.tool_mesh_offset_m,
                    vec![
                        ("configuration".to_owned(), c.name.to_owned()),
                        ("integrator".to_owned(), c.integrator.to_owned()),
                        ("back-end".to_owned(), "lod".to_owned()),
                        (
                            "error threshold".to_owned(),
                            format!("{}", base.config.query.error_threshold),
                        ),
                        (
                            "contact rate".to_owned(),
                            format!("{CONTACT_HZ} Hz (virtual time)"),
                        ),
                    ],
                    1000.0,
                    1000.0,
                )?,
            })
        })
        .collect::<anyhow::Result<_>>()?;
    let results: Vec<anyhow::Result<RunResult>> = std::thread::scope(|s| {
        let handles: Vec<_> = CONFIGS
            .iter()
            .zip(&records)
            .map(|(c, record)| {
                let bar = contact_run::bar(&multi, c.name, DURATION_S);
                let base = &base;
                s.spawn(move || run_config(base, c, &bar, record))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("a cup run panicked")))
            })
            .collect()
    });
    for (c, r) in CONFIGS.iter().zip(results) {
        let r = r?;
        let s = &r.series;
        let contact_at = r.first_contact_s.unwrap_or(DURATION_S);
        let row = CupRow {
            name: c.name,
            integrator: c.integrator,
            mass_kg: c.mass_kg,
            contact_stiffness_n_per_m: c.contact_stiffness_n_per_m,
            coupling_stiffness_n_per_m: base.coupling.stiffness_n_per_m,
            stable: r.stable,
            max_penetration_m: r.summary.max_penetration_m,
            first_contact_s: r.first_contact_s,
            rms_coupling_force_free_n: rms_between(&s.t_s, &s.coupling_force_n, 0.0, contact_at),
            rms_coupling_force_contact_n: rms_between(
                &s.t_s,
                &s.coupling_force_n,
                contact_at,
                DURATION_S + 1.0,
            ),
            max_coupling_force_n: r.summary.max_force_n,
            max_coupling_deviation_m: r.summary.max_coupling_deviation_m,
            raw_contact_count_max: r.summary.raw_contact_count_max,
            cluster_count_max: r.summary.cluster_count_max,
            zero_force_steps: r.summary.zero_force_steps,
        };
        println!(
            "{:<26} stable {:<5} max penetration {:.3} mm, RMS coupling force free {:.3} N / contact {:.3} N",
            c.name,
            r.stable,
            r.summary.max_penetration_m * 1e3,
            row.rms_coupling_force_free_n,
            row.rms_coupling_force_contact_n,
        );
        rows.push(row);
        pen.push(Series::new(
            c.name,
            points(
                &s.t_s,
                &s.penetration_m.iter().map(|p| p * 1e3).collect::<Vec<_>>(),
                2,
            ),
        ));
        dev.push(Series::new(
            c.name,
            points(
                &s.t_s,
                &s.deviation_m.iter().map(|p| p * 1e3).collect::<Vec<_>>(),
                2,
            ),
        ));
        fc.push(Series::new(c.name, points(&s.t_s, &s.contact_force_n, 2)));
        fk.push(Series::new(c.name, points(&s.t_s, &s.coupling_force_n, 2)));
    }
    for r in &records {
        let page = r.path.with_extension("html");
        crate::view::write_page(&r.path, &page, None)?;
        println!("replay: {}", page.display());
    }
    write_json(
        &dir.join("cup.json"),
        &CupReport {
            study: "cup (Fig. 4)",
            duration_s: DURATION_S,
            contact_rate_hz: CONTACT_HZ,
            haptic_rate_hz: base.config.haptic_rate_hz,
            delta_m: base.penalty.delta_m,
            configurations: rows,
        },
    )?;
    for (file, title, y, series) in [
        (
            "cup-penetration.svg",
            "Maximum local penetration",
            "penetration (mm)",
            &pen,
        ),
        (
            "cup-deviation.svg",
            "Coupling deviation",
            "deviation (mm)",
            &dev,
        ),
        (
            "cup-contact-force.svg",
            "Contact force on the tool",
            "|F_contact| (N)",
            &fc,
        ),
        (
            "cup-coupling-force.svg",
            "Coupling force sent to the device",
            "|F_c| (N)",
            &fk,
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

/// One configuration of `cup.json`.
#[derive(Serialize)]
struct CupRow {
    name: &'static str,
    integrator: &'static str,
    mass_kg: Real,
    contact_stiffness_n_per_m: Real,
    coupling_stiffness_n_per_m: Real,
    stable: bool,
    max_penetration_m: Real,
    first_contact_s: Option<Real>,
    rms_coupling_force_free_n: Real,
    rms_coupling_force_contact_n: Real,
    max_coupling_force_n: Real,
    max_coupling_deviation_m: Real,
    /// JSON `raw_contacts_max` (the name the studies' readers use).
    #[serde(rename = "raw_contacts_max")]
    raw_contact_count_max: u64,
    /// JSON `clusters_max`.
    #[serde(rename = "clusters_max")]
    cluster_count_max: u64,
    zero_force_steps: u64,
}

/// `cup.json`.
#[derive(Serialize)]
struct CupReport {
    study: &'static str,
    duration_s: Real,
    contact_rate_hz: Real,
    haptic_rate_hz: Real,
    delta_m: Real,
    configurations: Vec<CupRow>,
}
