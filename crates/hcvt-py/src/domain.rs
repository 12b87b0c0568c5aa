//! Domains: a checked, indexed boundary held by Python.

use hcvt_core::domain::{generalized_winding_number, Boundary, Polygon, Solid, WindingNumber};
use hcvt_core::geometry::Euclid;
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::arrays::{rows, to_array2, to_intp2};
use crate::errors::to_py_err;

/// Winding numbers (m,) and on-boundary flags (m,).
type Windings<'py> = (Bound<'py, PyArray1<i32>>, Bound<'py, PyArray1<bool>>);

/// Exact winding numbers of `points` about `boundary`, in parallel without the GIL; points
/// on the boundary get 0 and an on-boundary flag.
fn winding_numbers<'py, const D: usize>(
    py: Python<'py>,
    boundary: &Boundary<D>,
    points: &[[f64; D]],
) -> Windings<'py>
where
    Euclid: WindingNumber<D>,
{
    let w: Vec<Option<i32>> = py.detach(|| {
        crate::threads::run(|| {
            use rayon::prelude::*;
            points
                .par_iter()
                .map(|q| Euclid::winding_number(boundary, q))
                .collect()
        })
    });
    let on = w.iter().map(Option::is_none).collect::<Vec<_>>();
    let w = w.iter().map(|x| x.unwrap_or(0)).collect::<Vec<_>>();
    (PyArray1::from_vec(py, w), PyArray1::from_vec(py, on))
}

/// A polygonal domain: `vertices` (V, 2) float64 and `segments` (S, 2) uint32, outer rings
/// counter-clockwise and holes clockwise (interior on the left of every segment).
#[pyclass(frozen, module = "hcvt._core")]
pub struct PolygonDomain(pub Polygon);

#[pymethods]
impl PolygonDomain {
    #[new]
    fn new(
        vertices: PyReadonlyArray2<'_, f64>,
        segments: PyReadonlyArray2<'_, u32>,
    ) -> PyResult<Self> {
        let v = rows::<f64, 2>(&vertices, "vertices")?;
        let s = rows::<u32, 2>(&segments, "segments")?;
        Polygon::new(v, s).map(Self).map_err(to_py_err)
    }

    /// Area of the domain.
    #[getter]
    fn volume(&self) -> f64 {
        self.0.volume()
    }

    /// First moment `∫ x dx` (2,) about the coordinate origin.
    #[getter]
    fn first_moment(&self) -> [f64; 2] {
        self.0.first_moment()
    }

    /// `(lo, hi)` corners of the bounding box.
    #[getter]
    fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let b = self.0.bounds();
        (b.lo, b.hi)
    }

    /// `vertices` (V, 2) as indexed.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        to_array2(py, self.0.vertices())
    }

    /// `segments` (S, 2) as indexed, `np.intp`.
    #[getter]
    fn segments<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<isize>>> {
        to_intp2(py, self.0.simplices())
    }

    /// Winding number of each point (m,), exact; `on_boundary` marks points on a segment
    /// (their winding number is reported as 0).
    fn winding_numbers<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Windings<'py>> {
        let p = rows::<f64, 2>(&points, "points")?;
        Ok(winding_numbers(py, &self.0, &p))
    }
}

/// A solid: `vertices` (V, 3) float64 and `faces` (F, 3) uint32, a closed triangle mesh
/// with every face counter-clockwise seen from outside (checked: every directed edge has
/// its reverse, positive volume).
#[pyclass(frozen, module = "hcvt._core")]
pub struct SolidDomain(pub Solid);

#[pymethods]
impl SolidDomain {
    #[new]
    fn new(
        vertices: PyReadonlyArray2<'_, f64>,
        faces: PyReadonlyArray2<'_, u32>,
    ) -> PyResult<Self> {
        let v = rows::<f64, 3>(&vertices, "vertices")?;
        let f = rows::<u32, 3>(&faces, "faces")?;
        Solid::new(v, f).map(Self).map_err(to_py_err)
    }

    /// Volume of the solid.
    #[getter]
    fn volume(&self) -> f64 {
        self.0.volume()
    }

    /// First moment `∫ x dx` (3,) about the coordinate origin.
    #[getter]
    fn first_moment(&self) -> [f64; 3] {
        self.0.first_moment()
    }

    /// `(lo, hi)` corners of the bounding box.
    #[getter]
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let b = self.0.bounds();
        (b.lo, b.hi)
    }

    /// `vertices` (V, 3) as indexed.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        to_array2(py, self.0.vertices())
    }

    /// `faces` (F, 3) as indexed, `np.intp`.
    #[getter]
    fn faces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<isize>>> {
        to_intp2(py, self.0.simplices())
    }

    /// Exact winding number of each point (m,); `on_boundary` marks points on a triangle
    /// (their winding number is reported as 0).
    fn winding_numbers<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Windings<'py>> {
        let p = rows::<f64, 3>(&points, "points")?;
        Ok(winding_numbers(py, &self.0, &p))
    }

    /// Pairs of triangles sharing no vertex whose interiors cross: `(count, pairs)`, at
    /// most `max` pairs `(s, t)`, `s < t`, in index order.
    #[pyo3(signature = (max=10))]
    fn crossing_triangles(&self, py: Python<'_>, max: usize) -> (usize, Vec<(u32, u32)>) {
        py.detach(|| crate::threads::run(|| self.0.crossing_triangles(max)))
    }

    /// Generalised winding number of each point (m,): the solid angle of the surface over
    /// 4π, robust to small holes and overlaps.
    fn generalized_winding_numbers<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let p = rows::<f64, 3>(&points, "points")?;
        let w: Vec<f64> = py.detach(|| {
            crate::threads::run(|| {
                use rayon::prelude::*;
                p.par_iter()
                    .map(|q| generalized_winding_number(&self.0, q))
                    .collect()
            })
        });
        Ok(PyArray1::from_vec(py, w))
    }
}
