//! Study `free-space`: the paper's Fig. 3 (Section VII-B), on the built-in hand motion or on any
//! recorded one (`--trajectory FILE`, the replay format of `haptic_device::record`).
//!
//! A 20 cm spoon (`assets/meshes/newell_teaspoon.stl`, metres) hangs on the virtual coupling
//! (`k = 200 N/m`, `k_θ = 0.6 N m/rad`, damping from [`CouplingParams::default`]) and follows a
//! hand motion without touching anything. For each integrator the tool mass is swept
//! (log-spaced, 0.5 g to 500 g, inertia scaled with the mass); each run is judged stable or not,
//! and tracking or lagging, by the rules of [`mod@run`]. Reported per integrator: the smallest mass
//! above which every run is stable, the ranges of stable masses, and for each run the rule that
//! failed.
//!
//! The built-in motion is stored in `assets/trajectories/free_space_hand.csv`; `--write-trajectory
//! FILE` writes it anew wherever asked (the study itself never writes into the source tree).
//!
//! Output: `DIR/free-space.json`, and SVG plots of coupling deviation (log) and coupling force
//! against time for BE at 1 g, RK4 at 70 g and forward Euler at 100 g, as in Fig. 3.

mod motion;
mod run;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use haptic_collision::{LoadOptions, TriMesh};
use haptic_core::{Mat3, Real, Vec3};
use haptic_dynamics::{CouplingParams, IntegratorKind};
use serde::Serialize;

use crate::common;
use crate::plot::{Chart, Scale, Series, line_chart};

pub(crate) use motion::hand_at;
pub(crate) use run::GRASP_BODY_M;
use run::{Lag, RunResult, min_stable_mass, simulate, stable_ranges};

/// Haptic rate, Hz (paper: 1 kHz).
pub(crate) const RATE_HZ: Real = 1000.0;

/// Angular dampings (N m s/rad) of the sensitivity sweep; 3e-3 is the default, 1.9e-2 the value
/// at which `h b_θ / I_min` reaches forward Euler's bound 2 for a 100 g spoon.
const ANGULAR_DAMPING_SENSITIVITY: [Real; 4] = [1e-3, 3e-3, 1e-2, 1.9e-2];

/// Arguments of `study free-space`.
#[derive(clap::Args, Debug, Clone)]
pub struct FreeSpaceArgs {
    /// Output options.
    #[command(flatten)]
    pub out: crate::OutArgs,
    /// A hand motion to follow instead of the built-in one: a recording in the replay format
    /// (`haptic_device::record`: what a `haptic_device::Recorder` around any device writes), at
    /// least 0.5 s long.
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// Write the built-in hand motion to this file (in the replay format) and stop.
    #[arg(long)]
    pub write_trajectory: Option<PathBuf>,
}

/// The built-in motion, in the repository.
pub(crate) fn default_trajectory() -> PathBuf {
    common::repo_root().join("assets/trajectories/free_space_hand.csv")
}

/// Mass properties of the spoon per kilogram, in the mesh's axes.
pub(crate) struct SpoonShape {
    /// The mesh, in its file's frame.
    pub(crate) mesh: TriMesh,
    /// Centre of mass in mesh coordinates, m.
    pub(crate) com_m: Vec3,
    /// Inertia about the centre of mass per unit mass, m² (multiply by the mass).
    pub(crate) inertia_per_kg: Mat3,
    /// Enclosed volume, m³.
    volume_m3: Real,
    /// Extent along the mesh's y axis, m.
    length_m: Real,
    /// How much the volume depends on the integration origin: what the two open slits of the
    /// Newell teaspoon change (`MassProperties::open_volume_change_rel`).
    slit_volume_rel: Real,
}

