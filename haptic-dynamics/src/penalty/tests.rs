//! Tests of the penalty model: Jacobians against finite differences, the linearized and
//! fixed-frame models, and bad input.
use super::*;
use crate::testutil::{arb_body, arb_raw_state, column_check};
use haptic_core::math::{IL, IP, IQ};
use haptic_core::{ContactTangent, JacobianKind, LinearizationMode, LinearizedContact, ToolState};
use nalgebra::SMatrix;
use proptest::prelude::*;

const K_C: Real = 2000.0;
const B_C: Real = 5.0;
const DELTA: Real = 1e-3;

fn model() -> PenaltyModel {
    PenaltyModel::new(PenaltyParams::new(K_C, B_C, DELTA).unwrap()).unwrap()
}

/// Contacts fixed in the tool at the state `y`: body points `r_a`, normals `n`, depths `d`.
fn contacts_at(
    body: &RigidBody,
    y: &StateVector,
    raw: &[([f64; 3], [f64; 3], f64)],
) -> Vec<Contact> {
    let kin = Kinematics::new(body, y);
    let x: Vec3 = y.fixed_rows::<3>(IX).into_owned();
    raw.iter()
        .map(|(r, n, d)| {
            let r_a = Vec3::from(*r);
            let n = (Vec3::from(*n) + Vec3::new(0.0, 0.0, 1e-3)).normalize();
            let p_a = x + kin.r * r_a;
            Contact::new(p_a, r_a, p_a - *d * n, n, *d).unwrap()
        })
        .collect()
}

/// The state of `s0` (quaternion normalised), its contacts `raw`, and their model linearized
/// there (`lin.y0` is the state).
fn linearized_at(
    body: &RigidBody,
    s0: &crate::testutil::RawState,
    raw: &[([f64; 3], [f64; 3], f64)],
) -> (Vec<Contact>, LinearizedContact) {
    let tool = ToolState::from_vector_normalized(&s0.state_vector(body)).unwrap();
    let contacts = contacts_at(body, &tool.to_vector(), raw);
    let mut lin = LinearizedContact::none();
    model().linearize(body, &tool, &contacts, &mut lin).unwrap();
    (contacts, lin)
}

/// A model of `lin`'s tangent `t` alone.
fn alone(lin: &LinearizedContact, t: &ContactTangent) -> LinearizedContact {
    let mut one = LinearizedContact::none();
    one.y0 = lin.y0;
    one.push(*t).unwrap();
    one
}

fn eval(body: &RigidBody, y: &StateVector, contacts: &[Contact]) -> Wrench {
    let kin = Kinematics::new(body, y);
    model().evaluate(body, y, &kin, contacts, None).unwrap()
}

fn arb_raw_contacts() -> impl Strategy<Value = Vec<([f64; 3], [f64; 3], f64)>> {
    prop::collection::vec(
        (
            prop::array::uniform3(-0.05..0.05f64),
            prop::array::uniform3(-1.0..1.0f64),
            -0.5e-3..2e-3f64,
        ),
        1..8,
    )
}

/// The smallest normal-force magnitude over the contacts, relative to `k_c (d + δ)`: the
/// finite differences must not cross the switch-off at `λ = 0`.
fn min_lambda_ratio(body: &RigidBody, y: &StateVector, contacts: &[Contact]) -> Real {
    let kin = Kinematics::new(body, y);
    contacts
        .iter()
        .map(|c| {
            let rho = kin.r * c.r_a;
            let v_a = kin.v + kin.omega.cross(&rho);
            let g = c.depth_m + DELTA;
            (K_C * g + B_C * c.n.dot(&v_a)) / (K_C * g)
        })
        .fold(Real::INFINITY, Real::min)
}

/// Whether a contact's normal force `lambda` (gradient `dl`) is away from the bounds' kinks
/// (`λ = 0`, the release band `ε` and the cap `λ_max`) by more than central differences of the
/// state `scales` can reach: there the bounded model is smooth enough for them. (`λ = ε` too:
/// the smoothstep is C¹ there, not C², so the differences lose an order.)
fn away_from_kinks(
    t: &ContactTangent,
    lambda: Real,
    dl: &nalgebra::RowSVector<Real, 13>,
    scales: &[Real; 13],
) -> bool {
    let reach: Real = (0..13).map(|k| (dl[k] * scales[k] * 1e-5).abs()).sum();
    lambda.abs() > reach
        && (lambda - t.release_band_n).abs() > reach
        && (lambda - t.lambda_max_n).abs() > reach
}

