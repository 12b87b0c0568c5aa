//! Exact clipped Voronoi diagrams and regular centroidal Voronoi tessellations.
//!
//! Module map (DESIGN §2), each layer using only those above it:
//!
//! | module      | owns                                                                 |
//! |-------------|----------------------------------------------------------------------|
//! | [`geometry`]| small vector helpers and the per-dimension primitives ([`geometry::Space`]) |
//! | [`moments`] | closed-form mass, first and second moments of simplices; `G`          |
//! | [`density`] | a density ρ: polynomials of degree ≤ 2 (exact) and sampled functions; simplex quadrature rules |
//! | [`domain`]  | the oriented boundary of a 2D polygon or 3D solid, its BVH and winding number |
//! | [`diagram`] | convex Voronoi cells by kNN + half-space clipping, clipped exactly by the domain |
//! | [`optimise`]| CVT energy, gradient and Hessian from the diagram; Lloyd, L-BFGS and Newton to the stopping rule |
//!
//! [`error`] holds [`CoreError`], which every layer returns.
//!
//! With the cargo feature `sample` (on for this crate's tests and examples, off for the
//! binding), `sample` gives deterministic pseudo-random points for tests and examples: not
//! part of the API.
//!
//! Units: every length is in the unit of the input coordinates (`L`); volumes are `L^d`,
//! first moments `L^(d+1)`, second moments `L^(d+2)`.
//!
//! Determinism: work is per cell; results are collected in site order and every sum over
//! cells runs in index order, so the output does not depend on the number of threads.
#![forbid(unsafe_code)]

pub mod density;
pub mod diagram;
pub mod domain;
pub mod error;
pub mod geometry;
pub mod moments;
pub mod optimise;
#[cfg(any(test, feature = "sample"))]
pub mod sample;

pub use error::CoreError;
