//! The clipped Voronoi diagram as numpy arrays.

use hcvt_core::{
    clipped_diagram, ConvexCell, Diagram, DomainKind, Euclid, Options, PolygonCell, PolyhedronCell,
    Request, Space,
};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2, to_intp, to_intp2};
use crate::density::{Coefficients, Given};
use crate::domain::{by_kind, AnyDomain};

/// Clipped diagram of `sites` (n, d) in `domain` (a polygon, d = 2, a solid, d = 3, or a
/// box, periodic or not): a dict of arrays, row i = site i (see `hcvt.voronoi`); in a
/// periodic box also `neighbor_images` (k, d) int8. With `keep_cells`, also each
/// site's convex cell from the core (the Voronoi cell in the domain's box, already cut to
/// the domain for most boundary cells of a convex domain, see `clipped_diagram`),
/// absolute: in 2D `cell_offsets` (n+1,) and `cell_vertices` (m, 2), counter-clockwise;
/// in 3D a closed outward triangle mesh per cell, `cell_vertex_offsets` (n+1,),
/// `cell_vertices` (m, 3), `cell_face_offsets` (n+1,), `cell_faces` (f, 3) local.
/// With `weights` (n,), the power diagram of those weights (DESIGN §14).
#[pyfunction]
#[pyo3(signature = (domain, sites, allow_outside=false, keep_cells=false, polynomial=None, function=None, quadrature_degree=4, weights=None))]
#[allow(clippy::too_many_arguments)]
pub fn voronoi<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    allow_outside: bool,
    keep_cells: bool,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
    weights: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let given = Given::new(polynomial, function, quadrature_degree)?;
    let weights = weights.map(|w| w.as_array().to_vec());
    let asked = Asked {
        allow_outside,
        keep_cells,
        given: &given,
        weights: weights.as_deref(),
    };
    by_kind!(domain, voronoi_in(py, sites, asked))
}

/// What a diagram is asked for besides its domain and sites.
struct Asked<'a> {
    allow_outside: bool,
    keep_cells: bool,
    given: &'a Given,
    /// The power diagram's weights, one per site, `L²`.
    weights: Option<&'a [f64]>,
}

fn voronoi_in<'py, const D: usize, C: ConvexCell<D> + CellArrays<D>, K: DomainKind<D>>(
    domain: &K,
    py: Python<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    asked: Asked<'_>,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(&sites, "sites")?;
    let density = asked.given.density::<D>()?;
    let request = Request {
        options: Options {
            allow_outside: asked.allow_outside,
        },
        keep_cells: asked.keep_cells,
        density: density.as_ref(),
        weights: asked.weights,
        ..Request::default()
    };
    let clipped = py
        .detach(|| crate::threads::run(|| clipped_diagram::<D, C, _>(domain, &points, &request)))
        .map_err(|e| asked.given.error(e))?;
    let out = diagram_dict(py, domain, clipped.diagram, &points)?;
    if asked.keep_cells {
        C::cell_arrays(py, &clipped.cells, &points, &out)?;
    }
    Ok(out)
}

/// The kept convex cells as arrays, per kind of cell.
trait CellArrays<const D: usize>: Sized {
    /// Add the cells (each relative to its site in `sites`) to `out`, absolute.
    fn cell_arrays(
        py: Python<'_>,
        cells: &[Self],
        sites: &[[f64; D]],
        out: &Bound<'_, PyDict>,
    ) -> PyResult<()>;
}

impl CellArrays<2> for PolygonCell {
    /// `cell_offsets` (n+1,) and `cell_vertices` (m, 2), counter-clockwise.
    fn cell_arrays(
        py: Python<'_>,
        cells: &[Self],
        sites: &[[f64; 2]],
        out: &Bound<'_, PyDict>,
    ) -> PyResult<()> {
        let mut offsets = vec![0usize];
        let mut vertices: Vec<[f64; 2]> = Vec::new();
        for (cell, s) in cells.iter().zip(sites) {
            vertices.extend(cell.vertices().iter().map(|v| [v[0] + s[0], v[1] + s[1]]));
            offsets.push(vertices.len());
        }
        out.set_item("cell_offsets", to_intp(py, &offsets)?)?;
        out.set_item("cell_vertices", to_array2(py, &vertices)?)
    }
}

