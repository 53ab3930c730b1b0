//! Integrator properties: no Jacobians for explicit methods, conservation of angular momentum,
//! observed order of accuracy, unit quaternions, and typed errors for bad input.

use std::f64::consts::PI;

use haptic_core::{
    DeviceState, ForceModel, IntegrationError, Integrator, Kinematics, Pose, Real, RigidBody,
    StateVector, ToolState, Twist, Vec3, Wrench, WrenchJacobian,
};
use haptic_dynamics::{
    CouplingParams, DynamicsError, ForwardEuler, IntegratorKind, LinearizedBackwardEuler,
    NewtonBackwardEuler, Rk4, VirtualCoupling,
};
use nalgebra::UnitQuaternion;

/// Wraps a force model and counts how often each method is called.
struct Counting<F> {
    inner: F,
    wrench_calls: usize,
    jacobian_calls: usize,
}

impl<F: ForceModel> ForceModel for Counting<F> {
    fn wrench(&mut self, body: &RigidBody, t: Real, y: &StateVector, kin: &Kinematics) -> Wrench {
        self.wrench_calls += 1;
        self.inner.wrench(body, t, y, kin)
    }
    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t: Real,
        y: &StateVector,
        kin: &Kinematics,
        j: &mut WrenchJacobian,
    ) -> Wrench {
        self.jacobian_calls += 1;
        self.inner.wrench_and_jacobian(body, t, y, kin, j)
    }
}

fn all_integrators() -> Vec<Box<dyn Integrator + Send>> {
    let mut v: Vec<Box<dyn Integrator + Send>> =
        IntegratorKind::ALL.iter().map(|k| k.boxed()).collect();
    v[1] = Box::new(NewtonBackwardEuler::new(1e-13, 30).unwrap());
    v
}

/// An asymmetric tool (moments 1:2:2.6 about tilted axes).
fn asymmetric_body(mass_kg: Real) -> RigidBody {
    let r = UnitQuaternion::from_euler_angles(0.4, -0.3, 0.9)
        .to_rotation_matrix()
        .into_inner();
    let d = haptic_core::Mat3::from_diagonal(&Vec3::new(1.0e-3, 2.0e-3, 2.6e-3));
    RigidBody::new(mass_kg, r * d * r.transpose() * mass_kg).unwrap()
}

/// A smooth hand motion: 2 cm / 1.5 Hz sway, turning about z and x.
fn device_at(t: Real) -> DeviceState {
    let (wx, wa, wc) = (2.0 * PI * 1.5, 2.0 * PI * 1.1, 2.0 * PI * 0.7);
    let position = Vec3::new(
        0.02 * (wx * t).sin(),
        0.01 * (wa * t).cos(),
        0.015 * (wc * t).sin(),
    );
    let linear = Vec3::new(
        0.02 * wx * (wx * t).cos(),
        -0.01 * wa * (wa * t).sin(),
        0.015 * wc * (wc * t).cos(),
    );
    let (a, da) = (0.6 * (wa * t).sin(), 0.6 * wa * (wa * t).cos());
    let (c, dc) = (0.4 * (wc * t).sin(), 0.4 * wc * (wc * t).cos());
    let rz = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), a);
    let rx = UnitQuaternion::from_axis_angle(&Vec3::x_axis(), c);
    let angular = Vec3::z() * da + rz * (Vec3::x() * dc);
    DeviceState {
        pose: Pose {
            position,
            orientation: rz * rx,
        },
        twist: Twist { linear, angular },
        buttons: 0,
        timestamp_s: t,
    }
}

/// The coupling with a device that moves smoothly in time (the device is read at the stage
/// times, unlike the haptic loop's zero-order hold, so the problem is smooth in t).
struct MovingDevice(VirtualCoupling);

impl ForceModel for MovingDevice {
    fn wrench(&mut self, body: &RigidBody, t: Real, y: &StateVector, kin: &Kinematics) -> Wrench {
        self.0.set_device(&device_at(t)).unwrap();
        self.0.evaluate(body, y, kin, None)
    }
    fn wrench_and_jacobian(
        &mut self,
        body: &RigidBody,
        t: Real,
        y: &StateVector,
        kin: &Kinematics,
        j: &mut WrenchJacobian,
    ) -> Wrench {
        self.0.set_device(&device_at(t)).unwrap();
        self.0.evaluate(body, y, kin, Some(j))
    }
}

