//! The clipped Voronoi diagram as numpy arrays.

use hcvt_core::{
    clipped_diagram, ConvexCell, CoreError, Diagram, DomainKind, Euclid, Moments, Options,
    PolygonCell, PolyhedronCell, Request, Space,
};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2, to_intp, to_intp2};
use crate::density::{Coefficients, Given};
use crate::domain::{by_kind, AnyDomain};

/// Clipped diagram of `sites` (n, d) in `domain` (a polygon, d = 2, a solid, d = 3, or a
/// box, periodic or not): a dict of arrays, row i = site i: `moments` (n, d + 2), each
/// cell's mass, first moment (d) and second moment about its site (also `weighted`, the
/// ρ-weighted ones, with a density), from which `hcvt.Diagram` derives each quantity on
/// first read ([`diagram_field`]), `energy`, `boundary_measure`, `neighbor_offsets`,
/// `neighbor_sites` (uint32) and `neighbor_measures`; in a periodic box also
/// `neighbor_images` (k, d) int8. With `keep_cells`, also each
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
    // The arrays are made on the worker that assembled the diagram: the memory each
    // quantity frees there is reused by the next (issue 32: memory per site).
    let (arrays, cells) = py
        .detach(|| {
            crate::threads::run(|| {
                let clipped = clipped_diagram::<D, C, _>(domain, &points, &request)?;
                Ok::<_, CoreError>((DiagramArrays::new(clipped.diagram), clipped.cells))
            })
        })
        .map_err(|e| asked.given.error(e))?;
    let out = arrays.into_dict(py)?;
    if asked.keep_cells {
        C::cell_arrays(py, &cells, &points, &out)?;
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

/// The dict of a diagram's arrays (see `core_results.py`), the one shape every producer
/// returns (`voronoi`, the CVT's, the transport's, a part's, `restricted_delaunay`'s).
pub(crate) fn diagram_dict<const D: usize>(
    py: Python<'_>,
    diagram: Diagram<D>,
) -> PyResult<Bound<'_, PyDict>> {
    DiagramArrays::new(diagram).into_dict(py)
}

/// A quantity of each cell that `hcvt.Diagram` reads, from the cells' moments: centroids
/// retracted onto the domain (the sphere's `∫x/|∫x|`), second moments about them and `G`
/// in the cells' dimension ([`DomainKind::central_second`], [`DomainKind::g_value`]),
/// gradients along the domain ([`DomainKind::tangent`]).
#[derive(Clone, Copy)]
enum Field {
    Volume,
    Mass,
    Centroid,
    SecondMoment,
    G,
    EnergyTerms,
    Gradient,
}

impl Field {
    /// The field of `hcvt.Diagram`'s attribute `name`.
    fn named(name: &str) -> PyResult<Self> {
        Ok(match name {
            "volume" => Self::Volume,
            "mass" => Self::Mass,
            "centroid" => Self::Centroid,
            "second_moment" => Self::SecondMoment,
            "G" => Self::G,
            "energy_terms" => Self::EnergyTerms,
            "gradient" => Self::Gradient,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "no cell quantity named {name:?}: volume, mass, centroid, second_moment, \
                     G, energy_terms or gradient"
                )))
            }
        })
    }

    /// Values per cell: 1, or `D` for a point or a vector.
    fn width<const D: usize>(self) -> usize {
        match self {
            Self::Centroid | Self::Gradient => D,
            _ => 1,
        }
    }

    /// Its values for `diagram` of `sites` in `domain`, row-major `(n, width)`.
    fn of<const D: usize, K: DomainKind<D>>(
        self,
        domain: &K,
        diagram: &Diagram<D>,
        sites: &[[f64; D]],
    ) -> Vec<f64> {
        match self {
            Self::Volume => diagram.volumes(),
            Self::Mass => diagram.masses(),
            Self::Centroid => (diagram.centroids(sites).into_iter())
                .map(|c| domain.retract(c))
                .collect::<Vec<[f64; D]>>()
                .into_flattened(),
            Self::SecondMoment => (diagram.moments.iter())
                .map(|m| domain.central_second(m))
                .collect(),
            Self::G => (diagram.moments.iter())
                .map(|m| domain.g_value(m).unwrap_or(f64::NAN))
                .collect(),
            Self::EnergyTerms => diagram.energy_terms(),
            Self::Gradient => (diagram.gradient().into_iter().zip(sites))
                .map(|(g, &x)| domain.tangent(x, g))
                .collect::<Vec<[f64; D]>>()
                .into_flattened(),
        }
    }
}

