//! The diagram's side of a density (DESIGN §8): a sampled field's one evaluation over the
//! nodes of every cell, and the checks that name where a density is unusable.

use rayon::prelude::*;

use crate::density::{check_value, sum_nodes, Field, Quadratic};
use crate::domain::Boundary;
use crate::error::CoreError;
use crate::geometry::{add, Euclid, Space};

use super::{Batch, ConvexCell, Diagram};

/// Evaluate `field` once at the nodes of every cell of `batches` (in batch order, then
/// cell order: fixed by the sites, not by the threads), check every value, and replace each
/// batch's nodes by its cells' weighted moments.
pub(super) fn sample<const D: usize, C: ConvexCell<D>>(
    field: &dyn Field<D>,
    sites: &[[f64; D]],
    batches: &mut [Batch<D, C>],
) -> Result<(), CoreError> {
    let total: usize = batches.iter().map(|b| b.nodes.len()).sum();
    let mut points = Vec::with_capacity(total);
    for b in batches.iter() {
        let mut at = 0;
        for (&i, &count) in b.sites.iter().zip(&b.node_counts) {
            let site = sites[i as usize];
            let count = count as usize;
            points.extend(b.nodes[at..at + count].iter().map(|&y| add(site, y)));
            at += count;
        }
    }
    let values = field.values(&points)?;
    if values.len() != points.len() {
        return Err(CoreError::InvalidDensity {
            reason: format!(
                "the density function returned {} values for {} points",
                values.len(),
                points.len()
            ),
        });
    }
    if let Some(k) = values.iter().position(|&v| !(v.is_finite() && v > 0.0)) {
        check_value(points[k], values[k])?;
    }
    drop(points);
    let mut offsets = Vec::with_capacity(batches.len());
    let mut from = 0;
    for b in batches.iter() {
        offsets.push(from);
        from += b.nodes.len();
    }
    batches
        .par_iter_mut()
        .zip(offsets)
        .for_each(|(b, mut from)| {
            let mut at = 0;
            b.weighted.clear();
            for &count in &b.node_counts {
                let count = count as usize;
                let range = at..at + count;
                b.weighted.push(sum_nodes(
                    &b.nodes[range.clone()],
                    &b.node_weights[range],
                    &values[from..from + count],
                ));
                at += count;
                from += count;
            }
            b.nodes = Vec::new();
            b.node_weights = Vec::new();
        });
    Ok(())
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
