//! Scalar and matrix aliases, state-vector layout, and the quaternion calculus that every force
//! model needs (rotation matrix, its partials `R_k`, `Q(q)`, `Ω(ω)`).
//!
//! Quaternions are `(w, x, y, z)` in the state vector; `R(q)` maps body to world. The rotation
//! matrix is the usual unit-quaternion polynomial `1 - 2(y² + z²), …` evaluated on the raw
//! components, so that its partials `R_k = ∂R/∂q_k` are exact derivatives of what the dynamics
//! evaluate (paper eqs. 8–10, differentiated "entry by entry").

use nalgebra::{
    Matrix3, Matrix3x4, Matrix4, Matrix4x3, SMatrix, SVector, UnitQuaternion, Vector3, Vector4,
};

/// The scalar type of the whole workspace.
pub type Real = f64;
/// A 3-vector (metres, newtons, … as documented where used).
pub type Vec3 = Vector3<Real>;
/// A 3×3 matrix.
pub type Mat3 = Matrix3<Real>;
/// A quaternion as a plain 4-vector in `(w, x, y, z)` order.
pub type Quat4 = Vector4<Real>;
/// The 13-dimensional tool state `y = (x, q, P, L)` (paper eq. 2).
pub type StateVector = SVector<Real, 13>;
/// A wrench `(F, T)` as a 6-vector.
pub type WrenchVector = SVector<Real, 6>;
/// Jacobian of a wrench `(F, T)` with respect to the state `y`: 6×13.
pub type WrenchJacobian = SMatrix<Real, 6, 13>;
/// Jacobian of the state derivative with respect to the state: 13×13 (paper eqs. 6–12).
pub type SystemJacobian = SMatrix<Real, 13, 13>;

/// Offset of the centre-of-mass position `x` in [`StateVector`].
pub const IX: usize = 0;
/// Offset of the orientation quaternion `q = (w, x, y, z)` in [`StateVector`].
pub const IQ: usize = 3;
/// Offset of the linear momentum `P` in [`StateVector`].
pub const IP: usize = 7;
/// Offset of the angular momentum `L` in [`StateVector`].
pub const IL: usize = 10;

/// The skew matrix `[a]×` with `[a]× b = a × b`.
#[inline]
pub fn skew(a: &Vec3) -> Mat3 {
    Mat3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// `R(q)`, body to world, as the unit-quaternion polynomial evaluated on the raw components.
#[inline]
pub fn rotation_matrix(q: &Quat4) -> Mat3 {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    Mat3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    )
}

/// The partials `R_k = ∂R/∂q_k` for `k = w, x, y, z` of [`rotation_matrix`].
#[inline]
pub fn rotation_partials(q: &Quat4) -> [Mat3; 4] {
    let (w, x, y, z) = (2.0 * q[0], 2.0 * q[1], 2.0 * q[2], 2.0 * q[3]);
    [
        Mat3::new(0.0, -z, y, z, 0.0, -x, -y, x, 0.0),
        Mat3::new(0.0, y, z, y, -2.0 * x, -w, z, w, -2.0 * x),
        Mat3::new(-2.0 * y, x, w, x, 0.0, z, -w, z, -2.0 * y),
        Mat3::new(-2.0 * z, -w, x, w, -2.0 * z, y, x, y, 0.0),
    ]
}

/// `Q(q)` of `dq/dt = ½ Q(q) ω` (4×3): `[ -(x,y,z)ᵀ ; w I₃ - [(x,y,z)]× ]`.
#[inline]
pub fn q_matrix(q: &Quat4) -> Matrix4x3<Real> {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    Matrix4x3::new(-x, -y, -z, w, z, -y, -z, w, x, y, -x, w)
}

/// `Ω(ω)` with `∂(Q(q) ω)/∂q = Ω(ω)` (4×4): `[ 0  -ωᵀ ; ω  [ω]× ]`.
#[inline]
pub fn omega_matrix(omega: &Vec3) -> Matrix4<Real> {
    let (a, b, c) = (omega.x, omega.y, omega.z);
    Matrix4::new(0.0, -a, -b, -c, a, 0.0, -c, b, b, c, 0.0, -a, c, -b, a, 0.0)
}

/// The quaternion part of a state vector, `(w, x, y, z)`.
#[inline]
pub fn state_quat(y: &StateVector) -> Quat4 {
    y.fixed_rows::<4>(IQ).into_owned()
}

/// Whether every entry of a matrix or vector is finite.
#[inline]
pub fn all_finite<const R: usize, const C: usize>(m: &SMatrix<Real, R, C>) -> bool {
    m.iter().all(|v| v.is_finite())
}

