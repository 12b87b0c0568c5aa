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
use super::faces::FaceIntegrand;
use super::{Batch, ConvexCell, Diagram};

/// Nodes per [`FaceNodes`]: those of [`quadrature::SEGMENT_5`] (3-point Gauss–Legendre).
pub const FACE_NODES: usize = 3;

/// A face piece whose ρ-weighted moments wait for a sampled field's values: the sphere's
/// arcs, for Newton's Hessian (DESIGN §13). Its neighbour, its nodes relative to the site
/// with the measure each stands for, and its geometric moments (exact).
#[derive(Debug, Clone, Copy)]
pub struct FaceNodes<const D: usize> {
    /// The cell across the face.
    pub neighbor: u32,
    /// `(x − site, weight)` per node, `(L, L^(d−1))`.
    pub nodes: [([f64; D], f64); FACE_NODES],
    /// `∫1`, `∫y`, `∫y yᵀ` over the face, exact.
    pub geometric: FaceMoments<D>,
}

impl<const D: usize> FaceNodes<D> {
    /// The face's ρ-weighted moments from ρ's `values` at its nodes: the rule's sums
    /// `Q[ρ f] + ρ̄ (G − Q[f])` with `ρ̄ = Q[ρ]/Q[1]`, so that a constant is exact to
    /// round-off (as the sphere's cells are, `sphere_density.rs`).
    pub fn weighted(&self, values: &[f64]) -> FaceMoments<D> {
        let (mut rho, mut one) = (FaceMoments::zero(), FaceMoments::zero());
        for (&(y, w), &v) in self.nodes.iter().zip(values) {
            let term = FaceMoments {
                measure: w,
                first: scale(y, w),
                second: y.map(|a| scale(y, w * a)),
            };
            add_face_scaled(&mut one, &term, 1.0);
            add_face_scaled(&mut rho, &term, v);
        }
        if one.measure <= 0.0 {
            return rho;
        }
        let mean = rho.measure / one.measure;
        add_face_scaled(&mut rho, &self.geometric, mean);
        add_face_scaled(&mut rho, &one, -mean);
        rho
    }
}

/// `m += c · term`, every moment.
fn add_face_scaled<const D: usize>(m: &mut FaceMoments<D>, term: &FaceMoments<D>, c: f64) {
    m.measure += c * term.measure;
    m.first = add(m.first, scale(term.first, c));
    for (row, t) in m.second.iter_mut().zip(&term.second) {
        *row = add(*row, scale(*t, c));
    }
}

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
    /// With a field and a face integrand on the sphere: the cell's arcs, weighted once the
    /// field is sampled.
    pub faces: Vec<FaceNodes<D>>,
}

impl<const D: usize> Default for WeightedSums<D> {
    fn default() -> Self {
        Self {
            kind: Kind::Off,
            moments: Moments::zero(),
            cones: Vec::new(),
            faces: Vec::new(),
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
        self.faces.clear();
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
/// `batches`, and at the nodes of their deferred faces ([`FaceNodes`]) (in batch order, a
/// batch's cones then its faces, cell after cell: fixed by the sites, not by the threads),
/// check every value, and replace each batch's cones by its cells' weighted moments
/// (nodes and sums as `domain` makes them: [`DomainKind::sampled_node`],
/// [`DomainKind::sampled_moments`]) and add its faces' weighted moments to `integrand`'s
/// sums.
pub(super) fn sample<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    field: &dyn Field<D>,
    rule: &Rule,
    sites: &[[f64; D]],
    batches: &mut [Batch<D, C>],
    integrand: Option<&dyn FaceIntegrand<D>>,
) -> Result<(), CoreError> {
    let per_cone = rule.weights.len();
    let nodes_of = |b: &Batch<D, C>| b.cones.len() * per_cone + b.face_nodes.len() * FACE_NODES;
    let mut offsets = Vec::with_capacity(batches.len());
    let mut total = 0;
    for b in batches.iter() {
        offsets.push(total);
        total += nodes_of(b);
    }
    // The nodes in absolute coordinates, made in parallel into one buffer.
    let mut points = vec![[0.0; D]; total];
    let mut slices = Vec::with_capacity(batches.len());
    let mut rest = points.as_mut_slice();
    for b in batches.iter() {
        let (head, tail) = rest.split_at_mut(nodes_of(b));
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
            if let Some(integrand) = integrand {
                add_weighted_faces(b, integrand, &values[from..]);
            }
            b.face_nodes = Vec::new();
        });
    Ok(())
}

/// Add the weighted moments of batch `b`'s deferred faces, from ρ's `values` at their
/// nodes, to its rows' sums of `integrand`, in the order the faces were met.
fn add_weighted_faces<const D: usize, C>(
    b: &mut Batch<D, C>,
    integrand: &dyn FaceIntegrand<D>,
    values: &[f64],
) {
    let (mut first_face, mut at) = (0, 0);
    let mut values = values.chunks_exact(FACE_NODES);
    for (k, (&count, &faces)) in b.face_counts.iter().zip(&b.face_node_counts).enumerate() {
        let row = first_face..first_face + count as usize;
        let i = b.sites[k] as usize;
        for f in &b.face_nodes[at..at + faces as usize] {
            let v = values.next().expect("one set of values per face");
            // A face of no positive measure in all was dropped from the row.
            let Some(e) = (row.clone()).find(|&e| b.neighbor_sites[e] == f.neighbor) else {
                continue;
            };
            let m = f.weighted(v);
            let j = f.neighbor as usize;
            // A sampled density is not taken in a periodic box: no image to name.
            integrand.add(
                i,
                j,
                None,
                1.0,
                &m,
                &mut b.face_integrals[e],
                &mut b.cell_integrals[k],
            );
        }
        first_face = row.end;
        at += faces as usize;
    }
}

/// The nodes of batch `b`'s cones, then of its deferred faces, in absolute coordinates,
/// into `out`.
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
    for (site, f) in face_sites(b, sites) {
        for (&(y, _), x) in f.nodes.iter().zip(&mut slot) {
            *x = add(site, y);
        }
    }
}

/// Batch `b`'s deferred faces, each with its cell's site.
fn face_sites<'a, const D: usize, C>(
    b: &'a Batch<D, C>,
    sites: &'a [[f64; D]],
) -> impl Iterator<Item = ([f64; D], &'a FaceNodes<D>)> + 'a {
    let cells = b.sites.iter().zip(&b.face_node_counts);
    cells
        .flat_map(|(&i, &count)| std::iter::repeat_n(sites[i as usize], count as usize))
        .zip(&b.face_nodes)
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
    let named = |point: [f64; D]| CoreError::DensityValue {
        point: point.to_vec(),
        value,
    };
    for b in batches {
        let mut at = 0;
        for (&i, &count) in b.sites.iter().zip(&b.cone_counts) {
            let nodes = count as usize * per_cone;
            if k < nodes {
                let cone = &b.cones[at + k / per_cone];
                let lambda = rule.nodes().nth(k % per_cone).map_or(&[][..], |n| n.0);
                let site = sites[i as usize];
                return named(add(site, domain.sampled_node(site, cone, lambda)));
            }
            k -= nodes;
            at += count as usize;
        }
        for (site, f) in face_sites(b, sites) {
            if k < FACE_NODES {
                return named(add(site, f.nodes[k].0));
            }
            k -= FACE_NODES;
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
