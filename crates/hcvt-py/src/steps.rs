//! The steps of one part of a partitioned run (`hcvt.distributed.partition`), each the
//! core's: its Lloyd step and guards, the L-BFGS coefficients, direction and acceptance.
//! The part's client sums what the parts return; nothing here sees more than one part.

use hcvt_core::lbfgs::{self, LineSearch};
use hcvt_core::{lloyd, DomainKind, Euclid, Moments, Space};
use numpy::{
    PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::arrays::{rows, to_array2};
use crate::domain::{by_kind, AnyDomain};
use crate::errors::to_py_err;

/// What a part's next step needs from its cells (`hcvt.distributed.partition`): the shift
/// to the centroid (k, d) (0 for an empty cell), whether each site is pinned (k,), and the
/// preconditioner `1/(2 m_i)` (k,), each by the core's Lloyd and L-BFGS.
#[pyfunction]
pub fn step_fields<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    mass: PyReadonlyArray1<'py, f64>,
    first: PyReadonlyArray2<'py, f64>,
    boundary_measure: PyReadonlyArray1<'py, f64>,
) -> PyResult<StepFields<'py>> {
    by_kind!(domain, dim step_fields_in(py, &sites, &mass, &first, &boundary_measure))
}

/// The core's Lloyd step of `sites` (k, d) by `shifts` (k, d), held inside.
#[pyfunction]
pub fn lloyd_step<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    shifts: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    by_kind!(domain, dim lloyd_step_in(py, &sites, &shifts))
}

/// One part's rows (k, d) of the L-BFGS direction from the coefficients of
/// `lbfgs_coefficients`, held inside: `gradient` (k, d), pairs `s` and `y` (m, k, d) oldest
/// first, `preconditioner` (k,).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn lbfgs_direction<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    gradient: PyReadonlyArray2<'py, f64>,
    s: PyReadonlyArray3<'py, f64>,
    y: PyReadonlyArray3<'py, f64>,
    preconditioner: PyReadonlyArray1<'py, f64>,
    c: PyReadonlyArray1<'py, f64>,
    e: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let part = PartPairs {
        sites: &sites,
        gradient: &gradient,
        s: &s,
        y: &y,
        preconditioner: &preconditioner,
    };
    by_kind!(domain, dim lbfgs_direction_in(py, part, &c, &e))
}

/// The coefficients `(c, e)` of the L-BFGS direction from the Gram matrices `plain` and
/// `weighted` (2m+1, 2m+1) of `[s, y, g]`, summed over the parts: the core's two-loop
/// recursion in coefficient space.
#[pyfunction]
pub fn lbfgs_coefficients<'py>(
    py: Python<'py>,
    plain: PyReadonlyArray2<'py, f64>,
    weighted: PyReadonlyArray2<'py, f64>,
) -> PyResult<Coefficients2<'py>> {
    let (c, e) =
        lbfgs::gram_coefficients(plain.as_slice()?, weighted.as_slice()?).map_err(to_py_err)?;
    Ok((PyArray1::from_vec(py, c), PyArray1::from_vec(py, e)))
}

/// Whether the partitioned run's backtracking line search accepts the step `t` with
/// energy `value` and slope `slope` from `phi0`, `slope0` (the core's acceptance).
#[pyfunction]
pub fn line_search_accepts(phi0: f64, slope0: f64, t: f64, value: f64, slope: f64) -> bool {
    LineSearch::backtracking(1).accepts(phi0, slope0, t, value, slope)
}

/// Whether an L-BFGS pair with these products is kept (the core's curvature test).
#[pyfunction]
pub fn positive_curvature(sy: f64, ss: f64, yy: f64) -> bool {
    lbfgs::positive_curvature(sy, ss, yy)
}

/// `c` (m + 1,) and `e` (m,).
type Coefficients2<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Shifts (k, d), pinned (k,), preconditioner (k,).
type StepFields<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<f64>>,
);

