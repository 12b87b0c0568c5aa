//! The kernel of `hcvt.export.split` as numpy arrays (`hcvt.export._cut_kernel`): a
//! region measured, a cell cut by planes.
//!
//! Across the boundary indices are `np.int64` arrays and "nothing" is -1, as in
//! `hcvt.polymesh.PolyMesh`: a face's neighbour, a piece's ghost, a section's source.

use hcvt_core::split::{
    cut_cell_by_planes, measure_region, Across, Cell, Cut, Loops, Plane, Region,
};
use hcvt_core::CoreError;
use numpy::{PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2, to_intp, to_intp2};
use crate::errors::to_py_err;

/// Face loops from `face_offsets` (f+1,) and `face_vertices`, both int64.
fn loops(
    face_offsets: &PyReadonlyArray1<'_, i64>,
    face_vertices: &PyReadonlyArray1<'_, i64>,
) -> PyResult<Loops> {
    let offsets = face_offsets
        .as_slice()?
        .iter()
        .map(|&x| usize::try_from(x).map_err(|_| invalid(0, format!("face offset {x}"))))
        .collect::<PyResult<Vec<usize>>>()?;
    let vertices = indices(face_vertices, "vertex", |j| {
        offsets
            .partition_point(|&start| start <= j)
            .saturating_sub(1)
    })?;
    Loops::new(offsets, vertices).map_err(to_py_err)
}

/// Non-negative indices as `u32`; an error names the face `face_of(position)`.
fn indices(
    values: &PyReadonlyArray1<'_, i64>,
    what: &str,
    face_of: impl Fn(usize) -> usize,
) -> PyResult<Vec<u32>> {
    (values.as_slice()?.iter().enumerate())
        .map(|(j, &x)| u32::try_from(x).map_err(|_| invalid(face_of(j), format!("{what} {x}"))))
        .collect()
}

fn invalid(face: usize, reason: String) -> PyErr {
    to_py_err(CoreError::InvalidFace { face, reason })
}

/// `hcvt.export.split._Editor.measure` on a small mesh: `parts` cells bounded by faces
/// `face_offsets` (f+1,) / `face_vertices` into `points` (n, 3), each out of its `owner`
/// (f,); `neighbour` (f,) the part across, `parts + j` for ghost `j` centred at
/// `ghost_centroids[j]` (g, 3), or -1 on the boundary. Returns None if a part has no
/// positive volume, else `bad` (f,) bool, `badness` (f,), `volumes` (parts,) and
/// `centroids` (parts, 3).
#[pyfunction]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn measure_region_3d<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    face_offsets: PyReadonlyArray1<'py, i64>,
    face_vertices: PyReadonlyArray1<'py, i64>,
    owner: PyReadonlyArray1<'py, i64>,
    neighbour: PyReadonlyArray1<'py, i64>,
    parts: usize,
    ghost_centroids: PyReadonlyArray2<'py, f64>,
) -> PyResult<
    Option<(
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray2<f64>>,
    )>,
> {
    let points = rows::<f64, 3>(&points, "points")?;
    let faces = loops(&face_offsets, &face_vertices)?;
    let owner = indices(&owner, "owner", |k| k)?;
    let across = (neighbour.as_slice()?.iter().enumerate())
        .map(|(k, &x)| match usize::try_from(x) {
            Ok(p) if p < parts => Ok(Across::Part(p as u32)),
            Ok(p) => u32::try_from(p - parts)
                .map(Across::Ghost)
                .map_err(|_| invalid(k, format!("neighbour {x}"))),
            Err(_) if x == -1 => Ok(Across::Boundary),
            Err(_) => Err(invalid(k, format!("neighbour {x}"))),
        })
        .collect::<PyResult<Vec<Across>>>()?;
    let ghost_centroids = rows::<f64, 3>(&ghost_centroids, "ghost_centroids")?;
    let region = Region {
        points: &points,
        faces: &faces,
        owner: &owner,
        across: &across,
        parts,
        ghost_centroids: &ghost_centroids,
    };
    let Some(quality) = py.detach(|| measure_region(&region)).map_err(to_py_err)? else {
        return Ok(None);
    };
    Ok(Some((
        PyArray1::from_vec(py, quality.bad),
        PyArray1::from_vec(py, quality.badness),
        PyArray1::from_vec(py, quality.volumes),
        to_array2(py, &quality.centroids)?,
    )))
}

