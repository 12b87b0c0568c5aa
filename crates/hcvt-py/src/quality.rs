//! A mesh's geometry and checkMesh quality (`hcvt.mesh.quality`), computed by the core.

use hcvt_core::{mesh_quality as measure, Euclid, MeshArrays, MeshQuality, Space};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2};
use crate::errors::{to_py_err, InvalidMeshError};

/// Face centres and area vectors, cell volumes and centroids, and checkMesh's figures of
/// the mesh `points` (p, d), `face_offsets` (f + 1,), `face_vertices`, `owner` and
/// `neighbour` (f,, −1 on the boundary) of `n_cells` cells; with `centres` (n_cells, d),
/// the face figures are measured against those cell centres (see `hcvt.mesh.quality`).
#[pyfunction]
#[pyo3(signature = (points, face_offsets, face_vertices, owner, neighbour, n_cells, centres=None))]
#[allow(clippy::too_many_arguments)] // one per array of the mesh, as PolyMesh holds them
pub fn mesh_quality<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    face_offsets: PyReadonlyArray1<'py, isize>,
    face_vertices: PyReadonlyArray1<'py, isize>,
    owner: PyReadonlyArray1<'py, isize>,
    neighbour: PyReadonlyArray1<'py, isize>,
    n_cells: usize,
    centres: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mesh = Indices {
        face_offsets: indices(&face_offsets, "face_offsets")?,
        face_vertices: indices(&face_vertices, "face_vertices")?,
        owner: indices(&owner, "owner")?,
        neighbour: neighbour.as_slice()?.iter().map(|&c| c as i64).collect(),
        n_cells,
    };
    match points.shape() {
        [_, 2] => measured::<2>(py, &points, &mesh, centres.as_ref()),
        [_, 3] => measured::<3>(py, &points, &mesh, centres.as_ref()),
        shape => Err(PyValueError::new_err(format!(
            "points must have shape (p, 2) or (p, 3), got {shape:?}"
        ))),
    }
}

/// The mesh's index arrays in the core's types.
struct Indices {
    face_offsets: Vec<usize>,
    face_vertices: Vec<u32>,
    owner: Vec<u32>,
    neighbour: Vec<i64>,
    n_cells: usize,
}

/// `values` as non-negative indices of type `T`, or an error naming the first that is not.
fn indices<T: TryFrom<isize>>(
    values: &PyReadonlyArray1<'_, isize>,
    what: &str,
) -> PyResult<Vec<T>> {
    values
        .as_slice()?
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            T::try_from(v).map_err(|_| {
                InvalidMeshError::new_err(format!("{what}[{i}] = {v} is not an index"))
            })
        })
        .collect()
}

fn measured<'py, const D: usize>(
    py: Python<'py>,
    points: &PyReadonlyArray2<'py, f64>,
    mesh: &Indices,
    centres: Option<&PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(points, "points")?;
    let centres = centres.map(|c| rows::<f64, D>(c, "centres")).transpose()?;
    let arrays = MeshArrays {
        points: &points,
        face_offsets: &mesh.face_offsets,
        face_vertices: &mesh.face_vertices,
        owner: &mesh.owner,
        neighbour: &mesh.neighbour,
        n_cells: mesh.n_cells,
    };
    let quality = py
        .detach(|| crate::threads::run(|| measure(&arrays, centres.as_deref())))
        .map_err(to_py_err)?;
    quality_dict(py, quality)
}

/// The one place a `MeshQuality` becomes a dict (`hcvt.core_results.MeshQualityArrays`).
fn quality_dict<const D: usize>(py: Python<'_>, q: MeshQuality<D>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("face_centre", to_array2(py, &q.face_centre)?)?;
    out.set_item("area_vector", to_array2(py, &q.area_vector)?)?;
    out.set_item("volume", PyArray1::from_vec(py, q.volume))?;
    out.set_item("centroid", to_array2(py, &q.centroid)?)?;
    out.set_item("aspect_ratio", PyArray1::from_vec(py, q.aspect_ratio))?;
    out.set_item(
        "non_orthogonality",
        PyArray1::from_vec(py, q.non_orthogonality),
    )?;
    out.set_item("skewness", PyArray1::from_vec(py, q.skewness))?;
    out.set_item(
        "inverted_pyramid",
        PyArray1::from_vec(py, q.inverted_pyramid),
    )?;
    out.set_item("volume_ratio", PyArray1::from_vec(py, q.volume_ratio))?;
    Ok(out)
}