fn values(array: &PyReadonlyArray1<'_, f64>, n: usize, what: &str) -> PyResult<Vec<f64>> {
    let out = array.as_slice()?.to_vec();
    if out.len() != n {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape ({n},), got {:?}",
            array.shape()
        )));
    }
    Ok(out)
}

fn step_fields_in<'py, const D: usize, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    mass: &PyReadonlyArray1<'py, f64>,
    first: &PyReadonlyArray2<'py, f64>,
    boundary_measure: &PyReadonlyArray1<'py, f64>,
) -> PyResult<StepFields<'py>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(sites, "sites")?;
    let n = points.len();
    let mass = values(mass, n, "mass")?;
    let first = rows::<f64, D>(first, "first")?;
    let measure = values(boundary_measure, n, "boundary_measure")?;
    if first.len() != n {
        return Err(PyValueError::new_err("first must have one row per site"));
    }
    let moments: Vec<Moments<D>> = (mass.iter().zip(&first))
        .map(|(&mass, &first)| Moments {
            mass,
            first,
            second: 0.0,
        })
        .collect();
    let shifts = lloyd::centroid_shifts(&moments);
    let pinned = py.detach(|| lloyd::pinned(boundary, &points, &shifts, &measure));
    let shifts: Vec<[f64; D]> = shifts.iter().map(|s| s.unwrap_or([0.0; D])).collect();
    Ok((
        to_array2(py, &shifts)?,
        PyArray1::from_vec(py, pinned),
        PyArray1::from_vec(py, lbfgs::preconditioner(mass)),
    ))
}

fn lloyd_step_in<'py, const D: usize, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    shifts: &PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(sites, "sites")?;
    let shifts = rows::<f64, D>(shifts, "shifts")?;
    if shifts.len() != points.len() {
        return Err(PyValueError::new_err("shifts must have one row per site"));
    }
    let moved = py.detach(|| lloyd::lloyd_step(boundary, &points, &shifts));
    to_array2(py, &moved)
}

/// A part's sites and per-row L-BFGS state, as numpy arrays.
struct PartPairs<'a, 'py> {
    sites: &'a PyReadonlyArray2<'py, f64>,
    gradient: &'a PyReadonlyArray2<'py, f64>,
    s: &'a PyReadonlyArray3<'py, f64>,
    y: &'a PyReadonlyArray3<'py, f64>,
    preconditioner: &'a PyReadonlyArray1<'py, f64>,
}

/// An (m, k, D) array as m vectors of k rows.
fn pairs<const D: usize>(
    array: &PyReadonlyArray3<'_, f64>,
    k: usize,
    what: &str,
) -> PyResult<Vec<Vec<[f64; D]>>> {
    let shape = array.shape();
    if shape.get(1..) != Some(&[k, D][..]) {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape (m, {k}, {D}), got {shape:?}"
        )));
    }
    let flat = array.as_slice()?;
    Ok(flat
        .chunks_exact((k * D).max(1))
        .map(|pair| {
            pair.chunks_exact(D)
                .filter_map(|row| <[f64; D]>::try_from(row).ok())
                .collect()
        })
        .collect())
}

fn lbfgs_direction_in<'py, const D: usize, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    part: PartPairs<'_, 'py>,
    c: &PyReadonlyArray1<'py, f64>,
    e: &PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(part.sites, "sites")?;
    let k = points.len();
    let gradient = rows::<f64, D>(part.gradient, "gradient")?;
    let s = pairs::<D>(part.s, k, "s")?;
    let y = pairs::<D>(part.y, k, "y")?;
    if gradient.len() != k {
        return Err(PyValueError::new_err("gradient must have one row per site"));
    }
    let preconditioner = part.preconditioner.as_slice()?;
    let mut direction = lbfgs::combine(
        c.as_slice()?,
        e.as_slice()?,
        &gradient,
        &s,
        &y,
        preconditioner,
    )
    .map_err(to_py_err)?;
    py.detach(|| lloyd::hold_inside(boundary, &points, &mut direction));
    to_array2(py, &direction)
}