/// The Jacobian the haptic thread adds in `mode` is that of the wrench it returns, against
/// central differences, and the wrench is `wrench_at`'s.
fn jacobian_matches_fd(
    lin: &LinearizedContact,
    body: &RigidBody,
    y: &StateVector,
    mode: LinearizationMode,
) -> Result<(), TestCaseError> {
    let mut jac = WrenchJacobian::zeros();
    let kin = Kinematics::new(body, y);
    let w = lin.add_wrench_and_jacobian(y, &kin, mode, &mut jac);
    prop_assert_eq!(w, lin.wrench_at(y, &kin, mode));
    let r = column_check(&jac, y, body.mass_kg(), |yy| {
        lin.wrench_at(yy, &Kinematics::new(body, yy), mode)
            .to_vector()
    });
    prop_assert!(r.is_ok(), "{}", r.unwrap_err());
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Force and torque Jacobians (eqs. 34–41) against central differences.
    #[test]
    fn penalty_jacobian_matches_fd(
        body in arb_body(),
        s in arb_raw_state(),
        raw in arb_raw_contacts(),
    ) {
        let y = s.state_vector(&body);
        let contacts = contacts_at(&body, &y, &raw);
        prop_assume!(min_lambda_ratio(&body, &y, &contacts) > 1e-3);
        let kin = Kinematics::new(&body, &y);
        let mut jac = WrenchJacobian::zeros();
        let w = model().evaluate(&body, &y, &kin, &contacts, Some(&mut jac)).unwrap();
        prop_assert!(w.force.norm() > 0.0);
        let jf: SMatrix<Real, 3, 13> = jac.fixed_rows::<3>(0).into_owned();
        let jt: SMatrix<Real, 3, 13> = jac.fixed_rows::<3>(3).into_owned();
        let m = body.mass_kg();
        let r = column_check(&jf, &y, m, |yy| eval(&body, yy, &contacts).force);
        prop_assert!(r.is_ok(), "force: {}", r.unwrap_err());
        let r = column_check(&jt, &y, m, |yy| eval(&body, yy, &contacts).torque);
        prop_assert!(r.is_ok(), "torque: {}", r.unwrap_err());
    }

    /// A contact's stiffness share scales its wrench and Jacobian (eq. 33 with `k_c s` and
    /// `b_c s`) and its linearization's normal stiffness, so its cap is `λ₀ + s k_c δ`.
    #[test]
    fn stiffness_share_scales_the_contact(
        body in arb_body(),
        s in arb_raw_state(),
        raw in arb_raw_contacts(),
        share in 0.0..5.0f64,
    ) {
        let y = s.state_vector(&body);
        let contacts = contacts_at(&body, &y, &raw);
        let shared: Vec<Contact> = contacts.iter().map(|c| c.with_stiffness_share(share)).collect();
        let kin = Kinematics::new(&body, &y);
        let (mut j1, mut js) = (WrenchJacobian::zeros(), WrenchJacobian::zeros());
        let w1 = model().evaluate(&body, &y, &kin, &contacts, Some(&mut j1)).unwrap();
        let ws = model().evaluate(&body, &y, &kin, &shared, Some(&mut js)).unwrap();
        let tol = 1e-12 * (1.0 + w1.force.norm() + w1.torque.norm()) * (1.0 + share);
        prop_assert!((ws.force - w1.force * share).norm() <= tol);
        prop_assert!((ws.torque - w1.torque * share).norm() <= tol);
        prop_assert!((js - j1 * share).norm() <= 1e-12 * (1.0 + j1.norm()) * (1.0 + share));
        let tool = ToolState::from_vector_normalized(&y).unwrap();
        let y0 = tool.to_vector();
        let one = contacts_at(&body, &y0, &raw[..1]);
        let mut lin = LinearizedContact::none();
        model().linearize(&body, &tool, &[one[0].with_stiffness_share(share)], &mut lin).unwrap();
        for t in lin.tangents() {
            let cap = t.lambda_max_n - t.lambda0_n;
            prop_assert!((cap - share * K_C * DELTA).abs() <= 1e-9 * K_C * DELTA * (1.0 + share), "cap {cap}");
        }
    }

    /// The linearized model (eq. 42), evaluated anywhere, never pulls and never gives a
    /// contact more normal force than it had at `y₀` plus `k_c δ`: each contact's
    /// linearization on its own, at states far from `y₀` (the stale case).
    #[test]
    fn linearized_model_never_pulls_and_stays_within_reach(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
    ) {
        let tool = ToolState::from_vector_normalized(&s0.state_vector(&body)).unwrap();
        let y0 = tool.to_vector();
        let contacts = contacts_at(&body, &y0, &raw);
        let kin0 = Kinematics::new(&body, &y0);
        let y1 = s1.state_vector(&body);
        for c in &contacts {
            let mut lin = LinearizedContact::none();
            model().linearize(&body, &tool, std::slice::from_ref(c), &mut lin).unwrap();
            let lambda0 = -c.n.dot(&model().evaluate(&body, &y0, &kin0, std::slice::from_ref(c), None).unwrap().force);
            for e in [0.0, 1e-3, 0.1, 1.0] {
                let y = y0 + (y1 - y0) * e;
                let w = lin.wrench_at(&y, &Kinematics::new(&body, &y), LinearizationMode::Linearized);
                let lambda = -c.n.dot(&w.force);
                prop_assert!(lambda >= 0.0, "pulls: λ = {lambda}");
                prop_assert!(lambda <= lambda0.max(0.0) + K_C * DELTA + 1e-9 * (1.0 + lambda0.abs()),
                    "λ = {lambda} beyond λ₀ + k_c δ = {}", lambda0 + K_C * DELTA);
                prop_assert!(w.force.cross(&c.n).norm() <= 1e-9 * (1.0 + w.force.norm()));
            }
        }
    }

    /// The Jacobian the haptic thread uses is that of the bounded linearized wrench, away
    /// from where a contact switches off or reaches its cap.
    #[test]
    fn linearized_model_jacobian_matches_fd(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
        e in 0.0..1.0f64,
    ) {
        let (_, lin) = linearized_at(&body, &s0, &raw);
        let y0 = lin.y0;
        let y = y0 + (s1.state_vector(&body) - y0) * (e * e * 0.01);
        // Stay away from the kinks (λ = 0, ε and λ_max) by a margin the FD steps cannot cross.
        let dy = y - y0;
        let scales = crate::testutil::state_scales(&y, body.mass_kg());
        for t in lin.tangents() {
            let lambda = t.lambda0_n + (t.dlambda_dy * dy)[0];
            prop_assume!(away_from_kinks(t, lambda, &t.dlambda_dy, &scales));
        }
        jacobian_matches_fd(&lin, &body, &y, LinearizationMode::Linearized)?;
    }

    /// On its fixed frames the model is the penalty model itself (eq. 33) wherever no
    /// bound binds: at `y₀` and at any state where every contact is between its release
    /// band and its cap. The tangent agrees only at `y₀`.
    #[test]
    fn fixed_frames_are_the_penalty_model_on_the_contacts_of_y0(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
        e in 0.0..1.0f64,
    ) {
        let (contacts, lin) = linearized_at(&body, &s0, &raw);
        let y0 = lin.y0;
        let at_y0 = lin.wrench_at(&y0, &Kinematics::new(&body, &y0), LinearizationMode::FixedFrames);
        let tangent_y0 = lin.wrench_at(&y0, &Kinematics::new(&body, &y0), LinearizationMode::Linearized);
        prop_assert!((at_y0.to_vector() - tangent_y0.to_vector()).norm() <= 1e-9 * (1.0 + at_y0.to_vector().norm()));
        let y = y0 + (s1.state_vector(&body) - y0) * (e * e);
        let kin = Kinematics::new(&body, &y);
        // Only the contacts that push at y₀ have a frame, in order.
        let pushing: Vec<Contact> = contacts
            .iter()
            .copied()
            .filter(|c| -c.n.dot(&eval(&body, &y0, std::slice::from_ref(c)).force) > 0.0)
            .collect();
        prop_assert_eq!(pushing.len(), lin.contact_count);
        for (c, t) in pushing.iter().zip(lin.tangents()) {
            let exact = eval(&body, &y, std::slice::from_ref(c)).to_vector();
            let lambda = -c.n.dot(&exact.fixed_rows::<3>(0).into_owned());
            if lambda <= t.release_band_n || lambda >= t.lambda_max_n {
                continue; // a bound binds: see fixed_frames_never_pull_and_stay_within_reach
            }
            let one = alone(&lin, t);
            let ff = one.wrench_at(&y, &kin, LinearizationMode::FixedFrames).to_vector();
            prop_assert!((ff - exact).norm() <= 1e-9 * (1.0 + exact.norm()), "{ff} vs {exact}");
        }
    }

    /// The Jacobian of the fixed-frame model (what the implicit solve uses) against central
    /// differences, at states far from `y₀` too, away from the bounds' kinks.
    #[test]
    fn fixed_frames_jacobian_matches_fd(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
        e in 0.0..1.0f64,
    ) {
        let (_, lin) = linearized_at(&body, &s0, &raw);
        let y0 = lin.y0;
        let y = y0 + (s1.state_vector(&body) - y0) * (e * e * 0.3);
        let kin = Kinematics::new(&body, &y);
        let scales = crate::testutil::state_scales(&y, body.mass_kg());
        for t in lin.tangents() {
            let frame = t.frame.unwrap();
            let (rho, lambda) = frame.normal_force(&y, &kin);
            let dl = frame.normal_force_gradient(&kin, &rho);
            prop_assume!(away_from_kinks(t, lambda, &dl, &scales));
        }
        jacobian_matches_fd(&lin, &body, &y, LinearizationMode::FixedFrames)?;
    }

    /// On fixed frames, at any state: each contact pushes along `−n` only, never pulls, and
    /// never gives more than `λ₀ + k_c δ`; its torque is that force at the tool's point.
    #[test]
    fn fixed_frames_never_pull_and_stay_within_reach(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
    ) {
        let (_, lin) = linearized_at(&body, &s0, &raw);
        let y0 = lin.y0;
        let y1 = s1.state_vector(&body);
        for t in lin.tangents() {
            let one = alone(&lin, t);
            let frame = t.frame.unwrap();
            for e in [0.0, 1e-3, 0.1, 1.0] {
                let y = y0 + (y1 - y0) * e;
                let kin = Kinematics::new(&body, &y);
                let w = one.wrench_at(&y, &kin, LinearizationMode::FixedFrames);
                let lambda = -frame.n.dot(&w.force);
                prop_assert!(lambda >= 0.0, "pulls: λ = {lambda}");
                prop_assert!(lambda <= t.lambda0_n + K_C * DELTA + 1e-9 * (1.0 + t.lambda0_n));
                prop_assert!(w.force.cross(&frame.n).norm() <= 1e-9 * (1.0 + w.force.norm()));
                let rho = kin.r * frame.r_a;
                prop_assert!((w.torque - rho.cross(&w.force)).norm() <= 1e-12 * (1.0 + w.torque.norm()));
            }
        }
    }

    /// A contact that yields at any state lands at or below its cap, never above it by
    /// rounding: the implicit step that starts there has its stiffness in the Jacobian
    /// (`∂λ/∂y` the frame's), where above the cap it would have none and the capped force
    /// would act explicitly.
    #[test]
    fn a_yielded_contact_keeps_its_stiffness_in_the_jacobian(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
    ) {
        let (_, lin) = linearized_at(&body, &s0, &raw);
        let y0 = lin.y0;
        let y1 = s1.state_vector(&body);
        for t in lin.tangents() {
            for e in [1e-3, 0.1, 1.0] {
                let y = y0 + (y1 - y0) * e;
                let kin = Kinematics::new(&body, &y);
                let mut one = alone(&lin, t);
                let mut frame = t.frame.unwrap();
                if !frame.yield_to(&y, &kin, t.lambda_max_n) {
                    continue;
                }
                let (rho, lambda) = frame.normal_force(&y, &kin);
                prop_assert!(lambda <= t.lambda_max_n, "{lambda} above the cap {}", t.lambda_max_n);
                prop_assert!(lambda >= t.lambda_max_n * (1.0 - 1e-6), "{lambda} far below the cap {}", t.lambda_max_n);
                one.tangents[0].frame = Some(frame);
                let mut j = haptic_core::WrenchJacobian::zeros();
                let w = one.add_wrench_and_jacobian(&y, &kin, LinearizationMode::FixedFrames, &mut j);
                prop_assert!((-frame.n.dot(&w.force) - lambda).abs() <= 1e-9 * lambda);
                // The force's Jacobian is the spring's: −n ∂λ/∂y.
                let expected = -(frame.n * frame.normal_force_gradient(&kin, &rho));
                let got = j.fixed_rows::<3>(0).into_owned();
                prop_assert!(
                    (got - expected).norm() <= 1e-9 * (1.0 + expected.norm()),
                    "force Jacobian {got} against the spring's {expected}"
                );
            }
        }
    }

    /// The material Jacobian (what semi-implicit BE asks for) is the exact one without the
    /// geometric term: the same force rows, and torque rows `[ρ]× ∂F/∂y`.
    #[test]
    fn fixed_frames_material_jacobian_drops_only_the_geometric_term(
        body in arb_body(),
        s0 in arb_raw_state(),
        s1 in arb_raw_state(),
        raw in arb_raw_contacts(),
        e in 0.0..1.0f64,
    ) {
        let (_, lin) = linearized_at(&body, &s0, &raw);
        let y0 = lin.y0;
        let y = y0 + (s1.state_vector(&body) - y0) * (e * e * 0.3);
        let kin = Kinematics::new(&body, &y);
        for t in lin.tangents() {
            let one = alone(&lin, t);
            let (mut exact, mut material) = (WrenchJacobian::zeros(), WrenchJacobian::zeros());
            let mode = LinearizationMode::FixedFrames;
            let w = one.weighted(&y, &kin, mode, 1.0, Some((&mut exact, JacobianKind::Exact)));
            let wm = one.weighted(&y, &kin, mode, 1.0, Some((&mut material, JacobianKind::Material)));
            prop_assert_eq!(w, wm);
            let df: SMatrix<Real, 3, 13> = exact.fixed_rows::<3>(0).into_owned();
            prop_assert_eq!(df, material.fixed_rows::<3>(0).into_owned());
            let rho = kin.r * t.frame.unwrap().r_a;
            let dt_material: SMatrix<Real, 3, 13> = material.fixed_rows::<3>(3).into_owned();
            let expected = haptic_core::math::skew(&rho) * df;
            prop_assert!((dt_material - expected).norm() <= 1e-12 * (1.0 + expected.norm()));
        }
    }

    /// The normal force never pulls: n·F_k ≤ 0 for every contact, whatever the velocity.
    #[test]
    fn penalty_never_pulls(body in arb_body(), s in arb_raw_state(), raw in arb_raw_contacts()) {
        let y = s.state_vector(&body);
        let contacts = contacts_at(&body, &y, &raw);
        for c in &contacts {
            let w = eval(&body, &y, std::slice::from_ref(c));
            prop_assert!(c.n.dot(&w.force) <= 0.0);
            prop_assert!(w.force.cross(&c.n).norm() <= 1e-12 * w.force.norm().max(1e-300));
        }
    }
}

