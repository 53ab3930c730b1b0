//! The coupling's force, torque and Jacobians against finite differences, saturation, grasping
//! and bad input.

use super::*;
use crate::testutil::{FD_RTOL, arb_body, arb_raw_state, column_check, random_unit};
use haptic_core::Twist;
use nalgebra::Vector3;
use proptest::prelude::*;

/// Which range the coupling angle is drawn from.
#[derive(Debug, Clone, Copy)]
enum Angle {
    Any,
    NearZero,
    NearPi,
}

/// A random coupling around a random tool: grasp offset up to 5 cm, device displaced by up
/// to 5 cm from the coupling point, rotated by an angle from `angle`, moving at up to 1 m/s
/// and 10 rad/s; saturation (1..10 N, 0.05..0.5 N m) in half of the cases.
fn arb_case(
    angle: Angle,
) -> impl Strategy<Value = (RigidBody, StateVector, VirtualCoupling, ToolState)> {
    (
        arb_body(),
        arb_raw_state(),
        (
            prop::array::uniform3(-0.05..0.05f64),
            prop::array::uniform4(-1.0..1.0f64),
            prop::array::uniform3(-0.05..0.05f64),
            prop::array::uniform3(-1.0..1.0f64),
            0.0..1.0f64,
        ),
        (
            prop::array::uniform3(-1.0..1.0f64),
            prop::array::uniform3(-10.0..10.0f64),
            any::<bool>(),
            1.0..10.0f64,
            0.05..0.5f64,
            0.1..0.9f64,
        ),
    )
        .prop_map(
            move |(body, raw, (rc, qc, dx, axis, a), (vh, wh, sat, fmax, tmax, alpha))| {
                let y = raw.state_vector(&body);
                let tool = ToolState::from_vector_normalized(&y).expect("finite");
                let grasp = Grasp::from_parts(Vector3::from(rc), random_unit(&qc)).expect("finite");
                let axis = Vector3::from(axis);
                let axis = if axis.norm() < 1e-3 {
                    Vec3::x()
                } else {
                    axis.normalize()
                };
                let theta = match angle {
                    Angle::Any => a * (std::f64::consts::PI - 2e-3),
                    // 0 in 10 % of the cases, else log-uniform in [1e-8, 3e-2] rad: both
                    // sides of the switch between series and closed form (θ ≈ 0.02 rad).
                    Angle::NearZero => {
                        if a < 0.1 {
                            0.0
                        } else {
                            10f64.powf(-8.0 + 6.5 * (a - 0.1) / 0.9)
                        }
                    }
                    Angle::NearPi => std::f64::consts::PI - 1e-3 - a * 1e-2,
                };
                let coupled = tool.q * grasp.q_c;
                let q_h = UnitQuaternion::from_scaled_axis(axis * theta) * coupled;
                let x_h = tool.x + tool.q * grasp.r_c + Vector3::from(dx);
                let device = DeviceState {
                    pose: Pose {
                        position: x_h,
                        orientation: q_h,
                    },
                    twist: Twist {
                        linear: Vector3::from(vh),
                        angular: Vector3::from(wh),
                    },
                    buttons: 0,
                    timestamp_s: 0.0,
                };
                let saturation = sat
                    .then(|| Saturation::with_linear_fraction(fmax, tmax, alpha).expect("valid"));
                let params = CouplingParams::default().with_saturation(saturation);
                let coupling = VirtualCoupling::new(params, grasp, &device).expect("valid");
                (body, y, coupling, tool)
            },
        )
}

