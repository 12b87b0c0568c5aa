//! A density `ρ > 0` on the domain (DESIGN §8): the CVT energy becomes
//! `E(X) = Σ_i ∫_{Ω_i} ρ |x − x_i|²`, and each cell carries its ρ-weighted moments
//! `m_i = ∫ ρ`, `∫ ρ (x − x_i)` and `∫ ρ |x − x_i|²` beside its geometric ones.
//!
//! The weighted moments are integrated over the same signed cones from the site as the
//! geometric ones (DESIGN §3): each cone simplex gets a symmetric quadrature rule with
//! positive weights ([`quadrature`]). Two kinds of density:
//!
//! - [`Quadratic`]: a polynomial of degree ≤ 2, evaluated inside the core at the points of
//!   the degree-4 rule (5 in 3D): `ρ |x − x_i|²` has degree 4, so every moment is exact to
//!   round-off;
//! - [`Field`]: any function, sampled by a rule of stated degree; the diagram gathers the
//!   rule's points of every cell, asks the field for all of them in one call, and sums
//!   each cell's nodes in order;
//! - [`Density::PerVertex`]: on a triangle surface, values at its vertices, linear on each
//!   triangle: interpolated at the corners of each piece and integrated there by the
//!   degree-4 triangle rule, exact.
//!
//! | file | owns |
//! |------|------|
//! | `mod.rs` | [`Density`], [`Quadratic`], [`Field`] and the checks of their values |
//! | `quadrature.rs` | the simplex rules and their sources |
//! | `sums.rs` | the moments over one cone simplex: a polynomial by face averages, a field from its nodes; weighted face moments |

pub(crate) mod quadrature;
mod sums;

pub use sums::{
    cone_measure, cone_node, face_node, linear_face_moments, polynomial_cone, polynomial_cone_mass,
    polynomial_face_moments, sum_sampled, sum_sampled_on_faces, Cone,
};

use crate::error::CoreError;
use crate::geometry::{add, dot};
use quadrature::{Rule, MAX_DEGREE};

/// A polynomial density of degree ≤ 2, `ρ(x) = c + b·x + xᵀ A x` with `A` symmetric, in
/// absolute coordinates: `constant` has the unit of ρ, `linear` ρ/L, `quadratic` ρ/L².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quadratic<const D: usize> {
    /// `c`.
    pub constant: f64,
    /// `b`.
    pub linear: [f64; D],
    /// `A`, symmetric.
    pub quadratic: [[f64; D]; D],
}

impl<const D: usize> Quadratic<D> {
    /// The polynomial with these coefficients; `quadratic` is symmetrised (`(A + Aᵀ)/2`
    /// gives the same values). Refuses non-finite coefficients.
    pub fn new(
        constant: f64,
        linear: [f64; D],
        quadratic: [[f64; D]; D],
    ) -> Result<Self, CoreError> {
        let all = std::iter::once(constant)
            .chain(linear)
            .chain(quadratic.iter().flatten().copied());
        if let Some(value) = all.clone().find(|x| !x.is_finite()) {
            return Err(CoreError::InvalidDensity {
                reason: format!("a polynomial coefficient is not finite ({value})"),
            });
        }
        let quadratic = std::array::from_fn(|r| {
            std::array::from_fn(|c| 0.5 * (quadratic[r][c] + quadratic[c][r]))
        });
        Ok(Self {
            constant,
            linear,
            quadratic,
        })
    }

    /// The constant density `c`.
    pub fn constant(c: f64) -> Self {
        Self {
            constant: c,
            linear: [0.0; D],
            quadratic: [[0.0; D]; D],
        }
    }

    /// Whether `ρ` is a constant (no linear or quadratic term).
    pub fn is_constant(&self) -> bool {
        self.linear
            .iter()
            .chain(self.quadratic.iter().flatten())
            .all(|&x| x == 0.0)
    }

    /// `ρ(x)`.
    #[inline]
    pub fn value(&self, x: [f64; D]) -> f64 {
        let ax: [f64; D] = std::array::from_fn(|r| dot(self.quadratic[r], x));
        self.constant + dot(add(self.linear, ax), x)
    }

