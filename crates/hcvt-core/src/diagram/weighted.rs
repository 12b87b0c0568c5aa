//! The diagram's side of a density (DESIGN §8): a sampled field's one evaluation over the
//! nodes of every cell, and the checks that name where a density is unusable.

use rayon::prelude::*;

use crate::density::quadrature::Rule;
use crate::density::{check_value, cone_node, sum_sampled, Field, Quadratic};
use crate::domain::Boundary;
use crate::error::CoreError;
use crate::geometry::{add, Euclid, Space};

use super::{Batch, ConvexCell, Diagram};

/// Evaluate `field` once at the nodes of `rule` in every cone simplex of every cell of
/// `batches` (in batch order, then cell order: fixed by the sites, not by the threads),
/// check every value, and replace each batch's cones by its cells' weighted moments.
pub(super) fn sample<const D: usize, C: ConvexCell<D>>(
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
        .for_each(|(b, out)| write_nodes(b, rule, sites, out));
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
        return Err(bad_node(batches, rule, sites, k, values[k]));
    }
    batches
        .par_iter_mut()
        .zip(offsets)
        .for_each(|(b, mut from)| {
            let mut at = 0;
            b.weighted.clear();
            for &count in &b.cone_counts {
                let count = count as usize;
                let nodes = count * per_cone;
                b.weighted.push(sum_sampled(
                    &b.cones[at..at + count],
                    rule,
                    &values[from..from + nodes],
                ));
                at += count;
                from += nodes;
            }
            b.cones = Vec::new();
        });
    Ok(())
}

/// The nodes of batch `b`'s cones in absolute coordinates, into `out`.
fn write_nodes<const D: usize, C: ConvexCell<D>>(
    b: &Batch<D, C>,
    rule: &Rule,
    sites: &[[f64; D]],
    out: &mut [[f64; D]],
) {
    let mut slot = out.iter_mut();
    let mut at = 0;
    for (&i, &count) in b.sites.iter().zip(&b.cone_counts) {
        let site = sites[i as usize];
        for (face, _) in &b.cones[at..at + count as usize] {
            for ((lambda, _), x) in rule.nodes().zip(&mut slot) {
                *x = add(site, cone_node(face, lambda));
            }
        }
        at += count as usize;
    }
}

/// The error for a bad `value` at node `k` of the whole diagram.
fn bad_node<const D: usize, C: ConvexCell<D>>(
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
                let (face, _) = b.cones[at + k / per_cone];
                let lambda = rule.nodes().nth(k % per_cone).map_or(&[][..], |n| n.0);
                let point = add(sites[i as usize], cone_node(&face, lambda));
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

/// A polynomial must be finite and positive at every site and boundary vertex.
pub(super) fn check_polynomial<const D: usize>(
    q: &Quadratic<D>,
    boundary: &Boundary<D>,
    sites: &[[f64; D]],
) -> Result<(), CoreError>
where
    Euclid: Space<D>,
{
    for &x in sites.iter().chain(boundary.vertices()) {
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