/// A diagram's arrays as Rust vectors, each becoming numpy's without a copy (issue 32:
/// memory per site): each cell's moments, from which `hcvt.Diagram` derives a quantity
/// when it is first read ([`diagram_field`]), rather than seven quantities (72 bytes a
/// site in 2D, 80 in 3D, against 32 and 40), and the faces' sites as `u32` (4 bytes a
/// face, against 8). Made without the GIL where it can be, on the thread that assembled
/// the diagram, so that the memory of each array dropped is reused by the next.
pub(crate) struct DiagramArrays<const D: usize> {
    /// Rows `(mass, first moment (D), second moment)` about the site, flat.
    moments: Vec<f64>,
    /// The ρ-weighted ones alike, with a density; else empty.
    weighted: Vec<f64>,
    energy: f64,
    faces: FaceArrays<D>,
}

impl<const D: usize> DiagramArrays<D> {
    /// The arrays of `diagram`, consumed: each array is freed as soon as converted.
    pub(crate) fn new(mut diagram: Diagram<D>) -> Self {
        let energy = diagram.energy();
        let moments = flat_moments(std::mem::take(&mut diagram.moments));
        let weighted = flat_moments(std::mem::take(&mut diagram.weighted));
        Self {
            moments,
            weighted,
            energy,
            faces: FaceArrays::take(&mut diagram),
        }
    }

    /// The dict of the arrays (`DiagramArrays` in `core_results.py`).
    pub(crate) fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let out = PyDict::new(py);
        let by_row = |flat: Vec<f64>| {
            let n = flat.len() / (D + 2);
            PyArray1::from_vec(py, flat).reshape([n, D + 2])
        };
        out.set_item("moments", by_row(self.moments)?)?;
        if !self.weighted.is_empty() {
            out.set_item("weighted", by_row(self.weighted)?)?;
        }
        out.set_item("energy", self.energy)?;
        self.faces.set_items(py, &out)?;
        Ok(out)
    }
}

/// Moments as rows `(mass, first (D), second)`, flat.
fn flat_moments<const D: usize>(moments: Vec<Moments<D>>) -> Vec<f64> {
    let mut flat = Vec::with_capacity(moments.len() * (D + 2));
    for m in &moments {
        flat.push(m.mass);
        flat.extend_from_slice(&m.first);
        flat.push(m.second);
    }
    flat
}

/// [`flat_moments`]' rows `(n, D + 2)` back into moments, bit for bit.
fn moment_rows<const D: usize>(
    rows: &PyReadonlyArray2<'_, f64>,
    n: usize,
    what: &str,
) -> PyResult<Vec<Moments<D>>> {
    if rows.shape() != [n, D + 2] {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape ({n}, {}), got {:?}",
            D + 2,
            rows.shape()
        )));
    }
    (rows.as_slice()?.chunks_exact(D + 2))
        .map(|row| match row {
            [mass, first @ .., second] => Ok(Moments {
                mass: *mass,
                first: <[f64; D]>::try_from(first)
                    .map_err(|_| PyValueError::new_err(format!("{what}: bad row")))?,
                second: *second,
            }),
            _ => Err(PyValueError::new_err(format!("{what}: bad row"))),
        })
        .collect()
}

/// Quantity `name` ("volume", "mass", "centroid", "second_moment", "G", "energy_terms" or
/// "gradient", as `hcvt.Diagram` names them) of the cells whose `moments` (n, d + 2)
/// [`voronoi`] returned for `sites` (n, d) in `domain`, with `weighted` (n, d + 2) when
/// it returned those: (n,) or (n, d), in the domain's frame.
#[pyfunction]
#[pyo3(signature = (domain, sites, moments, weighted, name))]
pub fn diagram_field<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    moments: PyReadonlyArray2<'py, f64>,
    weighted: Option<PyReadonlyArray2<'py, f64>>,
    name: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let field = Field::named(name)?;
    by_kind!(
        domain,
        field_in(py, &sites, &moments, weighted.as_ref(), field)
    )
}

