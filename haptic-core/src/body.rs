//! The rigid body: mass and inertia, validated on construction.

use crate::error::CoreError;
use crate::math::{Mat3, Real};

/// Relative tolerance for the symmetry check of an inertia tensor.
const SYMMETRY_RTOL: Real = 1e-9;

/// Mass properties of the virtual tool: mass and inertia tensor about the centre of mass, in the
/// body frame.
///
/// Constructed only through [`RigidBody::new`] or [`RigidBody::from_principal`], which reject
/// non-physical values, so every `RigidBody` is usable by the dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBody {
    mass_kg: Real,
    inertia_body: Mat3,
    inertia_body_inv: Mat3,
}

impl RigidBody {
    /// A body of mass `mass_kg` (kg) with body-frame inertia `inertia_body` (kg m², about the
    /// centre of mass).
    ///
    /// # Errors
    /// - [`CoreError::NonFinite`] if any value is NaN or infinite;
    /// - [`CoreError::NonPositiveMass`] if `mass_kg <= 0`;
    /// - [`CoreError::InertiaNotSymmetric`] if `I` differs from `Iᵀ` beyond 1e-9 relative;
    /// - [`CoreError::InertiaNotPositiveDefinite`] if an eigenvalue is `<= 0`;
    /// - [`CoreError::InertiaNotPhysical`] if the principal moments violate `I₁ + I₂ ≥ I₃`.
    pub fn new(mass_kg: Real, inertia_body: Mat3) -> Result<Self, CoreError> {
        if !mass_kg.is_finite() {
            return Err(CoreError::NonFinite { what: "mass" });
        }
        if inertia_body.iter().any(|v| !v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "inertia tensor",
            });
        }
        if mass_kg <= 0.0 {
            return Err(CoreError::NonPositiveMass { mass_kg });
        }
        let scale = inertia_body.abs().max().max(Real::MIN_POSITIVE);
        let asymmetry = (inertia_body - inertia_body.transpose()).abs().max();
        if asymmetry > SYMMETRY_RTOL * scale {
            return Err(CoreError::InertiaNotSymmetric { asymmetry });
        }
        let sym = 0.5 * (inertia_body + inertia_body.transpose());
        let eig = sym.symmetric_eigenvalues();
        let min_eigenvalue = eig.min();
        if min_eigenvalue <= 0.0 {
            return Err(CoreError::InertiaNotPositiveDefinite { min_eigenvalue });
        }
        let (a, b, c) = (eig[0], eig[1], eig[2]);
        let slack = 1e-9 * scale;
        if a + b < c - slack || a + c < b - slack || b + c < a - slack {
            return Err(CoreError::InertiaNotPhysical);
        }
        let inertia_body_inv = sym
            .try_inverse()
            .ok_or(CoreError::InertiaNotPositiveDefinite { min_eigenvalue })?;
        Ok(Self {
            mass_kg,
            inertia_body: sym,
            inertia_body_inv,
        })
    }

    /// A body whose principal axes are the body axes, with principal moments `moments` (kg m²).
    ///
    /// # Errors
    /// As [`RigidBody::new`].
    pub fn from_principal(mass_kg: Real, moments: [Real; 3]) -> Result<Self, CoreError> {
        Self::new(
            mass_kg,
            Mat3::from_diagonal(&nalgebra::Vector3::new(moments[0], moments[1], moments[2])),
        )
    }

    /// A solid sphere of mass `mass_kg` and radius `radius_m`, handy for tests and examples.
    ///
    /// # Errors
    /// As [`RigidBody::new`], and [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] for a
    /// radius that is not positive and finite.
    pub fn sphere(mass_kg: Real, radius_m: Real) -> Result<Self, CoreError> {
        crate::check::positive("sphere.radius_m", radius_m)?;
        let i = 0.4 * mass_kg * radius_m * radius_m;
        Self::from_principal(mass_kg, [i, i, i])
    }

    /// The same shape with another mass: the inertia scales linearly with the mass.
    ///
    /// # Errors
    /// As [`RigidBody::new`].
    pub fn with_mass(&self, mass_kg: Real) -> Result<Self, CoreError> {
        if !mass_kg.is_finite() {
            return Err(CoreError::NonFinite { what: "mass" });
        }
        if mass_kg <= 0.0 {
            return Err(CoreError::NonPositiveMass { mass_kg });
        }
        Self::new(mass_kg, self.inertia_body * (mass_kg / self.mass_kg))
    }

    /// Mass in kilograms.
    #[inline]
    pub fn mass_kg(&self) -> Real {
        self.mass_kg
    }

    /// Body-frame inertia tensor about the centre of mass (kg m²).
    #[inline]
    pub fn inertia_body(&self) -> &Mat3 {
        &self.inertia_body
    }

    /// Inverse of the body-frame inertia tensor (1 / (kg m²)).
    #[inline]
    pub fn inertia_body_inv(&self) -> &Mat3 {
        &self.inertia_body_inv
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diag(a: Real, b: Real, c: Real) -> Mat3 {
        Mat3::from_diagonal(&nalgebra::Vector3::new(a, b, c))
    }

    #[test]
    fn accepts_a_valid_body() {
        let b = RigidBody::new(0.01, diag(1e-5, 2e-5, 2.5e-5)).unwrap();
        assert_eq!(b.mass_kg(), 0.01);
        let prod = b.inertia_body() * b.inertia_body_inv();
        assert!((prod - Mat3::identity()).norm() < 1e-12);
    }

    #[test]
    fn rejects_zero_and_negative_mass() {
        assert!(matches!(
            RigidBody::new(0.0, diag(1.0, 1.0, 1.0)),
            Err(CoreError::NonPositiveMass { .. })
        ));
        assert!(matches!(
            RigidBody::new(-1.0, diag(1.0, 1.0, 1.0)),
            Err(CoreError::NonPositiveMass { .. })
        ));
        assert!(matches!(
            RigidBody::sphere(1.0, 0.1).unwrap().with_mass(-2.0),
            Err(CoreError::NonPositiveMass { .. })
        ));
    }

    #[test]
    fn rejects_non_finite_values() {
        assert!(matches!(
            RigidBody::new(Real::NAN, diag(1.0, 1.0, 1.0)),
            Err(CoreError::NonFinite { what: "mass" })
        ));
        assert!(matches!(
            RigidBody::new(Real::INFINITY, diag(1.0, 1.0, 1.0)),
            Err(CoreError::NonFinite { what: "mass" })
        ));
        let mut i = diag(1.0, 1.0, 1.0);
        i[(0, 1)] = Real::NAN;
        assert!(matches!(
            RigidBody::new(1.0, i),
            Err(CoreError::NonFinite {
                what: "inertia tensor"
            })
        ));
        assert!(matches!(
            RigidBody::new(1.0, diag(1.0, Real::INFINITY, 1.0)),
            Err(CoreError::NonFinite { .. })
        ));
    }

    #[test]
    fn rejects_non_symmetric_inertia() {
        let mut i = diag(1.0, 1.0, 1.0);
        i[(0, 1)] = 0.1;
        assert!(matches!(
            RigidBody::new(1.0, i),
            Err(CoreError::InertiaNotSymmetric { .. })
        ));
    }

    #[test]
    fn rejects_non_positive_definite_inertia() {
        assert!(matches!(
            RigidBody::new(1.0, diag(1.0, 0.0, 1.0)),
            Err(CoreError::InertiaNotPositiveDefinite { .. })
        ));
        assert!(matches!(
            RigidBody::new(1.0, diag(1.0, -1.0, 1.0)),
            Err(CoreError::InertiaNotPositiveDefinite { .. })
        ));
        // Symmetric, positive diagonal, indefinite.
        let i = Mat3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(matches!(
            RigidBody::new(1.0, i),
            Err(CoreError::InertiaNotPositiveDefinite { .. })
        ));
    }

    #[test]
    fn rejects_non_physical_moments() {
        assert!(matches!(
            RigidBody::from_principal(1.0, [1.0, 1.0, 3.0]),
            Err(CoreError::InertiaNotPhysical)
        ));
    }

    #[test]
    fn sphere_rejects_bad_radius() {
        assert!(matches!(
            RigidBody::sphere(1.0, 0.0),
            Err(CoreError::OutOfRange {
                what: "sphere.radius_m",
                ..
            })
        ));
        assert!(matches!(
            RigidBody::sphere(1.0, f64::NAN),
            Err(CoreError::NonFinite {
                what: "sphere.radius_m"
            })
        ));
    }

    #[test]
    fn with_mass_scales_inertia() {
        let a = RigidBody::from_principal(0.1, [1e-4, 2e-4, 2.5e-4]).unwrap();
        let b = a.with_mass(0.001).unwrap();
        assert!((b.inertia_body()[(0, 0)] - 1e-6).abs() < 1e-18);
    }
}
