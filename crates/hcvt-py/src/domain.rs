//! Domains: a checked, indexed boundary held by Python.

use hcvt_core::{
    generalized_winding_number, DomainKind, PeriodicBox, Polygon, Solid, Sphere, SphereRegion,
    Surface, TriangleSet,
};
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::arrays::{rows, to_array2, to_intp2};
use crate::errors::to_py_err;

/// Winding numbers (m,) and on-boundary flags (m,).
type Windings<'py> = (Bound<'py, PyArray1<i32>>, Bound<'py, PyArray1<bool>>);

/// Exact winding numbers of `points` about `boundary`, in parallel without the GIL; points
/// on the boundary get 0 and an on-boundary flag.
fn winding_numbers<'py, const D: usize, K: DomainKind<D>>(
    py: Python<'py>,
    boundary: &K,
    points: &[[f64; D]],
) -> Windings<'py> {
    let w: Vec<Option<i32>> = py.detach(|| {
        crate::threads::run(|| {
            use rayon::prelude::*;
            points.par_iter().map(|q| boundary.locate(q)).collect()
        })
    });
    let on = w.iter().map(Option::is_none).collect::<Vec<_>>();
    let w = w.iter().map(|x| x.unwrap_or(0)).collect::<Vec<_>>();
    (PyArray1::from_vec(py, w), PyArray1::from_vec(py, on))
}

/// One `#[pymethods]` block for a domain class (PyO3 takes one per class), with the
/// getters and methods the kinds share written once here. `Class(d) { items }`: each item
/// below, then `{ … }` the class's own methods (`#[new]` among them), verbatim. A value is
/// given as a function of the core's kind (`Surface::area`, or a closure): an expression
/// naming `self` would not reach the method the macro writes.
///
/// - `volume("doc") = f`: getter `volume`, f64.
/// - `first_moment("doc") = f`: getter, `∫ x dx` as `[f64; d]`.
/// - `bounds("doc")`: getter `(lo, hi)` of the kind's bounding box.
/// - `vertices("doc") = f`: getter, `f`'s `&[[f64; d]]` as an (V, d) array.
/// - `simplices name("doc") = f`: getter `name`, `f`'s `&[[u32; d]]` as (S, d) `np.intp`.
/// - `winding_numbers("doc")`: the kind's [`DomainKind::locate`] of each point (m, d), by
///   [`winding_numbers`].
macro_rules! domain_methods {
    ($name:ident($d:tt) { $($items:tt)* }) => {
        domain_methods!(@munch $name $d [] $($items)*);
    };
    (@munch $name:ident $d:tt [$($done:tt)*] { $($own:tt)* }) => {
        #[pymethods]
        impl $name {
            $($done)*
            $($own)*
        }
    };
    (@munch $name:ident $d:tt [$($done:tt)*] volume($doc:expr) = $f:expr, $($rest:tt)*) => {
        domain_methods!(@munch $name $d [$($done)*
            #[doc = $doc]
            #[getter]
            fn volume(&self) -> f64 {
                ($f)(&self.0)
            }
        ] $($rest)*);
    };
    (@munch $name:ident $d:tt [$($done:tt)*] first_moment($doc:expr) = $f:expr, $($rest:tt)*) => {
        domain_methods!(@munch $name $d [$($done)*
            #[doc = $doc]
            #[getter]
            fn first_moment(&self) -> [f64; $d] {
                ($f)(&self.0)
            }
        ] $($rest)*);
    };
    (@munch $name:ident $d:tt [$($done:tt)*] bounds($doc:expr), $($rest:tt)*) => {
        domain_methods!(@munch $name $d [$($done)*
            #[doc = $doc]
            #[getter]
            fn bounds(&self) -> ([f64; $d], [f64; $d]) {
                let b = self.0.bounds();
                (b.lo, b.hi)
            }
        ] $($rest)*);
    };
    (@munch $name:ident $d:tt [$($done:tt)*] vertices($doc:expr) = $f:expr, $($rest:tt)*) => {
        domain_methods!(@munch $name $d [$($done)*
            #[doc = $doc]
            #[getter]
            fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
                to_array2(py, ($f)(&self.0))
            }
        ] $($rest)*);
    };
    (
        @munch $name:ident $d:tt [$($done:tt)*]
        simplices $simplices:ident($doc:expr) = $f:expr, $($rest:tt)*
    ) => {
        domain_methods!(@munch $name $d [$($done)*
            #[doc = $doc]
            #[getter]
            fn $simplices<'py>(
                &self,
                py: Python<'py>,
            ) -> PyResult<Bound<'py, numpy::PyArray2<isize>>> {
                to_intp2(py, ($f)(&self.0))
            }
        ] $($rest)*);
    };
    (@munch $name:ident $d:tt [$($done:tt)*] winding_numbers($doc:expr), $($rest:tt)*) => {
        domain_methods!(@munch $name $d [$($done)*
            #[doc = $doc]
            fn winding_numbers<'py>(
                &self,
                py: Python<'py>,
                points: PyReadonlyArray2<'py, f64>,
            ) -> PyResult<Windings<'py>> {
                let p = rows::<f64, $d>(&points, "points")?;
                Ok(winding_numbers(py, &self.0, &p))
            }
        ] $($rest)*);
    };
}

