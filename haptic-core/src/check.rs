//! One way to check a parameter: finiteness and ranges, with the same error everywhere.
//!
//! The parameters of core, dynamics and device types (device limits, query parameters, coupling,
//! penalty, integrators, gravity, the simulated hand, scaling, the SpaceMouse, recordings) are
//! checked with these functions, so a bad value gives [`CoreError::NonFinite`] or
//! [`CoreError::OutOfRange`] (wrapped in the crate's own error), naming the parameter by its field
//! path, as `"coupling.stiffness_n_per_m"`: the struct (or scene section) and the field, the way a
//! user writes it. Three validators keep their own error because they say more than a range: the
//! rigid body's (`NonPositiveMass`, `InertiaNotPhysical`, ...), the scene's and the runtime
//! configuration's (field paths built at run time, as `obstacles[2].scale_m_per_unit`), and the
//! mesh loader's and clusterer's (`MeshError::BadParameter`, `ClusterError::BadDelta`).
//!
//! ```
//! use haptic_core::{CoreError, check};
//!
//! assert_eq!(check::positive("penalty.stiffness_n_per_m", 2000.0), Ok(2000.0));
//! assert!(matches!(
//!     check::positive("penalty.stiffness_n_per_m", 0.0),
//!     Err(CoreError::OutOfRange { what: "penalty.stiffness_n_per_m", .. })
//! ));
//! assert!(matches!(
//!     check::non_negative("coupling.damping_ns_per_m", f64::NAN),
//!     Err(CoreError::NonFinite { what: "coupling.damping_ns_per_m" })
//! ));
//! ```

use crate::Real;
use crate::error::CoreError;

/// `value` if it is finite, else [`CoreError::NonFinite`].
///
/// # Errors
/// [`CoreError::NonFinite`] naming `what`.
pub fn finite(what: &'static str, value: Real) -> Result<Real, CoreError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(CoreError::NonFinite { what })
    }
}

/// `value` if it is finite and `> 0`.
///
/// # Errors
/// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] naming `what`.
pub fn positive(what: &'static str, value: Real) -> Result<Real, CoreError> {
    at_least(what, finite(what, value)?, 0.0, false, "> 0")
}

/// `value` if it is finite and `>= 0`.
///
/// # Errors
/// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] naming `what`.
pub fn non_negative(what: &'static str, value: Real) -> Result<Real, CoreError> {
    at_least(what, finite(what, value)?, 0.0, true, ">= 0")
}

/// `value` if it is finite and in `[lo, hi]`; `expected` says so in words (`"in [0, 1]"`).
///
/// # Errors
/// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] naming `what`.
pub fn in_range(
    what: &'static str,
    value: Real,
    lo: Real,
    hi: Real,
    expected: &'static str,
) -> Result<Real, CoreError> {
    let v = finite(what, value)?;
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(CoreError::OutOfRange {
            what,
            value: v,
            expected,
        })
    }
}

/// `value` if it is finite and in `[lo, hi)`; `expected` says so in words (`"in [0, 1)"`).
///
/// # Errors
/// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] naming `what`.
pub fn in_half_open(
    what: &'static str,
    value: Real,
    lo: Real,
    hi: Real,
    expected: &'static str,
) -> Result<Real, CoreError> {
    let v = finite(what, value)?;
    if (lo..hi).contains(&v) {
        Ok(v)
    } else {
        Err(CoreError::OutOfRange {
            what,
            value: v,
            expected,
        })
    }
}

/// `Ok` if every value is finite (the components of a vector or a pose).
///
/// # Errors
/// [`CoreError::NonFinite`] naming `what`.
pub fn all_finite(
    what: &'static str,
    values: impl IntoIterator<Item = Real>,
) -> Result<(), CoreError> {
    if values.into_iter().all(Real::is_finite) {
        Ok(())
    } else {
        Err(CoreError::NonFinite { what })
    }
}

fn at_least(
    what: &'static str,
    value: Real,
    min: Real,
    inclusive: bool,
    expected: &'static str,
) -> Result<Real, CoreError> {
    if value > min || (inclusive && value == min) {
        Ok(value)
    } else {
        Err(CoreError::OutOfRange {
            what,
            value,
            expected,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_name_the_field_and_the_rule() {
        assert_eq!(positive("a", 1.0), Ok(1.0));
        assert_eq!(non_negative("a", 0.0), Ok(0.0));
        assert_eq!(
            positive("a", 0.0),
            Err(CoreError::OutOfRange {
                what: "a",
                value: 0.0,
                expected: "> 0"
            })
        );
        assert_eq!(
            non_negative("b", -1.0),
            Err(CoreError::OutOfRange {
                what: "b",
                value: -1.0,
                expected: ">= 0"
            })
        );
        for bad in [Real::NAN, Real::INFINITY, Real::NEG_INFINITY] {
            assert_eq!(positive("c", bad), Err(CoreError::NonFinite { what: "c" }));
            assert_eq!(
                in_range("c", bad, 0.0, 1.0, "in [0, 1]"),
                Err(CoreError::NonFinite { what: "c" })
            );
        }
        assert_eq!(in_range("d", 1.0, 0.0, 1.0, "in [0, 1]"), Ok(1.0));
        assert!(in_half_open("e", 1.0, 0.0, 1.0, "in [0, 1)").is_err());
        assert_eq!(in_half_open("e", 0.0, 0.0, 1.0, "in [0, 1)"), Ok(0.0));
        assert_eq!(
            all_finite("f", [1.0, Real::NAN]),
            Err(CoreError::NonFinite { what: "f" })
        );
        assert_eq!(all_finite("f", [1.0, 2.0]), Ok(()));
        assert!(matches!(
            in_range("d", 1.5, 0.0, 1.0, "in [0, 1]"),
            Err(CoreError::OutOfRange { what: "d", .. })
        ));
    }
}