fn check_coupling(
    body: &RigidBody,
    y: &StateVector,
    coupling: &VirtualCoupling,
) -> Result<(), String> {
    let kin = Kinematics::new(body, y);
    let mut j = WrenchJacobian::zeros();
    coupling.evaluate(body, y, &kin, Some(&mut j));
    let m = body.mass_kg();
    let eval = |yy: &StateVector| {
        let k = Kinematics::new(body, yy);
        coupling.evaluate(body, yy, &k, None)
    };
    let jf = j.fixed_rows::<3>(0).into_owned();
    column_check(&jf, y, m, |yy| eval(yy).force).map_err(|e| format!("force: {e}"))?;
    let jt = j.fixed_rows::<3>(3).into_owned();
    column_check(&jt, y, m, |yy| eval(yy).torque).map_err(|e| format!("torque: {e}"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Force and torque Jacobians (eqs. 17–25, 27) at any coupling angle.
    #[test]
    fn coupling_jacobian_matches_fd((body, y, c, _) in arb_case(Angle::Any)) {
        let r = check_coupling(&body, &y, &c);
        prop_assert!(r.is_ok(), "{}", r.unwrap_err());
    }

    /// θu near θ = 0 (including exactly 0), where the series form is used.
    #[test]
    fn coupling_jacobian_matches_fd_near_zero((body, y, c, _) in arb_case(Angle::NearZero)) {
        let r = check_coupling(&body, &y, &c);
        prop_assert!(r.is_ok(), "{}", r.unwrap_err());
    }

    /// θu near θ = π (π - 1.1e-2 .. π - 1e-3).
    #[test]
    fn coupling_jacobian_matches_fd_near_pi((body, y, c, _) in arb_case(Angle::NearPi)) {
        let r = check_coupling(&body, &y, &c);
        prop_assert!(r.is_ok(), "{}", r.unwrap_err());
    }

    /// The saturation spline (eqs. 26–27): magnitude slope and vector Jacobian.
    #[test]
    fn saturation_spline_matches_fd(
        k in 1.0..1000.0f64,
        max in 0.1..10.0f64,
        alpha in 0.05..0.95f64,
        u in 0.0..3.0f64,
        dir in prop::array::uniform3(-1.0..1.0f64),
    ) {
        let s = SplineSpring::saturated(k, max, alpha).unwrap();
        let (_, d2) = s.knees();
        let d = u * d2;
        let h = 1e-6 * d2;
        prop_assume!(d > h);
        let (f, df) = s.magnitude(d);
        let fd = (s.magnitude(d + h).0 - s.magnitude(d - h).0) / (2.0 * h);
        prop_assert!((df - fd).abs() <= FD_RTOL * k + 1e-12, "{df} vs {fd}");
        prop_assert!(f <= max * (1.0 + 1e-12) && f >= 0.0);
        let dir = Vector3::from(dir);
        prop_assume!(dir.norm() > 1e-2);
        let e = dir.normalize() * d;
        let (_, jac) = s.vector(&e);
        for c in 0..3 {
            let mut ep = e;
            let mut em = e;
            ep[c] += h;
            em[c] -= h;
            let fdc = (s.vector(&ep).0 - s.vector(&em).0) / (2.0 * h);
            let an = jac.column(c).into_owned();
            prop_assert!((an - fdc).norm() <= FD_RTOL * k + 1e-12, "col {c}: {an} vs {fdc}");
        }
    }
}

#[test]
fn spline_is_c1_monotone_and_flat() {
    let s = SplineSpring::saturated(200.0, 3.0, 0.8).unwrap();
    let (d1, d2) = s.knees();
    assert!((d1 - 0.012).abs() < 1e-15 && (d2 - 0.018).abs() < 1e-15);
    for d in [d1, d2] {
        let (fl, dl) = s.magnitude(d - 1e-12);
        let (fr, dr) = s.magnitude(d + 1e-12);
        assert!(
            (fl - fr).abs() < 1e-9 && (dl - dr).abs() < 1e-6,
            "{d}: {fl} {fr} {dl} {dr}"
        );
    }
    let mut last = 0.0;
    for i in 0..=400 {
        let (f, df) = s.magnitude(i as f64 * 1e-4);
        assert!(f >= last - 1e-15 && df >= -1e-12 && f <= 3.0 + 1e-12);
        last = f;
    }
    assert_eq!(s.magnitude(1.0), (3.0, 0.0));
    // Linear region is exactly k e.
    let (v, _) = s.vector(&Vec3::new(0.001, 0.0, 0.0));
    assert!((v.x - 0.2).abs() < 1e-15);
}

fn still_tool() -> (RigidBody, ToolState, DeviceState) {
    let body = RigidBody::from_principal(0.05, [1e-5, 2e-5, 2.5e-5]).unwrap();
    let tool = ToolState::at_rest(&Pose {
        position: Vec3::new(0.1, 0.0, 0.2),
        orientation: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
    });
    let handle = Pose {
        position: Vec3::new(0.1, -0.03, 0.21),
        orientation: UnitQuaternion::from_euler_angles(0.0, 0.5, 0.0),
    };
    (body, tool, DeviceState::at_rest(handle, 0.0))
}

#[test]
fn grasp_gives_zero_wrench_and_reaction_opposes_the_pull() {
    let (body, tool, device) = still_tool();
    let mut c = VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
    let w = c.wrench_on_tool(&body, &tool);
    assert!(w.force.norm() < 1e-12 && w.torque.norm() < 1e-12, "{w:?}");
    let dev = c.deviation(&tool);
    assert!(dev.translation_m < 1e-15 && dev.angle_rad < 1e-7);
    // Move the handle 1 cm along +x and turn it 0.1 rad about z.
    let mut moved = device;
    moved.pose.position.x += 0.01;
    moved.pose.orientation =
        UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 0.1) * moved.pose.orientation;
    c.set_device(&moved).unwrap();
    let w = c.wrench_on_tool(&body, &tool);
    assert!(
        (w.force - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-12,
        "{:?}",
        w.force
    );
    let r = tool.q * c.grasp().r_c;
    let rot = w.torque - r.cross(&w.force);
    assert!((rot - Vec3::new(0.0, 0.0, 0.06)).norm() < 1e-12, "{rot}");
    let react = c.device_reaction(&body, &tool);
    assert!((react.force + w.force).norm() < 1e-15);
    assert!((react.torque + rot).norm() < 1e-15);
    let dev = c.deviation(&tool);
    assert!((dev.translation_m - 0.01).abs() < 1e-15 && (dev.angle_rad - 0.1).abs() < 1e-12);
    let placed = c.tool_at_handle();
    let dev = c.deviation(&placed);
    assert!(dev.translation_m < 1e-15 && dev.angle_rad < 1e-7, "{dev:?}");
    assert!(c.wrench_on_tool(&body, &placed).force.norm() < 1e-12);
}

#[test]
fn saturated_coupling_caps_the_force() {
    let (body, tool, device) = still_tool();
    let sat = Saturation::new(3.0, 0.2).unwrap();
    let params = CouplingParams::default().with_saturation(Some(sat));
    let mut c = VirtualCoupling::grasping(params, &tool, &device).unwrap();
    let mut far = device;
    far.pose.position.y += 0.5;
    far.pose.orientation =
        UnitQuaternion::from_axis_angle(&Vec3::x_axis(), 2.0) * far.pose.orientation;
    c.set_device(&far).unwrap();
    let react = c.device_reaction(&body, &tool);
    assert!((react.force.norm() - 3.0).abs() < 1e-12);
    assert!((react.torque.norm() - 0.2).abs() < 1e-12);
}

#[test]
fn bad_device_input_is_a_typed_error_and_keeps_the_old_reading() {
    let (_, tool, device) = still_tool();
    let mut c = VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
    let mut bad = device;
    bad.pose.position.y = Real::NAN;
    assert!(matches!(
        c.set_device(&bad),
        Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
            what: "device pose"
        }))
    ));
    assert_eq!(c.device(), &device);
    let mut bad = device;
    bad.twist.angular.z = Real::INFINITY;
    assert!(matches!(
        c.set_device(&bad),
        Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
            what: "device twist"
        }))
    ));
    let mut bad = device;
    bad.pose.orientation =
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0));
    assert!(matches!(
        c.set_device(&bad),
        Err(DynamicsError::Core(
            haptic_core::CoreError::NonUnitQuaternion { .. }
        ))
    ));
    let mut bad = device;
    bad.pose.orientation =
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(Real::NAN, 0.0, 0.0, 0.0));
    assert!(matches!(
        VirtualCoupling::grasping(CouplingParams::default(), &tool, &bad),
        Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
            what: "device pose"
        }))
    ));
}

