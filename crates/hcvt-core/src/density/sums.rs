//! One cell's ρ-weighted moments, summed over its signed pieces as the diagram measures
//! them (DESIGN §3, §8).

use crate::diagram::ConvexCell;
use crate::error::CoreError;
use crate::geometry::norm2;
use crate::moments::Moments;

use super::quadrature::Rule;
use super::{Density, Quadratic};

/// What is summed.
#[derive(Debug, Clone, Copy)]
enum Kind<const D: usize> {
    /// No density: nothing.
    Off,
    /// A polynomial, in absolute coordinates and about the current cell's site.
    Polynomial {
        global: Quadratic<D>,
        local: Quadratic<D>,
        rule: Rule,
    },
    /// A field: the rule's nodes are kept for one evaluation of the whole diagram.
    Sampled { rule: Rule },
}

/// The weighted moments of one cell about its site (a [`Quadratic`]), or the quadrature
/// nodes that give them (a [`super::Field`]); buffers reused from cell to cell.
#[derive(Debug, Clone)]
pub struct WeightedSums<const D: usize> {
    kind: Kind<D>,
    /// With a polynomial: `∫ρ`, `∫ρ y`, `∫ρ |y|²` so far, `y = x − site`.
    pub moments: Moments<D>,
    /// With a field: the nodes relative to the site, and their signed weights (rule
    /// weight × signed simplex measure, L^d).
    pub nodes: Vec<[f64; D]>,
    /// See `nodes`.
    pub weights: Vec<f64>,
}

impl<const D: usize> Default for WeightedSums<D> {
    fn default() -> Self {
        Self {
            kind: Kind::Off,
            moments: Moments::zero(),
            nodes: Vec::new(),
            weights: Vec::new(),
        }
    }
}

impl<const D: usize> WeightedSums<D> {
    /// Sums for `density`; off without one.
    pub fn new(density: Option<&Density<'_, D>>) -> Result<Self, CoreError> {
        let kind = match density {
            None => Kind::Off,
            Some(d @ Density::Polynomial(q)) => Kind::Polynomial {
                global: *q,
                local: *q,
                rule: d.rule()?,
            },
            Some(d @ Density::Sampled { .. }) => Kind::Sampled { rule: d.rule()? },
        };
        Ok(Self {
            kind,
            ..Self::default()
        })
    }
}

impl<const D: usize> WeightedSums<D> {
    /// Whether there is a density.
    pub fn is_on(&self) -> bool {
        !matches!(self.kind, Kind::Off)
    }

    /// Whether the density is a field, sampled at nodes.
    pub fn is_sampled(&self) -> bool {
        matches!(self.kind, Kind::Sampled { .. })
    }

    /// Begin the cell of the site at `site`: nothing summed yet.
    pub fn start_cell(&mut self, site: [f64; D]) {
        if let Kind::Polynomial { global, local, .. } = &mut self.kind {
            *local = global.about(site);
        }
        self.clear();
    }

    /// Forget what this cell has summed (an empty cell).
    pub fn clear(&mut self) {
        self.moments = Moments::zero();
        self.nodes.clear();
        self.weights.clear();
    }

    /// Add `piece` (relative to the site) with `sign`, cone simplex by cone simplex.
    pub fn add_piece<C: ConvexCell<D>>(&mut self, piece: &C, sign: f64) {
        match self.kind {
            Kind::Off => {}
            Kind::Polynomial { local, rule, .. } => {
                let m = &mut self.moments;
                piece.for_each_cone(|simplex, measure| {
                    let mut cone = Moments::zero();
                    for (lambda, w) in rule.nodes() {
                        let y = at(simplex, lambda);
                        let f = w * local.value(y);
                        cone.mass += f;
                        for (sum, &yk) in cone.first.iter_mut().zip(&y) {
                            *sum += f * yk;
                        }
                        cone.second += f * norm2(y);
                    }
                    m.add_scaled(&cone, sign * measure);
                });
            }
            Kind::Sampled { rule } => {
                let (nodes, weights) = (&mut self.nodes, &mut self.weights);
                piece.for_each_cone(|simplex, measure| {
                    for (lambda, w) in rule.nodes() {
                        nodes.push(at(simplex, lambda));
                        weights.push(sign * measure * w);
                    }
                });
            }
        }
    }
}

/// The point of barycentric coordinates `lambda` (on vertices `1..=D`; vertex 0, the
/// site, is the origin) of the cone simplex `simplex`.
#[inline]
fn at<const D: usize>(simplex: &[[f64; D]; D], lambda: &[f64]) -> [f64; D] {
    std::array::from_fn(|k| (0..D).map(|v| lambda[v] * simplex[v][k]).sum())
}

/// The weighted moments of a cell from its nodes (relative to its site), their weights
/// and `values` of the density there, summed in node order.
pub fn sum_nodes<const D: usize>(
    nodes: &[[f64; D]],
    weights: &[f64],
    values: &[f64],
) -> Moments<D> {
    let mut m = Moments::zero();
    for ((y, &w), &rho) in nodes.iter().zip(weights).zip(values) {
        let f = w * rho;
        m.mass += f;
        for (sum, &yk) in m.first.iter_mut().zip(y) {
            *sum += f * yk;
        }
        m.second += f * norm2(*y);
    }
    m
}
