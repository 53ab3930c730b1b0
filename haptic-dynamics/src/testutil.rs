//! Shared helpers of the unit tests: random bodies and states, and the finite-difference check
//! every analytic Jacobian goes through.
//!
//! **How "relative 1e-6" is measured.** Central differences with a step `h_j = 1e-6 s_j`, where
//! `s_j` is a typical magnitude of state component `j` (0.1 m for positions, 1 for the
//! quaternion, `max(|P|∞, 0.01 m)` kg m/s for momentum, `max(|L|∞, 10⁻¹²)` kg m²/s for angular
//! momentum). Column `j` of the analytic Jacobian `a_j` must match the difference quotient `d_j` to
//! `|a_j - d_j|₂ <= 1e-6 max(|a_j|₂, |d_j|₂) + 1e-9 max_k(|a_k|₂ s_k) / s_j`: relative in the
//! 2-norm per column, with an absolute floor one millionth below the tolerance for columns that
//! are (nearly) zero, scaled so that it corresponds to a change of the function under a typical
//! perturbation. The difference quotient is Richardson-extrapolated from steps `h` and `h/2`, so
//! its truncation error is `O(h⁴)` (functions with a large third derivative, as a smoothstep
//! over a narrow band, need it). Its rounding error, `O(ε |f| / h)`, is usually far below the
//! tolerance; where it is not (a column whose entries are small beside the function's values, as
//! a force that does not depend on a tiny angular momentum), it is added to the tolerance, with
//! the factor 3 that the extrapolation puts on it.

use haptic_core::math::{IL, IP, IQ, IX};
use haptic_core::{Mat3, Quat4, Real, RigidBody, StateVector, Vec3};
use nalgebra::{SMatrix, SVector, UnitQuaternion};
use proptest::prelude::*;

/// Relative tolerance of the finite-difference checks.
pub const FD_RTOL: Real = 1e-6;

/// A random rigid body: mass log-uniform in [1 g, 1 kg], asymmetric inertia with random
/// principal axes, radii of gyration between 5 mm and 10 cm.
pub fn arb_body() -> impl Strategy<Value = RigidBody> {
    (
        -3.0..0.0f64,
        prop::array::uniform3(2.5e-5..1e-2f64),
        prop::array::uniform4(-1.0..1.0f64),
    )
        .prop_map(|(log_m, a, axes)| {
            let m = 10f64.powf(log_m);
            // Second moments a_i give physical principal moments I_1 = m (a_2 + a_3), ...
            let moments = [m * (a[1] + a[2]), m * (a[0] + a[2]), m * (a[0] + a[1])];
            let r = random_unit(&axes).to_rotation_matrix().into_inner();
            let i = r * Mat3::from_diagonal(&Vec3::from(moments)) * r.transpose();
            RigidBody::new(m, 0.5 * (i + i.transpose())).expect("physical by construction")
        })
}

/// A unit quaternion from four numbers in [-1, 1] (identity if they are all tiny).
pub fn random_unit(c: &[f64; 4]) -> UnitQuaternion<Real> {
    let q = nalgebra::Quaternion::new(c[0], c[1], c[2], c[3]);
    if q.norm() < 1e-3 {
        UnitQuaternion::identity()
    } else {
        UnitQuaternion::from_quaternion(q)
    }
}

/// Raw kinematic values of a random state: position (m), orientation, velocity (m/s), angular
/// velocity (rad/s), and a factor by which the quaternion is off unit (as inside a step).
#[derive(Debug, Clone, Copy)]
pub struct RawState {
    /// Position, m.
    pub x: Vec3,
    /// Orientation.
    pub q: UnitQuaternion<Real>,
    /// Velocity, m/s.
    pub v: Vec3,
    /// Angular velocity, rad/s.
    pub w: Vec3,
    /// Multiplies the quaternion (1 ± 1e-3).
    pub q_scale: Real,
}

