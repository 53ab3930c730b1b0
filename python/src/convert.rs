//! Arguments from Python checked into Rust values, and Rust values out as numpy arrays. Any
//! array-like numpy accepts is taken; shapes are checked, and a NaN or an infinity is an
//! `InputError` naming the argument.

use haptic_core::{Pose, Real, Vec3};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::input;

/// `obj` as a float64 numpy array (a copy only when numpy needs one).
fn as_f64<'py>(obj: &Bound<'py, PyAny>, field: &str) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| input(field, format!("must be an array of numbers ({e})")))?;
    // Real numbers only: a complex array would lose its imaginary part, a boolean or object
    // array is not a number.
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "i" | "u" | "f") {
        return Err(input(
            field,
            format!(
                "must be an array of real numbers, got dtype {}",
                arr.getattr("dtype")?
            ),
        ));
    }
    let arr = np.call_method1("asarray", (arr, "float64"))?;
    arr.cast_into::<PyArrayDyn<f64>>()
        .map_err(|_| input(field, "must be an array of numbers"))
}

/// A `(n, cols)` float64 array, finite, as rows; `n ≥ 1` unless `allow_empty`.
pub fn rows<const C: usize>(
    obj: &Bound<'_, PyAny>,
    field: &str,
    allow_empty: bool,
) -> PyResult<Vec<[f64; C]>> {
    let arr = as_f64(obj, field)?;
    let shape = arr.shape().to_vec();
    if shape.len() != 2 || shape[1] != C {
        return Err(input(
            field,
            format!("must have shape (n, {C}), got {shape:?}"),
        ));
    }
    if shape[0] == 0 && !allow_empty {
        return Err(input(field, "must not be empty"));
    }
    let ro = arr.readonly();
    let view = ro.as_array();
    let mut out = Vec::with_capacity(shape[0]);
    for (i, row) in view.outer_iter().enumerate() {
        let mut r = [0.0; C];
        for (j, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(input(
                    field,
                    format!("row {i} holds {v}: values must be finite"),
                ));
            }
            r[j] = *v;
        }
        out.push(r);
    }
    Ok(out)
}

/// A 1-D float64 array of finite values, of length `len` if given.
pub fn vector(obj: &Bound<'_, PyAny>, field: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let v = vector_unchecked(obj, field, len)?;
    if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
        return Err(input(field, format!("holds {bad}: values must be finite")));
    }
    Ok(v)
}

/// A 1-D float64 array of length `len` if given, NaN and infinities kept.
pub fn vector_unchecked(
    obj: &Bound<'_, PyAny>,
    field: &str,
    len: Option<usize>,
) -> PyResult<Vec<f64>> {
    let arr = as_f64(obj, field)?;
    let shape = arr.shape().to_vec();
    if shape.len() != 1 || len.is_some_and(|n| shape[0] != n) {
        let want = len.map_or("(n,)".to_owned(), |n| format!("({n},)"));
        return Err(input(
            field,
            format!("must have shape {want}, got {shape:?}"),
        ));
    }
    let ro = arr.readonly();
    Ok(ro.as_array().iter().copied().collect())
}

/// Three finite floats.
pub fn vec3(obj: &Bound<'_, PyAny>, field: &str) -> PyResult<Vec3> {
    let v = vector(obj, field, Some(3))?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// A 3×3 finite matrix.
pub fn mat3(obj: &Bound<'_, PyAny>, field: &str) -> PyResult<haptic_core::Mat3> {
    let shape = as_f64(obj, field)?.shape().to_vec();
    if shape != [3, 3] {
        return Err(input(
            field,
            format!("must have shape (3, 3), got {shape:?}"),
        ));
    }
    let r = rows::<3>(obj, field, false)?;
    Ok(haptic_core::Mat3::from_fn(|i, j| r[i][j]))
}

/// A pose from `[x, y, z, qw, qx, qy, qz]`: finite, with a unit quaternion (within 1e-6, then
/// normalised).
pub fn pose_from(v: &[f64], field: &str) -> PyResult<Pose> {
    if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
        return Err(input(field, format!("holds {bad}: a pose must be finite")));
    }
    let q = nalgebra::Quaternion::new(v[3], v[4], v[5], v[6]);
    let norm = q.norm();
    if (norm - 1.0).abs() > 1e-6 {
        return Err(input(
            field,
            format!("the quaternion [qw, qx, qy, qz] has norm {norm}, not 1"),
        ));
    }
    // Within the core's 1e-9 the quaternion goes as it is (normalised once, by the core, as in
    // Rust: the same bits); within 1e-6 (single-precision sources) it is scaled to unit first.
    let q = if (norm - 1.0).abs() <= haptic_core::state::UNIT_QUATERNION_TOL {
        q
    } else {
        q / norm
    };
    Pose::new(Vec3::new(v[0], v[1], v[2]), q).map_err(|e| input(field, e))
}

/// A pose argument (7 floats).
pub fn pose(obj: &Bound<'_, PyAny>, field: &str) -> PyResult<Pose> {
    // The common case, a float64 array of 7, without a call into numpy.
    if let Ok(a) = obj.cast::<PyArray1<f64>>() {
        if let Ok(ro) = a.try_readonly() {
            if let Ok(v) = ro.as_slice() {
                if v.len() == 7 {
                    return pose_from(v, field);
                }
            }
        }
    }
    let arr = as_f64(obj, field)?;
    if arr.shape() != [7] {
        return Err(input(
            field,
            format!(
                "a pose is 7 floats [x, y, z, qw, qx, qy, qz], got shape {:?}",
                arr.shape()
            ),
        ));
    }
    let ro = arr.readonly();
    let v: Vec<f64> = ro.as_array().iter().copied().collect();
    pose_from(&v, field)
}

/// A positive, finite float.
pub fn positive(v: f64, field: &str) -> PyResult<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(input(
            field,
            format!("must be positive and finite, got {v}"),
        ))
    }
}

/// A non-negative, finite float.
pub fn non_negative(v: f64, field: &str) -> PyResult<f64> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(input(
            field,
            format!("must be non-negative and finite, got {v}"),
        ))
    }
}

/// `[x, y, z, qw, qx, qy, qz]` of a pose.
pub fn pose_array(p: &Pose) -> [Real; 7] {
    haptic_runtime::recording::pose_array(p)
}

/// A `(n, 3)` array from vectors.
pub fn array3<'py>(
    py: Python<'py>,
    v: impl ExactSizeIterator<Item = Vec3>,
) -> Bound<'py, PyArray2<f64>> {
    let n = v.len();
    let mut flat = Vec::with_capacity(3 * n);
    for p in v {
        flat.extend_from_slice(&[p.x, p.y, p.z]);
    }
    Array2::from_shape_vec((n, 3), flat)
        .expect("3 values a row")
        .into_pyarray(py)
}

/// A `(n, C)` array from rows.
pub fn array_rows<'py, const C: usize>(
    py: Python<'py>,
    rows: &[[f64; C]],
) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Array2::from_shape_vec((rows.len(), C), flat)
        .expect("C values a row")
        .into_pyarray(py)
}

/// Two 1-D arrays: a force and a torque.
pub type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// A 1-D array.
pub fn array1<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>) -> Bound<'py, PyArray1<T>> {
    v.into_pyarray(py)
}

/// A stopping rule by its name (`"deviation"`, `"coherence"` or `"coherence-budget"`), for
/// the argument `field`.
pub fn stopping_rule(name: &str, field: &str) -> PyResult<haptic_collision::StoppingRule> {
    name.parse().map_err(|e| input(field, e))
}