/// A domain class bounded by simplices (a polygon's segments, a solid's triangles),
/// checked by the core's `new(vertices, simplices)`, and `$own` (methods of that kind alone).
macro_rules! simplex_class {
    (
        $(#[$doc:meta])*
        $name:ident($inner:ty, $d:tt, $simplices:ident, $measure:literal) { $($own:tt)* }
    ) => {
        $(#[$doc])*
        #[pyclass(frozen, module = "hcvt._core")]
        pub struct $name(pub $inner);

        domain_methods! {
            $name($d) {
                volume(concat!($measure, " of the domain.")) = <$inner>::volume,
                first_moment(concat!(
                    "First moment `∫ x dx` (", $d, ",) about the coordinate origin."
                ))
                    = <$inner>::first_moment,
                bounds("`(lo, hi)` corners of the bounding box."),
                vertices(concat!("`vertices` (V, ", $d, ") as indexed.")) = <$inner>::vertices,
                simplices $simplices(concat!(
                    "`", stringify!($simplices), "` (S, ", $d, ") as indexed, `np.intp`."
                ))
                    = <$inner>::simplices,
                winding_numbers(concat!(
                    "Exact winding number of each point (m,); `on_boundary` marks points on the\n",
                    "boundary (their winding number is reported as 0)."
                )),
                {
                    #[new]
                    fn new(
                        vertices: PyReadonlyArray2<'_, f64>,
                        $simplices: PyReadonlyArray2<'_, u32>,
                    ) -> PyResult<Self> {
                        let v = rows::<f64, $d>(&vertices, "vertices")?;
                        let s = rows::<u32, $d>(&$simplices, stringify!($simplices))?;
                        <$inner>::new(v, s).map(Self).map_err(to_py_err)
                    }

                    $($own)*
                }
            }
        }
    };
}

simplex_class! {
    /// A polygonal domain: `vertices` (V, 2) float64 and `segments` (S, 2) uint32, outer
    /// rings counter-clockwise and holes clockwise (interior on the left of every segment).
    PolygonDomain(Polygon, 2, segments, "Area") {}
}

simplex_class! {
    /// A solid: `vertices` (V, 3) float64 and `faces` (F, 3) uint32, a closed triangle mesh
    /// with every face counter-clockwise seen from outside (checked: every directed edge has
    /// its reverse, positive volume).
    SolidDomain(Solid, 3, faces, "Volume") {
        /// Pairs of triangles sharing no vertex whose interiors cross: `(count, pairs)`, at
        /// most `max` pairs `(s, t)`, `s < t`, in index order.
        #[pyo3(signature = (max=10))]
        fn crossing_triangles(&self, py: Python<'_>, max: usize) -> (usize, Vec<(u32, u32)>) {
            py.detach(|| crate::threads::run(|| self.0.crossing_triangles(max)))
        }

        /// Generalised winding number of each point (m,): the solid angle of the surface
        /// over 4π, robust to small holes and overlaps.
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
}

/// A box domain class held by Python: `lo`, `hi` (d,) and which axes are periodic.
macro_rules! box_class {
    ($(#[$doc:meta])* $name:ident($d:tt)) => {
        $(#[$doc])*
        #[pyclass(frozen, module = "hcvt._core")]
        pub struct $name(pub PeriodicBox<$d>);

        domain_methods! {
            $name($d) {
                volume("Area (2D) or volume (3D) of the box.") = PeriodicBox::<$d>::volume,
                first_moment("First moment `∫ x dx` (d,) about the coordinate origin.")
                    = |k: &PeriodicBox<$d>| {
                        let v = k.volume();
                        k.bounds().center().map(|c| v * c)
                    },
                bounds("`(lo, hi)` corners."),
                vertices("The `2^d` corners (2^d, d), the box's vertices.")
                    = PeriodicBox::<$d>::density_checkpoints,
                winding_numbers(concat!(
                    "Winding number of each point (m,): 1 inside (along periodic axes every\n",
                    "point is inside), 0 outside; `on_boundary` marks points on a side that is\n",
                    "not periodic (reported as 0)."
                )),
                {
                    #[new]
                    fn new(lo: [f64; $d], hi: [f64; $d], periodic: [bool; $d]) -> PyResult<Self> {
                        PeriodicBox::new(lo, hi, periodic).map(Self).map_err(to_py_err)
                    }

                    /// Which axes are periodic (d,).
                    #[getter]
                    fn periodic(&self) -> [bool; $d] {
                        self.0.torus().periodic_axes()
                    }

                    /// `points` (m, d) moved by whole periods into `[lo, hi)` along the periodic
                    /// axes.
                    fn wrap<'py>(
                        &self,
                        py: Python<'py>,
                        points: PyReadonlyArray2<'py, f64>,
                    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
                        let p = rows::<f64, $d>(&points, "points")?;
                        let torus = self.0.torus();
                        let wrapped: Vec<[f64; $d]> = p.iter().map(|&x| torus.wrap(x)).collect();
                        to_array2(py, &wrapped)
                    }
                }
            }
        }
    };
}

box_class! {
    /// An axis-aligned box `[lo, hi]` (2D), periodic along the axes marked so: cells of
    /// the torus there, clipped by the sides along the others.
    BoxDomain2(2)
}

box_class! {
    /// An axis-aligned box `[lo, hi]` (3D), periodic along the axes marked so.
    BoxDomain3(3)
}

/// The unit sphere about the origin (`hcvt.Domain.sphere` scales by the radius): cells are
/// spherical polygons, sites unit vectors (n, 3).
#[pyclass(frozen, module = "hcvt._core")]
pub struct SphereDomain(pub Sphere);

domain_methods! {
    SphereDomain(3) {
        volume("Area of the unit sphere, 4π.") = Sphere::volume,
        first_moment("First moment `∫ x dA` (3,): zero.") = |_: &Sphere| [0.0; 3],
        bounds("`(lo, hi)` corners of the bounding box."),
        winding_numbers(concat!(
            "1 for points (m, 3) on the unit sphere (to `ON_SPHERE_TOL`), else 0; `on_boundary`\n",
            "all false (the sphere has none)."
        )),
        {
            #[new]
            fn new() -> Self {
                Self(Sphere::new())
            }
        }
    }
}

/// A region of the unit sphere bounded by rings of great-circle arcs (the outline, then
/// holes): cells are the spherical Voronoi cells clipped to it, sites unit vectors (n, 3)
/// inside it.
#[pyclass(frozen, module = "hcvt._core")]
pub struct SphereRegionDomain(pub SphereRegion);

domain_methods! {
    SphereRegionDomain(3) {
        volume("Area of the region on the unit sphere.") = SphereRegion::volume,
        bounds("`(lo, hi)` corners of the bounding box of the sphere."),
        winding_numbers(concat!(
            "1 for points (m, 3) on the unit sphere inside the region, else 0; `on_boundary`\n",
            "where a point lies on the region's boundary."
        )),
        {
            /// `rings`: a list of (m, 3) float64 arrays of points on the unit sphere (normalised
            /// here), the outline first, then holes; checked (`SphereRegion::new`).
            #[new]
            fn new(rings: Vec<PyReadonlyArray2<'_, f64>>) -> PyResult<Self> {
                let rings = (rings.iter().enumerate())
                    .map(|(r, ring)| rows::<f64, 3>(ring, &format!("rings[{r}]")))
                    .collect::<PyResult<Vec<_>>>()?;
                SphereRegion::new(rings).map(Self).map_err(to_py_err)
            }

            /// Length of the region's boundary on the unit sphere.
            #[getter]
            fn perimeter(&self) -> f64 {
                self.0.perimeter()
            }

            /// The unit vector (3,) about which the region lies.
            #[getter]
            fn centre(&self) -> [f64; 3] {
                self.0.centre()
            }

            /// The rings as oriented by the check (outline counter-clockwise seen from outside,
            /// holes clockwise): a list of (m, 3) arrays of unit vectors.
            #[getter]
            fn rings<'py>(
                &self,
                py: Python<'py>,
            ) -> PyResult<Vec<Bound<'py, numpy::PyArray2<f64>>>> {
                self.0.rings().iter().map(|r| to_array2(py, r)).collect()
            }
        }
    }
}

/// A triangle surface in 3D (open or closed, any number of components): cells are the
/// parts of the surface nearer their site than any other (restricted Voronoi cells), sites
/// anywhere in space.
#[pyclass(frozen, module = "hcvt._core")]
pub struct SurfaceDomain(pub Surface);

domain_methods! {
    SurfaceDomain(3) {
        volume("Area of the surface.") = Surface::area,
        first_moment("First moment `∫ x dA` (3,) about the coordinate origin.")
            = Surface::first_moment,
        bounds("`(lo, hi)` corners of the bounding box."),
        vertices("`vertices` (V, 3) as indexed.") = Surface::vertices,
        simplices faces("`faces` (F, 3) as indexed, `np.intp`.") = Surface::triangles,
        {
            /// `vertices` (V, 3) float64 and `faces` (F, 3) uint32, checked: no degenerate or
            /// repeated triangles, no non-manifold edges, consistent orientation.
            #[new]
            fn new(
                vertices: PyReadonlyArray2<'_, f64>,
                faces: PyReadonlyArray2<'_, u32>,
            ) -> PyResult<Self> {
                let v = rows::<f64, 3>(&vertices, "vertices")?;
                let f = rows::<u32, 3>(&faces, "faces")?;
                Surface::new(v, f).map(Self).map_err(to_py_err)
            }

            /// The nearest point of the surface to each of `points` (m, 3): `(nearest (m, 3),
            /// triangle (m,) np.intp)`, as [`closest_points`] of the surface's vertices and faces
            /// but through the surface's own BVH, built once with it (armadillo: 1 s a call saved).
            fn closest<'py>(
                &self,
                py: Python<'py>,
                points: PyReadonlyArray2<'py, f64>,
            ) -> PyResult<Nearest<'py>> {
                let p = rows::<f64, 3>(&points, "points")?;
                nearest_arrays(py, closest_all(py, self.0.triangle_set(), &p))
            }
        }
    }
}

