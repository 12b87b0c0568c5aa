//! The clipped Voronoi diagram as numpy arrays.

use hcvt_core::diagram::{clipped_diagram_weighted, Diagram, Options, PolygonCell, PolyhedronCell};
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2, to_intp, to_intp2};
use crate::density::{Coefficients, Given};
use crate::domain::{PolygonDomain, SolidDomain};

/// Clipped diagram of `sites` (n, 2) in `domain`: a dict of arrays, row i = site i
/// (see `hcvt.voronoi`). With `keep_cells`, also `cell_offsets` (n+1,) and
/// `cell_vertices` (m, 2): each site's unclipped convex cell, counter-clockwise, absolute.
#[pyfunction]
#[pyo3(signature = (domain, sites, allow_outside=false, keep_cells=false, polynomial=None, function=None, quadrature_degree=4))]
#[allow(clippy::too_many_arguments)]
pub fn voronoi_2d<'py>(
    py: Python<'py>,
    domain: &PolygonDomain,
    sites: PyReadonlyArray2<'py, f64>,
    allow_outside: bool,
    keep_cells: bool,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let points = rows::<f64, 2>(&sites, "sites")?;
    let options = Options { allow_outside };
    let given = Given::new(polynomial, function, quadrature_degree)?;
    let density = given.density::<2>()?;
    let (diagram, cells, _) = py
        .detach(|| {
            crate::threads::run(|| {
                clipped_diagram_weighted::<2, PolygonCell>(
                    &domain.0,
                    &points,
                    options,
                    keep_cells,
                    None,
                    density.as_ref(),
                )
            })
        })
        .map_err(|e| given.error(e))?;
    let out = diagram_dict(py, &diagram, &points)?;
    if keep_cells {
        let mut offsets = vec![0usize];
        let mut vertices: Vec<[f64; 2]> = Vec::new();
        for (cell, s) in cells.iter().zip(&points) {
            vertices.extend(cell.vertices().iter().map(|v| [v[0] + s[0], v[1] + s[1]]));
            offsets.push(vertices.len());
        }
        out.set_item("cell_offsets", to_intp(py, &offsets)?)?;
        out.set_item("cell_vertices", to_array2(py, &vertices)?)?;
    }
    Ok(out)
}

/// Clipped diagram of `sites` (n, 3) in the solid `domain`: a dict of arrays, row i =
/// site i (see `hcvt.voronoi`). With `keep_cells`, also each site's convex cell from the
/// core (the Voronoi cell in the domain's box, already cut to the domain for most boundary
/// cells of a convex domain, see `clipped_diagram`) as a closed outward triangle mesh: `cell_vertex_offsets` (n+1,), `cell_vertices` (m, 3)
/// absolute, `cell_face_offsets` (n+1,), `cell_faces` (f, 3) indices local to the cell.
#[pyfunction]
#[pyo3(signature = (domain, sites, allow_outside=false, keep_cells=false, polynomial=None, function=None, quadrature_degree=4))]
#[allow(clippy::too_many_arguments)]
pub fn voronoi_3d<'py>(
    py: Python<'py>,
    domain: &SolidDomain,
    sites: PyReadonlyArray2<'py, f64>,
    allow_outside: bool,
    keep_cells: bool,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let points = rows::<f64, 3>(&sites, "sites")?;
    let options = Options { allow_outside };
    let given = Given::new(polynomial, function, quadrature_degree)?;
    let density = given.density::<3>()?;
    let (diagram, cells, _) = py
        .detach(|| {
            crate::threads::run(|| {
                clipped_diagram_weighted::<3, PolyhedronCell>(
                    &domain.0,
                    &points,
                    options,
                    keep_cells,
                    None,
                    density.as_ref(),
                )
            })
        })
        .map_err(|e| given.error(e))?;
    let out = diagram_dict(py, &diagram, &points)?;
    if keep_cells {
        let (mut vertex_offsets, mut face_offsets) = (vec![0usize], vec![0usize]);
        let mut vertices: Vec<[f64; 3]> = Vec::new();
        let mut faces: Vec<[u32; 3]> = Vec::new();
        for (cell, s) in cells.iter().zip(&points) {
            vertices.extend(
                cell.vertices()
                    .iter()
                    .map(|v| [v[0] + s[0], v[1] + s[1], v[2] + s[2]]),
            );
            cell.boundary_triangles(&mut faces);
            vertex_offsets.push(vertices.len());
            face_offsets.push(faces.len());
        }
        out.set_item("cell_vertex_offsets", to_intp(py, &vertex_offsets)?)?;
        out.set_item("cell_vertices", to_array2(py, &vertices)?)?;
        out.set_item("cell_face_offsets", to_intp(py, &face_offsets)?)?;
        out.set_item("cell_faces", to_intp2(py, &faces)?)?;
    }
    Ok(out)
}

/// The arrays every diagram carries, in any dimension.
pub(crate) fn diagram_dict<'py, const D: usize>(
    py: Python<'py>,
    diagram: &Diagram<D>,
    sites: &[[f64; D]],
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("volume", PyArray1::from_vec(py, diagram.volumes()))?;
    out.set_item("mass", PyArray1::from_vec(py, diagram.masses()))?;
    out.set_item("centroid", to_array2(py, &diagram.centroids(sites))?)?;
    out.set_item(
        "second_moment",
        PyArray1::from_vec(py, diagram.second_moments()),
    )?;
    out.set_item("G", PyArray1::from_vec(py, diagram.g_values()))?;
    out.set_item(
        "energy_terms",
        PyArray1::from_vec(py, diagram.energy_terms()),
    )?;
    out.set_item("energy", diagram.energy())?;
    out.set_item("gradient", to_array2(py, &diagram.gradient())?)?;
    out.set_item(
        "boundary_measure",
        PyArray1::from_vec(py, diagram.boundary_measure.clone()),
    )?;
    out.set_item("neighbor_offsets", to_intp(py, &diagram.neighbor_offsets)?)?;
    out.set_item("neighbor_sites", to_intp(py, &diagram.neighbor_sites)?)?;
    out.set_item(
        "neighbor_measures",
        PyArray1::from_vec(py, diagram.neighbor_measures.clone()),
    )?;
    Ok(out)
}
