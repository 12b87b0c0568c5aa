//! The one place where core errors become Python exceptions.

use hcvt_core::CoreError;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

pyo3::import_exception!(hcvt.errors, InvalidSitesError);
pyo3::import_exception!(hcvt.errors, InvalidDomainError);
pyo3::import_exception!(hcvt.errors, InvalidDensityError);
pyo3::import_exception!(hcvt.errors, InvalidMeshError);

/// No wildcard arm: a new `CoreError` variant does not compile until it is given a class.
pub fn to_py_err(err: CoreError) -> PyErr {
    let message = err.to_string();
    match err {
        CoreError::NoSites
        | CoreError::NonFiniteSite { .. }
        | CoreError::DuplicateSites { .. }
        | CoreError::SiteOutsideDomain { .. }
        | CoreError::SiteFarOutside { .. }
        | CoreError::SiteIndex { .. }
        | CoreError::ShapeMismatch { .. } => InvalidSitesError::new_err(message),
        CoreError::NonFiniteVertex { .. }
        | CoreError::VertexIndexOutOfRange { .. }
        | CoreError::OpenBoundary { .. }
        | CoreError::NonPositiveVolume { .. }
        | CoreError::EmptyBoundary
        | CoreError::InvalidSurface { .. }
        | CoreError::InvalidRegion { .. } => InvalidDomainError::new_err(message),
        CoreError::InvalidDensity { .. } | CoreError::DensityValue { .. } => {
            InvalidDensityError::new_err(message)
        }
        CoreError::InvalidSettings { .. } | CoreError::InvalidWeights { .. } => {
            PyValueError::new_err(message)
        }
        CoreError::InvalidFace { .. }
        | CoreError::InvalidPoint { .. }
        | CoreError::InvalidPlane { .. } => InvalidMeshError::new_err(message),
    }
}