/// Nearest points (m, 3) and their triangles (m,).
type Nearest<'py> = (
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, PyArray1<isize>>,
);

/// The nearest point of the triangles `faces` (F, 3) over `vertices` (V, 3) to each of
/// `points` (m, 3): `(nearest (m, 3), triangle (m,) np.intp)`, through a BVH, in parallel
/// without the GIL. The triangles need no checks beyond finite coordinates and indices in
/// range.
#[pyfunction]
pub fn closest_points<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
    points: PyReadonlyArray2<'py, f64>,
) -> PyResult<Nearest<'py>> {
    let v = rows::<f64, 3>(&vertices, "vertices")?;
    let f = rows::<u32, 3>(&faces, "faces")?;
    let p = rows::<f64, 3>(&points, "points")?;
    let set = TriangleSet::new(v, f).map_err(to_py_err)?;
    nearest_arrays(py, closest_all(py, &set, &p))
}

/// [`TriangleSet::closest_all`] without the GIL, on the pool when the core runs it in
/// parallel ([`TriangleSet::closest_in_parallel`]).
fn closest_all(py: Python<'_>, set: &TriangleSet, points: &[[f64; 3]]) -> Vec<([f64; 3], u32)> {
    let parallel = TriangleSet::closest_in_parallel(points.len());
    py.detach(|| crate::threads::run_if(parallel, || set.closest_all(points)))
}

