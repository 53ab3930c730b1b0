//! One run of the free-space study: the spoon of one mass on the coupling, following the hand,
//! and the verdict on it.
//!
//! The verdict keeps two questions apart (see `docs/decisions.md`, "free-space verdict"):
//! - **Stable** (no divergence): every step succeeds with a finite state, the coupling
//!   deviation never runs away (`|e| <= 1 m`), and the coupling energy is not growing (its
//!   maximum over the last fifth of the motion is at most 10 times its maximum before).
//! - **Tracks** (the tool follows the hand): the deviation stays within `0.1 m` and `π/2`. A heavy
//!   tool on a soft coupling lags a fast hand by more, physically, whatever the integrator: that
//!   is a large but bounded deviation, not an instability.

use haptic_core::{DeviceState, Kinematics, Mat3, Pose, Real, RigidBody, ToolState, Vec3};
use haptic_dynamics::{CouplingParams, HapticForces, IntegratorKind, VirtualCoupling};
use serde::Serialize;

use super::RATE_HZ;

/// Where the coupling grasps the spoon, in its body frame (m): on the handle, 3.5 cm from the
/// centre of mass.
pub(crate) const GRASP_BODY_M: [Real; 3] = [0.0, -0.035, 0.0];
/// Deviation beyond which a run has run away (m).
const RUNAWAY_DEVIATION_M: Real = 1.0;
/// Deviation within which the tool tracks the hand (m).
const TRACKING_DEVIATION_M: Real = 0.1;
/// Angle within which the tool tracks the hand (rad).
const TRACKING_ANGLE_RAD: Real = std::f64::consts::FRAC_PI_2;
/// Largest ratio of the coupling energy's maximum in the last fifth of the motion to its
/// maximum before.
const ENERGY_GROWTH_LIMIT: Real = 10.0;
/// The share of the motion at its end whose energy is compared with the rest.
const ENERGY_TAIL_FRACTION: Real = 0.2;
/// The energy before the tail is counted as at least the coupling's at this deviation (m)...
const TRACKING_FLOOR_M: Real = 1e-3;
/// ... and this angle (rad).
const TRACKING_FLOOR_RAD: Real = 1e-2;

/// The rule that made a run unstable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Divergence {
    /// An integration step failed (a singular system, a non-finite state).
    StepFailed,
    /// The deviation, force, torque or energy became NaN or infinite.
    NonFinite,
    /// The coupling deviation passed [`RUNAWAY_DEVIATION_M`].
    RunawayDeviation,
    /// The coupling energy grew by more than [`ENERGY_GROWTH_LIMIT`].
    EnergyGrowth,
}

/// The tracking bound a stable run went beyond.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Lag {
    /// `|e| > 0.1 m`.
    Deviation,
    /// `θ > π/2`.
    Angle,
}

/// What one run measured.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct RunResult {
    /// No divergence.
    pub(crate) stable: bool,
    /// The rule that failed, if the run diverged.
    pub(crate) divergence: Option<Divergence>,
    /// In words, with the step.
    pub(crate) divergence_detail: Option<String>,
    /// The tracking bound exceeded, if any (a stable run may lag).
    pub(crate) lag: Option<Lag>,
    pub(crate) steps_completed: usize,
    pub(crate) rms_deviation_m: Real,
    pub(crate) max_deviation_m: Real,
    pub(crate) rms_angle_rad: Real,
    pub(crate) max_angle_rad: Real,
    pub(crate) rms_force_n: Real,
    pub(crate) max_force_n: Real,
    pub(crate) rms_torque_nm: Real,
    pub(crate) max_torque_nm: Real,
    /// Mean wall time of one integrator step, µs.
    pub(crate) mean_step_us: Real,
    /// Per step: (t, deviation m, |force| N), when asked for.
    #[serde(skip)]
    pub(crate) trace: Vec<(Real, Real, Real)>,
}

/// The coupling energy (J) of the tool in state `tool` against the handle `device`: the springs'
/// potential plus the tool's kinetic energy relative to the handle,
/// `½ k |e|² + ½ k_θ θ² + ½ m |v + ω × r - v_h|² + ½ (ω - ω_h)ᵀ I_w (ω - ω_h)`.
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