#[test]
fn parameters_are_validated() {
    assert!(matches!(
        CouplingParams::new(0.0, 1.0, 0.6, 0.0),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "coupling.stiffness_n_per_m",
            ..
        }))
    ));
    assert!(matches!(
        CouplingParams::new(200.0, -1.0, 0.6, 0.0),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "coupling.damping_ns_per_m",
            ..
        }))
    ));
    assert!(matches!(
        CouplingParams::new(200.0, 1.0, Real::NAN, 0.0),
        Err(DynamicsError::Core(haptic_core::CoreError::NonFinite {
            what: "coupling.angular_stiffness_nm_per_rad"
        }))
    ));
    assert!(matches!(
        CouplingParams::new(200.0, 1.0, 0.6, -1e-3),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "coupling.angular_damping_nms_per_rad",
            ..
        }))
    ));
    assert!(matches!(
        Saturation::new(0.0, 1.0),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "saturation.max_force_n",
            ..
        }))
    ));
    assert!(matches!(
        Saturation::with_linear_fraction(1.0, 1.0, 1.0),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "saturation.linear_fraction",
            ..
        }))
    ));
    let p = CouplingParams::default().with_saturation(Some(Saturation {
        max_force_n: 1.0,
        max_torque_nm: -1.0,
        linear_fraction: 0.5,
    }));
    let (_, tool, device) = still_tool();
    assert!(matches!(
        VirtualCoupling::grasping(p, &tool, &device),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "saturation.max_torque_nm",
            ..
        }))
    ));
    let d = CouplingParams::default();
    assert_eq!(
        (d.stiffness_n_per_m, d.angular_stiffness_nm_per_rad),
        (200.0, 0.6)
    );
    assert!(d.validate().is_ok());
}
