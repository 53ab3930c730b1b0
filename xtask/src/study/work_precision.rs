//! `cargo xtask study work-precision [--out DIR] [--quick]`: error against cost of each integrator.
//!
//! **Scenario** (the free-space study's, see `study/free_space/`): the 20 cm Newell teaspoon,
//! 100 g (inertia scaled from its uniform-density mass properties), hangs on the default virtual
//! coupling and follows the analytic hand motion of the free-space study for 2.5 s.
//!
//! - The device reading is evaluated at every time the integrator asks for (its stage times),
//!   from the analytic hand motion: the ODE is then smooth, so each method's order shows. (The
//!   real haptic loop holds the reading constant over a step, which caps every method at first
//!   order against the continuous-time hand.)
//! - **With contact**: the same run with a fixed, smooth contact model: the spoon's underside
//!   rests on a table (normal `+z`) at five representatives (the lowest vertex of the spoon in
//!   each fifth of its length), each 0.5 mm deep; the penalty model (`PenaltyParams::default`,
//!   `k_c = 2000 N/m` and `b_c = 2 N s/m` per contact) is linearized once at the start state and
//!   that linearized wrench (eq. 42, as the haptic loop integrates it between contact updates)
//!   acts for the whole run. It is affine in the state, hence smooth: the runs converge. It is
//!   stiff (five contacts: 10⁴ N/m against the coupling's 200 N/m), which is what separates the
//!   explicit from the implicit methods.
//! - Step sizes from 0.05 ms to 2 ms, each dividing the 10 ms sampling interval.
//! - **Reference**: RK4 at 0.01 ms (five times smaller than the smallest step of the sweep).
//! - **Error**: the largest, over the samples every 10 ms, of `|x − x_ref| + L · ∠(q, q_ref)`
//!   with `L = 0.1 m` (half the spoon's length), in metres.
//! - **Stable**: every step succeeds with a finite state and the error stays below 0.1 m.
//! - **Cost**: wall time of the run (all steps with their force evaluations) per simulated second;
//!   the best of three runs (one with `--quick`).
//! - **Observed order**: least-squares slope of log error against log step over the stable
//!   free-space rows whose error is above 1e-11 m (round-off).
//!
//! Output: `DIR/work-precision.json` and `DIR/work-precision.svg` (log error against log cost, one
//! curve per integrator and scenario, as SciML's work-precision diagrams). If the collision
//! benchmark's `collision.json` exists (in `DIR` or `target/xtask/collision`), its rows go into
//! the JSON under `collision` and into `DIR/work-precision-collision.svg` (wrench error against
//! query time per back-end: other units, so another diagram).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use haptic_core::{
    Contact, ContactModel, DeviceState, ForceModel, Kinematics, LinearizedContact, Pose, Real,
    RigidBody, StateVector, ToolState, Twist, Vec3, Wrench, WrenchJacobian,
};
use haptic_dynamics::{
    CouplingParams, DynamicsError, HapticForces, IntegratorKind, PenaltyModel, PenaltyParams,
    VirtualCoupling,
};
use nalgebra::UnitQuaternion;
use serde::Serialize;
use serde_json::Value;

use crate::common;
use crate::plot::{Chart, Scale, Series, line_chart};

use crate::study::free_space;

/// Tool mass, kg.
const MASS_KG: Real = 0.1;
/// Simulated time, s.
const DURATION_S: Real = 2.5;
/// Sampling interval of the error, s (every step size divides it).
const SAMPLE_S: Real = 0.01;
/// Reference step, s.
const REFERENCE_DT_S: Real = 1e-5;
/// Lever turning an orientation error into metres.
const LEVER_M: Real = 0.1;
/// Error above which a run counts as unstable, m.
const UNSTABLE_ERROR_M: Real = 0.1;
/// Errors below this are round-off and left out of the order fit, m.
const ROUNDOFF_M: Real = 1e-11;
/// Depth of each table contact at the start, m.
const TABLE_DEPTH_M: Real = 5e-4;
/// Step sizes, ms.
const STEPS_MS_FULL: [Real; 10] = [0.05, 0.1, 0.125, 0.2, 0.25, 0.4, 0.5, 1.0, 1.25, 2.0];
const STEPS_MS_QUICK: [Real; 6] = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0];

/// The device reading of the hand motion at `t_s`.
pub(crate) fn hand_device(t_s: Real) -> DeviceState {
    let (p, q, v, w) = free_space::hand_at(t_s);
    DeviceState {
        pose: Pose {
            position: p,
            orientation: q,
        },
        twist: Twist {
            linear: v,
            angular: w,
        },
        buttons: 1,
        timestamp_s: t_s,
    }
}

