//! The diagram's side of a density (DESIGN §8): each cell's weighted sums over its signed
//! pieces ([`WeightedSums`]), a sampled field's one evaluation over the nodes of every
//! cell, and the checks that name where a density is unusable.

use rayon::prelude::*;

use crate::density::quadrature::{self, Rule};
use crate::density::{
    check_value, polynomial_cone, polynomial_face_moments, Cone, Density, Field, Quadratic,
    POLYNOMIAL_DEGREE,
};
use crate::error::CoreError;
use crate::geometry::{add, scale};
use crate::moments::{FaceMoments, Moments};

use super::domain_kind::DomainKind;
use super::{Batch, ConvexCell, Diagram};

/// What is summed.
#[derive(Debug, Clone, Copy)]
enum Kind<const D: usize> {
    /// No density: nothing.
    Off,
    /// A polynomial, in absolute coordinates and about the current cell's site, with the
    /// face rule.
    Polynomial {
        global: Quadratic<D>,
        local: Quadratic<D>,
        face_rule: Rule,
    },
    /// A field: the cone simplices are kept for one evaluation of the whole diagram.
    Sampled,
}

/// The weighted moments of one cell about its site (a [`Quadratic`]), or the cone
/// simplices that give them (a [`Field`]); buffers reused from cell to cell.
#[derive(Debug, Clone)]
pub struct WeightedSums<const D: usize> {
    kind: Kind<D>,
    /// With a polynomial: `∫ρ`, `∫ρ y`, `∫ρ |y|²` so far, `y = x − site`.
    pub moments: Moments<D>,
    /// With a field: the cell's cone simplices.
    pub cones: Vec<Cone<D>>,
}

impl<const D: usize> Default for WeightedSums<D> {
    fn default() -> Self {
        Self {
            kind: Kind::Off,
            moments: Moments::zero(),
            cones: Vec::new(),
        }
    }
}

impl<const D: usize> WeightedSums<D> {
    /// Sums for `density`; off without one. Checks the degree of a field's rule.
    pub fn new(density: Option<&Density<'_, D>>) -> Result<Self, CoreError> {
        let kind = match density {
            None => Kind::Off,
            Some(Density::Polynomial(q)) => Kind::Polynomial {
                global: *q,
                local: *q,
                // Face averages of degree ≤ 4 on (D − 1)-simplices.
                face_rule: quadrature::rule(D - 1, POLYNOMIAL_DEGREE).ok_or(
                    CoreError::InvalidDensity {
                        reason: format!("no face rule in {D} dimensions"),
                    },
                )?,
            },
            Some(d @ Density::Sampled { .. }) => {
                d.rule()?;
                Kind::Sampled
            }
        };
        Ok(Self {
            kind,
            ..Self::default()
        })
    }

    /// Whether there is a density.
    pub fn is_on(&self) -> bool {
        !matches!(self.kind, Kind::Off)
    }

    /// Whether the density is a field, sampled at nodes.
    pub fn is_sampled(&self) -> bool {
        matches!(self.kind, Kind::Sampled)
    }

    /// Whether face moments can be weighted ([`WeightedSums::face_moments`]): a polynomial.
    pub fn weighs_faces(&self) -> bool {
        matches!(self.kind, Kind::Polynomial { .. })
    }

    /// The ρ-weighted moments `∫ρ`, `∫ρ y`, `∫ρ y yᵀ` of the face simplex `simplex`
    /// (relative to the site) of `measure`, exact for a polynomial (degree ≤ 4 on the
    /// face); the geometric ones without a polynomial.
    pub fn face_moments(&self, simplex: &[[f64; D]; D], measure: f64) -> FaceMoments<D> {
        match &self.kind {
            Kind::Polynomial {
                local, face_rule, ..
            } => polynomial_face_moments(local, face_rule, simplex, measure),
            _ => FaceMoments::simplex(simplex, measure),
        }
    }

    /// With a polynomial: the polynomial about the current cell's site (the sphere
    /// samples it at its own nodes).
    pub fn polynomial_about_site(&self) -> Option<&Quadratic<D>> {
        match &self.kind {
            Kind::Polynomial { local, .. } => Some(local),
            _ => None,
        }
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
        self.cones.clear();
    }

    /// Add `piece` (relative to the site) with `sign`, cone simplex by cone simplex.
    pub fn add_piece<C: ConvexCell<D>>(&mut self, piece: &C, sign: f64) {
        match self.kind {
            Kind::Off => {}
            Kind::Polynomial {
                local, face_rule, ..
            } => {
                let m = &mut self.moments;
                piece.for_each_cone(|face, measure| {
                    let cone = polynomial_cone(&local, &face_rule, face, measure);
                    m.add_scaled(&cone, sign);
                });
            }
            Kind::Sampled => {
                let cones = &mut self.cones;
                piece.for_each_cone(|face, measure| cones.push((*face, sign * measure)));
            }
        }
    }
}