/// One cell cut by each plane `normals[i] · (x - origins[i]) = 0` (p, 3); see
/// `hcvt_core::split::cut_cell_by_planes`.
///
/// The cell: `points` (m, 3), outward faces `face_offsets` (f+1,) / `face_vertices`,
/// `ghosts` (f,) the cell across each face (a row of `ghost_centroids` (g, 3)) or -1.
///
/// Returns a dict: `tried` (int) planes tried; per cut made (r of them, None cuts left
/// out) `plane` (r,) its row, `parts`, `failing` (r,), `worst` (r,) and `oblique` (r,); each cut's rows of
/// the arrays below run from its offset to the next: `crossing_offsets` (r+1,) into
/// `crossing_edges` (x, 2) and `crossing_points` (x, 3), the crossing `j` of a cut being
/// vertex `m + j`; `face_offsets` (r+1,) into the faces `loop_offsets` (F+1,) /
/// `loop_vertices`, `source`, `part`, `across`, `ghost`, `bad`, `badness` (F,); and
/// `part_offsets` (r+1,) into `part_failing`, `volumes` (P,) and `centroids` (P, 3).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn cut_cell_3d<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    face_offsets: PyReadonlyArray1<'py, i64>,
    face_vertices: PyReadonlyArray1<'py, i64>,
    ghosts: PyReadonlyArray1<'py, i64>,
    ghost_centroids: PyReadonlyArray2<'py, f64>,
    normals: PyReadonlyArray2<'py, f64>,
    origins: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let points = rows::<f64, 3>(&points, "points")?;
    let faces = loops(&face_offsets, &face_vertices)?;
    let ghosts = (ghosts.as_slice()?.iter().enumerate())
        .map(|(k, &g)| match u32::try_from(g) {
            Ok(g) => Ok(Some(g)),
            Err(_) if g == -1 => Ok(None),
            Err(_) => Err(invalid(k, format!("ghost {g}"))),
        })
        .collect::<PyResult<Vec<Option<u32>>>>()?;
    let ghost_centroids = rows::<f64, 3>(&ghost_centroids, "ghost_centroids")?;
    let normals = rows::<f64, 3>(&normals, "normals")?;
    let origins = rows::<f64, 3>(&origins, "origins")?;
    if normals.len() != origins.len() {
        let (n, o) = (normals.len(), origins.len());
        let msg = format!("{n} normals but {o} origins");
        return Err(pyo3::exceptions::PyValueError::new_err(msg));
    }
    let planes: Vec<Plane> = (normals.iter().zip(&origins))
        .map(|(&normal, &origin)| Plane { normal, origin })
        .collect();
    let cell = Cell {
        points: &points,
        faces: &faces,
        ghosts: &ghosts,
        ghost_centroids: &ghost_centroids,
    };
    let tried = py
        .detach(|| cut_cell_by_planes(&cell, &planes))
        .map_err(to_py_err)?;
    cuts_dict(py, &tried)
}

/// The cuts made, flattened into the arrays [`cut_cell_3d`] describes.
fn cuts_dict<'py>(py: Python<'py>, tried: &[Option<Cut>]) -> PyResult<Bound<'py, PyDict>> {
    let mut flat = FlatCuts::default();
    for (row, cut) in tried.iter().enumerate() {
        if let Some(cut) = cut {
            flat.push(row, cut);
        }
    }
    let out = PyDict::new(py);
    out.set_item("tried", tried.len())?;
    out.set_item("plane", to_intp(py, &flat.plane)?)?;
    out.set_item("parts", to_intp(py, &flat.parts)?)?;
    out.set_item("failing", to_intp(py, &flat.failing)?)?;
    out.set_item("worst", PyArray1::from_vec(py, flat.worst))?;
    out.set_item("oblique", PyArray1::from_vec(py, flat.oblique))?;
    out.set_item("crossing_offsets", to_intp(py, &flat.crossing_offsets)?)?;
    out.set_item("crossing_edges", to_intp2(py, &flat.crossing_edges)?)?;
    out.set_item("crossing_points", to_array2(py, &flat.crossing_points)?)?;
    out.set_item("face_offsets", to_intp(py, &flat.face_offsets)?)?;
    out.set_item("loop_offsets", to_intp(py, &flat.loop_offsets)?)?;
    out.set_item("loop_vertices", to_intp(py, &flat.loop_vertices)?)?;
    out.set_item("source", to_intp(py, &flat.source)?)?;
    out.set_item("part", to_intp(py, &flat.part)?)?;
    out.set_item("across", to_intp(py, &flat.across)?)?;
    out.set_item("ghost", to_intp(py, &flat.ghost)?)?;
    out.set_item("bad", PyArray1::from_vec(py, flat.bad))?;
    out.set_item("badness", PyArray1::from_vec(py, flat.badness))?;
    out.set_item("part_offsets", to_intp(py, &flat.part_offsets)?)?;
    out.set_item("part_failing", to_intp(py, &flat.part_failing)?)?;
    out.set_item("volumes", PyArray1::from_vec(py, flat.volumes))?;
    out.set_item("centroids", to_array2(py, &flat.centroids)?)?;
    Ok(out)
}

