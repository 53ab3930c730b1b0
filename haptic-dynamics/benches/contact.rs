//! The contact side of the haptic loop: one evaluation of the linearized contact model (eq. 42,
//! goal < 100 ns) and the penalty model at 5 cluster representatives with its Jacobian.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use haptic_core::{
    Contact, ContactModel, Kinematics, LinearizationMode, LinearizedContact, Pose, Real, RigidBody,
    ToolState, Vec3, WrenchJacobian,
};
use haptic_dynamics::{PenaltyModel, PenaltyParams};

fn setup() -> (RigidBody, ToolState, Vec<Contact>) {
    let body = RigidBody::from_principal(0.05, [2e-5, 3e-5, 4e-5]).unwrap();
    let mut tool = ToolState::at_rest(&Pose::identity());
    tool.p = Vec3::new(0.001, -0.002, 0.0005);
    tool.l = Vec3::new(1e-6, -2e-6, 1.5e-6);
    let contacts = (0..5)
        .map(|i| {
            let a = i as Real * 1.3;
            let r_a = Vec3::new(0.02 * a.cos(), 0.02 * a.sin(), -0.01);
            let n = Vec3::new(0.1 * a.sin(), 0.1 * a.cos(), -1.0).normalize();
            let d = 2e-4 * (1.0 + a.sin());
            Contact::new(r_a, r_a, r_a - d * n, n, d).unwrap()
        })
        .collect();
    (body, tool, contacts)
}

fn bench(c: &mut Criterion) {
    let (body, tool, contacts) = setup();
    let mut model = PenaltyModel::new(PenaltyParams::default()).unwrap();
    let mut lin = LinearizedContact::none();
    model.linearize(&body, &tool, &contacts, &mut lin).unwrap();
    let mut y = tool.to_vector();
    y[0] += 1e-4;
    let kin = Kinematics::new(&body, &y);

    for (name, mode) in [
        ("", LinearizationMode::Linearized),
        ("fixed_frames/", LinearizationMode::FixedFrames),
    ] {
        c.bench_function(&format!("linearized_contact/{name}wrench_at"), |b| {
            b.iter(|| black_box(&lin).wrench_at(black_box(&y), &kin, mode))
        });
        c.bench_function(
            &format!("linearized_contact/{name}wrench_and_jacobian"),
            |b| {
                let mut jac = WrenchJacobian::zeros();
                b.iter(|| {
                    black_box(&lin).add_wrench_and_jacobian(black_box(&y), &kin, mode, &mut jac)
                })
            },
        );
    }
    c.bench_function("penalty/5_representatives_with_jacobian", |b| {
        let kin = Kinematics::new(&body, &y);
        let mut jac = WrenchJacobian::zeros();
        b.iter(|| {
            model
                .evaluate(
                    &body,
                    black_box(&y),
                    &kin,
                    black_box(&contacts),
                    Some(&mut jac),
                )
                .unwrap()
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