    /// The same function in coordinates `y = x − origin`: `ρ(origin + y) = ρ(origin) +
    /// (b + 2 A origin)·y + yᵀ A y`. Cells integrate about their site, in small relative
    /// coordinates.
    pub fn about(&self, origin: [f64; D]) -> Self {
        let a_origin: [f64; D] = std::array::from_fn(|r| dot(self.quadratic[r], origin));
        Self {
            constant: self.value(origin),
            linear: std::array::from_fn(|k| self.linear[k] + 2.0 * a_origin[k]),
            quadratic: self.quadratic,
        }
    }
}

/// A density given as a function: the values at many points in one call.
pub trait Field<const D: usize>: Sync {
    /// `ρ` at each of `points` (absolute coordinates), in order: one value per point.
    /// The points are handed over (a binding can pass their buffer on without a copy:
    /// a diagram has tens of millions). An error here (the caller's function failed) ends
    /// the diagram with it.
    fn values(&self, points: Vec<[f64; D]>) -> Result<Vec<f64>, CoreError>;
}

/// The density of a diagram or a CVT.
#[derive(Clone, Copy)]
pub enum Density<'a, const D: usize> {
    /// A polynomial of degree ≤ 2: moments exact to round-off.
    Polynomial(Quadratic<D>),
    /// A function sampled by the simplex rule of at least `degree` ([`quadrature`]).
    Sampled {
        /// The function.
        field: &'a dyn Field<D>,
        /// Degree of exactness asked of the rule, `1..=5`.
        degree: usize,
    },
    /// A field on a triangle surface given by its values at the surface's vertices (in
    /// their order), linear on each triangle: moments exact to round-off (`ρ |y|²` has
    /// degree 3 on each flat piece). Other domains refuse it.
    PerVertex(&'a [f64]),
}

impl<const D: usize> std::fmt::Debug for Density<'_, D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Polynomial(q) => f.debug_tuple("Polynomial").field(q).finish(),
            Self::Sampled { degree, .. } => write!(f, "Sampled {{ degree: {degree} }}"),
            Self::PerVertex(values) => write!(f, "PerVertex({} values)", values.len()),
        }
    }
}

/// Degree of the rule a [`Quadratic`] is integrated with: `ρ |y|²` has degree 4.
pub const POLYNOMIAL_DEGREE: usize = 4;

/// Degree of the face rule a [`Quadratic`]'s cone masses alone are integrated with
/// ([`polynomial_cone_mass`]): ρ has degree 2.
pub const POLYNOMIAL_MASS_DEGREE: usize = 2;

impl<const D: usize> Density<'_, D> {
    /// The quadrature rule this density is integrated with in cells of dimension `D`.
    pub fn rule(&self) -> Result<Rule, CoreError> {
        self.rule_in(D)
    }

    /// The quadrature rule on simplices of dimension `dim`: cells of dimension 2 in 3D
    /// (the sphere) take triangle rules.
    pub fn rule_in(&self, dim: usize) -> Result<Rule, CoreError> {
        let degree = match self {
            Self::Polynomial(_) | Self::PerVertex(_) => POLYNOMIAL_DEGREE,
            Self::Sampled { degree, .. } => *degree,
        };
        quadrature::rule(dim, degree).ok_or_else(|| CoreError::InvalidDensity {
            reason: format!("quadrature degree must be 1 to {MAX_DEGREE}, got {degree}"),
        })
    }
}

/// `Ok` when `value` is a usable density at `point`: finite and positive.
pub fn check_value<const D: usize>(point: [f64; D], value: f64) -> Result<(), CoreError> {
    if value.is_finite() && value > 0.0 {
        return Ok(());
    }
    Err(CoreError::DensityValue {
        point: point.to_vec(),
        value,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polynomial_about_a_point_has_the_same_values() {
        let q = Quadratic::new(2.0, [0.5, -1.0], [[1.0, 0.3], [-0.1, 2.0]]).unwrap();
        assert_eq!(q.quadratic[0][1], q.quadratic[1][0]);
        let origin = [3.0, -2.0];
        let shifted = q.about(origin);
        for y in [[0.0, 0.0], [0.1, 0.2], [-1.5, 0.7]] {
            let (a, b) = (q.value(add(origin, y)), shifted.value(y));
            assert!((a - b).abs() < 1e-13 * a.abs().max(1.0), "{a} vs {b}");
        }
        assert!(Quadratic::new(f64::NAN, [0.0; 2], [[0.0; 2]; 2]).is_err());
    }
}
