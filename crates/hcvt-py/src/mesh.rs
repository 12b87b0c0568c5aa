//! The conforming mesh of a diagram's cells as numpy arrays (`hcvt.polymesh.PolyMesh`).

use hcvt_core::diagram::mesh::{conforming_mesh_2d, conforming_mesh_3d, PolyMesh};
use hcvt_core::diagram::Options;
use numpy::PyReadonlyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2, to_intp};
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
    let points = rows::<f64, 2>(&sites, "sites")?;
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
    let points = rows::<f64, 3>(&sites, "sites")?;
    let options = Options { allow_outside };
    let mesh = py
        .detach(|| crate::threads::run(|| conforming_mesh_3d(&domain.0, &points, options)))
        .map_err(to_py_err)?;
    mesh_dict(py, &mesh)
}