#[test]
fn force_matches_eq_33_at_rest() {
    let body = RigidBody::sphere(0.1, 0.01).unwrap();
    let tool = ToolState::at_rest(&haptic_core::Pose::identity());
    let y = tool.to_vector();
    // 0.5 mm deep, normal −z out of the tool (the floor is below).
    let c = contacts_at(&body, &y, &[([0.0, 0.0, -0.01], [0.0, 0.0, -1.0], 0.5e-3)]);
    let w = eval(&body, &y, &c);
    // F = k_c (d + δ) pushing up; the contact point is under the centre: no torque.
    approx::assert_relative_eq!(w.force, Vec3::new(0.0, 0.0, K_C * 1.5e-3), epsilon = 1e-9);
    assert!(w.torque.norm() < 1e-12);
    // Beyond δ: nothing.
    let far = contacts_at(&body, &y, &[([0.0, 0.0, -0.01], [0.0, 0.0, -1.0], -0.5e-3)]);
    let mut far = far[0];
    far.p_b += 1e-3 * far.n; // 1.5 mm apart, beyond δ
    assert_eq!(eval(&body, &y, &[far]).force, Vec3::zeros());
}

#[test]
fn bad_input_gives_typed_errors() {
    assert!(matches!(
        PenaltyParams::new(0.0, 1.0, 1e-3),
        Err(DynamicsError::Core(
            haptic_core::CoreError::OutOfRange { .. }
        ))
    ));
    assert!(matches!(
        PenaltyParams::new(1.0, -1.0, 1e-3),
        Err(DynamicsError::Core(
            haptic_core::CoreError::OutOfRange { .. }
        ))
    ));
    assert!(matches!(
        PenaltyParams::new(1.0, 1.0, Real::NAN),
        Err(DynamicsError::Core(
            haptic_core::CoreError::NonFinite { .. }
        ))
    ));
    let body = RigidBody::sphere(0.1, 0.01).unwrap();
    let y = ToolState::at_rest(&haptic_core::Pose::identity()).to_vector();
    let kin = Kinematics::new(&body, &y);
    let good = contacts_at(&body, &y, &[([0.0, 0.0, -0.01], [0.0, 0.0, -1.0], 0.0)])[0];
    let mut nan = good;
    nan.p_b.x = Real::NAN;
    assert!(matches!(
        model().evaluate(&body, &y, &kin, &[good, nan], None),
        Err(ContactModelError::NonFiniteContact { index: 1, .. })
    ));
    let mut zero = good;
    zero.n = Vec3::zeros();
    assert!(matches!(
        model().evaluate(&body, &y, &kin, &[zero], None),
        Err(ContactModelError::BadNormal { index: 0, .. })
    ));
    let many = vec![good; haptic_core::MAX_REPRESENTATIVES + 1];
    let mut lin = LinearizedContact::none();
    let tool = ToolState::at_rest(&haptic_core::Pose::identity());
    assert!(matches!(
        model().linearize(&body, &tool, &many, &mut lin),
        Err(ContactModelError::TooManyContacts { .. })
    ));
    assert!(matches!(
        model().linearize(&body, &tool, &[good, nan], &mut lin),
        Err(ContactModelError::NonFiniteContact { index: 1, .. })
    ));
    let mut y_nan = y;
    y_nan[IP] = Real::NAN;
    assert!(matches!(
        model().evaluate(&body, &y_nan, &kin, &[good], None),
        Err(ContactModelError::NonFiniteState)
    ));
}

