//! Study `free-space`: the paper's Fig. 3 (Section VII-B).
//!
//! A 20 cm spoon (`newell_teaspoon.stl`, metres) hangs on the virtual coupling
//! (`k = 200 N/m`, `k_θ = 0.6 N m/rad`, damping from [`CouplingParams::default`]) and follows one
//! recorded hand motion (`xtask/data/free_space_trajectory.csv`, 2.5 s at 1 kHz) without touching
//! anything. For each integrator the tool mass is swept (log-spaced, 0.5 g to 500 g, inertia
//! scaled with the mass) and the smallest mass above which every run is stable is reported.
//!
//! **Stable** (see `docs/decisions.md`): every step succeeds with a finite state; the coupling
//! deviation stays bounded (`|e| <= 0.1 m`, `θ <= π/2`); and the coupling energy is not growing:
//! its maximum over the last 0.5 s is at most 10 times its maximum over the first 2 s. The
//! coupling energy is the springs' potential plus the tool's kinetic energy relative to the
//! handle: `½ k |e|² + ½ k_θ θ² + ½ m |v + ω × r - v_h|² + ½ (ω - ω_h)ᵀ I_w (ω - ω_h)`.
//!
//! Output: `DIR/free-space.json` (per integrator `min_stable_mass_kg` and `rows`), and SVG plots
//! of coupling deviation (log) and coupling force against time for BE at 1 g, RK4 at 70 g and
//! forward Euler at 100 g, as in Fig. 3.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use haptic_core::{DeviceState, Kinematics, Mat3, Pose, Real, RigidBody, ToolState, Twist, Vec3};
use haptic_dynamics::{CouplingParams, HapticForces, IntegratorKind, VirtualCoupling};
use nalgebra::{Quaternion, UnitQuaternion};
use serde_json::{Value, json};

use crate::common;
use crate::plot::{Chart, Scale, Series, line_chart};

/// Haptic rate, Hz (paper: 1 kHz).
const RATE_HZ: Real = 1000.0;
/// Simulated time, s (paper: 2.5 s).
const DURATION_S: Real = 2.5;
/// Steps per run.
const STEPS: usize = 2500;
/// Grasp point in the spoon's body frame (m from the centre of mass): on the handle, 3.5 cm
/// towards the handle end (the mesh's `-y`).
pub(crate) const GRASP_BODY_M: [Real; 3] = [0.0, -0.035, 0.0];
/// Stability bounds (see the module docs).
const MAX_DEVIATION_M: Real = 0.1;
const MAX_ANGLE_RAD: Real = std::f64::consts::FRAC_PI_2;
const ENERGY_GROWTH_LIMIT: Real = 10.0;
const ENERGY_SPLIT_S: Real = 2.0;
/// Angular dampings (N m s/rad) of the sensitivity sweep; 3e-3 is the default, 1.9e-2 the value
/// at which `h b_θ / I_min` reaches forward Euler's bound 2 for a 100 g spoon.
const ANGULAR_DAMPING_SENSITIVITY: [Real; 4] = [1e-3, 3e-3, 1e-2, 1.9e-2];

/// The trajectory file, relative to the repository root.
fn trajectory_path() -> PathBuf {
    common::repo_root()
        .join("xtask")
        .join("data")
        .join("free_space_trajectory.csv")
}

// ---------------------------------------------------------------------------------------------
// The hand motion
// ---------------------------------------------------------------------------------------------

/// One minimum-jerk sub-movement (Flash & Hogan 1985): starts at `t0_s`, lasts `dur_s`, moves the
/// handle by `d_m` (m, world) and turns it by the rotation vector `phi_rad` (rad, world).
struct SubMovement {
    t0_s: Real,
    dur_s: Real,
    d_m: [Real; 3],
    phi_rad: [Real; 3],
}

