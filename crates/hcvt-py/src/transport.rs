//! Semi-discrete optimal transport as numpy arrays (`hcvt.optimal_transport`): the
//! core's damped Newton iteration with the GIL released.

use hcvt_core::{
    optimal_transport as core_transport, ConvexCell, DomainKind, Euclid, Space, TransportRecord,
    TransportSettings,
};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::rows;
use crate::density::{Coefficients, Given};
use crate::diagram::diagram_dict;
use crate::domain::{by_kind, AnyDomain};

/// Semi-discrete optimal transport (see `hcvt.optimal_transport`): the weights of the power
/// diagram of `sites` (n, d) in `domain` whose cell i has mass `masses[i]` (with a density,
/// ∫ρ), by the core's damped Newton iteration. A dict with `weights` (n,), `diagram` (the
/// arrays of `voronoi` for those weights), `targets` (n,), `max_error`, `converged` and
/// `history` (per Newton step: `max_error`, `step`, `cg_iterations`, `diagrams`,
/// `min_mass`).
#[pyfunction]
#[pyo3(signature = (domain, sites, masses, tol=1e-10, max_iter=100, normalise=false, polynomial=None, function=None, quadrature_degree=4))]
#[allow(clippy::too_many_arguments)]
pub fn optimal_transport<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    masses: PyReadonlyArray1<'py, f64>,
    tol: f64,
    max_iter: usize,
    normalise: bool,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let given = Given::new(polynomial, function, quadrature_degree)?;
    let asked = Transported {
        masses: masses.as_array().to_vec(),
        tol,
        max_iter,
        normalise,
        given: &given,
    };
    by_kind!(domain, transport_in(py, sites, &asked))
}

/// What `optimal_transport` is asked for besides its domain and sites.
struct Transported<'a> {
    masses: Vec<f64>,
    tol: f64,
    max_iter: usize,
    normalise: bool,
    given: &'a Given,
}

fn transport_in<'py, const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    py: Python<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    asked: &Transported<'_>,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(&sites, "sites")?;
    let density = asked.given.density::<D>()?;
    let settings = TransportSettings {
        tol: asked.tol,
        max_iter: asked.max_iter,
        density: density.as_ref(),
        normalise: asked.normalise,
    };
    let out = py
        .detach(|| {
            crate::threads::run(|| {
                core_transport::<D, C, K>(domain, &points, &asked.masses, &settings)
            })
        })
        .map_err(|e| asked.given.error(e))?;
    let result = PyDict::new(py);
    result.set_item("weights", PyArray1::from_vec(py, out.weights))?;
    result.set_item("diagram", diagram_dict(py, out.diagram)?)?;
    result.set_item("targets", PyArray1::from_vec(py, out.targets))?;
    result.set_item("max_error", out.max_error)?;
    result.set_item("converged", out.converged)?;
    let history = PyDict::new(py);
    let column =
        |f: fn(&TransportRecord) -> f64| -> Vec<f64> { out.history.iter().map(f).collect() };
    history.set_item("max_error", PyArray1::from_vec(py, column(|r| r.max_error)))?;
    history.set_item("step", PyArray1::from_vec(py, column(|r| r.step)))?;
    history.set_item("min_mass", PyArray1::from_vec(py, column(|r| r.min_mass)))?;
    let counts =
        |f: fn(&TransportRecord) -> usize| -> Vec<usize> { out.history.iter().map(f).collect() };
    history.set_item(
        "cg_iterations",
        PyArray1::from_vec(py, counts(|r| r.cg_iterations)),
    )?;
    history.set_item("diagrams", PyArray1::from_vec(py, counts(|r| r.diagrams)))?;
    result.set_item("history", history)?;
    Ok(result)
}
