//! Clustering bounds the contact stiffness: 50 raw contacts clustered into K = 5 (each a torque
//! pair of two springs, the default) give a translational stiffness of at most 5·k_c, where the
//! raw contacts would give up to 50·k_c.

use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::math::IX;
use haptic_core::{
    Contact, ContactModel, ContactSet, Kinematics, Pose, Real, RigidBody, ToolState, Vec3,
    WrenchJacobian,
};
use haptic_dynamics::{PenaltyModel, PenaltyParams};

/// The largest singular value of `∂F/∂x` (N/m).
fn translational_stiffness(model: &mut PenaltyModel, contacts: &[Contact]) -> Real {
    let body = RigidBody::sphere(0.1, 0.02).unwrap();
    let tool = ToolState::at_rest(&Pose::identity());
    let y = tool.to_vector();
    let kin = Kinematics::new(&body, &y);
    let mut jac = WrenchJacobian::zeros();
    model
        .evaluate(&body, &y, &kin, contacts, Some(&mut jac))
        .unwrap();
    let k = jac.fixed_view::<3, 3>(0, IX).into_owned();
    k.singular_values().max()
}

#[test]
fn fifty_contacts_into_five_clusters_stay_below_five_kc() {
    let params = PenaltyParams::default();
    let k_c = params.stiffness_n_per_m;
    let mut model = PenaltyModel::new(params).unwrap();
    for seed in 0..20u64 {
        // A patch of 50 contacts on the underside of the tool, normals near −z.
        let raw: Vec<Contact> = (0..50)
            .map(|i| {
                let t = (seed * 50 + i) as Real;
                let r_a = Vec3::new(0.015 * (0.9 * t).sin(), 0.015 * (1.7 * t).cos(), -0.02);
                let n = Vec3::new(0.2 * (2.3 * t).sin(), 0.2 * (3.1 * t).cos(), -1.0).normalize();
                let d = 3e-4 * (1.0 + (0.37 * t).sin());
                Contact::new(r_a, r_a, r_a - d * n, n, d).unwrap()
            })
            .collect();
        let raw_stiffness = translational_stiffness(&mut model, &raw);
        let mut clusterer = Clusterer::new(ClusterParams::default()).unwrap();
        let mut reps = ContactSet::new();
        clusterer.cluster(&raw, params.delta_m, &mut reps).unwrap();
        // Five clusters, each a torque pair of two springs: the shares keep the bound.
        assert!(reps.len() <= ClusterParams::default().max_representatives());
        let clustered = translational_stiffness(&mut model, reps.as_slice());
        assert!(
            clustered <= 5.0 * k_c * (1.0 + 1e-12),
            "clustered stiffness {clustered} N/m > 5 k_c"
        );
        // The raw contacts are nearly parallel, so their stiffness is close to 50 k_c.
        assert!(raw_stiffness > 40.0 * k_c, "raw stiffness {raw_stiffness}");
    }
}