/// The hand motion: overlapping point-to-point strokes of 5–9 cm and 0.6–0.9 rad (after the
/// gains below), each a minimum-jerk profile, so that the hand reverses and turns several times;
/// peak speed about 0.5 m/s and peak angular speed about 5 rad/s. Plus a physiological tremor of 0.2 mm / 9 Hz and
/// 3 mrad / 7 Hz.
const STROKES: [SubMovement; 7] = [
    SubMovement {
        t0_s: 0.10,
        dur_s: 0.40,
        d_m: [0.10, 0.02, 0.00],
        phi_rad: [0.0, 0.0, 0.8],
    },
    SubMovement {
        t0_s: 0.40,
        dur_s: 0.35,
        d_m: [-0.06, 0.05, 0.03],
        phi_rad: [0.6, 0.0, -0.5],
    },
    SubMovement {
        t0_s: 0.75,
        dur_s: 0.30,
        d_m: [-0.05, -0.08, 0.01],
        phi_rad: [0.0, -0.9, 0.3],
    },
    SubMovement {
        t0_s: 1.00,
        dur_s: 0.40,
        d_m: [0.03, 0.02, -0.08],
        phi_rad: [-0.5, 0.4, 0.0],
    },
    SubMovement {
        t0_s: 1.35,
        dur_s: 0.30,
        d_m: [0.07, 0.00, 0.04],
        phi_rad: [0.2, 0.0, 0.8],
    },
    SubMovement {
        t0_s: 1.65,
        dur_s: 0.35,
        d_m: [-0.08, 0.03, 0.00],
        phi_rad: [0.0, 0.8, -0.6],
    },
    SubMovement {
        t0_s: 2.00,
        dur_s: 0.35,
        d_m: [0.02, -0.06, 0.03],
        phi_rad: [-0.7, -0.3, 0.2],
    },
];

/// Scales the strokes' displacements so that the peak hand speed is about 0.5 m/s.
const LINEAR_GAIN: Real = 0.85;
/// Scales the strokes' rotations so that the peak angular speed is about 5 rad/s.
const ANGULAR_GAIN: Real = 0.84;

/// Minimum-jerk profile `s(τ) = 10τ³ - 15τ⁴ + 6τ⁵` and `ds/dt`.
fn min_jerk(t: Real, t0: Real, dur: Real) -> (Real, Real) {
    let tau = ((t - t0) / dur).clamp(0.0, 1.0);
    let s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
    let ds = if (0.0..=1.0).contains(&((t - t0) / dur)) {
        30.0 * tau * tau * (1.0 - tau) * (1.0 - tau) / dur
    } else {
        0.0
    };
    (s, ds)
}

/// The handle's pose and twist at `t_s`, starting at the origin with identity orientation.
pub(crate) fn hand_at(t_s: Real) -> (Vec3, UnitQuaternion<Real>, Vec3, Vec3) {
    use std::f64::consts::TAU;
    let mut p = Vec3::zeros();
    let mut v = Vec3::zeros();
    let mut q = UnitQuaternion::identity();
    let mut w = Vec3::zeros();
    for s in &STROKES {
        let (a, da) = min_jerk(t_s, s.t0_s, s.dur_s);
        let d = Vec3::from(s.d_m) * LINEAR_GAIN;
        p += d * a;
        v += d * da;
        // q ← exp(φ s) q: ω ← exp(φ s) ω + φ ds (fixed world axis per stroke).
        let phi = Vec3::from(s.phi_rad) * ANGULAR_GAIN;
        let e = UnitQuaternion::from_scaled_axis(phi * a);
        q = e * q;
        w = e * w + phi * da;
    }
    // Tremor.
    let (ft, fr) = (9.0 * TAU, 7.0 * TAU);
    let amp = 2e-4;
    p += Vec3::new((ft * t_s).sin(), (1.1 * ft * t_s).cos() - 1.0, 0.0) * amp;
    v += Vec3::new(
        ft * (ft * t_s).cos(),
        -1.1 * ft * (1.1 * ft * t_s).sin(),
        0.0,
    ) * amp;
    let (ang, dang) = (3e-3 * (fr * t_s).sin(), 3e-3 * fr * (fr * t_s).cos());
    let axis = Vec3::new(1.0, 1.0, 0.0).normalize();
    q = UnitQuaternion::from_scaled_axis(axis * ang) * q;
    w = UnitQuaternion::from_scaled_axis(axis * ang) * w + axis * dang;
    (p, q, v, w)
}