/// The tool starts 1 cm and 0.3 rad off the handle, grasped 3 cm from its centre of mass.
fn coupled_start() -> (ToolState, MovingDevice) {
    let d0 = device_at(0.0);
    let grasp_tool = ToolState::at_rest(&Pose {
        position: d0.pose.position - Vec3::new(0.0, -0.03, 0.0),
        orientation: d0.pose.orientation,
    });
    let coupling = VirtualCoupling::grasping(CouplingParams::default(), &grasp_tool, &d0).unwrap();
    let start = ToolState::at_rest(&Pose {
        position: grasp_tool.x + Vec3::new(0.01, 0.0, -0.005),
        orientation: UnitQuaternion::from_axis_angle(&Vec3::y_axis(), 0.3) * grasp_tool.q,
    });
    (start, MovingDevice(coupling))
}

fn run(
    integ: &mut dyn Integrator,
    body: &RigidBody,
    start: &ToolState,
    forces: &mut dyn ForceModel,
    t_end: Real,
    n: usize,
) -> ToolState {
    let h = t_end / n as Real;
    let mut s = *start;
    for i in 0..n {
        s = integ.step(body, &s, i as Real * h, h, forces).unwrap();
        let norm = s.q.coords.norm();
        assert!(
            (norm - 1.0).abs() <= 1e-12,
            "{}: |q| = {norm}",
            integ.name()
        );
    }
    s
}

#[test]
fn explicit_integrators_never_ask_for_a_jacobian() {
    let body = asymmetric_body(0.05);
    let (start, moving) = coupled_start();
    let mut counting = Counting {
        inner: moving,
        wrench_calls: 0,
        jacobian_calls: 0,
    };
    let expected = [
        (IntegratorKind::ForwardEuler, 1, 0),
        (IntegratorKind::Rk4, 4, 0),
        (IntegratorKind::LinearizedBackwardEuler, 0, 1),
    ];
    for (kind, wrenches, jacobians) in expected {
        let mut integ = kind.boxed();
        assert_eq!(integ.uses_jacobian(), kind.is_implicit());
        counting.wrench_calls = 0;
        counting.jacobian_calls = 0;
        run(integ.as_mut(), &body, &start, &mut counting, 0.1, 100);
        assert_eq!(counting.wrench_calls, 100 * wrenches, "{kind}");
        assert_eq!(counting.jacobian_calls, 100 * jacobians, "{kind}");
    }
    counting.wrench_calls = 0;
    counting.jacobian_calls = 0;
    let mut newton = NewtonBackwardEuler::default();
    run(&mut newton, &body, &start, &mut counting, 0.1, 100);
    assert_eq!(counting.wrench_calls, 0);
    assert!(counting.jacobian_calls >= 100);
}

#[test]
fn torque_free_asymmetric_body_conserves_world_angular_momentum() {
    let body = asymmetric_body(0.1);
    let omega0 = Vec3::new(8.0, 0.5, 3.0);
    let q0 = UnitQuaternion::from_euler_angles(0.2, 0.1, -0.4);
    let r0 = q0.to_rotation_matrix().into_inner();
    let l0 = r0 * body.inertia_body() * r0.transpose() * omega0;
    let start = ToolState::new(
        Vec3::zeros(),
        *q0.quaternion(),
        Vec3::new(0.01, 0.0, 0.0),
        l0,
    )
    .unwrap();
    for mut integ in all_integrators() {
        let mut s = start;
        let mut min_cos = 1.0_f64;
        for i in 0..1000 {
            s = integ
                .step(&body, &s, i as Real * 1e-3, 1e-3, &mut ())
                .unwrap();
            assert!(
                (s.l - l0).norm() <= 1e-12 * l0.norm(),
                "{}: {} vs {l0}",
                integ.name(),
                s.l
            );
            assert!((s.q.coords.norm() - 1.0).abs() <= 1e-12);
            let w = s.angular_velocity(&body);
            min_cos = min_cos.min(w.normalize().dot(&omega0.normalize()));
        }
        // Not vacuous: the body tumbles (ω turns away from its initial direction).
        assert!(
            min_cos < 0.9,
            "{}: ω barely moved ({min_cos})",
            integ.name()
        );
        assert!(
            (s.x - Vec3::new(0.1, 0.0, 0.0)).norm() < 1e-12,
            "{}",
            integ.name()
        );
    }
}