/// `θ u` of the rotation `p` (any non-zero scale), shortest arc, and its derivative w.r.t. the
/// four components of `p` (3×4; eqs. 24–25). Used by the virtual coupling's rotational spring (eq. 16).
///
/// With `p = ±(w, v)` flipped so that `w >= 0`: `θ u = g v` with `g = 2 atan2(|v|, w) / |v|`,
/// `∂(θu)/∂w = -2 v / |p|²`, `∂(θu)/∂v = g I + h v vᵀ`, `h = (∂g/∂|v|)/|v|`. For
/// `|v| < 10⁻² w` (θ below about 1.1°) `g` and `h` use their series in `t = |v|²/w²`, which
/// avoids `0/0` at `θ = 0`. Near `θ = π` (`w → 0`) the closed forms are regular; `θ u` itself
/// jumps from `π u` to `-π u` when `w` changes sign, as any shortest-arc map must.
pub fn rotation_vector(p: &Quat4) -> (Vec3, Matrix3x4<Real>) {
    let sign = if p[0] < 0.0 { -1.0 } else { 1.0 };
    let w = sign * p[0];
    let v = sign * Vec3::new(p[1], p[2], p[3]);
    let n2 = v.norm_squared();
    let s = n2 + w * w;
    if !(s > 0.0 && s.is_finite()) {
        return (Vec3::zeros(), Matrix3x4::zeros());
    }
    let n = n2.sqrt();
    let (g, h) = if n < 1e-2 * w {
        let t = n2 / (w * w);
        let g = (2.0 / w) * (1.0 + t * (-1.0 / 3.0 + t * (1.0 / 5.0 + t * (-1.0 / 7.0 + t / 9.0))));
        let h = (2.0 / (w * w * w))
            * (-2.0 / 3.0 + t * (4.0 / 5.0 + t * (-6.0 / 7.0 + t * (8.0 / 9.0 - t * 10.0 / 11.0))));
        (g, h)
    } else {
        let a = n.atan2(w);
        (2.0 * a / n, 2.0 * (w / (n2 * s) - a / (n2 * n)))
    };
    let phi = g * v;
    let mut jac = Matrix3x4::zeros();
    jac.set_column(0, &(v * (-2.0 * sign / s)));
    let dv = (Mat3::identity() * g + h * v * v.transpose()) * sign;
    jac.fixed_view_mut::<3, 3>(0, 1).copy_from(&dv);
    (phi, jac)
}

/// The matrix `M(a)` of left multiplication, `a ⊗ b = M(a) b`, quaternions `(w, x, y, z)`.
pub fn left_product_matrix(a: &Quat4) -> Matrix4<Real> {
    let (w, x, y, z) = (a[0], a[1], a[2], a[3]);
    Matrix4::new(w, -x, -y, -z, x, w, -z, y, y, z, w, -x, z, -y, x, w)
}

/// The components `(w, x, y, z)` of a unit quaternion, as a 4-vector.
pub fn quat4(q: &UnitQuaternion<Real>) -> Quat4 {
    Quat4::new(q.w, q.i, q.j, q.k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Quaternion, UnitQuaternion};

    fn central_partial(q: &Quat4, k: usize) -> Mat3 {
        let h = 1e-6;
        let mut qp = *q;
        let mut qm = *q;
        qp[k] += h;
        qm[k] -= h;
        (rotation_matrix(&qp) - rotation_matrix(&qm)) / (2.0 * h)
    }

    #[test]
    fn rotation_matches_nalgebra_for_unit_quaternions() {
        let uq = UnitQuaternion::from_quaternion(Quaternion::new(0.3, -0.5, 0.7, 0.2));
        let q = Quat4::new(uq.w, uq.i, uq.j, uq.k);
        let diff = rotation_matrix(&q) - uq.to_rotation_matrix().into_inner();
        assert!(diff.norm() < 1e-14, "{diff}");
    }

    #[test]
    fn rotation_partials_match_central_differences() {
        let q = Quat4::new(0.3, -0.5, 0.7, 0.2).normalize();
        let partials = rotation_partials(&q);
        for (k, analytic) in partials.iter().enumerate() {
            let fd = central_partial(&q, k);
            assert!((analytic - fd).norm() < 1e-8, "k = {k}: {analytic} vs {fd}");
        }
    }

    #[test]
    fn q_and_omega_matrices_agree_with_quaternion_product() {
        let q = Quat4::new(0.3, -0.5, 0.7, 0.2).normalize();
        let omega = Vec3::new(1.5, -2.0, 0.25);
        let via_q = q_matrix(&q) * omega;
        let via_omega = omega_matrix(&omega) * q;
        let prod = Quaternion::new(0.0, omega.x, omega.y, omega.z)
            * Quaternion::new(q[0], q[1], q[2], q[3]);
        let expected = Quat4::new(prod.w, prod.i, prod.j, prod.k);
        assert!((via_q - expected).norm() < 1e-14);
        assert!((via_omega - expected).norm() < 1e-14);
    }

    #[test]
    fn skew_is_cross_product() {
        let a = Vec3::new(1.0, 2.0, 3.0);
        let b = Vec3::new(-0.5, 0.25, 4.0);
        assert!((skew(&a) * b - a.cross(&b)).norm() < 1e-15);
    }

    #[test]
    fn rotation_vector_matches_nalgebra_and_takes_the_short_arc() {
        for (axis, angle) in [
            (Vec3::new(1.0, 2.0, -0.5), 0.3),
            (Vec3::new(0.0, 0.0, 1.0), 3.0),
            (Vec3::new(-1.0, 0.2, 0.1), 1e-7),
        ] {
            let q = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
            let (phi, _) = rotation_vector(&quat4(&q));
            assert!(
                (phi - q.scaled_axis()).norm() < 1e-14,
                "{phi} vs {}",
                q.scaled_axis()
            );
            // -q is the same rotation: same vector, and a scaled quaternion too.
            let (phi2, _) = rotation_vector(&(-quat4(&q) * 1.7));
            assert!((phi2 - phi).norm() < 1e-14);
        }
        // A rotation by 350° about z is -10° about z.
        let q = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 350f64.to_radians());
        let (phi, _) = rotation_vector(&quat4(&q));
        assert!((phi - Vec3::new(0.0, 0.0, -10f64.to_radians())).norm() < 1e-12);
        assert_eq!(rotation_vector(&Quat4::zeros()).0, Vec3::zeros());
    }
}