/// Several cuts' arrays one after the other, -1 for "none".
struct FlatCuts {
    plane: Vec<usize>,
    parts: Vec<usize>,
    failing: Vec<usize>,
    worst: Vec<f64>,
    oblique: Vec<f64>,
    crossing_offsets: Vec<usize>,
    crossing_edges: Vec<[u32; 2]>,
    crossing_points: Vec<[f64; 3]>,
    face_offsets: Vec<usize>,
    loop_offsets: Vec<usize>,
    loop_vertices: Vec<u32>,
    source: Vec<i64>,
    part: Vec<u32>,
    across: Vec<i64>,
    ghost: Vec<i64>,
    bad: Vec<bool>,
    badness: Vec<f64>,
    part_offsets: Vec<usize>,
    part_failing: Vec<u32>,
    volumes: Vec<f64>,
    centroids: Vec<[f64; 3]>,
}

impl Default for FlatCuts {
    fn default() -> Self {
        Self {
            plane: Vec::new(),
            parts: Vec::new(),
            failing: Vec::new(),
            worst: Vec::new(),
            oblique: Vec::new(),
            crossing_offsets: vec![0],
            crossing_edges: Vec::new(),
            crossing_points: Vec::new(),
            face_offsets: vec![0],
            loop_offsets: vec![0],
            loop_vertices: Vec::new(),
            source: Vec::new(),
            part: Vec::new(),
            across: Vec::new(),
            ghost: Vec::new(),
            bad: Vec::new(),
            badness: Vec::new(),
            part_offsets: vec![0],
            part_failing: Vec::new(),
            volumes: Vec::new(),
            centroids: Vec::new(),
        }
    }
}

impl FlatCuts {
    fn push(&mut self, row: usize, cut: &Cut) {
        self.plane.push(row);
        self.parts.push(cut.parts);
        self.failing.push(cut.failing);
        self.worst.push(cut.worst);
        self.oblique.push(cut.quality.oblique);
        self.crossing_edges
            .extend(cut.crossings.iter().map(|c| c.edge));
        self.crossing_points
            .extend(cut.crossings.iter().map(|c| c.point));
        self.crossing_offsets.push(self.crossing_edges.len());
        for ring in cut.faces.iter() {
            self.loop_vertices.extend_from_slice(ring);
            self.loop_offsets.push(self.loop_vertices.len());
        }
        self.source
            .extend(cut.source.iter().map(|s| s.map_or(-1, i64::from)));
        self.part.extend_from_slice(&cut.part);
        for across in &cut.across {
            let (part, ghost) = match *across {
                Across::Part(p) => (i64::from(p), -1),
                Across::Ghost(g) => (-1, i64::from(g)),
                Across::Boundary => (-1, -1),
            };
            self.across.push(part);
            self.ghost.push(ghost);
        }
        self.bad.extend_from_slice(&cut.quality.bad);
        self.badness.extend_from_slice(&cut.quality.badness);
        self.face_offsets.push(self.source.len());
        self.part_failing.extend_from_slice(&cut.part_failing);
        self.volumes.extend_from_slice(&cut.quality.volumes);
        self.centroids.extend_from_slice(&cut.quality.centroids);
        self.part_offsets.push(self.part_failing.len());
    }
}
