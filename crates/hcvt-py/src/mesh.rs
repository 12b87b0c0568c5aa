//! The conforming mesh of a diagram's cells as numpy arrays (`hcvt.polymesh.PolyMesh`).

use hcvt_core::diagram::mesh::{
    conforming_mesh_2d, conforming_mesh_3d, conforming_mesh_part_2d, conforming_mesh_part_3d,
    MeshPart, PolyMesh,
};
use hcvt_core::diagram::Options;
use hcvt_core::error::CoreError;
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{increasing_rows, rows as site_rows, to_array2, to_intp};
use crate::domain::{PolygonDomain, SolidDomain};
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

/// Conforming polygon mesh of the clipped diagram of `sites` (n, 2) in `domain` (see
/// `hcvt.Diagram.mesh`).
#[pyfunction]
#[pyo3(signature = (domain, sites, allow_outside=false))]
pub fn mesh_2d<'py>(
    py: Python<'py>,
    domain: &PolygonDomain,
    sites: PyReadonlyArray2<'py, f64>,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let points = site_rows::<f64, 2>(&sites, "sites")?;
    let options = Options { allow_outside };
    let mesh = py
        .detach(|| crate::threads::run(|| conforming_mesh_2d(&domain.0, &points, options)))
        .map_err(to_py_err)?;
    mesh_dict(py, &mesh)
}

/// Conforming polyhedral mesh of the clipped diagram of `sites` (n, 3) in the solid
/// `domain` (see `hcvt.Diagram.mesh`).
#[pyfunction]
#[pyo3(signature = (domain, sites, allow_outside=false))]
pub fn mesh_3d<'py>(
    py: Python<'py>,
    domain: &SolidDomain,
    sites: PyReadonlyArray2<'py, f64>,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let points = site_rows::<f64, 3>(&sites, "sites")?;
    let options = Options { allow_outside };
    let mesh = py
        .detach(|| crate::threads::run(|| conforming_mesh_3d(&domain.0, &points, options)))
        .map_err(to_py_err)?;
    mesh_dict(py, &mesh)
}

/// The faces of the cells `sites[own]` (n, 2) in the conforming mesh of a problem of
/// `total_sites` sites, of which `sites` are those of rows `rows` (n,), increasing: a
/// mesh dict whose `owner` and `neighbour` index `sites` (every face owned by an own
/// cell; see `hcvt.partition_mesh`), plus `computed` (c,) the cells computed and `reach2`
/// (c,) their reach squared. Errors name problem rows.
#[pyfunction]
#[pyo3(signature = (domain, sites, rows, own, total_sites, allow_outside=false))]
pub fn mesh_part_2d<'py>(
    py: Python<'py>,
    domain: &PolygonDomain,
    sites: PyReadonlyArray2<'py, f64>,
    rows: PyReadonlyArray1<'py, i64>,
    own: PyReadonlyArray1<'py, u32>,
    total_sites: usize,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let points = site_rows::<f64, 2>(&sites, "sites")?;
    let global = increasing_rows(&rows, points.len())?;
    let own = own.as_slice()?.to_vec();
    let options = Options { allow_outside };
    let part = py.detach(|| {
        crate::threads::run(|| {
            conforming_mesh_part_2d(&domain.0, &points, &own, total_sites, options)
        })
    });
    part_dict(py, named_by_rows(part, &global)?)
}

/// [`mesh_part_2d`] for sites (n, 3) in a solid.
#[pyfunction]
#[pyo3(signature = (domain, sites, rows, own, total_sites, allow_outside=false))]
pub fn mesh_part_3d<'py>(
    py: Python<'py>,
    domain: &SolidDomain,
    sites: PyReadonlyArray2<'py, f64>,
    rows: PyReadonlyArray1<'py, i64>,
    own: PyReadonlyArray1<'py, u32>,
    total_sites: usize,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let points = site_rows::<f64, 3>(&sites, "sites")?;
    let global = increasing_rows(&rows, points.len())?;
    let own = own.as_slice()?.to_vec();
    let options = Options { allow_outside };
    let part = py.detach(|| {
        crate::threads::run(|| {
            conforming_mesh_part_3d(&domain.0, &points, &own, total_sites, options)
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