/// Evaluate `field` once at the nodes of `rule` in every cone simplex of every cell of
/// `batches` (in batch order, then cell order: fixed by the sites, not by the threads),
/// check every value, and replace each batch's cones by its cells' weighted moments
/// (nodes and sums as `domain` makes them: [`DomainKind::sampled_node`],
/// [`DomainKind::sampled_moments`]).
pub(super) fn sample<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    field: &dyn Field<D>,
    rule: &Rule,
    sites: &[[f64; D]],
    batches: &mut [Batch<D, C>],
) -> Result<(), CoreError> {
    let per_cone = rule.weights.len();
    let mut offsets = Vec::with_capacity(batches.len());
    let mut total = 0;
    for b in batches.iter() {
        offsets.push(total);
        total += b.cones.len() * per_cone;
    }
    // The nodes in absolute coordinates, made in parallel into one buffer.
    let mut points = vec![[0.0; D]; total];
    let mut slices = Vec::with_capacity(batches.len());
    let mut rest = points.as_mut_slice();
    for b in batches.iter() {
        let (head, tail) = rest.split_at_mut(b.cones.len() * per_cone);
        slices.push(head);
        rest = tail;
    }
    batches
        .par_iter()
        .zip(slices)
        .for_each(|(b, out)| write_nodes(domain, b, rule, sites, out));
    let values = field.values(points)?;
    if values.len() != total {
        return Err(CoreError::InvalidDensity {
            reason: format!(
                "the density function returned {} values for {total} points",
                values.len()
            ),
        });
    }
    if let Some(k) = values.iter().position(|&v| !(v.is_finite() && v > 0.0)) {
        // Name the point: find its cell and cone again.
        return Err(bad_node(domain, batches, rule, sites, k, values[k]));
    }
    batches
        .par_iter_mut()
        .zip(offsets)
        .for_each(|(b, mut from)| {
            let mut at = 0;
            b.weighted.clear();
            for (k, &count) in b.cone_counts.iter().enumerate() {
                let count = count as usize;
                let nodes = count * per_cone;
                let site = sites[b.sites[k] as usize];
                b.weighted.push(domain.sampled_moments(
                    site,
                    &b.cones[at..at + count],
                    rule,
                    &values[from..from + nodes],
                    &b.moments[k],
                ));
                at += count;
                from += nodes;
            }
            b.cones = Vec::new();
        });
    Ok(())
}

/// The nodes of batch `b`'s cones in absolute coordinates, into `out`.
fn write_nodes<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    b: &Batch<D, C>,
    rule: &Rule,
    sites: &[[f64; D]],
    out: &mut [[f64; D]],
) {
    let mut slot = out.iter_mut();
    let mut at = 0;
    for (&i, &count) in b.sites.iter().zip(&b.cone_counts) {
        let site = sites[i as usize];
        for cone in &b.cones[at..at + count as usize] {
            for ((lambda, _), x) in rule.nodes().zip(&mut slot) {
                *x = add(site, domain.sampled_node(site, cone, lambda));
            }
        }
        at += count as usize;
    }
}

/// The error for a bad `value` at node `k` of the whole diagram.
fn bad_node<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    batches: &[Batch<D, C>],
    rule: &Rule,
    sites: &[[f64; D]],
    mut k: usize,
    value: f64,
) -> CoreError {
    let per_cone = rule.weights.len();
    for b in batches {
        let mut at = 0;
        for (&i, &count) in b.sites.iter().zip(&b.cone_counts) {
            let nodes = count as usize * per_cone;
            if k < nodes {
                let cone = &b.cones[at + k / per_cone];
                let lambda = rule.nodes().nth(k % per_cone).map_or(&[][..], |n| n.0);
                let site = sites[i as usize];
                let point = add(site, domain.sampled_node(site, cone, lambda));
                return CoreError::DensityValue {
                    point: point.to_vec(),
                    value,
                };
            }
            k -= nodes;
            at += count as usize;
        }
    }
    CoreError::InvalidDensity {
        reason: format!("the density is {value} at a node"),
    }
}

/// The moments of a constant density `c`: every moment times `c` (exact; for `c = 1` the
/// geometric moments bit for bit).
pub(super) fn scaled<const D: usize>(moments: &[Moments<D>], c: f64) -> Vec<Moments<D>> {
    moments
        .iter()
        .map(|m| Moments {
            mass: c * m.mass,
            first: scale(m.first, c),
            second: c * m.second,
        })
        .collect()
}

/// A polynomial must be finite and positive at every site and boundary vertex.
pub(super) fn check_polynomial<const D: usize, K: DomainKind<D>>(
    q: &Quadratic<D>,
    domain: &K,
    sites: &[[f64; D]],
) -> Result<(), CoreError> {
    for &x in sites.iter().chain(domain.density_checkpoints()) {
        check_value(x, q.value(x))?;
    }
    Ok(())
}

/// Every cell of positive volume has a positive, finite weighted mass: a density negative
/// somewhere inside a cell shows here, named by the cell's centroid and its mean density.
pub(super) fn check_masses<const D: usize>(
    diagram: &Diagram<D>,
    sites: &[[f64; D]],
) -> Result<(), CoreError> {
    for ((m, w), &site) in diagram.moments.iter().zip(&diagram.weighted).zip(sites) {
        if m.mass > 0.0 && !(w.mass.is_finite() && w.mass > 0.0) {
            let centroid = m.centroid().map_or(site, |c| add(site, c));
            return Err(CoreError::DensityValue {
                point: centroid.to_vec(),
                value: w.mass / m.mass,
            });
        }
    }
    Ok(())
}