/// [`HapticForces`] whose device reading follows the hand motion at the time of each evaluation.
struct HandDriven {
    forces: HapticForces,
    t_set: Real,
    error: Option<DynamicsError>,
}

impl HandDriven {
    fn sync(&mut self, t_s: Real) {
        if t_s != self.t_set {
            if let Err(e) = self.forces.coupling.set_device(&hand_device(t_s)) {
                self.error.get_or_insert(e);
            }
            self.t_set = t_s;
        }
    }
}

impl ForceModel for HandDriven {
    fn wrench(&mut self, body: &RigidBody, t_s: Real, y: &StateVector, kin: &Kinematics) -> Wrench {
        self.sync(t_s);
        self.forces.wrench(body, t_s, y, kin)
    }

    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t_s: Real,
        y: &StateVector,
        kin: &Kinematics,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        self.sync(t_s);
        self.forces.wrench_and_jacobian(body, t_s, y, kin, jacobian)
    }
}

/// The body, the start state, the coupling and (with contact) the fixed linearized contact.
pub(crate) struct Setup {
    pub(crate) body: RigidBody,
    pub(crate) start: ToolState,
    pub(crate) coupling: VirtualCoupling,
    pub(crate) table: LinearizedContact,
    pub(crate) table_points_body_m: Vec<Vec3>,
}

