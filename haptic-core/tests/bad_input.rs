//! Bad input to the remaining constructors gives the right error variant.

use haptic_core::{CoreError, RigidBody};

#[test]
fn with_mass_rejects_bad_masses() {
    let body = RigidBody::from_principal(0.1, [1e-4, 2e-4, 3e-4]).unwrap();
    assert!(matches!(
        body.with_mass(f64::NAN),
        Err(CoreError::NonFinite { what: "mass" })
    ));
    assert!(matches!(
        body.with_mass(0.0),
        Err(CoreError::NonPositiveMass { .. })
    ));
    assert!(matches!(
        body.with_mass(-1.0),
        Err(CoreError::NonPositiveMass { .. })
    ));
    let heavier = body.with_mass(0.2).unwrap();
    assert!((heavier.inertia_body()[(2, 2)] - 6e-4).abs() < 1e-15);
}
