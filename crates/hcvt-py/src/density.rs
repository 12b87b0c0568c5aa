//! A density from Python (DESIGN §8): polynomial coefficients become the core's
//! `Quadratic`; a callable becomes a `Field` that the core calls once per diagram, with
//! the GIL taken for that call only; a 1-D float array given as the function (a surface's
//! per-vertex field) becomes `Density::PerVertex`.

use std::sync::Mutex;

use hcvt_core::{CoreError, Density, Field, Quadratic};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::InvalidDensityError;

/// Polynomial coefficients as Python passes them: `(constant, linear (d,), quadratic (d, d))`.
pub type Coefficients = (f64, Vec<f64>, Vec<Vec<f64>>);

/// The core's polynomial from `coefficients`.
pub fn quadratic<const D: usize>(coefficients: &Coefficients) -> PyResult<Quadratic<D>> {
    let (constant, linear, quadratic) = coefficients;
    let shape_error = || {
        PyValueError::new_err(format!(
            "polynomial coefficients must have shapes ({D},) and ({D}, {D})"
        ))
    };
    let linear: [f64; D] = linear.as_slice().try_into().map_err(|_| shape_error())?;
    let mut rows = [[0.0; D]; D];
    if quadratic.len() != D {
        return Err(shape_error());
    }
    for (row, given) in rows.iter_mut().zip(quadratic) {
        *row = given.as_slice().try_into().map_err(|_| shape_error())?;
    }
    Quadratic::new(*constant, linear, rows).map_err(crate::errors::to_py_err)
}

/// A Python callable `f(points (m, d)) -> (m,)` as the core's [`Field`]. An exception it
/// raises is kept, and raised in place of the core's error ([`PyField::take_error`]).
pub struct PyField {
    function: Py<PyAny>,
    raised: Mutex<Option<PyErr>>,
}

impl PyField {
    /// Wrap `function`.
    pub fn new(function: Py<PyAny>) -> Self {
        Self {
            function,
            raised: Mutex::new(None),
        }
    }

    /// The exception the callable raised, if any.
    pub fn take_error(&self) -> Option<PyErr> {
        self.raised.lock().ok().and_then(|mut slot| slot.take())
    }

    fn call<const D: usize>(&self, py: Python<'_>, points: Vec<[f64; D]>) -> PyResult<Vec<f64>> {
        let count = points.len();
        // The buffer becomes the array's: no copy of tens of millions of points.
        let array = PyArray1::from_vec(py, points.into_flattened()).reshape([count, D])?;
        let result = self.function.bind(py).call1((array,))?;
        let numpy = py.import("numpy")?;
        let values = numpy.call_method1("ascontiguousarray", (result, "float64"))?;
        let values: Bound<'_, PyArray1<f64>> = values.cast_into().map_err(|_| {
            InvalidDensityError::new_err(format!(
                "the density function must return an array of shape ({count},)"
            ))
        })?;
        let values: PyReadonlyArray1<'_, f64> = values.readonly();
        if values.shape() != [count] {
            return Err(InvalidDensityError::new_err(format!(
                "the density function must return shape ({count},), got {:?}",
                values.shape()
            )));
        }
        Ok(values.as_array().iter().copied().collect())
    }
}

impl<const D: usize> Field<D> for PyField {
    fn values(&self, points: Vec<[f64; D]>) -> Result<Vec<f64>, CoreError> {
        Python::attach(|py| self.call(py, points)).map_err(|err| {
            let reason = format!("the density function failed: {err}");
            if let Ok(mut slot) = self.raised.lock() {
                slot.get_or_insert(err);
            }
            CoreError::InvalidDensity { reason }
        })
    }
}

/// What Python gave: polynomial coefficients, or a callable with its quadrature degree.
pub enum Given {
    /// No density.
    None,
    /// A polynomial.
    Polynomial(Coefficients),
    /// A callable.
    Function(PyField, usize),
    /// Values at a surface's vertices.
    PerVertex(Vec<f64>),
}

impl Given {
    /// From the binding's keyword arguments; both given is an error. A `function` that is
    /// a 1-D float64 array rather than a callable is a surface's per-vertex field.
    pub fn new(
        polynomial: Option<Coefficients>,
        function: Option<Py<PyAny>>,
        degree: usize,
    ) -> PyResult<Self> {
        match (polynomial, function) {
            (None, None) => Ok(Self::None),
            (Some(p), None) => Ok(Self::Polynomial(p)),
            (None, Some(f)) => Python::attach(|py| {
                let bound = f.bind(py);
                if bound.is_callable() {
                    return Ok(Self::Function(PyField::new(f), degree));
                }
                let values: PyReadonlyArray1<'_, f64> = bound.extract().map_err(|_| {
                    InvalidDensityError::new_err(
                        "a density must be a callable or a 1-D float64 array of values at \
                         the surface's vertices",
                    )
                })?;
                Ok(Self::PerVertex(values.as_array().to_vec()))
            }),
            (Some(_), Some(_)) => Err(PyValueError::new_err(
                "give a density as a polynomial or as a function, not both",
            )),
        }
    }

    /// The core's density.
    pub fn density<const D: usize>(&self) -> PyResult<Option<Density<'_, D>>> {
        Ok(match self {
            Self::None => None,
            Self::Polynomial(c) => Some(Density::Polynomial(quadratic::<D>(c)?)),
            Self::Function(field, degree) => Some(Density::Sampled {
                field,
                degree: *degree,
            }),
            Self::PerVertex(values) => Some(Density::PerVertex(values)),
        })
    }

    /// `err` as a Python exception: what the callable raised, if that is why.
    pub fn error(&self, err: CoreError) -> PyErr {
        if let Self::Function(field, _) = self {
            if let Some(raised) = field.take_error() {
                return raised;
            }
        }
        crate::errors::to_py_err(err)
    }
}
