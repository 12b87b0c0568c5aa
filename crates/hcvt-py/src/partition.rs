//! One partition's cells among its own sites and a halo (`hcvt.distributed`).

use hcvt_core::{
    clipped_cells, ConvexCell, DomainKind, Euclid, Options, PartCells, PowerWhole, Request, Space,
};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{increasing_rows, rows, to_intp};
use crate::density::{Coefficients, Given};
use crate::diagram::diagram_dict;
use crate::domain::{by_kind, AnyDomain};

/// Cells of `sites[own]` among `sites` (n, d), a part of a problem of `total_sites` sites
/// whose row numbers are `rows` (n,), increasing: `voronoi`'s dict with one row per own
/// site (moments about `sites[own]`) and neighbours in the problem's rows (intp), plus
/// `reach2` (k,) (see `hcvt.distributed`). The density as for `voronoi`. A part of a
/// power diagram takes `weights` (n,), indexed like `sites`, and `power_whole`, the whole
/// problem's `(lo (d,), hi (d,), largest weight)` of its sites (`hcvt_core::PowerWhole`).
#[pyfunction]
#[pyo3(signature = (domain, sites, rows, own, total_sites, allow_outside=false, polynomial=None, function=None, quadrature_degree=4, weights=None, power_whole=None))]
#[allow(clippy::too_many_arguments)]
pub fn partition_cells<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    rows: PyReadonlyArray1<'py, i64>,
    own: PyReadonlyArray1<'py, u32>,
    total_sites: usize,
    allow_outside: bool,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
    weights: Option<PyReadonlyArray1<'py, f64>>,
    power_whole: Option<(Vec<f64>, Vec<f64>, f64)>,
) -> PyResult<Bound<'py, PyDict>> {
    let given = Given::new(polynomial, function, quadrature_degree)?;
    let weights = weights.as_ref().map(|w| w.as_slice()).transpose()?;
    let job = Part {
        total_sites,
        allow_outside,
        given: &given,
        weights,
        power_whole: power_whole.as_ref(),
    };
    by_kind!(domain, cells_dict(py, sites, rows, own, job))
}

/// What a part's computation is told besides its sites.
struct Part<'a> {
    total_sites: usize,
    allow_outside: bool,
    given: &'a Given,
    weights: Option<&'a [f64]>,
    power_whole: Option<&'a (Vec<f64>, Vec<f64>, f64)>,
}

/// The whole problem's box and largest weight as the core takes them, checked.
fn power_whole<const D: usize>(
    given: (&[f64], &[f64], f64),
    sites: usize,
) -> PyResult<PowerWhole<D>> {
    let (lo, hi, max_weight) = given;
    let corner = |v: &[f64], what: &str| -> PyResult<[f64; D]> {
        <[f64; D]>::try_from(v).map_err(|_| {
            pyo3::exceptions::PyValueError::new_err(format!(
                "power_whole: {what} must have {D} values, got {}",
                v.len()
            ))
        })
    };
    Ok(PowerWhole {
        lo: corner(lo, "lo")?,
        hi: corner(hi, "hi")?,
        sites,
        max_weight,
    })
}

fn cells_dict<'py, const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    py: Python<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    rows_in: PyReadonlyArray1<'py, i64>,
    own: PyReadonlyArray1<'py, u32>,
    job: Part<'_>,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(&sites, "sites")?;
    let global = increasing_rows(&rows_in, points.len())?;
    let own: Vec<u32> = own.as_slice()?.to_vec();
    let density = job.given.density::<D>()?;
    let request = Request {
        options: Options {
            allow_outside: job.allow_outside,
        },
        density: density.as_ref(),
        weights: job.weights,
        ..Request::default()
    };
    let total_sites = job.total_sites;
    let whole = job
        .power_whole
        .map(|(lo, hi, w)| power_whole::<D>((lo, hi, *w), total_sites))
        .transpose()?;
    let part: PartCells<D> = py
        .detach(|| {
            crate::threads::run(|| {
                clipped_cells::<D, C, _>(
                    domain,
                    &points,
                    &own,
                    total_sites,
                    &request,
                    whole.as_ref(),
                )
            })
        })
        .map_err(|e| {
            job.given
                .error(e.with_site_rows(|i| global.get(i).copied().unwrap_or(i)))
        })?;
    let mut diagram = part.diagram;
    let neighbors: Vec<usize> = diagram
        .neighbor_sites
        .iter()
        .map(|&j| global.get(j as usize).copied().unwrap_or(usize::MAX))
        .collect();
    diagram.neighbor_sites.clear();
    let out = diagram_dict(py, diagram)?;
    out.set_item("neighbor_sites", to_intp(py, &neighbors)?)?;
    out.set_item("reach2", PyArray1::from_vec(py, part.reach2))?;
    Ok(out)
}
