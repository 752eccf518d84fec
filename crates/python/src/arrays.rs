//! NumPy arrays in and out: `(N, 3)` float64 points, `(F, 3)` integer triangles, read
//! through their strides (any layout), checked before anything is built from them.

use fibfluid_geometry::Vec3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::error;

/// Points from an `(N, 3)` float64 array (the Python side converts other dtypes first).
/// `what` names the argument in messages.
pub(crate) fn points(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vec3>> {
    let a: PyReadonlyArrayDyn<'_, f64> =
        a.extract().map_err(|_| error(format!("{what} must be a float64 array of shape (N, 3)")))?;
    let v = a.as_array();
    if v.ndim() != 2 || v.shape()[1] != 3 {
        return Err(error(format!("{what} must be an array of shape (N, 3), got shape {:?}", v.shape())));
    }
    let v = v.into_dimensionality::<numpy::ndarray::Ix2>().map_err(|e| error(format!("{what}: {e}")))?;
    Ok(v.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// Triangles from an `(F, 3)` int64 array; a negative index or one past `u32` is an error
/// naming the face. (Indices past the vertices are the mesh check's error.)
pub(crate) fn triangles(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[u32; 3]>> {
    let a: PyReadonlyArrayDyn<'_, i64> =
        a.extract().map_err(|_| error(format!("{what} must be an integer array of shape (F, 3)")))?;
    let v = a.as_array();
    if v.ndim() != 2 || v.shape()[1] != 3 {
        return Err(error(format!("{what} must be an array of shape (F, 3), got shape {:?}", v.shape())));
    }
    let v = v.into_dimensionality::<numpy::ndarray::Ix2>().map_err(|e| error(format!("{what}: {e}")))?;
    v.rows()
        .into_iter()
        .enumerate()
        .map(|(face, r)| {
            let index = |i: i64| {
                u32::try_from(i).map_err(|_| {
                    error(format!("face {face} refers to vertex {i}, which is not a valid index"))
                })
            };
            Ok([index(r[0])?, index(r[1])?, index(r[2])?])
        })
        .collect()
}

/// Points as a new `(N, 3)` float64 array.
pub(crate) fn points_array<'py>(py: Python<'py>, p: &[Vec3]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((p.len(), 3), |(i, c)| p[i][c]).into_pyarray(py)
}

/// Triangles as a new `(F, 3)` int64 array.
pub(crate) fn triangles_array<'py>(py: Python<'py>, t: &[[u32; 3]]) -> Bound<'py, PyArray2<i64>> {
    Array2::from_shape_fn((t.len(), 3), |(k, c)| i64::from(t[k][c])).into_pyarray(py)
}

/// Three finite floats from any sequence of three numbers; `what` names it in messages.
pub(crate) fn vec3(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec3> {
    let bad = || error(format!("{what} must be three finite numbers [x, y, z]"));
    let seq: Vec<f64> = v.extract().map_err(|_| bad())?;
    match seq.as_slice() {
        [x, y, z] if [x, y, z].iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(bad()),
    }
}