impl RawState {
    /// The 13-vector for `body`.
    pub fn state_vector(&self, body: &RigidBody) -> StateVector {
        let r = self.q.to_rotation_matrix().into_inner();
        let iw = r * body.inertia_body() * r.transpose();
        let mut y = StateVector::zeros();
        y.fixed_rows_mut::<3>(IX).copy_from(&self.x);
        let q = Quat4::new(self.q.w, self.q.i, self.q.j, self.q.k) * self.q_scale;
        y.fixed_rows_mut::<4>(IQ).copy_from(&q);
        y.fixed_rows_mut::<3>(IP)
            .copy_from(&(self.v * body.mass_kg()));
        y.fixed_rows_mut::<3>(IL).copy_from(&(iw * self.w));
        y
    }
}

/// A random [`RawState`]: |x| ≤ 0.1 m, |v| ≤ 1 m/s, |ω| ≤ 10 rad/s per component.
pub fn arb_raw_state() -> impl Strategy<Value = RawState> {
    (
        prop::array::uniform3(-0.1..0.1f64),
        prop::array::uniform4(-1.0..1.0f64),
        prop::array::uniform3(-1.0..1.0f64),
        prop::array::uniform3(-10.0..10.0f64),
        -1e-3..1e-3f64,
    )
        .prop_map(|(x, q, v, w, dq)| RawState {
            x: Vec3::from(x),
            q: random_unit(&q),
            v: Vec3::from(v),
            w: Vec3::from(w),
            q_scale: 1.0 + dq,
        })
}

/// Typical magnitudes `s_j` of the state components (see the module docs).
pub fn state_scales(y: &StateVector, body_mass_kg: Real) -> [Real; 13] {
    let mut s = [0.0; 13];
    let p = y.fixed_rows::<3>(IP).amax().max(0.01 * body_mass_kg);
    let l = y.fixed_rows::<3>(IL).amax().max(1e-12);
    for j in 0..13 {
        s[j] = match j {
            j if j < IQ => 0.1,
            j if j < IP => 1.0,
            j if j < IL => p,
            _ => l,
        };
    }
    s
}

/// Checks the analytic Jacobian `jac` of `f` at `y` against central differences, column by
/// column (see the module docs for the norm), to the relative tolerance [`FD_RTOL`].
/// `body_mass_kg` sets the momentum scale.
pub fn column_check<const R: usize>(
    jac: &SMatrix<Real, R, 13>,
    y: &StateVector,
    body_mass_kg: Real,
    mut f: impl FnMut(&StateVector) -> SVector<Real, R>,
) -> Result<(), String> {
    let s = state_scales(y, body_mass_kg);
    let floor = (0..13)
        .map(|k| jac.column(k).norm() * s[k])
        .fold(0.0, Real::max);
    for j in 0..13 {
        let h = 1e-6 * s[j];
        let mut yp = *y;
        let mut ym = *y;
        yp[j] += h;
        ym[j] -= h;
        let d_h = (f(&yp) - f(&ym)) / (2.0 * h);
        let (mut yp2, mut ym2) = (*y, *y);
        yp2[j] += 0.5 * h;
        ym2[j] -= 0.5 * h;
        let d_h2 = (f(&yp2) - f(&ym2)) / h;
        // Richardson: the O(h²) truncation of the central differences cancels.
        let fd = (d_h2 * 4.0 - d_h) / 3.0;
        let an = jac.column(j).into_owned();
        let err = (an - fd).norm();
        // Relative error, plus the floor of the other columns, plus the round-off of the
        // difference quotient itself: a few ulps of the values divided by 2h for `d_h`, twice
        // that for `d_h2`, so (4 · 2 + 1) / 3 = 3 times that for their extrapolation.
        let roundoff = 3.0 * 8.0 * Real::EPSILON * f(&yp).norm().max(f(&ym).norm()) / (2.0 * h);
        let tol = FD_RTOL * an.norm().max(fd.norm()) + 1e-9 * floor / s[j] + roundoff;
        if err > tol || err.is_nan() {
            return Err(format!(
                "column {j}: |analytic - fd| = {err:e} > {tol:e}\nanalytic {an}\nfd {fd}"
            ));
        }
    }
    Ok(())
}