/// The spoon, its start state, its coupling and the fixed table contact (see the module docs).
pub(crate) fn setup() -> anyhow::Result<Setup> {
    let mesh = common::meshes_dir().join("newell_teaspoon.stl");
    let shape = free_space::spoon_shape(&mesh)?;
    let body = RigidBody::new(MASS_KG, shape.inertia_per_kg * MASS_KG)?;
    let d0 = hand_device(0.0);
    let r_c = Vec3::from(free_space::GRASP_BODY_M);
    let start = ToolState::at_rest(&Pose {
        position: d0.pose.position - d0.pose.orientation * r_c,
        orientation: d0.pose.orientation,
    });
    let coupling = VirtualCoupling::grasping(CouplingParams::default(), &start, &d0)?;
    // Five representatives: the lowest vertex in each fifth of the spoon's length (body frame).
    let vertices = shape.mesh.vertices();
    let (lo, hi) = shape.mesh.bounding_box();
    let (lo_y, hi_y) = (lo.y, hi.y);
    let mut lowest: [Option<Vec3>; 5] = [None; 5];
    for p in vertices {
        let bin = (((p.y - lo_y) / (hi_y - lo_y) * 5.0) as usize).min(4);
        if lowest[bin].is_none_or(|q| p.z < q.z) {
            lowest[bin] = Some(*p);
        }
    }
    let table_points_body_m: Vec<Vec3> = lowest.iter().flatten().map(|p| p - shape.com_m).collect();
    let n = -Vec3::z(); // out of the tool, into the table
    let contacts = table_points_body_m
        .iter()
        .map(|r| {
            let p_a = start.x + start.q * r;
            Contact::new(p_a, *r, p_a - TABLE_DEPTH_M * n, n, TABLE_DEPTH_M)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut model = PenaltyModel::new(PenaltyParams::default())?;
    let mut table = LinearizedContact::none();
    model.linearize(&body, &start, &contacts, &mut table)?;
    Ok(Setup {
        body,
        start,
        coupling,
        table,
        table_points_body_m,
    })
}

/// Tool positions and orientations every 10 ms.
type Samples = Vec<(Vec3, UnitQuaternion<Real>)>;

/// One run: the samples every 10 ms (or `None` if a step failed) and the wall time, s.
fn simulate(
    kind: IntegratorKind,
    s: &Setup,
    contact: bool,
    dt_s: Real,
) -> anyhow::Result<(Option<Samples>, Real)> {
    let mut forces = HapticForces::new(s.coupling);
    if contact {
        forces.contact = s.table;
    }
    let mut model = HandDriven {
        forces,
        t_set: Real::NAN,
        error: None,
    };
    let mut integ = kind.boxed();
    let steps = (DURATION_S / dt_s).round() as usize;
    let per_sample = (SAMPLE_S / dt_s).round() as usize;
    let mut tool = s.start;
    let mut samples = Vec::with_capacity(steps / per_sample + 1);
    samples.push((tool.x, tool.q));
    let clock = Instant::now();
    for n in 0..steps {
        let t = n as Real * dt_s;
        match integ.step(&s.body, &tool, t, dt_s, &mut model) {
            Ok(next) if next.x.iter().all(|v| v.is_finite()) => tool = next,
            _ => return Ok((None, clock.elapsed().as_secs_f64())),
        }
        if (n + 1) % per_sample == 0 {
            samples.push((tool.x, tool.q));
        }
    }
    let wall = clock.elapsed().as_secs_f64();
    if let Some(e) = model.error {
        return Err(e).context("device reading refused");
    }
    Ok((Some(samples), wall))
}

/// The error of `run` against `reference` (see the module docs).
fn error_against(
    run: &[(Vec3, UnitQuaternion<Real>)],
    reference: &[(Vec3, UnitQuaternion<Real>)],
) -> Real {
    run.iter()
        .zip(reference)
        .map(|((x, q), (xr, qr))| (x - xr).norm() + LEVER_M * q.angle_to(qr))
        .fold(0.0, Real::max)
}

/// Least-squares slope of log `y` against log `x`.
fn log_slope(points: &[(Real, Real)]) -> Option<Real> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as Real;
    let (xs, ys): (Vec<Real>, Vec<Real>) = points.iter().map(|(x, y)| (x.ln(), y.ln())).unzip();
    let (mx, my) = (xs.iter().sum::<Real>() / n, ys.iter().sum::<Real>() / n);
    let sxy: Real = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: Real = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The collision benchmark's results, if a run left them.
fn collision_json(dir: &std::path::Path) -> Option<(PathBuf, Value)> {
    let candidates = [
        dir.join("collision.json"),
        common::repo_root()
            .join("target")
            .join("xtask")
            .join("collision")
            .join("collision.json"),
    ];
    candidates.into_iter().find_map(|p| {
        let text = std::fs::read_to_string(&p).ok()?;
        let v: Value = serde_json::from_str(&text).ok()?;
        Some((p, v))
    })
}

/// Runs the work-precision study.
pub fn run(args: &crate::OutArgs) -> anyhow::Result<()> {
    let dir = args.dir("work-precision")?;
    let s = setup()?;
    let steps_ms: &[Real] = if args.quick {
        &STEPS_MS_QUICK
    } else {
        &STEPS_MS_FULL
    };
    let repeats = if args.quick { 1 } else { 3 };
    let mut references = Vec::new();
    for contact in [false, true] {
        let (r, wall) = simulate(IntegratorKind::Rk4, &s, contact, REFERENCE_DT_S)?;
        let r = r.context("the RK4 reference run failed")?;
        println!(
            "reference ({}): RK4 at {} ms, {wall:.2} s",
            if contact { "contact" } else { "free space" },
            REFERENCE_DT_S * 1e3
        );
        references.push(r);
    }
    let mut integrators = std::collections::BTreeMap::new();
    let mut series = Vec::new();
    for kind in IntegratorKind::ALL {
        let mut entry = WpIntegrator::default();
        let mut fit = Vec::new();
        for (contact, reference) in [false, true].into_iter().zip(&references) {
            let mut rows = Vec::new();
            let mut curve = Vec::new();
            for &ms in steps_ms {
                let dt = ms * 1e-3;
                let mut best = Real::INFINITY;
                let mut samples = None;
                for _ in 0..repeats {
                    let (r, wall) = simulate(kind, &s, contact, dt)?;
                    best = best.min(wall);
                    samples = r;
                }
                let error = samples.as_deref().map(|r| error_against(r, reference));
                let stable = error.is_some_and(|e| e.is_finite() && e < UNSTABLE_ERROR_M);
                let cost = best / DURATION_S;
                if stable {
                    let e = error.unwrap_or(Real::NAN);
                    curve.push((cost, e));
                    if !contact && e > ROUNDOFF_M {
                        fit.push((dt, e));
                    }
                }
                rows.push(WpRow {
                    dt_s: dt,
                    error: error.filter(|e| e.is_finite()),
                    seconds_per_simulated_second: cost,
                    stable,
                });
            }
            let label = if contact {
                format!("{} (contact)", kind.name())
            } else {
                kind.name().to_owned()
            };
            series.push(Series::new(label, curve));
            if contact {
                entry.contact_rows = rows;
            } else {
                entry.rows = rows;
            }
        }
        let order = log_slope(&fit);
        entry.order_observed = order;
        println!(
            "{:<22} observed order {}",
            kind.name(),
            order.map_or("n/a".to_owned(), |p| format!("{p:.2}"))
        );
        for (key, rows) in [("rows", &entry.rows), ("contact_rows", &entry.contact_rows)] {
            for r in rows {
                println!(
                    "  {:<12} dt {:6.3} ms  error {:>10}  {:8.4} s/s{}",
                    key,
                    r.dt_s * 1e3,
                    r.error.map_or("-".to_owned(), |e| format!("{e:.3e}")),
                    r.seconds_per_simulated_second,
                    if r.stable { "" } else { "  unstable" }
                );
            }
        }
        integrators.insert(kind.name(), entry);
    }
    let collision = collision_json(&dir);
    let mut report = WpReport {
        integrators,
        setup: WpSetup {
            mesh: "newell_teaspoon.stl",
            mass_kg: MASS_KG,
            duration_s: DURATION_S,
            hand: "analytic hand motion of the free-space study (xtask/src/study/free_space/motion.rs, hand_at), evaluated at the integrators' stage times",
            coupling: "CouplingParams::default()",
            reference: format!("rk4 at dt = {REFERENCE_DT_S} s"),
            error: format!(
                "max over samples every {SAMPLE_S} s of |x - x_ref| + {LEVER_M} m * angle(q, q_ref), in m"
            ),
            stable: format!(
                "every step succeeds with a finite state and error < {UNSTABLE_ERROR_M} m"
            ),
            cost: format!("wall time of the run per simulated second, best of {repeats}"),
            order_observed: format!(
                "least-squares slope of log error against log dt over the stable free-space rows with error > {ROUNDOFF_M} m"
            ),
            contact: format!(
                "linearized penalty wrench (PenaltyParams::default, eq. 42) of {} fixed representatives on the spoon's underside, each {} m deep in a table with normal +z, linearized once at the start state and held for the run",
                s.table_points_body_m.len(),
                TABLE_DEPTH_M
            ),
            contact_points_body_m: s
                .table_points_body_m
                .iter()
                .map(|p| [p.x, p.y, p.z])
                .collect(),
            steps_ms: steps_ms.to_vec(),
            quick: args.quick,
        },
        collision: None,
    };
    if let Some((path, value)) = &collision {
        report.collision = Some(CollisionCurves {
            source: path.display().to_string(),
            results: value.clone(),
        });
        let rows = value["rows"].as_array().cloned().unwrap_or_default();
        let mut curves = Vec::new();
        for backend in ["lod", "parry"] {
            let points: Vec<(Real, Real)> = rows
                .iter()
                .filter(|r| r["backend"] == backend)
                .filter_map(|r| {
                    let t = r["median_s"].as_f64()?;
                    let e = r["wrench_error_rel_median"].as_f64()?;
                    (t > 0.0 && e > 0.0).then_some((t * 1e3, e))
                })
                .collect();
            if !points.is_empty() {
                curves.push(Series::new(backend, points));
            }
        }
        if !curves.is_empty() {
            line_chart(
                &dir.join("work-precision-collision.svg"),
                &Chart {
                    title: "Collision back-ends: wrench error against query time (from collision.json)",
                    x_label: "median query time (ms)",
                    y_label: "median relative wrench error",
                    x_scale: Scale::Log,
                    y_scale: Scale::Log,
                },
                &curves,
            )?;
        }
        println!("collision curves from {}", path.display());
    } else {
        println!("no collision.json found: run `cargo xtask bench collision` for those curves");
    }
    common::write_json(&dir.join("work-precision.json"), &report)?;
    line_chart(
        &dir.join("work-precision.svg"),
        &Chart {
            title: "Work-precision: spoon on the coupling, free space and on a table",
            x_label: "wall time per simulated second (s)",
            y_label: "max error against RK4 at 0.01 ms (m)",
            x_scale: Scale::Log,
            y_scale: Scale::Log,
        },
        &series,
    )?;
    Ok(())
}

/// One step size of one integrator.
#[derive(Serialize)]
struct WpRow {
    dt_s: Real,
    error: Option<Real>,
    seconds_per_simulated_second: Real,
    stable: bool,
}

/// One integrator: free space (`rows`) and on the table (`contact_rows`).
#[derive(Serialize, Default)]
struct WpIntegrator {
    rows: Vec<WpRow>,
    contact_rows: Vec<WpRow>,
    order_observed: Option<Real>,
}

/// The set-up, for the record.
#[derive(Serialize)]
struct WpSetup {
    mesh: &'static str,
    mass_kg: Real,
    duration_s: Real,
    hand: &'static str,
    coupling: &'static str,
    reference: String,
    error: String,
    stable: String,
    cost: String,
    order_observed: String,
    contact: String,
    contact_points_body_m: Vec<[Real; 3]>,
    steps_ms: Vec<Real>,
    quick: bool,
}

/// The collision back-ends' curves, passed through from `collision.json` (its own schema).
#[derive(Serialize)]
struct CollisionCurves {
    source: String,
    results: serde_json::Value,
}

/// `work-precision.json`.
#[derive(Serialize)]
struct WpReport {
    integrators: std::collections::BTreeMap<&'static str, WpIntegrator>,
    setup: WpSetup,
    collision: Option<CollisionCurves>,
}