/// Error at t = 0.25 s of the coupled tool against a fine RK4 reference, position in cm plus
/// quaternion distance.
fn error_against(reference: &ToolState, s: &ToolState) -> Real {
    let dq = if reference.q.coords.dot(&s.q.coords) < 0.0 {
        (reference.q.coords + s.q.coords).norm()
    } else {
        (reference.q.coords - s.q.coords).norm()
    };
    (reference.x - s.x).norm() / 0.01 + dq
}

/// Least-squares slope of log(error) against log(h).
fn observed_order(hs: &[Real], errs: &[Real]) -> Real {
    let xs: Vec<Real> = hs.iter().map(|h| h.ln()).collect();
    let ys: Vec<Real> = errs.iter().map(|e| e.ln()).collect();
    let n = xs.len() as Real;
    let (mx, my) = (xs.iter().sum::<Real>() / n, ys.iter().sum::<Real>() / n);
    let sxy: Real = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: Real = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

#[test]
fn observed_order_of_accuracy() {
    let body = asymmetric_body(0.1);
    let t_end = 0.25;
    let (start, mut forces) = coupled_start();
    let reference = run(&mut Rk4, &body, &start, &mut forces, t_end, 20_000);
    let cases: [(Box<dyn Integrator>, Real, &[usize]); 4] = [
        (Box::new(ForwardEuler), 1.0, &[500, 1000, 2000, 4000]),
        (
            Box::new(LinearizedBackwardEuler),
            1.0,
            &[500, 1000, 2000, 4000],
        ),
        (
            Box::new(NewtonBackwardEuler::new(1e-13, 30).unwrap()),
            1.0,
            &[500, 1000, 2000, 4000],
        ),
        (Box::new(Rk4), 4.0, &[50, 100, 200, 400]),
    ];
    for (mut integ, expected, steps) in cases {
        let hs: Vec<Real> = steps.iter().map(|&n| t_end / n as Real).collect();
        let errs: Vec<Real> = steps
            .iter()
            .map(|&n| {
                let (s0, mut f) = coupled_start();
                error_against(
                    &reference,
                    &run(integ.as_mut(), &body, &s0, &mut f, t_end, n),
                )
            })
            .collect();
        let p = observed_order(&hs, &errs);
        eprintln!("{}: observed order {p:.3}", integ.name());
        assert!(
            (p - expected).abs() <= 0.2,
            "{}: observed order {p:.3}, expected {expected}; errors {errs:?}",
            integ.name()
        );
    }
}

/// A force model that returns what it is told to.
struct Fixed {
    wrench: Wrench,
    jacobian: WrenchJacobian,
}

impl ForceModel for Fixed {
    fn wrench(&mut self, _: &RigidBody, _: Real, _: &StateVector, _: &Kinematics) -> Wrench {
        self.wrench
    }
    fn wrench_and_jacobian(
        &mut self,
        _: &RigidBody,
        _: Real,
        _: &StateVector,
        _: &Kinematics,
        j: &mut WrenchJacobian,
    ) -> Wrench {
        *j = self.jacobian;
        self.wrench
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let body = asymmetric_body(0.01);
    let good = ToolState::at_rest(&Pose::identity());
    for mut integ in all_integrators() {
        for dt in [0.0, -1e-3, Real::NAN, Real::INFINITY] {
            assert!(
                matches!(
                    integ.step(&body, &good, 0.0, dt, &mut ()),
                    Err(IntegrationError::InvalidStep { .. })
                ),
                "{} dt = {dt}",
                integ.name()
            );
        }
        let mut bad = good;
        bad.p.y = Real::NAN;
        assert!(matches!(
            integ.step(&body, &bad, 0.0, 1e-3, &mut ()),
            Err(IntegrationError::NonFiniteInput { .. })
        ));
        let mut nan_force = Fixed {
            wrench: Wrench::new(Vec3::new(Real::NAN, 0.0, 0.0), Vec3::zeros()),
            jacobian: WrenchJacobian::zeros(),
        };
        assert!(matches!(
            integ.step(&body, &good, 0.0, 1e-3, &mut nan_force),
            Err(IntegrationError::NonFiniteForce { what: "wrench" })
        ));
        // Overflow: a finite but absurd force gives an error, not an infinite state.
        let mut huge = Fixed {
            wrench: Wrench::new(Vec3::new(Real::MAX, 0.0, 0.0), Vec3::zeros()),
            jacobian: WrenchJacobian::zeros(),
        };
        assert!(
            matches!(
                integ.step(&body, &good, 0.0, 10.0, &mut huge),
                Err(IntegrationError::NonFiniteState)
            ),
            "{}: {:?}",
            integ.name(),
            integ.step(&body, &good, 0.0, 10.0, &mut huge)
        );
    }
    // NaN in the Jacobian, and a singular I - h J: ∂F/∂P = I/h zeroes the P rows.
    let h = 1e-3;
    let mut nan_jac = Fixed {
        wrench: Wrench::zero(),
        jacobian: WrenchJacobian::zeros(),
    };
    nan_jac.jacobian[(0, 3)] = Real::NAN;
    let mut singular = Fixed {
        wrench: Wrench::zero(),
        jacobian: WrenchJacobian::zeros(),
    };
    for i in 0..3 {
        singular.jacobian[(i, 7 + i)] = 1.0 / h;
    }
    let implicit: [Box<dyn Integrator>; 2] = [
        Box::new(LinearizedBackwardEuler),
        Box::new(NewtonBackwardEuler::default()),
    ];
    for mut integ in implicit {
        assert!(matches!(
            integ.step(&body, &good, 0.0, h, &mut nan_jac),
            Err(IntegrationError::NonFiniteForce { what: "jacobian" })
        ));
        assert!(
            matches!(
                integ.step(&body, &good, 0.0, h, &mut singular),
                Err(IntegrationError::SingularSystem)
            ),
            "{}",
            integ.name()
        );
    }
    // Newton with one iteration and a tolerance it cannot meet on a nonlinear problem.
    let (start, mut forces) = coupled_start();
    let mut newton = NewtonBackwardEuler::new(1e-15, 1).unwrap();
    assert!(matches!(
        newton.step(&asymmetric_body(0.05), &start, 0.0, 1e-3, &mut forces),
        Err(IntegrationError::NotConverged { iterations: 1, .. })
    ));
    assert!(matches!(
        NewtonBackwardEuler::new(0.0, 5),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "newton.tolerance",
            ..
        }))
    ));
    assert!(matches!(
        NewtonBackwardEuler::new(1e-9, 0),
        Err(DynamicsError::Core(haptic_core::CoreError::OutOfRange {
            what: "newton.max_iterations",
            ..
        }))
    ));
}

