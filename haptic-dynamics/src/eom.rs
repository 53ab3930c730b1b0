//! Equations of motion of the 13-state tool (paper eqs. 2–3) and their Jacobian (eqs. 6–12).
//!
//! `y = (x, q, P, L)`, `f(y) = (P/m, ½ Q(q) ω, F, T)` with `ω = R I_b⁻¹ Rᵀ L`. Everything is
//! evaluated on the quaternion as given (possibly slightly off unit inside a step), so that the
//! analytic Jacobian is the exact derivative of what [`state_derivative`] computes.

use haptic_core::math::{IL, IP, IQ, IX, omega_matrix, q_matrix, state_quat};
use haptic_core::{Kinematics, RigidBody, StateVector, SystemJacobian, Wrench, WrenchJacobian};

/// The state derivative `dy/dt = (v, ½ Q(q) ω, F, T)` (eqs. 2–3).
///
/// `kin` must be the kinematics of `body` at `y`; `wrench` is the external force (N, at the
/// centre of mass) and torque (N m, about it), world frame.
#[inline]
pub fn state_derivative(
    body: &RigidBody,
    y: &StateVector,
    kin: &Kinematics,
    wrench: &Wrench,
) -> StateVector {
    let _ = body; // v and ω are already in `kin`; the body is part of the signature for clarity.
    let q = state_quat(y);
    let dq = 0.5 * q_matrix(&q) * kin.omega; // eq. 3
    let mut dy = StateVector::zeros();
    dy.fixed_rows_mut::<3>(IX).copy_from(&kin.v);
    dy.fixed_rows_mut::<4>(IQ).copy_from(&dq);
    dy.fixed_rows_mut::<3>(IP).copy_from(&wrench.force);
    dy.fixed_rows_mut::<3>(IL).copy_from(&wrench.torque);
    dy
}

/// The force-free part of `∂f/∂y` (eqs. 6–12), written into `out` (every entry is set).
///
/// Non-zero blocks: `∂(dx)/∂P = I₃/m`, `∂(dq)/∂q = ½ Ω(ω) + ½ Q(q) ∂ω/∂q`,
/// `∂(dq)/∂L = ½ Q(q) I_w⁻¹`. The rows of `dP` and `dL` are zero here; add the wrench
/// Jacobian with [`add_wrench_jacobian`].
#[inline]
pub fn free_jacobian(
    body: &RigidBody,
    y: &StateVector,
    kin: &Kinematics,
    out: &mut SystemJacobian,
) {
    out.fill(0.0);
    let inv_m = 1.0 / body.mass_kg();
    for i in 0..3 {
        out[(IX + i, IP + i)] = inv_m; // eq. 6
    }
    let (dqq, dql) = quaternion_jacobian_blocks(y, kin);
    out.fixed_view_mut::<4, 4>(IQ, IQ).copy_from(&dqq);
    out.fixed_view_mut::<4, 3>(IQ, IL).copy_from(&dql);
}

/// The two non-zero blocks of the quaternion rows of `∂f/∂y`: `∂q̇/∂q = ½ Ω(ω) + ½ Q(q) ∂ω/∂q`
/// (eqs. 8, 11) and `∂q̇/∂L = ½ Q(q) I_w⁻¹` (eq. 9).
#[inline]
pub fn quaternion_jacobian_blocks(
    y: &StateVector,
    kin: &Kinematics,
) -> (
    nalgebra::Matrix4<haptic_core::Real>,
    nalgebra::Matrix4x3<haptic_core::Real>,
) {
    let qm = q_matrix(&state_quat(y));
    let dqq = 0.5 * omega_matrix(&kin.omega) + 0.5 * qm * kin.omega_q; // eqs. 8, 11
    let dql = 0.5 * qm * kin.inertia_world_inv; // eq. 9
    (dqq, dql)
}

/// Adds a 6×13 wrench Jacobian `∂(F, T)/∂y` into the `dP` and `dL` rows of `out` (eq. 10).
#[inline]
pub fn add_wrench_jacobian(out: &mut SystemJacobian, wrench_jacobian: &WrenchJacobian) {
    let mut rows = out.fixed_view_mut::<6, 13>(IP, 0);
    rows += wrench_jacobian;
}

/// The full `∂f/∂y`: [`free_jacobian`] plus the wrench Jacobian.
#[inline]
pub fn system_jacobian(
    body: &RigidBody,
    y: &StateVector,
    kin: &Kinematics,
    wrench_jacobian: &WrenchJacobian,
    out: &mut SystemJacobian,
) {
    free_jacobian(body, y, kin, out);
    add_wrench_jacobian(out, wrench_jacobian);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{arb_body, arb_raw_state, column_check};
    use haptic_core::Vec3;
    use proptest::prelude::*;

    /// `f(y)` with a wrench that depends on `y` linearly, so the test also exercises the
    /// `dP`/`dL` rows.
    fn f_with_linear_wrench(body: &RigidBody, y: &StateVector, a: &WrenchJacobian) -> StateVector {
        let kin = Kinematics::new(body, y);
        let w = Wrench::from_vector(&(a * y));
        state_derivative(body, y, &kin, &w)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]

        /// eqs. 6–12 against central differences, column by column (see `column_check`).
        #[test]
        fn eom_jacobian_matches_central_differences(
            body in arb_body(),
            raw in arb_raw_state(),
            seed in prop::array::uniform6(-1.0..1.0f64),
        ) {
            let mut a = WrenchJacobian::zeros();
            for (i, s) in seed.iter().enumerate() {
                a[(i, (i * 2 + 1) % 13)] = 10.0 * s;
                a[(i, (i * 5 + 3) % 13)] = -3.0 * s;
            }
            let y = raw.state_vector(&body);
            let kin = Kinematics::new(&body, &y);
            let mut jac = SystemJacobian::zeros();
            system_jacobian(&body, &y, &kin, &a, &mut jac);
            let m = body.mass_kg();
            let res = column_check(&jac, &y, m, |yy| f_with_linear_wrench(&body, yy, &a));
            prop_assert!(res.is_ok(), "{}", res.unwrap_err());
        }
    }

    #[test]
    fn derivative_of_a_spinning_body() {
        let body = RigidBody::from_principal(2.0, [1.0, 2.0, 2.5]).unwrap();
        let mut y = StateVector::zeros();
        y[IQ] = 1.0;
        y[IP] = 4.0;
        y[IL + 2] = 5.0; // ω = (0, 0, 2)
        let kin = Kinematics::new(&body, &y);
        let w = Wrench::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.5, 0.0));
        let dy = state_derivative(&body, &y, &kin, &w);
        assert!((dy[IX] - 2.0).abs() < 1e-15);
        // dq/dt = ½ (0, ω) ⊗ (1, 0, 0, 0) = (0, 0, 0, 1)
        assert!((dy[IQ + 3] - 1.0).abs() < 1e-15 && dy[IQ].abs() < 1e-15);
        assert_eq!(dy[IP], 1.0);
        assert_eq!(dy[IL + 1], 0.5);
    }
}
