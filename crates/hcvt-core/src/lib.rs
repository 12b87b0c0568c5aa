//! Exact clipped Voronoi diagrams and regular centroidal Voronoi tessellations.
//!
//! Module map (DESIGN §2), each layer using only those above it; the modules are private
//! and the names users need are re-exported below (spade's layout):
//!
//! | module      | owns                                                                 |
//! |-------------|----------------------------------------------------------------------|
//! | `geometry`  | small vector helpers and the per-dimension primitives ([`Space`]) |
//! | `moments`   | closed-form mass, first and second moments of simplices; `G` ([`Moments`]) |
//! | `density`   | a density ρ ([`Density`]): polynomials of degree ≤ 2 (exact) and sampled functions; simplex quadrature rules |
//! | `domain`    | the oriented boundary of a 2D polygon or 3D solid ([`Boundary`]), its BVH and winding number |
//! | `diagram`   | convex Voronoi cells by kNN + half-space clipping ([`ConvexCell`]), restricted exactly to a domain through the seam [`DomainKind`] ([`clipped_diagram`], [`clipped_cells`]); the conforming mesh ([`conforming_mesh`]) |
//! | `optimise`  | CVT energy, gradient and Hessian from the diagram ([`evaluate`]); Lloyd, L-BFGS and Newton to the stopping rule ([`cvt`]) |
//! | `quality`   | a mesh's geometry and quality as OpenFOAM's `checkMesh` measures them ([`mesh_quality`]), from its arrays alone |
//!
//! `error` holds [`CoreError`], which every layer returns.
//!
//! With the cargo feature `sample` (on for this crate's tests and examples, off for the
//! binding), the module `sample` gives deterministic pseudo-random points for tests and
//! examples: not part of the API.
//!
//! Units: every length is in the unit of the input coordinates (`L`); volumes are `L^d`,
//! first moments `L^(d+1)`, second moments `L^(d+2)`.
//!
//! Determinism: work is per cell; results are collected in site order and every sum over
//! cells runs in index order, so the output does not depend on the number of threads.
#![forbid(unsafe_code)]

mod density;
mod diagram;
mod domain;
mod error;
mod geometry;
mod moments;
#[cfg(test)]
mod on_threads;
mod optimise;
mod quality;
#[cfg(any(test, feature = "sample"))]
pub mod sample;

pub use density::{Density, Field, Quadratic};
pub use diagram::{
    clipped_cells, clipped_diagram, conforming_mesh, conforming_mesh_part, conforming_power_mesh,
    morton_order, BoxDomain, Clipped, ConvexCell, Diagram, DomainKind, Face, FaceIntegrals,
    FaceIntegrand, Matrix, MeshDomain, MeshPart, Options, PartCells, PeriodicBox, PolyMesh,
    PolygonCell, PolyhedronCell, PowerWhole, Request, RestrictedDelaunay, SiteIndex, Sphere,
    SphereRegion, Surface, SurfacePieces, Torus, WarmStart, MAX_REACH_DEGREES, ON_SPHERE_TOL,
};
pub use domain::{generalized_winding_number, Boundary, Polygon, Solid, TriangleSet};
pub use error::CoreError;
pub use geometry::{Aabb, Euclid, Space};
pub use moments::{tetra_moments, triangle_moments, FaceMoments, Moments};
#[doc(hidden)]
pub use optimise::set_stored_margins;
pub use optimise::{
    capacity_cvt, cvt, evaluate, evaluate_warm, lbfgs, lloyd, optimal_transport,
    optimal_transport_from, Capacity, CapacityRecord, CapacitySettings, Frame, Measures, Method,
    Named, Outcome, Point, PointRequest, Record, Rule, Settings, Step, StopReason, Transport,
    TransportRecord, TransportSettings, DEFAULT_VOLUME_TOL,
};
pub use quality::{mesh_quality, MeshArrays, MeshQuality};