// `by_kind!` names every kind's cell type `C`; a quantity of the moments needs none.
#[allow(clippy::extra_unused_type_parameters)]
fn field_in<'py, const D: usize, C, K: DomainKind<D>>(
    domain: &K,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    moments: &PyReadonlyArray2<'py, f64>,
    weighted: Option<&PyReadonlyArray2<'py, f64>>,
    field: Field,
) -> PyResult<Bound<'py, PyAny>> {
    let points = rows::<f64, D>(sites, "sites")?;
    let n = points.len();
    let diagram = Diagram {
        moments: moment_rows(moments, n, "moments")?,
        weighted: weighted.map_or(Ok(Vec::new()), |w| moment_rows(w, n, "weighted"))?,
        ..Diagram::default()
    };
    let values = PyArray1::from_vec(py, field.of(domain, &diagram, &points));
    match field.width::<D>() {
        1 => Ok(values.into_any()),
        width => Ok(values.reshape([n, width])?.into_any()),
    }
}

/// A diagram's faces and boundary shares as numpy takes them, the site across each face
/// as `u32`.
struct FaceArrays<const D: usize> {
    boundary_measure: Vec<f64>,
    neighbor_offsets: Vec<isize>,
    neighbor_sites: Vec<u32>,
    neighbor_measures: Vec<f64>,
    /// In a periodic box, each neighbour's image shift, `(k, D)`; else empty.
    neighbor_images: Vec<i8>,
}

impl<const D: usize> FaceArrays<D> {
    /// `diagram`'s faces, moved (the offsets converted in place).
    fn take(diagram: &mut Diagram<D>) -> Self {
        use std::mem::take;
        Self {
            boundary_measure: take(&mut diagram.boundary_measure),
            neighbor_offsets: offsets_to_intp(take(&mut diagram.neighbor_offsets)),
            neighbor_sites: take(&mut diagram.neighbor_sites),
            neighbor_measures: take(&mut diagram.neighbor_measures),
            neighbor_images: take(&mut diagram.neighbor_images).into_flattened(),
        }
    }

    /// Add the arrays to `out`.
    fn set_items(self, py: Python<'_>, out: &Bound<'_, PyDict>) -> PyResult<()> {
        out.set_item(
            "boundary_measure",
            PyArray1::from_vec(py, self.boundary_measure),
        )?;
        out.set_item(
            "neighbor_offsets",
            PyArray1::from_vec(py, self.neighbor_offsets),
        )?;
        out.set_item(
            "neighbor_sites",
            PyArray1::from_vec(py, self.neighbor_sites),
        )?;
        out.set_item(
            "neighbor_measures",
            PyArray1::from_vec(py, self.neighbor_measures),
        )?;
        if !self.neighbor_images.is_empty() {
            // A periodic box: each neighbour's image shift (k, d), int8.
            let k = self.neighbor_images.len() / D;
            let images = PyArray1::from_vec(py, self.neighbor_images).reshape([k, D])?;
            out.set_item("neighbor_images", images)?;
        }
        Ok(())
    }
}

/// Face offsets as `np.intp`, in place: a `Vec`'s length never exceeds `isize::MAX`, so
/// neither does an offset into one.
fn offsets_to_intp(offsets: Vec<usize>) -> Vec<isize> {
    offsets.into_iter().map(|x| x as isize).collect()
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
        let diagram = DiagramArrays::new(std::mem::take(&mut rdt.diagram));
        out.set_item("diagram", diagram.into_dict(py)?)?;
    }
    Ok(out)
}

/// The restricted Voronoi cells of `sites` (n, 3) on `surface` as convex planar pieces,
/// those the diagram's measure clips from the input triangles: a dict with `points`
/// (p, 3) every piece's nodes, absolute, counter-clockwise about its triangle's normal,
/// `piece_offsets` (m + 1,) intp (piece k's nodes are rows `piece_offsets[k]:[k + 1]`),
/// `piece_cell` (m,) intp its site (non-decreasing) and `piece_face` (m,) intp its input
/// triangle.
#[pyfunction]
pub fn surface_pieces<'py>(
    py: Python<'py>,
    surface: PyRef<'py, crate::domain::SurfaceDomain>,
    sites: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let points = rows::<f64, 3>(&sites, "sites")?;
    let kind = &surface.0;
    let pieces = py
        .detach(|| crate::threads::run(|| kind.pieces(&points)))
        .map_err(crate::errors::to_py_err)?;
    let out = PyDict::new(py);
    out.set_item("points", to_array2(py, &pieces.points)?)?;
    out.set_item("piece_offsets", to_intp(py, &pieces.offsets)?)?;
    out.set_item("piece_cell", to_intp(py, &pieces.cells)?)?;
    out.set_item("piece_face", to_intp(py, &pieces.triangles)?)?;
    Ok(out)
}
