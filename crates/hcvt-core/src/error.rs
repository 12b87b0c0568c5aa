//! Why the core refused an input.

/// Why the core refused an input. Every variant names the offending index.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CoreError {
    /// No sites at all.
    #[error("no sites given: a diagram needs n >= 1 sites")]
    NoSites,
    /// A site coordinate is NaN or infinite.
    #[error("site {index} has a non-finite coordinate ({value})")]
    NonFiniteSite {
        /// Row of the site.
        index: usize,
        /// The offending coordinate.
        value: f64,
    },
    /// Two sites share the same position.
    #[error("sites {first} and {second} coincide at {point:?}; remove duplicates first")]
    DuplicateSites {
        /// Lower row.
        first: usize,
        /// Higher row.
        second: usize,
        /// The shared position.
        point: Vec<f64>,
    },
    /// A site lies outside the domain and outside sites were not allowed.
    #[error("site {index} at {point:?} lies outside the domain")]
    SiteOutsideDomain {
        /// Row of the site.
        index: usize,
        /// Its position.
        point: Vec<f64>,
    },
    /// With outside sites allowed, a site lies so far from the domain that its cell, cut in
    /// coordinates relative to the site, would lose every digit (error ~ eps·(R/size)²).
    #[error(
        "site {index} at {point:?} lies {distance:e} outside the domain, more than \
         {limit} times the smallest side of its bounding box: too far for its cell to be \
         cut accurately"
    )]
    SiteFarOutside {
        /// Row of the site.
        index: usize,
        /// Its position.
        point: Vec<f64>,
        /// Distance from the domain's bounding box.
        distance: f64,
        /// The limit, in units of the bounding box's smallest side.
        limit: f64,
    },
    /// The sites could not be indexed (more than `u32::MAX`, or too many coinciding).
    #[error("cannot index the sites: {reason}")]
    SiteIndex {
        /// What the kd-tree reported.
        reason: String,
    },
    /// A boundary vertex coordinate is NaN or infinite.
    #[error("boundary vertex {index} has a non-finite coordinate ({value})")]
    NonFiniteVertex {
        /// Index of the vertex.
        index: usize,
        /// The offending coordinate.
        value: f64,
    },
    /// A boundary simplex refers to a vertex that does not exist.
    #[error(
        "boundary element {element} refers to vertex {vertex}, but there are only {count} vertices"
    )]
    VertexIndexOutOfRange {
        /// Index of the segment or triangle.
        element: usize,
        /// The bad vertex index.
        vertex: u32,
        /// Number of vertices.
        count: usize,
    },
    /// A directed boundary edge has no reverse, so the boundary is not a closed cycle.
    #[error("boundary is not closed: {count} directed edge(s) have no reverse, first {edge:?}")]
    OpenBoundary {
        /// First unmatched directed edge (vertex indices).
        edge: Vec<u32>,
        /// How many are unmatched.
        count: usize,
    },
    /// The enclosed volume (area in 2D) is zero or negative.
    #[error("the domain encloses no positive volume (signed volume {volume:e}); is it inside out or flat?")]
    NonPositiveVolume {
        /// Signed volume of the boundary cycle.
        volume: f64,
    },
    /// The boundary has no elements.
    #[error("the domain boundary is empty")]
    EmptyBoundary,
    /// An array length does not match what the caller said.
    #[error("{what}: expected length {expected}, got {got}")]
    ShapeMismatch {
        /// Which array.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// The weights of a power diagram, or the masses prescribed to its cells, cannot be
    /// used as given (length, a non-finite value, a domain that takes none).
    #[error("{reason}")]
    InvalidWeights {
        /// What is wrong, naming the offending row.
        reason: String,
    },
    /// An optimiser setting out of its range, or an unknown method or rule name.
    #[error("{reason}")]
    InvalidSettings {
        /// What is wrong, naming the setting.
        reason: String,
    },
    /// The density cannot be used as given (a bad coefficient, degree or option).
    #[error("invalid density: {reason}")]
    InvalidDensity {
        /// What is wrong.
        reason: String,
    },
    /// The density is zero, negative or not finite at a point where it is evaluated.
    #[error(
        "the density is {value} at {point:?}: it must be finite and positive on the domain \
         (a function is sampled at points of the domain's bounding box, on a surface at \
         points of the surface)"
    )]
    DensityValue {
        /// Where, in absolute coordinates.
        point: Vec<f64>,
        /// The value found there.
        value: f64,
    },
    /// A face of a mesh handed to [`crate::mesh_quality`] refers to a vertex or cell that
    /// does not exist, has the wrong number of vertices, or one cell on both sides.
    #[error("face {face}: {reason}")]
    InvalidFace {
        /// Index of the face.
        face: usize,
        /// What is wrong.
        reason: String,
    },
    /// A point of a mesh handed to [`crate::mesh_quality`] has a non-finite coordinate.
    #[error("point {index} has a non-finite coordinate ({value})")]
    InvalidPoint {
        /// Index of the point.
        index: usize,
        /// The offending coordinate.
        value: f64,
    },
    /// A triangle surface ([`crate::Surface`]) that cannot be a domain: degenerate or
    /// repeated faces, non-manifold or inconsistently oriented edges.
    #[error("invalid surface: {reason}")]
    InvalidSurface {
        /// What is wrong, with the count and the first offending element.
        reason: String,
    },
    /// A region of the sphere ([`crate::SphereRegion`]) that cannot be a domain: too few,
    /// non-finite or repeated vertices, edges that cross, a region not inside an open
    /// hemisphere.
    #[error("invalid region of the sphere: {reason}")]
    InvalidRegion {
        /// What is wrong, naming the ring and the vertex or edge.
        reason: String,
    },
    /// A cutting plane has a non-finite normal or origin.
    #[error("plane {index}: {reason}")]
    InvalidPlane {
        /// Row of the plane.
        index: usize,
        /// What is wrong.
        reason: String,
    },
}

impl CoreError {
    /// The same error with every site row `i` it names replaced by `row(i)`: a partition's
    /// cells are computed on its own rows and reported in the whole problem's.
    pub fn with_site_rows(self, row: impl Fn(usize) -> usize) -> Self {
        match self {
            Self::NonFiniteSite { index, value } => Self::NonFiniteSite {
                index: row(index),
                value,
            },
            Self::DuplicateSites {
                first,
                second,
                point,
            } => {
                let (a, b) = (row(first), row(second));
                Self::DuplicateSites {
                    first: a.min(b),
                    second: a.max(b),
                    point,
                }
            }
            Self::SiteOutsideDomain { index, point } => Self::SiteOutsideDomain {
                index: row(index),
                point,
            },
            Self::SiteFarOutside {
                index,
                point,
                distance,
                limit,
            } => Self::SiteFarOutside {
                index: row(index),
                point,
                distance,
                limit,
            },
            other => other,
        }
    }
}