#[test]
fn integrator_kinds_parse_and_name_themselves() {
    for (s, k) in [
        ("be", IntegratorKind::LinearizedBackwardEuler),
        ("backward_euler", IntegratorKind::LinearizedBackwardEuler),
        (
            "linearized-backward-euler",
            IntegratorKind::LinearizedBackwardEuler,
        ),
        ("newton-be", IntegratorKind::NewtonBackwardEuler),
        ("newton_backward_euler", IntegratorKind::NewtonBackwardEuler),
        ("RK4", IntegratorKind::Rk4),
        ("fe", IntegratorKind::ForwardEuler),
        ("forward-euler", IntegratorKind::ForwardEuler),
    ] {
        assert_eq!(s.parse::<IntegratorKind>().unwrap(), k);
    }
    assert!(matches!(
        "leapfrog".parse::<IntegratorKind>(),
        Err(DynamicsError::UnknownIntegrator { .. })
    ));
    for k in IntegratorKind::ALL {
        assert_eq!(k.name().parse::<IntegratorKind>().unwrap(), k);
        assert_eq!(k.boxed().name(), k.name());
        assert_eq!(k.to_string(), k.name());
    }
}

/// The paper's claim in miniature: with a stiff coupling and a light, thin tool, backward Euler
/// stays bounded where forward Euler blows up.
#[test]
fn backward_euler_is_stable_where_forward_euler_is_not() {
    // 1 g, thin about one axis (the spoon's weak axis).
    let body = RigidBody::from_principal(1e-3, [4e-6, 1e-7, 4e-6]).unwrap();
    let (start, mut forces) = coupled_start();
    let s = run(
        &mut LinearizedBackwardEuler,
        &body,
        &start,
        &mut forces,
        0.5,
        500,
    );
    assert!(forces.0.deviation(&s).translation_m < 0.01);
    let (start, mut forces) = coupled_start();
    let mut fe = ForwardEuler;
    let mut s = start;
    let mut failed = false;
    for i in 0..500 {
        match fe.step(&body, &s, i as Real * 1e-3, 1e-3, &mut forces) {
            Ok(next) => s = next,
            Err(_) => {
                failed = true;
                break;
            }
        }
        if forces.0.deviation(&s).translation_m > 1.0 {
            failed = true;
            break;
        }
    }
    assert!(failed, "forward Euler stayed bounded with a 1 g tool");
}