/// A contact pressed far beyond its reach yields (`yield_beyond_reach`): it pushes with its
/// cap `λ_max` where it was found, and gives back at most `λ_max² / 2k_c` of work as the
/// tool leaves, where the capped spring without yielding gives `λ_max` all the way back.
#[test]
fn a_contact_pressed_beyond_its_reach_yields_and_gives_back_a_bounded_work() {
    let body = RigidBody::sphere(0.1, 0.01).unwrap();
    let tool = ToolState::at_rest(&haptic_core::Pose::identity());
    let y0 = tool.to_vector();
    // 0.5 mm deep in a floor below the tool (n = −z, out of the tool), at rest.
    let c = contacts_at(&body, &y0, &[([0.0, 0.0, -0.01], [0.0, 0.0, -1.0], 0.5e-3)]);
    let mut lin = LinearizedContact::none();
    model().linearize(&body, &tool, &c, &mut lin).unwrap();
    let lambda_max = lin.tangents()[0].lambda_max_n;
    let cap = K_C * (c[0].depth_m + 2.0 * DELTA); // λ₀ + k_c δ with λ₀ = k_c (d + δ)
    assert!(
        (lambda_max - cap).abs() < 1e-9 * cap,
        "{lambda_max} vs {cap}"
    );
    let at = |z: Real| {
        let mut y = y0;
        y[2] = z;
        y
    };
    let push = |l: &LinearizedContact, z: Real| {
        let y = at(z);
        l.wrench_at(
            &y,
            &Kinematics::new(&body, &y),
            LinearizationMode::FixedFrames,
        )
        .force
        .z
    };
    // The tool has travelled 10 mm deeper by the time the model is used: capped.
    let deep = -10e-3;
    assert!((push(&lin, deep) - lambda_max).abs() < 1e-9 * lambda_max);
    // The work given back on the way out, from `deep` to where the contact lets go.
    let work = |l: &LinearizedContact| {
        let n = 20_000;
        let dz = 0.02 / n as Real;
        (0..n)
            .map(|i| {
                let z = deep + (i as Real + 0.5) * dz;
                push(l, z) * dz
            })
            .sum::<Real>()
    };
    let unyielded = work(&lin);
    let mut yielded = lin;
    let y = at(deep);
    assert_eq!(
        yielded.yield_beyond_reach(&y, &Kinematics::new(&body, &y)),
        1
    );
    // Just below its cap (never above it by rounding), so the implicit step that starts
    // there has the contact's stiffness in its Jacobian.
    let pushed = push(&yielded, deep);
    assert!(
        pushed <= lambda_max && pushed >= lambda_max * (1.0 - 2.0 * haptic_core::YIELD_MARGIN),
        "{pushed} vs {lambda_max}"
    );
    let mut jacobian = haptic_core::WrenchJacobian::zeros();
    yielded.add_wrench_and_jacobian(
        &y,
        &Kinematics::new(&body, &y),
        LinearizationMode::FixedFrames,
        &mut jacobian,
    );
    assert!(
        (jacobian[(2, 2)] + K_C).abs() < 1e-6 * K_C,
        "dF_z/dz = {} at the cap, spring {K_C}",
        jacobian[(2, 2)]
    );
    // Nothing more to yield where it already has.
    assert_eq!(
        yielded.yield_beyond_reach(&y, &Kinematics::new(&body, &y)),
        0
    );
    let bound = lambda_max * lambda_max / (2.0 * K_C);
    let given = work(&yielded);
    println!("work given back: {given:.4} J yielded (bound {bound:.4} J), {unyielded:.4} J not");
    assert!(
        given <= bound * (1.0 + 1e-6) && given > 0.5 * bound,
        "{given} vs {bound}"
    );
    assert!(unyielded > 4.0 * bound, "{unyielded} vs {bound}");
}