/// Simulates the spoon of `mass_kg` (inertia `inertia_per_kg · mass_kg`) following `traj` with
/// integrator `kind`, as the haptic loop does: read the device, step, compute the feedback with
/// the new state.
pub(crate) fn simulate(
    kind: IntegratorKind,
    inertia_per_kg: &Mat3,
    params: &CouplingParams,
    mass_kg: Real,
    traj: &[DeviceState],
    keep_trace: bool,
) -> anyhow::Result<RunResult> {
    let body = RigidBody::new(mass_kg, inertia_per_kg * mass_kg)?;
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
        divergence: None,
        divergence_detail: None,
        lag: None,
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
    let steps = traj.len() - 1;
    let tail_from_s = (1.0 - ENERGY_TAIL_FRACTION) * steps as Real * h;
    let mut step_time = std::time::Duration::ZERO;
    let (mut s_dev, mut s_ang, mut s_f, mut s_t) = (0.0, 0.0, 0.0, 0.0);
    let (mut e_head, mut e_tail) = (0.0_f64, 0.0_f64);
    let diverge = |res: &mut RunResult, rule, detail: String| {
        res.divergence = Some(rule);
        res.divergence_detail = Some(detail);
    };
    for (n, device) in traj.iter().take(steps).enumerate() {
        let t = n as Real * h;
        forces.coupling.set_device(device)?;
        let clock = std::time::Instant::now();
        let stepped = integ.step(&body, &tool, t, h, &mut forces);
        step_time += clock.elapsed();
        match stepped {
            Ok(next) => tool = next,
            Err(e) => {
                diverge(&mut res, Divergence::StepFailed, format!("step {n}: {e}"));
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
            diverge(
                &mut res,
                Divergence::NonFinite,
                format!("step {n}: non-finite output"),
            );
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
        if t + h <= tail_from_s + 1e-9 {
            e_head = e_head.max(energy);
        } else {
            e_tail = e_tail.max(energy);
        }
        if keep_trace {
            res.trace.push((t + h, dev.translation_m, f));
        }
        if dev.translation_m > RUNAWAY_DEVIATION_M {
            diverge(
                &mut res,
                Divergence::RunawayDeviation,
                format!("step {n}: coupling deviation {:.3} m", dev.translation_m),
            );
            break;
        }
    }
    let k = res.steps_completed.max(1) as Real;
    res.rms_deviation_m = (s_dev / k).sqrt();
    res.rms_angle_rad = (s_ang / k).sqrt();
    res.rms_force_n = (s_f / k).sqrt();
    res.rms_torque_nm = (s_t / k).sqrt();
    res.mean_step_us = step_time.as_secs_f64() * 1e6 / k;
    // The floor: the coupling energy of a tool tracking within 1 mm and 0.01 rad, or the kinetic
    // energy of a tool moving with the hand at its fastest, whichever is larger; so that a hand at
    // rest before it moves (energy ≈ 0 at the start) does not read as growth.
    let i_max = body.inertia_body().symmetric_eigenvalues().max();
    let hand_kinetic_j = traj.iter().fold(0.0_f64, |e, d| {
        e.max(
            0.5 * mass_kg * d.twist.linear.norm_squared()
                + 0.5 * i_max * d.twist.angular.norm_squared(),
        )
    });
    let floor_j = (0.5 * params.stiffness_n_per_m * TRACKING_FLOOR_M.powi(2)
        + 0.5 * params.angular_stiffness_nm_per_rad * TRACKING_FLOOR_RAD.powi(2))
    .max(hand_kinetic_j);
    if res.divergence.is_none() && e_tail > ENERGY_GROWTH_LIMIT * e_head.max(floor_j) {
        diverge(
            &mut res,
            Divergence::EnergyGrowth,
            format!(
                "coupling energy growing: max {e_tail:.3e} J at the end vs {e_head:.3e} J before"
            ),
        );
    }
    res.stable = res.divergence.is_none();
    if res.max_deviation_m > TRACKING_DEVIATION_M {
        res.lag = Some(Lag::Deviation);
    } else if res.max_angle_rad > TRACKING_ANGLE_RAD {
        res.lag = Some(Lag::Angle);
    }
    Ok(res)
}

/// The rules in words, for the report and the JSON.
pub(crate) fn rules() -> String {
    format!(
        "stable: every step succeeds with a finite state, the coupling deviation stays within \
         {RUNAWAY_DEVIATION_M} m, and the coupling energy's maximum over the last {:.0} % of the \
         motion is at most {ENERGY_GROWTH_LIMIT} x its maximum before (counted as at least the \
         energy of a {TRACKING_FLOOR_M} m, {TRACKING_FLOOR_RAD} rad deviation, and at least the \
         kinetic energy of the tool moving with the hand at its fastest); tracks: deviation within \
         {TRACKING_DEVIATION_M} m and angle within pi/2 (a stable run may lag beyond them)",
        100.0 * ENERGY_TAIL_FRACTION
    )
}

/// The smallest mass such that it and every heavier mass of the sweep are stable.
pub(crate) fn min_stable_mass(rows: &[(Real, bool)]) -> Option<Real> {
    let mut best = None;
    for &(m, stable) in rows.iter().rev() {
        if !stable {
            break;
        }
        best = Some(m);
    }
    best
}

/// The contiguous ranges `[lightest, heaviest]` of stable masses in the sweep.
pub(crate) fn stable_ranges(rows: &[(Real, bool)]) -> Vec<[Real; 2]> {
    let mut out: Vec<[Real; 2]> = Vec::new();
    let mut open = false;
    for &(m, stable) in rows {
        match (stable, open) {
            (true, true) => out.last_mut().expect("an open range")[1] = m,
            (true, false) => {
                out.push([m, m]);
                open = true;
            }
            (false, _) => open = false,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn min_stable_mass_needs_every_heavier_mass_stable() {
        let rows = [(1.0, true), (2.0, false), (3.0, true), (4.0, true)];
        assert_eq!(min_stable_mass(&rows), Some(3.0));
        assert_eq!(min_stable_mass(&[(1.0, true), (2.0, false)]), None);
        assert_eq!(stable_ranges(&rows), vec![[1.0, 1.0], [3.0, 4.0]]);
        assert_eq!(stable_ranges(&[(1.0, false)]), Vec::<[Real; 2]>::new());
    }

    /// A hand at rest until the last fifth of the motion, then moving: the energy before is about
    /// zero, which must not read as growth.
    #[test]
    fn a_hand_that_starts_late_is_not_energy_growth() {
        let traj: Vec<DeviceState> = (0..=1000)
            .map(|n| {
                let t = n as Real / RATE_HZ;
                let s = ((t - 0.8) / 0.2).clamp(0.0, 1.0);
                let (p, dp, _) = haptic_device::min_jerk(s);
                let mut d =
                    DeviceState::at_rest(Pose::from_position(Vec3::new(0.05 * p, 0.0, 0.0)), t);
                d.twist.linear.x = 0.05 * dp / 0.2;
                d
            })
            .collect();
        let inertia = Mat3::from_diagonal(&Vec3::new(4e-3, 1e-4, 4e-3));
        for kind in [IntegratorKind::LinearizedBackwardEuler, IntegratorKind::Rk4] {
            let r = simulate(
                kind,
                &inertia,
                &CouplingParams::default(),
                0.1,
                &traj,
                false,
            )
            .unwrap();
            assert!(r.stable, "{kind}: {:?}", r.divergence_detail);
        }
    }

    /// A fast turn (3 rad back and forth twice a second, 19 rad/s peak) that a heavy, long tool
    /// on the default coupling cannot follow within π/2: the run lags, and is still stable; a
    /// light tool with forward Euler diverges.
    #[test]
    fn a_lagging_heavy_tool_is_stable_and_a_light_explicit_one_is_not() {
        let turn = |t: Real| {
            // Two back-and-forth turns a second.
            let a = 0.5 * (1.0 - (2.0 * TAU * t).cos());
            let w = TAU * (2.0 * TAU * t).sin();
            (a, w)
        };
        // About a tilted axis, so that every axis of the tool is excited.
        let axis = nalgebra::Unit::new_normalize(Vec3::new(0.3, 0.2, 1.0));
        let traj: Vec<DeviceState> = (0..=1500)
            .map(|n| {
                let t = n as Real / RATE_HZ;
                let (a, w) = turn(t);
                let mut d = DeviceState::at_rest(
                    Pose {
                        position: Vec3::new(0.05 * a, 0.0, 0.0),
                        orientation: nalgebra::UnitQuaternion::from_axis_angle(&axis, 3.0 * a),
                    },
                    t,
                );
                d.twist.linear.x = 0.05 * w;
                d.twist.angular = axis.into_inner() * (3.0 * w);
                d
            })
            .collect();
        let inertia = Mat3::from_diagonal(&Vec3::new(1e-2, 2e-5, 1e-2)); // a 35 cm rod, per kg
        let heavy = simulate(
            IntegratorKind::LinearizedBackwardEuler,
            &inertia,
            &CouplingParams::default(),
            0.5,
            &traj,
            false,
        )
        .unwrap();
        assert!(heavy.stable, "{:?}", heavy.divergence_detail);
        assert!(heavy.lag.is_some() && heavy.max_angle_rad > TRACKING_ANGLE_RAD);
        let light = simulate(
            IntegratorKind::ForwardEuler,
            &inertia,
            &CouplingParams::default(),
            1e-3,
            &traj,
            false,
        )
        .unwrap();
        assert!(!light.stable);
        assert!(light.divergence.is_some());
    }
}