/// Full Newton converges against a stale, bounded contact model: a 1 g tool on four contacts
/// (5 kN/m, `h² k_c / m` = 20 together) linearized once, while the hand moves 3 cm in and out of the floor for
/// 0.5 s. Each contact's tangent switches off and reaches its cap many times (the piecewise-smooth
/// force that made undamped full-Newton steps cycle); every step must converge.
#[test]
fn newton_converges_against_a_stale_bounded_contact() {
    use haptic_core::{Contact, ContactModel, LinearizedContact};
    use haptic_dynamics::{HapticForces, PenaltyModel, PenaltyParams};
    let body = RigidBody::from_principal(1e-3, [4e-6, 1e-7, 4e-6]).unwrap();
    let start = ToolState::at_rest(&Pose::identity());
    let hand = |t: Real| {
        let z = -0.03 * (2.0 * PI * 5.0 * t).sin();
        let mut d = DeviceState::at_rest(
            Pose {
                position: Vec3::new(0.0, 0.0, z),
                orientation: UnitQuaternion::identity(),
            },
            t,
        );
        d.twist.linear.z = -0.03 * 2.0 * PI * 5.0 * (2.0 * PI * 5.0 * t).cos();
        d
    };
    // A stiff coupling (10× the default, as in the stress runs), which presses the light tool
    // past every tangent's cap at the bottom of the stroke.
    let d = CouplingParams::default();
    let params = CouplingParams {
        stiffness_n_per_m: 10.0 * d.stiffness_n_per_m,
        damping_ns_per_m: 10.0 * d.damping_ns_per_m,
        angular_stiffness_nm_per_rad: 10.0 * d.angular_stiffness_nm_per_rad,
        angular_damping_nms_per_rad: 10.0 * d.angular_damping_nms_per_rad,
        saturation: None,
    };
    let coupling = VirtualCoupling::grasping(params, &start, &hand(0.0)).unwrap();
    let mut forces = HapticForces::new(coupling);
    // Four corners of a 2 cm square 0.8 mm above the floor, within δ (normal −z, out of the
    // tool): 1 N each at y₀, capped at 6 N.
    let n = -Vec3::z();
    let contacts: Vec<Contact> = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
        .iter()
        .map(|(a, b)| {
            let r_a = Vec3::new(0.01 * a, 0.01 * b, -0.005);
            Contact::new(r_a, r_a, r_a + 0.8e-3 * n, n, -0.8e-3).unwrap()
        })
        .collect();
    let mut model = PenaltyModel::new(PenaltyParams::new(5_000.0, 5.0, 1e-3).unwrap()).unwrap();
    let mut lin = LinearizedContact::none();
    model.linearize(&body, &start, &contacts, &mut lin).unwrap();
    forces.contact = lin;
    let mut newton = NewtonBackwardEuler::default();
    let h = 1e-3;
    let mut s = start;
    let (mut released, mut capped) = (0, 0);
    for i in 0..500 {
        let t = i as Real * h;
        forces.coupling.set_device(&hand(t)).unwrap();
        s = match newton.step(&body, &s, t, h, &mut forces) {
            Ok(next) => next,
            Err(e) => panic!("step {i} (t = {t:.3} s): {e}"),
        };
        let dy = s.to_vector() - lin.y0;
        for tangent in lin.tangents() {
            let lambda = tangent.lambda0_n + (tangent.dlambda_dy * dy)[0];
            released += usize::from(lambda <= 0.0);
            capped += usize::from(lambda > tangent.lambda_max_n);
        }
    }
    assert!(
        released > 0 && capped > 0,
        "released {released}, capped {capped}"
    );
}