/// The linearized model (eq. 42) has an error second order in `y − y₀`: the slope of
/// log(error) against log(‖y − y₀‖) is 2 (for contacts pressed well above the release band
/// and moves within their reach, where the tangent is not bounded).
#[test]
fn linearization_error_is_second_order() {
    let body = RigidBody::from_principal(0.05, [2e-5, 3e-5, 4e-5]).unwrap();
    let mut tool = ToolState::at_rest(&haptic_core::Pose::identity());
    tool.p = Vec3::new(0.001, -0.002, 0.0005);
    tool.l = Vec3::new(1e-6, -2e-6, 1.5e-6);
    let y0 = tool.to_vector();
    let contacts = contacts_at(
        &body,
        &y0,
        &[
            ([0.02, 0.0, -0.01], [0.1, 0.0, -1.0], 1.4e-3),
            ([-0.02, 0.01, -0.01], [-0.2, 0.1, -1.0], 1.2e-3),
            ([0.0, -0.03, 0.0], [0.0, -1.0, 0.0], 1.1e-3),
        ],
    );
    let mut lin = LinearizedContact::none();
    model()
        .linearize(&body, &tool, &contacts, &mut lin)
        .unwrap();
    // A fixed direction mixing every state component, scaled per component.
    let mut dir = StateVector::zeros();
    for j in 0..13 {
        let scale = match j {
            j if j < IQ => 3e-4,
            j if j < IP => 3e-3,
            j if j < IL => 3e-4 * body.mass_kg(),
            _ => 3e-7,
        };
        dir[j] = scale * ((j as Real + 1.0) * 0.7).sin();
    }
    let (mut xs, mut es) = (Vec::new(), Vec::new());
    for e in [1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125] {
        let y = y0 + dir * e;
        let exact = eval(&body, &y, &contacts);
        let approx = lin.wrench_at(
            &y,
            &Kinematics::new(&body, &y),
            LinearizationMode::Linearized,
        );
        let err = (exact.to_vector() - approx.to_vector()).norm();
        xs.push(Real::ln(e));
        es.push(Real::ln(err));
    }
    // Least-squares slope of the log-log points.
    let n = xs.len() as Real;
    let (mx, me) = (xs.iter().sum::<Real>() / n, es.iter().sum::<Real>() / n);
    let slope = xs
        .iter()
        .zip(&es)
        .map(|(x, e)| (x - mx) * (e - me))
        .sum::<Real>()
        / xs.iter().map(|x| (x - mx).powi(2)).sum::<Real>();
    println!("linearization error slope {slope:.3}");
    assert!((slope - 2.0).abs() < 0.1, "slope {slope}");
    // And held constant (the ablation) the error is first order.
    let held = |e: Real| {
        let y = y0 + dir * e;
        (eval(&body, &y, &contacts).to_vector()
            - lin
                .wrench_at(&y, &Kinematics::new(&body, &y), LinearizationMode::Constant)
                .to_vector())
        .norm()
    };
    let ratio = held(0.1) / held(0.05);
    assert!((ratio - 2.0).abs() < 0.2, "constant-mode ratio {ratio}");
}
