//! numpy <-> fixed-size rows.

use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Copy an `(n, D)` array into rows. Copying before the GIL is released keeps another
/// Python thread from writing under us; `as_slice` fails unless C-contiguous, which the
/// Python layer guarantees.
pub fn rows<T: numpy::Element + Copy, const D: usize>(
    array: &PyReadonlyArray2<'_, T>,
    what: &str,
) -> PyResult<Vec<[T; D]>> {
    let shape = array.shape();
    if shape.len() != 2 || shape.get(1) != Some(&D) {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape (n, {D}), got {shape:?}"
        )));
    }
    let flat = array.as_slice()?;
    flat.chunks_exact(D)
        .map(|c| {
            <[T; D]>::try_from(c).map_err(|_| PyValueError::new_err(format!("{what}: bad row")))
        })
        .collect()
}

/// Rows back into an `(n, D)` array.
pub fn to_array2<'py, T: numpy::Element + Copy, const D: usize>(
    py: Python<'py>,
    rows: &[[T; D]],
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let flat: Vec<T> = rows.iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([rows.len(), D])
}

/// Indices (offsets, site and vertex numbers, counts) as `np.intp`, the integer numpy
/// indexes with: one integer dtype across the Python API, whatever the core stores.
pub fn to_intp<'py, T: Copy>(py: Python<'py>, values: &[T]) -> PyResult<Bound<'py, PyArray1<isize>>>
where
    isize: TryFrom<T>,
{
    let out = values
        .iter()
        .map(|&x| isize::try_from(x).map_err(|_| PyValueError::new_err("index exceeds intp")))
        .collect::<PyResult<Vec<isize>>>()?;
    Ok(PyArray1::from_vec(py, out))
}

/// Rows of indices into an `(n, D)` `np.intp` array.
pub fn to_intp2<'py, T: Copy, const D: usize>(
    py: Python<'py>,
    rows: &[[T; D]],
) -> PyResult<Bound<'py, PyArray2<isize>>>
where
    isize: TryFrom<T>,
{
    let flat: Vec<T> = rows.iter().flatten().copied().collect();
    to_intp(py, &flat)?.reshape([rows.len(), D])
}

/// One increasing, non-negative problem row per site.
pub fn increasing_rows(rows: &PyReadonlyArray1<'_, i64>, n: usize) -> PyResult<Vec<usize>> {
    let global: Vec<usize> = rows
        .as_slice()?
        .iter()
        .map(|&r| usize::try_from(r).map_err(|_| PyValueError::new_err("negative row")))
        .collect::<PyResult<_>>()?;
    if global.len() != n
        || global
            .iter()
            .zip(global.iter().skip(1))
            .any(|(a, b)| a >= b)
    {
        return Err(PyValueError::new_err(
            "rows must hold one increasing row number per site",
        ));
    }
    Ok(global)
}
