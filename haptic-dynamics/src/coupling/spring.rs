//! The coupling's springs: linear, or levelling off at the device's limit (eqs. 26–27).

use haptic_core::check;
use haptic_core::{Mat3, Real, Vec3};

use crate::error::DynamicsError;

/// Device saturation (eqs. 26–27): the largest force and torque the coupling springs produce.
///
/// The spring's force magnitude `f(d)` is `k d` up to `d₁ = α F_max / k`, follows the cubic
/// Hermite curve with `f(d₁) = k d₁`, `f'(d₁) = k`, `f(d₂) = F_max`, `f'(d₂) = 0` on `[d₁, d₂]`,
/// and stays at `F_max` beyond `d₂`. `d₂ = (2 - α) F_max / k` is the only choice that keeps the
/// curve monotone and concave (the Hermite cubic then reduces to a parabola); `α` is
/// [`Saturation::linear_fraction`]. The torque spring does the same with `k_θ` and `τ_max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Saturation {
    /// Largest spring force, N (`F_max`).
    pub max_force_n: Real,
    /// Largest spring torque, N m (`τ_max`).
    pub max_torque_nm: Real,
    /// Fraction `α` of the limit reached linearly before the spline starts, in (0, 1).
    pub linear_fraction: Real,
}

impl Saturation {
    /// Default [`Saturation::linear_fraction`]: linear up to 80 % of the limit.
    pub const DEFAULT_LINEAR_FRACTION: Real = 0.8;

    /// Limits of `max_force_n` (N) and `max_torque_nm` (N m), linear up to 80 % of them.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) for limits that are not
    /// positive and finite.
    pub fn new(max_force_n: Real, max_torque_nm: Real) -> Result<Self, DynamicsError> {
        Self::with_linear_fraction(max_force_n, max_torque_nm, Self::DEFAULT_LINEAR_FRACTION)
    }

    /// As [`Saturation::new`] with an explicit linear fraction `α`.
    ///
    /// # Errors
    /// As [`Saturation::new`], and [`DynamicsError::Core`] unless `0 < α < 1`.
    pub fn with_linear_fraction(
        max_force_n: Real,
        max_torque_nm: Real,
        linear_fraction: Real,
    ) -> Result<Self, DynamicsError> {
        let s = Self {
            max_force_n,
            max_torque_nm,
            linear_fraction,
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks the fields (they are public).
    ///
    /// # Errors
    /// As [`Saturation::with_linear_fraction`].
    pub fn validate(&self) -> Result<(), DynamicsError> {
        check::positive("saturation.max_force_n", self.max_force_n)?;
        check::positive("saturation.max_torque_nm", self.max_torque_nm)?;
        let a = check::finite("saturation.linear_fraction", self.linear_fraction)?;
        if !(a > 0.0 && a < 1.0) {
            return Err(haptic_core::CoreError::OutOfRange {
                what: "saturation.linear_fraction",
                value: a,
                expected: "strictly between 0 and 1",
            }
            .into());
        }
        Ok(())
    }
}

/// A spring `S(e) = f(|e|) e / |e|` whose magnitude is linear, then the saturation spline, then
/// flat (eqs. 26–27). Without a limit it is the linear spring `k e`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplineSpring {
    stiffness: Real,
    d1: Real,
    d2: Real,
    max: Real,
}

impl SplineSpring {
    /// The linear spring `k e` (stiffness in N/m or N m/rad).
    pub fn linear(stiffness: Real) -> Self {
        Self {
            stiffness,
            d1: Real::INFINITY,
            d2: Real::INFINITY,
            max: Real::INFINITY,
        }
    }

    /// A spring of stiffness `stiffness` saturating at `max` with linear fraction `alpha`.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) unless stiffness and limit are positive
    /// and `0 < alpha < 1`.
    pub fn saturated(stiffness: Real, max: Real, alpha: Real) -> Result<Self, DynamicsError> {
        check::positive("spring.stiffness", stiffness)?;
        check::positive("spring.max", max)?;
        Saturation::with_linear_fraction(max, max, alpha)?;
        let d1 = alpha * max / stiffness;
        let d2 = (2.0 - alpha) * max / stiffness;
        Ok(Self {
            stiffness,
            d1,
            d2,
            max,
        })
    }

    /// Deviation where the spline starts (`d₁`) and where it is flat (`d₂`); infinite when the
    /// spring is linear.
    pub fn knees(&self) -> (Real, Real) {
        (self.d1, self.d2)
    }

    /// The magnitude `f(d)` and its slope `f'(d)` at deviation `d >= 0` (eq. 26).
    #[inline]
    pub fn magnitude(&self, d: Real) -> (Real, Real) {
        let k = self.stiffness;
        if d <= self.d1 {
            (k * d, k)
        } else if d >= self.d2 {
            (self.max, 0.0)
        } else {
            // Cubic Hermite on [d1, d2]: p0 = k d1, m0 = k, p1 = max, m1 = 0.
            let delta = self.d2 - self.d1;
            let s = (d - self.d1) / delta;
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let f = h00 * k * self.d1 + h10 * delta * k + h01 * self.max;
            let dh00 = 6.0 * s2 - 6.0 * s;
            let dh10 = 3.0 * s2 - 4.0 * s + 1.0;
            let dh01 = -6.0 * s2 + 6.0 * s;
            let df = (dh00 * k * self.d1 + dh10 * delta * k + dh01 * self.max) / delta;
            (f, df)
        }
    }

    /// `S(e)` and `∂S/∂e = k(d) I + k'(d) e eᵀ / d` with `k(d) = f(d)/d` (eq. 27).
    #[inline]
    pub fn vector(&self, e: &Vec3) -> (Vec3, Mat3) {
        let d = e.norm();
        if d <= self.d1 {
            return (self.stiffness * e, Mat3::identity() * self.stiffness);
        }
        let (f, df) = self.magnitude(d);
        let kd = f / d;
        let dkd = (df * d - f) / (d * d);
        (
            kd * e,
            Mat3::identity() * kd + (dkd / d) * e * e.transpose(),
        )
    }
}