/// The trajectory as CSV text, 1 kHz samples from 0 to 2.5 s inclusive.
fn trajectory_csv() -> String {
    let mut out = String::from(
        "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_per_s,vy_m_per_s,vz_m_per_s,wx_rad_per_s,wy_rad_per_s,wz_rad_per_s\n",
    );
    for n in 0..=STEPS {
        let t = n as Real / RATE_HZ;
        let (p, q, v, w) = hand_at(t);
        let vals = [
            t, p.x, p.y, p.z, q.w, q.i, q.j, q.k, v.x, v.y, v.z, w.x, w.y, w.z,
        ];
        let line: Vec<String> = vals.iter().map(|x| format!("{x:.12e}")).collect();
        let _ = writeln!(out, "{}", line.join(","));
    }
    out
}

/// Reads the device trajectory (validating every pose).
fn read_trajectory(path: &Path) -> anyhow::Result<Vec<DeviceState>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut out = Vec::with_capacity(STEPS + 1);
    for (i, line) in text.lines().enumerate().skip(1) {
        let vals: Vec<Real> = line
            .split(',')
            .map(|s| s.trim().parse::<Real>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}:{}: bad number", path.display(), i + 1))?;
        if vals.len() != 14 {
            bail!(
                "{}:{}: expected 14 columns, got {}",
                path.display(),
                i + 1,
                vals.len()
            );
        }
        let q = Quaternion::new(vals[4], vals[5], vals[6], vals[7]);
        let pose = Pose::new(Vec3::new(vals[1], vals[2], vals[3]), q / q.norm())
            .with_context(|| format!("{}:{}", path.display(), i + 1))?;
        let twist = Twist {
            linear: Vec3::new(vals[8], vals[9], vals[10]),
            angular: Vec3::new(vals[11], vals[12], vals[13]),
        };
        if !twist.is_finite() || !vals[0].is_finite() {
            bail!("{}:{}: non-finite twist or time", path.display(), i + 1);
        }
        out.push(DeviceState {
            pose,
            twist,
            buttons: 1,
            timestamp_s: vals[0],
        });
    }
    if out.len() < STEPS {
        bail!("{}: {} samples, need {}", path.display(), out.len(), STEPS);
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// The spoon's mass properties
// ---------------------------------------------------------------------------------------------

/// Mass properties of the spoon per kilogram, in the mesh's axes.
pub(crate) struct SpoonShape {
    /// Centre of mass in mesh coordinates, m.
    pub(crate) com_m: Vec3,
    /// Inertia about the centre of mass per unit mass, m² (multiply by the mass).
    pub(crate) inertia_per_kg: Mat3,
    /// Enclosed volume, m³.
    volume_m3: Real,
    /// Extent along the mesh's y axis, m.
    length_m: Real,
    /// Relative change of the volume when the origin of the divergence integral moves by the
    /// spoon's length: how much the open slits matter.
    slit_volume_rel: Real,
    /// Where the numbers came from.
    source: &'static str,
    /// Triangles read.
    triangles: usize,
}

/// Reads a binary STL's triangles.
pub(crate) fn read_stl(path: &Path) -> anyhow::Result<Vec<[Vec3; 3]>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if bytes.len() < 84 {
        bail!("{}: too short for binary STL", path.display());
    }
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    if bytes.len() < 84 + 50 * n {
        bail!("{}: truncated ({} triangles announced)", path.display(), n);
    }
    let f =
        |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]) as Real;
    let mut tris = Vec::with_capacity(n);
    for i in 0..n {
        let o = 84 + 50 * i + 12;
        let v = |k: usize| Vec3::new(f(o + 12 * k), f(o + 12 * k + 4), f(o + 12 * k + 8));
        let t = [v(0), v(1), v(2)];
        if t.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
            bail!("{}: triangle {i} is not finite", path.display());
        }
        tris.push(t);
    }
    Ok(tris)
}