impl CellArrays<3> for PolyhedronCell {
    /// A closed outward triangle mesh per cell: `cell_vertex_offsets` (n+1,),
    /// `cell_vertices` (m, 3), `cell_face_offsets` (n+1,), `cell_faces` (f, 3) local.
    fn cell_arrays(
        py: Python<'_>,
        cells: &[Self],
        sites: &[[f64; 3]],
        out: &Bound<'_, PyDict>,
    ) -> PyResult<()> {
        let (mut vertex_offsets, mut face_offsets) = (vec![0usize], vec![0usize]);
        let mut vertices: Vec<[f64; 3]> = Vec::new();
        let mut faces: Vec<[u32; 3]> = Vec::new();
        for (cell, s) in cells.iter().zip(sites) {
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
        out.set_item("cell_faces", to_intp2(py, &faces)?)
    }
}

/// The arrays every diagram carries, in any dimension and kind: centroids retracted onto
/// the domain (the sphere's `∫x/|∫x|`), second moments about them and `G` in the cells'
/// dimension ([`DomainKind::central_second`], [`DomainKind::g_value`]). The diagram is
/// consumed: its arrays become numpy's without a copy where the types agree, and the
/// others are dropped as soon as they are converted (issue 32: memory per site).
pub(crate) fn diagram_dict<'py, const D: usize, K: DomainKind<D>>(
    py: Python<'py>,
    domain: &K,
    diagram: Diagram<D>,
    sites: &[[f64; D]],
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("volume", PyArray1::from_vec(py, diagram.volumes()))?;
    out.set_item("mass", PyArray1::from_vec(py, diagram.masses()))?;
    let centroids: Vec<[f64; D]> = (diagram.centroids(sites).into_iter())
        .map(|c| domain.retract(c))
        .collect();
    out.set_item("centroid", to_array2(py, &centroids)?)?;
    let second: Vec<f64> = (diagram.moments.iter())
        .map(|m| domain.central_second(m))
        .collect();
    out.set_item("second_moment", PyArray1::from_vec(py, second))?;
    let g: Vec<f64> = (diagram.moments.iter())
        .map(|m| domain.g_value(m).unwrap_or(f64::NAN))
        .collect();
    out.set_item("G", PyArray1::from_vec(py, g))?;
    out.set_item(
        "energy_terms",
        PyArray1::from_vec(py, diagram.energy_terms()),
    )?;
    out.set_item("energy", diagram.energy())?;
    let gradient: Vec<[f64; D]> = (diagram.gradient().into_iter().zip(sites))
        .map(|(g, &x)| domain.tangent(x, g))
        .collect();
    out.set_item("gradient", to_array2(py, &gradient)?)?;
    drop((diagram.moments, diagram.weighted));
    out.set_item(
        "boundary_measure",
        PyArray1::from_vec(py, diagram.boundary_measure),
    )?;
    out.set_item("neighbor_offsets", to_intp(py, &diagram.neighbor_offsets)?)?;
    drop(diagram.neighbor_offsets);
    out.set_item("neighbor_sites", to_intp(py, &diagram.neighbor_sites)?)?;
    drop(diagram.neighbor_sites);
    out.set_item(
        "neighbor_measures",
        PyArray1::from_vec(py, diagram.neighbor_measures),
    )?;
    if !diagram.neighbor_images.is_empty() {
        // A periodic box: each neighbour's image shift (k, d), int8.
        out.set_item("neighbor_images", to_array2(py, &diagram.neighbor_images)?)?;
    }
    Ok(out)
}

/// The restricted Delaunay triangulation of `sites` (n, 3) on `surface`: a dict with
/// `triangles` (m, 3) intp (a triangle per point where three cells meet on the surface,
/// counter-clockwise about the surface's normal there), `points` (m, 3) the meeting
/// points, `faces` (m,) intp the surface triangle of each, and `repeated` (r, 3) intp the
/// triples of cells that meet at more than one point (cells that are not discs); with
/// `with_diagram`, also `diagram`: the dict [`voronoi`] gives for these sites (computed
/// on the way, bit for bit the same).
#[pyfunction]
#[pyo3(signature = (surface, sites, with_diagram = false))]
pub fn restricted_delaunay<'py>(
    py: Python<'py>,
    surface: PyRef<'py, crate::domain::SurfaceDomain>,
    sites: PyReadonlyArray2<'py, f64>,
    with_diagram: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let points = rows::<f64, 3>(&sites, "sites")?;
    let kind = &surface.0;
    let mut rdt = py
        .detach(|| crate::threads::run(|| kind.restricted_delaunay(&points)))
        .map_err(crate::errors::to_py_err)?;
    let out = PyDict::new(py);
    out.set_item("triangles", to_intp2(py, &rdt.triangles)?)?;
    out.set_item("points", to_array2(py, &rdt.points)?)?;
    let faces: Vec<usize> = rdt.faces.iter().map(|&f| f as usize).collect();
    out.set_item("faces", to_intp(py, &faces)?)?;
    out.set_item("repeated", to_intp2(py, &rdt.repeated)?)?;
    if with_diagram {
        let diagram = std::mem::take(&mut rdt.diagram);
        out.set_item("diagram", diagram_dict(py, kind, diagram, &points)?)?;
    }
    Ok(out)
}
