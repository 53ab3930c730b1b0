//! Tests of the linearized contact model: its bounds, Jacobians and storage.

use super::*;

/// A contact pushing up (`n = −z`) with stiffness 1000 N/m in z and 0.5 N at `y₀`.
fn floor(reach_m: Real) -> ContactTangent {
    let mut j = WrenchJacobian::zeros();
    j[(2, 2)] = -1000.0;
    j[(3, 1)] = 7.0; // some torque coupling
    let w = Wrench::new(Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.01, 0.0, 0.0));
    ContactTangent::new(-Vec3::z(), w, j, reach_m).unwrap()
}

#[test]
fn tangent_never_pulls_and_is_capped_at_its_reach() {
    let t = floor(1e-3);
    assert_eq!(t.lambda0_n, 0.5);
    assert!((t.lambda_max_n - 1.5).abs() < 1e-12, "{}", t.lambda_max_n);
    let at = |z: Real| {
        let mut dy = StateVector::zeros();
        dy[2] = z;
        t.wrench_at(&dy, None)
    };
    // Within: the tangent.
    assert!((at(-0.2e-3)[2] - 0.7).abs() < 1e-12);
    // In the release band (λ = 0.3 N < ε = 0.5 N): faded by the smoothstep.
    let t: Real = 0.3 / 0.5;
    assert!((at(0.2e-3)[2] - 0.3 * t * t * (3.0 - 2.0 * t)).abs() < 1e-12);
    // Lifted 0.5 mm: the force has gone to zero; lifted more: still zero, never pulling.
    assert!(at(0.5e-3)[2].abs() < 1e-12);
    assert_eq!(at(2e-3), WrenchVector::zeros());
    // Pressed 5 mm deeper: capped at λ₀ + k δ = 1.5 N.
    assert!((at(-5e-3)[2] - 1.5).abs() < 1e-12);
}

#[test]
fn no_tangent_for_a_contact_that_does_not_push() {
    let w = Wrench::new(Vec3::new(0.0, 0.0, -0.5), Vec3::zeros());
    assert!(ContactTangent::new(-Vec3::z(), w, WrenchJacobian::zeros(), 1e-3).is_none());
    assert!(
        ContactTangent::new(-Vec3::z(), Wrench::zero(), WrenchJacobian::zeros(), 1e-3).is_none()
    );
}

#[test]
fn bounded_jacobian_matches_finite_differences() {
    let t = floor(1e-3);
    let mut dir = StateVector::zeros();
    for k in 0..13 {
        dir[k] = ((k as Real + 1.0) * 0.37).sin();
    }
    // Points in the release band, within, capped and beyond the cap (away from the kinks).
    for z in [0.2e-3, 0.45e-3, -0.3e-3, -3e-3, -8e-3] {
        let mut dy = StateVector::zeros();
        dy[2] = z;
        let mut j = WrenchJacobian::zeros();
        t.wrench_at(&dy, Some(&mut j));
        for k in 0..13 {
            let mut e = StateVector::zeros();
            e[k] = 1e-7;
            let fd = (t.wrench_at(&(dy + e), None) - t.wrench_at(&(dy - e), None)) / 2e-7;
            let col = j.column(k);
            assert!(
                (fd - col).norm() <= 1e-5 * (1.0 + col.norm()),
                "z {z} column {k}: {fd} vs {col}"
            );
        }
    }
}

#[test]
fn beyond_reach_is_deeper_than_the_cap() {
    let mut lin = LinearizedContact::none();
    lin.push(floor(1e-3)).unwrap();
    let at = |z: Real| {
        let mut y = StateVector::zeros();
        y[2] = z;
        lin.beyond_reach(&y)
    };
    assert!(!at(0.0) && !at(-0.9e-3) && !at(5e-3));
    assert!(at(-1.1e-3));
}

#[test]
fn push_is_bounded_and_scaled_fades() {
    let mut lin = LinearizedContact::none();
    for _ in 0..MAX_REPRESENTATIVES {
        lin.push(floor(1e-3)).unwrap();
    }
    assert!(matches!(
        lin.push(floor(1e-3)),
        Err(ContactModelError::TooManyContacts {
            max: MAX_REPRESENTATIVES,
            ..
        })
    ));
    let y = StateVector::zeros();
    let kin = Kinematics::new(&RigidBody::sphere(0.1, 0.01).unwrap(), &y);
    let full = lin.wrench_at(&y, &kin, LinearizationMode::Linearized);
    assert!((full.force.z - 0.5 * MAX_REPRESENTATIVES as Real).abs() < 1e-12);
    let half = lin.scaled(0.5);
    let mut j = WrenchJacobian::zeros();
    let w = half.add_wrench_and_jacobian(&y, &kin, LinearizationMode::Linearized, &mut j);
    assert!((w.force.z - full.force.z / 2.0).abs() < 1e-12);
    assert!((j[(2, 2)] + 500.0 * MAX_REPRESENTATIVES as Real).abs() < 1e-9);
    let c = half.wrench_at(&y, &kin, LinearizationMode::Constant);
    assert!((c.force.z - full.force.z / 2.0).abs() < 1e-12);
}

#[test]
fn clear_and_copy_from_give_the_same_model_as_whole_copies() {
    let y = StateVector::from_fn(|k, _| 0.01 * k as Real);
    let kin = Kinematics::new(&RigidBody::sphere(0.1, 0.01).unwrap(), &y);
    let model = |count: usize, reach_m: Real| {
        let mut lin = LinearizedContact::none();
        lin.y0 = y;
        lin.max_depth_m = 1e-4 * count as Real;
        for _ in 0..count {
            lin.push(floor(reach_m)).unwrap();
        }
        lin
    };
    let (five, two) = (model(5, 1e-3), model(2, 2e-3));
    // A model with stale tangents beyond its count, made equal to a smaller one.
    let mut target = five;
    target.copy_from(&two);
    assert_eq!(target, two);
    assert_eq!(target.tangents().len(), 2);
    assert_ne!(
        target.tangents, two.tangents,
        "the storage beyond the count is stale"
    );
    for mode in [
        LinearizationMode::Linearized,
        LinearizationMode::FixedFrames,
    ] {
        assert_eq!(
            target.wrench_at(&y, &kin, mode),
            two.wrench_at(&y, &kin, mode)
        );
    }
    assert_eq!(format!("{target:?}"), format!("{two:?}"));
    // Cleared: no contact, equal to a fresh one, and a push starts from the first tangent.
    target.clear();
    assert_eq!(target, LinearizedContact::none());
    assert!(target.is_empty());
    assert_eq!(
        target.wrench_at(&y, &kin, LinearizationMode::Linearized),
        Wrench::zero()
    );
    target.push(floor(1e-3)).unwrap();
    assert_eq!(target.tangents(), &five.tangents()[..1]);
    assert_ne!(target, two);
}