/// Volume, first and second moments of the solid bounded by `tris`, by the divergence theorem
/// (signed tetrahedra from `origin`), for uniform unit density.
fn volume_integrals(tris: &[[Vec3; 3]], origin: &Vec3) -> (Real, Vec3, Mat3) {
    let (mut vol, mut first, mut second) = (0.0, Vec3::zeros(), Mat3::zeros());
    for t in tris {
        let (a, b, c) = (t[0] - origin, t[1] - origin, t[2] - origin);
        let d = a.dot(&b.cross(&c)) / 6.0;
        vol += d;
        first += d * (a + b + c) / 4.0;
        // ∫ x xᵀ over the tetrahedron (0, a, b, c).
        let s = a * a.transpose() + b * b.transpose() + c * c.transpose();
        let sum = a + b + c;
        second += d / 20.0 * (s + sum * sum.transpose());
    }
    (vol, first, second)
}

/// The spoon's mass properties, from the triangle soup (uniform density, divergence theorem).
///
/// The Newell teaspoon is closed except for two slits under 0.15 mm wide at the bowl tip and the
/// handle end. The divergence theorem then depends (slightly) on the origin of the tetrahedra:
/// we integrate from the bounding-box centre and report how much the volume changes when the
/// origin moves by the spoon's length, which bounds the slits' effect.
pub(crate) fn spoon_shape(path: &Path) -> anyhow::Result<SpoonShape> {
    let tris = read_stl(path)?;
    let (mut lo, mut hi) = (
        Vec3::repeat(Real::INFINITY),
        Vec3::repeat(Real::NEG_INFINITY),
    );
    for t in &tris {
        for p in t {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
    }
    let centre = 0.5 * (lo + hi);
    let (vol, first, second) = volume_integrals(&tris, &centre);
    if vol <= 0.0 {
        bail!(
            "{}: enclosed volume {vol} m³ is not positive (inward normals?)",
            path.display()
        );
    }
    let length = hi.y - lo.y;
    let (vol2, _, _) = volume_integrals(&tris, &(centre + Vec3::new(length, length, length)));
    let com_rel = first / vol;
    // Second moment about the centre of mass per unit volume, then inertia per unit mass.
    let s = second / vol - com_rel * com_rel.transpose();
    let inertia_per_kg = Mat3::identity() * s.trace() - s;
    Ok(SpoonShape {
        com_m: centre + com_rel,
        inertia_per_kg: 0.5 * (inertia_per_kg + inertia_per_kg.transpose()),
        volume_m3: vol,
        length_m: length,
        slit_volume_rel: ((vol2 - vol) / vol).abs(),
        source: "xtask free_space.rs divergence theorem over the STL triangles (uniform density)",
        triangles: tris.len(),
    })
}

// ---------------------------------------------------------------------------------------------
// One run
// ---------------------------------------------------------------------------------------------

/// What one run measured.
struct RunResult {
    stable: bool,
    /// Why the run is unstable, if it is.
    failure: Option<String>,
    steps_completed: usize,
    rms_deviation_m: Real,
    max_deviation_m: Real,
    rms_angle_rad: Real,
    max_angle_rad: Real,
    rms_force_n: Real,
    max_force_n: Real,
    rms_torque_nm: Real,
    max_torque_nm: Real,
    /// Mean wall time of one integrator step, µs.
    mean_step_us: Real,
    /// Per step: (t, deviation m, |force| N), when asked for.
    trace: Vec<(Real, Real, Real)>,
}

/// The coupling energy (J) of the tool in state `tool` against the handle `device`.
fn coupling_energy(
    body: &RigidBody,
    coupling: &VirtualCoupling,
    tool: &ToolState,
    device: &DeviceState,
) -> Real {
    let p = coupling.params();
    let y = tool.to_vector();
    let kin = Kinematics::new(body, &y);
    let (e, phi) = coupling.stretch(&y, &kin);
    let r = kin.r * coupling.grasp().r_c;
    let dv = kin.v + kin.omega.cross(&r) - device.twist.linear;
    let dw = kin.omega - device.twist.angular;
    let iw = kin.r * body.inertia_body() * kin.r.transpose();
    0.5 * p.stiffness_n_per_m * e.norm_squared()
        + 0.5 * p.angular_stiffness_nm_per_rad * phi.norm_squared()
        + 0.5 * body.mass_kg() * dv.norm_squared()
        + 0.5 * dw.dot(&(iw * dw))
}

/// Simulates the spoon of `mass_kg` following `traj` with integrator `kind`, as the haptic loop
/// does: read the device, step, compute the feedback with the new state.
fn simulate(
    kind: IntegratorKind,
    shape: &SpoonShape,
    params: &CouplingParams,
    mass_kg: Real,
    traj: &[DeviceState],
    keep_trace: bool,
) -> anyhow::Result<RunResult> {
    let body = RigidBody::new(mass_kg, shape.inertia_per_kg * mass_kg)?;
    let h = 1.0 / RATE_HZ;
    let r_c = Vec3::from(GRASP_BODY_M);
    let d0 = traj[0];
    // The tool at rest, in the mesh's orientation, with its grasp point on the handle.
    let mut tool = ToolState::at_rest(&Pose {
        position: d0.pose.position - d0.pose.orientation * r_c,
        orientation: d0.pose.orientation,
    });
    let coupling = VirtualCoupling::grasping(*params, &tool, &d0)?;
    let mut forces = HapticForces::new(coupling);
    let mut integ = kind.boxed();
    let mut res = RunResult {
        stable: true,
        failure: None,
        steps_completed: 0,
        rms_deviation_m: 0.0,
        max_deviation_m: 0.0,
        rms_angle_rad: 0.0,
        max_angle_rad: 0.0,
        rms_force_n: 0.0,
        max_force_n: 0.0,
        rms_torque_nm: 0.0,
        max_torque_nm: 0.0,
        mean_step_us: 0.0,
        trace: Vec::new(),
    };
    let mut step_time = std::time::Duration::ZERO;
    let (mut s_dev, mut s_ang, mut s_f, mut s_t) = (0.0, 0.0, 0.0, 0.0);
    let (mut e_head, mut e_tail) = (0.0_f64, 0.0_f64);
    for (n, device) in traj.iter().take(STEPS).enumerate() {
        let t = n as Real * h;
        forces.coupling.set_device(device)?;
        let clock = std::time::Instant::now();
        let stepped = integ.step(&body, &tool, t, h, &mut forces);
        step_time += clock.elapsed();
        match stepped {
            Ok(next) => tool = next,
            Err(e) => {
                res.failure = Some(format!("step {n}: {e}"));
                break;
            }
        }
        let dev = forces.coupling.deviation(&tool);
        let w = forces.coupling.device_reaction(&body, &tool);
        let energy = coupling_energy(&body, &forces.coupling, &tool, device);
        let (f, tq) = (w.force.norm(), w.torque.norm());
        if ![dev.translation_m, dev.angle_rad, f, tq, energy]
            .iter()
            .all(|v| v.is_finite())
        {
            res.failure = Some(format!("step {n}: non-finite output"));
            break;
        }
        res.steps_completed = n + 1;
        s_dev += dev.translation_m.powi(2);
        s_ang += dev.angle_rad.powi(2);
        s_f += f * f;
        s_t += tq * tq;
        res.max_deviation_m = res.max_deviation_m.max(dev.translation_m);
        res.max_angle_rad = res.max_angle_rad.max(dev.angle_rad);
        res.max_force_n = res.max_force_n.max(f);
        res.max_torque_nm = res.max_torque_nm.max(tq);
        if t + h <= ENERGY_SPLIT_S + 1e-9 {
            e_head = e_head.max(energy);
        } else {
            e_tail = e_tail.max(energy);
        }
        if keep_trace {
            res.trace.push((t + h, dev.translation_m, f));
        }
        if dev.translation_m > MAX_DEVIATION_M || dev.angle_rad > MAX_ANGLE_RAD {
            res.failure = Some(format!(
                "step {n}: coupling deviation {:.3} m / {:.3} rad beyond the bound",
                dev.translation_m, dev.angle_rad
            ));
            break;
        }
    }
    let k = res.steps_completed.max(1) as Real;
    res.rms_deviation_m = (s_dev / k).sqrt();
    res.rms_angle_rad = (s_ang / k).sqrt();
    res.rms_force_n = (s_f / k).sqrt();
    res.rms_torque_nm = (s_t / k).sqrt();
    res.mean_step_us = step_time.as_secs_f64() * 1e6 / k;
    if res.failure.is_none() && e_tail > ENERGY_GROWTH_LIMIT * e_head + 1e-12 {
        res.failure = Some(format!(
            "coupling energy growing: max {e_tail:.3e} J in the last 0.5 s vs {e_head:.3e} J before"
        ));
    }
    res.stable = res.failure.is_none();
    Ok(res)
}

// ---------------------------------------------------------------------------------------------
// The study
// ---------------------------------------------------------------------------------------------

/// `per_decade` log-spaced masses from 0.5 g to 500 g inclusive.
fn mass_grid(per_decade: usize) -> Vec<Real> {
    let n = 3 * per_decade;
    (0..=n)
        .map(|i| 5e-4 * 10f64.powf(3.0 * i as Real / n as Real))
        .collect()
}

/// The smallest mass such that it and every heavier mass of the sweep are stable.
fn min_stable_mass(rows: &[(Real, bool)]) -> Option<Real> {
    let mut best = None;
    for &(m, stable) in rows.iter().rev() {
        if !stable {
            break;
        }
        best = Some(m);
    }
    best
}

/// Peak linear and angular speed of the trajectory.
fn peak_speeds(traj: &[DeviceState]) -> (Real, Real) {
    traj.iter().fold((0.0, 0.0), |(v, w), d| {
        (
            Real::max(v, d.twist.linear.norm()),
            Real::max(w, d.twist.angular.norm()),
        )
    })
}

/// Runs the study.
pub fn run(args: &crate::OutArgs) -> anyhow::Result<()> {
    let dir = args.dir("free-space")?;
    let csv = trajectory_path();
    if !csv.exists() {
        if let Some(parent) = csv.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(&csv, trajectory_csv())?;
        println!("generated {}", csv.display());
    }
    let traj = read_trajectory(&csv)?;
    let (v_peak, w_peak) = peak_speeds(&traj);
    let mesh = common::meshes_dir().join("newell_teaspoon.stl");
    let shape = spoon_shape(&mesh)?;
    let eig = shape.inertia_per_kg.symmetric_eigenvalues();
    println!(
        "spoon: {} triangles, {:.1} cm long, volume {:.3} cm³ (slits change it by {:.1e}), \
         principal inertia per kg {:.3e} {:.3e} {:.3e} m²",
        shape.triangles,
        100.0 * shape.length_m,
        shape.volume_m3 * 1e6,
        shape.slit_volume_rel,
        eig[0],
        eig[1],
        eig[2]
    );
    println!("hand motion: peak {v_peak:.2} m/s, {w_peak:.2} rad/s");

    let masses = mass_grid(if args.quick { 5 } else { 10 });
    let mut report = serde_json::Map::new();
    let mut summary = Vec::new();
    let mut sweep_series = Vec::new();
    for kind in IntegratorKind::ALL {
        let mut rows = Vec::new();
        let mut flags = Vec::new();
        let mut step_us = Vec::new();
        let mut force_curve = Vec::new();
        for &m in &masses {
            let r = simulate(kind, &shape, &CouplingParams::default(), m, &traj, false)?;
            flags.push((m, r.stable));
            step_us.push(r.mean_step_us);
            if r.stable {
                force_curve.push((m * 1e3, r.rms_force_n));
            }
            rows.push(json!({
                "mass_kg": m,
                "stable": r.stable,
                "failure": r.failure,
                "steps_completed": r.steps_completed,
                "rms_deviation_m": r.rms_deviation_m,
                "max_deviation_m": r.max_deviation_m,
                "rms_angle_rad": r.rms_angle_rad,
                "max_angle_rad": r.max_angle_rad,
                "rms_force_n": r.rms_force_n,
                "max_force_n": r.max_force_n,
                "rms_torque_nm": r.rms_torque_nm,
                "max_torque_nm": r.max_torque_nm,
            }));
        }
        let min = min_stable_mass(&flags);
        step_us.sort_by(Real::total_cmp);
        let median_step_us = step_us[step_us.len() / 2];
        summary.push((kind, min, median_step_us));
        sweep_series.push(Series::new(kind.name(), force_curve));
        report.insert(
            kind.name().to_owned(),
            json!({
                "min_stable_mass_kg": min,
                "median_step_us": median_step_us,
                "rows": rows,
            }),
        );
    }
    // Sensitivity: the explicit methods' thresholds against the angular damping b_θ, all else
    // equal (the paper does not give its damping).
    let mut sensitivity = Vec::new();
    for b_theta in ANGULAR_DAMPING_SENSITIVITY {
        let params = CouplingParams {
            angular_damping_nms_per_rad: b_theta,
            ..CouplingParams::default()
        };
        let mut entry = serde_json::Map::new();
        entry.insert("angular_damping_nms_per_rad".to_owned(), json!(b_theta));
        let mut line = format!("  b_θ = {b_theta:.1e} N m s/rad:");
        for kind in IntegratorKind::ALL {
            let mut flags = Vec::new();
            for &m in &masses {
                flags.push((m, simulate(kind, &shape, &params, m, &traj, false)?.stable));
            }
            let min = min_stable_mass(&flags);
            entry.insert(kind.name().to_owned(), json!({ "min_stable_mass_kg": min }));
            let _ = write!(
                line,
                " {} {}",
                kind.name(),
                min.map_or("none".to_owned(), |m| format!("{:.1} g", m * 1e3))
            );
        }
        println!("{line}");
        sensitivity.push(Value::Object(entry));
    }
    report.insert(
        "angular_damping_sensitivity".to_owned(),
        Value::Array(sensitivity),
    );
    let params = CouplingParams::default();
    report.insert(
        "setup".to_owned(),
        json!({
            "mesh": "newell_teaspoon.stl",
            "mesh_triangles": shape.triangles,
            "length_m": shape.length_m,
            "volume_m3": shape.volume_m3,
            "slit_volume_change_rel": shape.slit_volume_rel,
            "com_mesh_m": [shape.com_m.x, shape.com_m.y, shape.com_m.z],
            "inertia_per_kg_m2": shape.inertia_per_kg.as_slice(),
            "principal_inertia_per_kg_m2": [eig[0], eig[1], eig[2]],
            "mass_properties_source": shape.source,
            "grasp_body_m": GRASP_BODY_M,
            "stiffness_n_per_m": params.stiffness_n_per_m,
            "damping_ns_per_m": params.damping_ns_per_m,
            "angular_stiffness_nm_per_rad": params.angular_stiffness_nm_per_rad,
            "angular_damping_nms_per_rad": params.angular_damping_nms_per_rad,
            "rate_hz": RATE_HZ,
            "duration_s": DURATION_S,
            "trajectory": "xtask/data/free_space_trajectory.csv",
            "trajectory_peak_speed_m_per_s": v_peak,
            "trajectory_peak_angular_speed_rad_per_s": w_peak,
            "masses_kg": masses,
            "quick": args.quick,
            "stability": format!(
                "every step succeeds with a finite state; coupling deviation <= {MAX_DEVIATION_M} m \
                 and angle <= pi/2; max coupling energy over the last 0.5 s <= \
                 {ENERGY_GROWTH_LIMIT} x its max over the first 2 s; min_stable_mass_kg is the \
                 smallest swept mass above which every swept mass is stable"
            ),
        }),
    );
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
    let mut dev_series = Vec::new();
    let mut force_series = Vec::new();
    let mut figure_runs = Vec::new();
    for (kind, m, label) in figure {
        let r = simulate(kind, &shape, &CouplingParams::default(), m, &traj, true)?;
        println!(
            "{label}: {} (rms deviation {:.2} mm, rms force {:.3} N)",
            if r.stable { "stable" } else { "unstable" },
            r.rms_deviation_m * 1e3,
            r.rms_force_n
        );
        figure_runs.push(json!({
            "integrator": kind.name(),
            "mass_kg": m,
            "stable": r.stable,
            "rms_deviation_m": r.rms_deviation_m,
            "max_deviation_m": r.max_deviation_m,
            "rms_force_n": r.rms_force_n,
            "max_force_n": r.max_force_n,
        }));
        dev_series.push(Series::new(
            label,
            r.trace.iter().map(|p| (p.0, p.1)).collect(),
        ));
        force_series.push(Series::new(
            label,
            r.trace.iter().map(|p| (p.0, p.2)).collect(),
        ));
    }
    report.insert("figure_runs".to_owned(), Value::Array(figure_runs));
    common::write_json(&dir.join("free-space.json"), &Value::Object(report))?;
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

    println!("minimum stable mass:");
    for (kind, min, us) in &summary {
        match min {
            Some(m) => println!(
                "  {:<22} {:8.2} g   ({us:.2} µs/step)",
                kind.name(),
                m * 1e3
            ),
            None => println!(
                "  {:<22} none in the sweep   ({us:.2} µs/step)",
                kind.name()
            ),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn committed_trajectory_is_the_generated_one() {
        let committed = read_trajectory(&trajectory_path()).unwrap();
        let dir = std::env::temp_dir().join(format!("free-space-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fresh_path = dir.join("t.csv");
        std::fs::write(&fresh_path, trajectory_csv()).unwrap();
        let fresh = read_trajectory(&fresh_path).unwrap();
        assert_eq!(committed.len(), fresh.len());
        for (a, b) in committed.iter().zip(&fresh) {
            assert_eq!(a.timestamp_s, b.timestamp_s);
            assert!((a.pose.position - b.pose.position).norm() < 1e-12);
            assert!(a.pose.orientation.angle_to(&b.pose.orientation) < 1e-9);
            assert!((a.twist.linear - b.twist.linear).norm() < 1e-9);
            assert!((a.twist.angular - b.twist.angular).norm() < 1e-9);
        }
    }

    #[test]
    fn twist_is_the_derivative_of_the_pose() {
        let h = 1e-6;
        for i in 0..250 {
            let t = 0.01 * i as Real;
            let (p0, q0, v, w) = hand_at(t);
            let (p1, q1, _, _) = hand_at(t + h);
            let (pm, qm, _, _) = hand_at(t - h);
            assert!(((p1 - pm) / (2.0 * h) - v).norm() < 1e-6, "t = {t}");
            let w_fd = (q1 * qm.inverse()).scaled_axis() / (2.0 * h);
            assert!(
                (w_fd - w).norm() < 1e-5 * (1.0 + w.norm()),
                "t = {t}: {w_fd} vs {w}"
            );
            let _ = (p0, q0);
        }
    }

    #[test]
    fn min_stable_mass_needs_every_heavier_mass_stable() {
        let rows = [(1.0, true), (2.0, false), (3.0, true), (4.0, true)];
        assert_eq!(min_stable_mass(&rows), Some(3.0));
        assert_eq!(min_stable_mass(&[(1.0, true), (2.0, false)]), None);
    }
}
