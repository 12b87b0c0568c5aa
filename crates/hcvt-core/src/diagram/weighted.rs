//! The diagram's side of a density (DESIGN §8): a sampled field's one evaluation over the
//! nodes of every cell (the cells' weighted sums are `weighted_sums.rs`'s), and the checks
//! that name where a density is unusable.

use rayon::prelude::*;

use crate::density::quadrature::Rule;
use crate::density::{check_value, Field, Quadratic};
use crate::error::CoreError;
use crate::geometry::{add, scale};
use crate::moments::Moments;

use super::convex_cell::ConvexCell;
use super::domain_kind::DomainKind;
use super::faces::FaceIntegrand;
use super::output::{Batch, Diagram};
use super::weighted_sums::{FaceNodes, FACE_NODES};

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

/// A per-vertex density is given on a kind that takes one (a triangle surface), with one
/// value per vertex, each finite and positive (else the vertex is named).
pub(super) fn check_per_vertex<const D: usize, K: DomainKind<D>>(
    values: &[f64],
    domain: &K,
) -> Result<(), CoreError> {
    let Some(count) = domain.vertex_density_len() else {
        return Err(CoreError::InvalidDensity {
            reason: "a per-vertex density is taken on a triangle surface only".into(),
        });
    };
    if values.len() != count {
        return Err(CoreError::InvalidDensity {
            reason: format!(
                "a per-vertex density needs one value per vertex of the surface: {} values \
                 for {count} vertices",
                values.len()
            ),
        });
    }
    let vertices = domain.density_checkpoints();
    for (k, &v) in values.iter().enumerate() {
        let point = vertices.get(k).copied().unwrap_or([f64::NAN; D]);
        check_value(point, v)?;
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