/// The spoon's mass properties, uniform density (`TriMesh::mass_properties`).
pub(crate) fn spoon_shape(path: &Path) -> anyhow::Result<SpoonShape> {
    let (mesh, _) = TriMesh::load(path, &LoadOptions::default())
        .with_context(|| format!("loading {}", path.display()))?;
    let unit = mesh.mass_properties(1.0)?; // 1 kg/m³: the mass is the volume
    let (lo, hi) = mesh.bounding_box();
    Ok(SpoonShape {
        com_m: unit.centre_of_mass_m,
        inertia_per_kg: unit.inertia_about_com / unit.volume_m3,
        volume_m3: unit.volume_m3,
        length_m: hi.y - lo.y,
        slit_volume_rel: unit.open_volume_change_rel,
        mesh,
    })
}

/// `per_decade` log-spaced masses from 0.5 g to 500 g inclusive.
fn mass_grid(per_decade: usize) -> Vec<Real> {
    let n = 3 * per_decade;
    (0..=n)
        .map(|i| 5e-4 * 10f64.powf(3.0 * i as Real / n as Real))
        .collect()
}

/// One swept run, as reported.
#[derive(Serialize)]
struct Row {
    mass_kg: Real,
    #[serde(flatten)]
    result: RunResult,
}

/// One integrator's sweep.
#[derive(Serialize)]
struct IntegratorReport {
    /// Smallest swept mass above which every swept mass is stable.
    min_stable_mass_kg: Option<Real>,
    /// Contiguous ranges `[lightest, heaviest]` of stable masses.
    stable_mass_ranges_kg: Vec<[Real; 2]>,
    /// Stable runs that lag beyond the tracking bounds (masses, kg).
    lagging_masses_kg: Vec<Real>,
    median_step_us: Real,
    rows: Vec<Row>,
}

/// The explicit methods' thresholds at one angular damping.
#[derive(Serialize)]
struct Sensitivity {
    angular_damping_nms_per_rad: Real,
    min_stable_mass_kg: std::collections::BTreeMap<&'static str, Option<Real>>,
}

/// The set-up, for the record.
#[derive(Serialize)]
struct Setup {
    mesh: &'static str,
    mesh_triangles: usize,
    length_m: Real,
    volume_m3: Real,
    slit_volume_change_rel: Real,
    com_mesh_m: [Real; 3],
    principal_inertia_per_kg_m2: [Real; 3],
    grasp_body_m: [Real; 3],
    coupling: CouplingSetup,
    rate_hz: Real,
    duration_s: Real,
    trajectory: String,
    trajectory_peak_speed_m_per_s: Real,
    trajectory_peak_angular_speed_rad_per_s: Real,
    masses_kg: Vec<Real>,
    quick: bool,
    rules: String,
}

/// The coupling's parameters.
#[derive(Serialize)]
struct CouplingSetup {
    stiffness_n_per_m: Real,
    damping_ns_per_m: Real,
    angular_stiffness_nm_per_rad: Real,
    angular_damping_nms_per_rad: Real,
}

/// One of the Fig. 3 runs.
#[derive(Serialize)]
struct FigureRun {
    integrator: &'static str,
    mass_kg: Real,
    #[serde(flatten)]
    result: RunResult,
}

/// `free-space.json`: per integrator (by its JSON name) its sweep, plus the set-up, the
/// sensitivity to the angular damping and the Fig. 3 runs.
#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    integrators: std::collections::BTreeMap<&'static str, IntegratorReport>,
    angular_damping_sensitivity: Vec<Sensitivity>,
    setup: Setup,
    figure_runs: Vec<FigureRun>,
}