/// [`TriangleSet::closest_all`]'s answers as numpy arrays.
fn nearest_arrays<'py>(py: Python<'py>, found: Vec<([f64; 3], u32)>) -> PyResult<Nearest<'py>> {
    let nearest: Vec<[f64; 3]> = found.iter().map(|x| x.0).collect();
    let triangle: Vec<isize> = found.iter().map(|x| x.1 as isize).collect();
    Ok((to_array2(py, &nearest)?, PyArray1::from_vec(py, triangle)))
}

/// Any kind of domain, as the binding's functions take it: one Python function per job,
/// dispatched by [`by_kind`] to the core's generic code in the domain's dimension (the
/// only place where the 2D and 3D paths part).
#[derive(FromPyObject)]
pub enum AnyDomain<'py> {
    /// A polygon with holes: dimension 2, [`hcvt_core::PolygonCell`]s.
    Polygon(PyRef<'py, PolygonDomain>),
    /// A solid: dimension 3, [`hcvt_core::PolyhedronCell`]s.
    Solid(PyRef<'py, SolidDomain>),
    /// A box, periodic along some axes (or none): dimension 2.
    Box2(PyRef<'py, BoxDomain2>),
    /// A box, periodic along some axes (or none): dimension 3.
    Box3(PyRef<'py, BoxDomain3>),
    /// The unit sphere: sites in 3D, [`hcvt_core::PolyhedronCell`]s (cones from the
    /// centre), cells of dimension 2.
    Sphere(PyRef<'py, SphereDomain>),
    /// A region of the unit sphere: as the sphere, its cells clipped to the region.
    SphereRegion(PyRef<'py, SphereRegionDomain>),
    /// A triangle surface: sites in 3D, [`hcvt_core::PolyhedronCell`]s, cells of
    /// dimension 2.
    Surface(PyRef<'py, SurfaceDomain>),
}

/// `by_kind!(domain, f(args…))` calls `f::<D, Cell, _>(&kind, args…)` for the dimension
/// `D`, convex cell type and domain kind of `domain` (an [`AnyDomain`]; `f` is generic over
/// [`DomainKind`]). `by_kind!(domain, dim f(args…))` calls `f::<D, _>(&kind, args…)` for
/// the steps of a partitioned run (a surface is refused: its runs are not partitioned);
/// `by_kind!(domain, bounded dim f(args…))` calls `f::<D>(&boundary, args…)` for jobs
/// that read a [`hcvt_core::Boundary`] of simplices (the conforming mesh): boxes and the sphere are
/// refused.
macro_rules! by_kind {
    ($domain:expr, bounded dim $f:ident($($arg:expr),* $(,)?)) => {
        match &$domain {
            $crate::domain::AnyDomain::Polygon(d) => $f::<2>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Solid(d) => $f::<3>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Box2(_) | $crate::domain::AnyDomain::Box3(_) => {
                Err($crate::errors::InvalidDomainError::new_err(
                    "a box has no boundary of simplices: the conforming mesh takes a polygon \
                     or a solid",
                ))
            }
            $crate::domain::AnyDomain::Sphere(_) => Err(pyo3::exceptions::PyValueError::new_err(
                concat!(stringify!($f), ": not available on the sphere"),
            )),
            $crate::domain::AnyDomain::SphereRegion(_) => {
                Err(pyo3::exceptions::PyValueError::new_err(concat!(
                    stringify!($f),
                    ": not available on a region of the sphere"
                )))
            }
            $crate::domain::AnyDomain::Surface(_) => Err(pyo3::exceptions::PyValueError::new_err(
                concat!(stringify!($f), ": not available on a surface"),
            )),
        }
    };
    ($domain:expr, dim $f:ident($($arg:expr),* $(,)?)) => {
        match &$domain {
            $crate::domain::AnyDomain::Polygon(d) => $f::<2, _>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Solid(d) => $f::<3, _>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Sphere(d) => $f::<3, _>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Box2(d) => $f::<2, _>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Box3(d) => $f::<3, _>(&d.0, $($arg),*),
            $crate::domain::AnyDomain::Surface(_) => {
                Err($crate::errors::InvalidDomainError::new_err(
                    "the steps of a partitioned run take a polygon, a solid, a box or the \
                     sphere, not a surface",
                ))
            }
            $crate::domain::AnyDomain::SphereRegion(_) => {
                Err($crate::errors::InvalidDomainError::new_err(
                    "the steps of a partitioned run take a polygon, a solid, a box or the \
                     sphere, not yet a region of the sphere",
                ))
            }
        }
    };
    ($domain:expr, $f:ident($($arg:expr),* $(,)?)) => {
        match &$domain {
            $crate::domain::AnyDomain::Polygon(d) => {
                $f::<2, hcvt_core::PolygonCell, _>(&d.0, $($arg),*)
            }
            $crate::domain::AnyDomain::Solid(d) => {
                $f::<3, hcvt_core::PolyhedronCell, _>(&d.0, $($arg),*)
            }
            $crate::domain::AnyDomain::Box2(d) => {
                $f::<2, hcvt_core::PolygonCell, _>(&d.0, $($arg),*)
            }
            $crate::domain::AnyDomain::Box3(d) => {
                $f::<3, hcvt_core::PolyhedronCell, _>(&d.0, $($arg),*)
            }
            $crate::domain::AnyDomain::Sphere(d) => {
                $f::<3, hcvt_core::PolyhedronCell, _>(&d.0, $($arg),*)
            }
            $crate::domain::AnyDomain::SphereRegion(d) => {
                $f::<3, hcvt_core::PolyhedronCell, _>(&d.0, $($arg),*)
            }
            $crate::domain::AnyDomain::Surface(d) => {
                $f::<3, hcvt_core::PolyhedronCell, _>(&d.0, $($arg),*)
            }
        }
    };
}
pub(crate) use by_kind;
