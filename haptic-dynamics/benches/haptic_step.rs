//! One haptic step per integrator, in free space and with the linearized wrench of 5 contacts
//! (five clusters of one spring each) and of 10 (five torque pairs, `haptic-cluster`'s
//! default): `set_device` + integrator step with `HapticForces` + `device_reaction` (goal for
//! backward Euler with 5 contacts: ≤ 2 µs median). `cargo xtask bench` reports the same step's
//! quantiles.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use haptic_core::{
    Contact, ContactModel, DeviceState, LinearizedContact, Pose, Real, RigidBody, ToolState, Twist,
    Vec3,
};
use haptic_dynamics::{
    CouplingParams, HapticForces, IntegratorKind, PenaltyModel, PenaltyParams, VirtualCoupling,
};
use nalgebra::UnitQuaternion;

/// A 100 g spoon-like body, its start state, the coupling and `count` linearized contacts below
/// it.
fn setup(count: usize) -> (RigidBody, ToolState, HapticForces, LinearizedContact) {
    let body = RigidBody::from_principal(0.1, [3.4e-4, 1.2e-5, 3.5e-4]).unwrap();
    let tool = ToolState::at_rest(&Pose::identity());
    let device = DeviceState::at_rest(Pose::from_position(Vec3::new(0.0, -0.035, 0.0)), 0.0);
    let coupling = VirtualCoupling::grasping(CouplingParams::default(), &tool, &device).unwrap();
    let n = -Vec3::z();
    let contacts: Vec<Contact> = (0..count)
        .map(|i| {
            // Five places along the spoon; a second spring 2 mm beside each for ten.
            let (j, side) = (i % 5, (i / 5) as Real * 0.002);
            let r = Vec3::new(
                0.004 * (j as Real - 2.0).sin() + side,
                0.03 * (j as Real - 2.0),
                -0.006,
            );
            Contact::new(r, r, r - 5e-4 * n, n, 5e-4).unwrap()
        })
        .collect();
    let mut model = PenaltyModel::new(PenaltyParams::default()).unwrap();
    let mut lin = LinearizedContact::none();
    model.linearize(&body, &tool, &contacts, &mut lin).unwrap();
    (body, tool, HapticForces::new(coupling), lin)
}

/// The device moving on a small circle, turning slowly (a reading per call).
fn device_at(k: usize) -> DeviceState {
    let t = k as Real * 1e-3;
    let w = 6.0;
    DeviceState {
        pose: Pose {
            position: Vec3::new(0.002 * (w * t).sin(), -0.035 + 0.002 * (w * t).cos(), 0.0),
            orientation: UnitQuaternion::from_scaled_axis(Vec3::new(
                0.0,
                0.0,
                0.05 * (w * t).sin(),
            )),
        },
        twist: Twist {
            linear: Vec3::new(0.012 * (w * t).cos(), -0.012 * (w * t).sin(), 0.0),
            angular: Vec3::new(0.0, 0.0, 0.3 * (w * t).cos()),
        },
        buttons: 1,
        timestamp_s: t,
    }
}

fn bench(c: &mut Criterion) {
    let (body, tool0, forces0, _) = setup(0);
    let devices: Vec<DeviceState> = (0..1000).map(device_at).collect();
    let mut group = c.benchmark_group("haptic_step");
    for kind in IntegratorKind::ALL {
        for contacts in [0, 5, 10] {
            let mut forces = forces0;
            if contacts > 0 {
                forces.contact = setup(contacts).3;
            }
            let mut integ = kind.boxed();
            let mut tool = tool0;
            let mut k = 0usize;
            let name = match contacts {
                0 => format!("{}/free", kind.name()),
                n => format!("{}/contacts{n}", kind.name()),
            };
            group.bench_function(&name, |b| {
                b.iter(|| {
                    k = (k + 1) % devices.len();
                    if k == 0 {
                        tool = tool0;
                    }
                    forces.coupling.set_device(&devices[k]).unwrap();
                    tool = integ
                        .step(&body, black_box(&tool), k as Real * 1e-3, 1e-3, &mut forces)
                        .unwrap_or(tool0);
                    black_box(forces.coupling.device_reaction(&body, &tool))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