/// Runs the study.
pub fn run(args: &FreeSpaceArgs) -> anyhow::Result<()> {
    if let Some(path) = &args.write_trajectory {
        motion::write_built_in(path)?;
        println!("wrote the built-in hand motion to {}", path.display());
        return Ok(());
    }
    let dir = args.out.dir("free-space")?;
    let traj_path = args.trajectory.clone().unwrap_or_else(default_trajectory);
    let traj = motion::read(&traj_path)?;
    let duration_s = (traj.len() - 1) as Real / RATE_HZ;
    let (v_peak, w_peak) = motion::peak_speeds(&traj);
    let shape = spoon_shape(&common::meshes_dir().join("newell_teaspoon.stl"))?;
    let eig = shape.inertia_per_kg.symmetric_eigenvalues();
    println!(
        "spoon: {} triangles, {:.1} cm long, volume {:.3} cm³ (slits change it by {:.1e}), \
         principal inertia per kg {:.3e} {:.3e} {:.3e} m²",
        shape.mesh.triangles().len(),
        100.0 * shape.length_m,
        shape.volume_m3 * 1e6,
        shape.slit_volume_rel,
        eig[0],
        eig[1],
        eig[2]
    );
    println!(
        "hand motion: {} ({duration_s:.2} s), peak {v_peak:.2} m/s, {w_peak:.2} rad/s",
        traj_path.display()
    );

    let masses = mass_grid(if args.out.quick { 5 } else { 10 });
    let params = CouplingParams::default();
    let mut integrators = std::collections::BTreeMap::new();
    let mut sweep_series = Vec::new();
    for kind in IntegratorKind::ALL {
        let mut rows = Vec::new();
        for &m in &masses {
            let result = simulate(kind, &shape.inertia_per_kg, &params, m, &traj, false)?;
            rows.push(Row { mass_kg: m, result });
        }
        let flags: Vec<(Real, bool)> = rows.iter().map(|r| (r.mass_kg, r.result.stable)).collect();
        let mut step_us: Vec<Real> = rows.iter().map(|r| r.result.mean_step_us).collect();
        step_us.sort_by(Real::total_cmp);
        sweep_series.push(Series::new(
            kind.name(),
            rows.iter()
                .filter(|r| r.result.stable)
                .map(|r| (r.mass_kg * 1e3, r.result.rms_force_n))
                .collect(),
        ));
        integrators.insert(
            kind.name(),
            IntegratorReport {
                min_stable_mass_kg: min_stable_mass(&flags),
                stable_mass_ranges_kg: stable_ranges(&flags),
                lagging_masses_kg: rows
                    .iter()
                    .filter(|r| r.result.stable && r.result.lag.is_some())
                    .map(|r| r.mass_kg)
                    .collect(),
                median_step_us: step_us[step_us.len() / 2],
                rows,
            },
        );
    }

    // Sensitivity: the thresholds against the angular damping b_θ, all else equal (the paper
    // does not give its damping).
    let mut sensitivity = Vec::new();
    for b_theta in ANGULAR_DAMPING_SENSITIVITY {
        let p = CouplingParams {
            angular_damping_nms_per_rad: b_theta,
            ..params
        };
        let mut mins = std::collections::BTreeMap::new();
        let mut line = format!("  b_θ = {b_theta:.1e} N m s/rad:");
        for kind in IntegratorKind::ALL {
            let mut flags = Vec::new();
            for &m in &masses {
                let stable = simulate(kind, &shape.inertia_per_kg, &p, m, &traj, false)?.stable;
                flags.push((m, stable));
            }
            let min = min_stable_mass(&flags);
            let _ = write!(line, " {} {}", kind.name(), grams(min));
            mins.insert(kind.name(), min);
        }
        println!("{line}");
        sensitivity.push(Sensitivity {
            angular_damping_nms_per_rad: b_theta,
            min_stable_mass_kg: mins,
        });
    }

    // Fig. 3: BE 1 g, RK4 70 g, FE 100 g.
    let figure = [
        (
            IntegratorKind::LinearizedBackwardEuler,
            1e-3,
            "backward Euler, 1 g",
        ),
        (IntegratorKind::Rk4, 70e-3, "RK4, 70 g"),
        (IntegratorKind::ForwardEuler, 100e-3, "forward Euler, 100 g"),
    ];
    let (mut dev_series, mut force_series, mut figure_runs) = (Vec::new(), Vec::new(), Vec::new());
    for (kind, m, label) in figure {
        let r = simulate(kind, &shape.inertia_per_kg, &params, m, &traj, true)?;
        println!(
            "{label}: {} (rms deviation {:.2} mm, rms force {:.3} N)",
            verdict(&r),
            r.rms_deviation_m * 1e3,
            r.rms_force_n
        );
        dev_series.push(Series::new(
            label,
            r.trace.iter().map(|p| (p.0, p.1)).collect(),
        ));
        force_series.push(Series::new(
            label,
            r.trace.iter().map(|p| (p.0, p.2)).collect(),
        ));
        figure_runs.push(FigureRun {
            integrator: kind.name(),
            mass_kg: m,
            result: r,
        });
    }

    println!(
        "stable masses (sweep {:.1} g – {:.0} g):",
        masses[0] * 1e3,
        masses[masses.len() - 1] * 1e3
    );
    for (name, r) in &integrators {
        let ranges: Vec<String> = r
            .stable_mass_ranges_kg
            .iter()
            .map(|[a, b]| format!("{:.1}–{:.1} g", a * 1e3, b * 1e3))
            .collect();
        println!(
            "  {name:<22} stable above {:>9}; ranges {}; lagging but stable at {} masses   ({:.2} µs/step)",
            grams(r.min_stable_mass_kg),
            if ranges.is_empty() {
                "none".to_owned()
            } else {
                ranges.join(", ")
            },
            r.lagging_masses_kg.len(),
            r.median_step_us
        );
    }

    let report = Report {
        integrators,
        angular_damping_sensitivity: sensitivity,
        setup: Setup {
            mesh: "newell_teaspoon.stl",
            mesh_triangles: shape.mesh.triangles().len(),
            length_m: shape.length_m,
            volume_m3: shape.volume_m3,
            slit_volume_change_rel: shape.slit_volume_rel,
            com_mesh_m: [shape.com_m.x, shape.com_m.y, shape.com_m.z],
            principal_inertia_per_kg_m2: [eig[0], eig[1], eig[2]],
            grasp_body_m: GRASP_BODY_M,
            coupling: CouplingSetup {
                stiffness_n_per_m: params.stiffness_n_per_m,
                damping_ns_per_m: params.damping_ns_per_m,
                angular_stiffness_nm_per_rad: params.angular_stiffness_nm_per_rad,
                angular_damping_nms_per_rad: params.angular_damping_nms_per_rad,
            },
            rate_hz: RATE_HZ,
            duration_s,
            trajectory: traj_path.display().to_string(),
            trajectory_peak_speed_m_per_s: v_peak,
            trajectory_peak_angular_speed_rad_per_s: w_peak,
            masses_kg: masses,
            quick: args.out.quick,
            rules: run::rules(),
        },
        figure_runs,
    };
    common::write_json(&dir.join("free-space.json"), &report)?;
    line_chart(
        &dir.join("free-space-sweep.svg"),
        &Chart {
            title: "RMS coupling force of the stable runs against tool mass",
            x_label: "tool mass (g)",
            y_label: "RMS |F_c| (N)",
            x_scale: Scale::Log,
            y_scale: Scale::Log,
        },
        &sweep_series,
    )?;
    line_chart(
        &dir.join("free-space-deviation.svg"),
        &Chart {
            title: "Coupling deviation in free space",
            x_label: "time (s)",
            y_label: "|x_h - x - R r_c| (m)",
            x_scale: Scale::Linear,
            y_scale: Scale::Log,
        },
        &dev_series,
    )?;
    line_chart(
        &dir.join("free-space-force.svg"),
        &Chart {
            title: "Coupling force in free space",
            x_label: "time (s)",
            y_label: "|F_c| (N)",
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
        },
        &force_series,
    )?;
    Ok(())
}

/// A mass in grams, or `none`.
fn grams(m: Option<Real>) -> String {
    m.map_or("none".to_owned(), |m| format!("{:.1} g", m * 1e3))
}

/// A run's verdict in words.
fn verdict(r: &RunResult) -> String {
    match (r.divergence, r.lag) {
        (Some(d), _) => format!("unstable ({d:?})"),
        (None, Some(Lag::Deviation)) => "stable, lags beyond 0.1 m".to_owned(),
        (None, Some(Lag::Angle)) => "stable, lags beyond π/2".to_owned(),
        (None, None) => "stable".to_owned(),
    }
}
