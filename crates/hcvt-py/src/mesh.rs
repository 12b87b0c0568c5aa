//! The conforming mesh of a diagram's cells as numpy arrays (`hcvt.polymesh.PolyMesh`).

use hcvt_core::{
    conforming_mesh, conforming_mesh_part, conforming_power_mesh, Boundary, CoreError, MeshDomain,
    MeshPart, Options, PolyMesh,
};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{increasing_rows, rows as site_rows, to_array2, to_intp};
use crate::domain::{by_kind, AnyDomain};
use crate::errors::to_py_err;

/// The mesh as a dict: `points` (p, D), `face_offsets` (f+1,), `face_vertices`, `owner`,
/// `neighbour`, `boundary_element` (f,) as intp, and `open_chains` (int).
fn mesh_dict<'py, const D: usize>(
    py: Python<'py>,
    mesh: &PolyMesh<D>,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("points", to_array2(py, &mesh.points)?)?;
    out.set_item("face_offsets", to_intp(py, &mesh.face_offsets)?)?;
    out.set_item("face_vertices", to_intp(py, &mesh.face_vertices)?)?;
    out.set_item("owner", to_intp(py, &mesh.owner)?)?;
    out.set_item("neighbour", to_intp(py, &mesh.neighbour)?)?;
    out.set_item("boundary_element", to_intp(py, &mesh.boundary_element)?)?;
    out.set_item("open_chains", mesh.open_chains)?;

    Ok(out)
}

/// Conforming mesh of the clipped diagram of `sites` (n, d) in `domain`: polygons in a
/// polygon, polyhedra in a solid (see `hcvt.Diagram.mesh`); with `weights` (n,), of the
/// power diagram of those weights (an empty cell has no faces).
#[pyfunction]
#[pyo3(signature = (domain, sites, allow_outside=false, weights=None))]
pub fn mesh<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    allow_outside: bool,
    weights: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let weights = weights.map(|w| w.as_array().to_vec());
    let options = Options { allow_outside };
    by_kind!(domain, bounded dim mesh_in(py, &sites, weights.as_deref(), options))
}

/// The faces of the cells `sites[own]` (n, d) in the conforming mesh of a problem of
/// `total_sites` sites, of which `sites` are those of rows `rows` (n,), increasing: a mesh
/// dict whose `owner` and `neighbour` index `sites` (every face owned by an own cell; see
/// `hcvt.distributed`), plus `computed` (c,) the cells computed and `reach2` (c,) their
/// reach squared. Errors name problem rows.
#[pyfunction]
#[pyo3(signature = (domain, sites, rows, own, total_sites, allow_outside=false))]
pub fn mesh_part<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    rows: PyReadonlyArray1<'py, i64>,
    own: PyReadonlyArray1<'py, u32>,
    total_sites: usize,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let part = Part {
        rows: &rows,
        own: own.as_slice()?,
        total_sites,
        options: Options { allow_outside },
    };
    by_kind!(domain, bounded dim mesh_part_in(py, &sites, part))
}

fn mesh_in<'py, const D: usize>(
    domain: &Boundary<D>,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    weights: Option<&[f64]>,
    options: Options,
) -> PyResult<Bound<'py, PyDict>>
where
    Boundary<D>: MeshDomain<D>,
{
    let points = site_rows::<f64, D>(sites, "sites")?;
    let mesh = py
        .detach(|| {
            crate::threads::run(|| match weights {
                None => conforming_mesh(domain, &points, options),
                Some(w) => conforming_power_mesh(domain, &points, w, options),
            })
        })
        .map_err(to_py_err)?;
    mesh_dict(py, &mesh)
}

/// Which cells of which problem a mesh part is.
struct Part<'a, 'py> {
    rows: &'a PyReadonlyArray1<'py, i64>,
    own: &'a [u32],
    total_sites: usize,
    options: Options,
}

fn mesh_part_in<'py, const D: usize>(
    domain: &Boundary<D>,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    job: Part<'_, 'py>,
) -> PyResult<Bound<'py, PyDict>>
where
    Boundary<D>: MeshDomain<D>,
{
    let points = site_rows::<f64, D>(sites, "sites")?;
    let global = increasing_rows(job.rows, points.len())?;
    let part = py.detach(|| {
        crate::threads::run(|| {
            conforming_mesh_part(domain, &points, job.own, job.total_sites, job.options)
        })
    });
    part_dict(py, named_by_rows(part, &global)?)
}

/// The part, or its error naming problem rows.
fn named_by_rows<const D: usize>(
    part: Result<MeshPart<D>, CoreError>,
    global: &[usize],
) -> PyResult<MeshPart<D>> {
    part.map_err(|e| to_py_err(e.with_site_rows(|i| global.get(i).copied().unwrap_or(i))))
}

fn part_dict<const D: usize>(py: Python<'_>, part: MeshPart<D>) -> PyResult<Bound<'_, PyDict>> {
    let out = mesh_dict(py, &part.mesh)?;
    out.set_item("computed", to_intp(py, &part.computed)?)?;
    out.set_item("reach2", PyArray1::from_vec(py, part.reach2))?;
    Ok(out)
}
