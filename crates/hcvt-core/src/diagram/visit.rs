//! One pass over the cells of a diagram: the sites' cells in batches of [`BATCH`] in
//! parallel ([`Visit::batches`]), each cell found ([`voronoi_cell`], a warm start, a power
//! diagram's hint), clipped by the domain and measured; errors kept in their batch and the
//! first in index order reported ([`without_errors`]).

use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::CoreError;
use crate::geometry::{Euclid, Space};

use super::clip::{measure, MeasureScratch};
use super::convex_cell::ConvexCell;
use super::domain_kind::DomainKind;
use super::faces::{FaceIntegrand, FaceRow};
use super::knn::IndexRef;
use super::output::{Batch, Diagram, BATCH};
use super::power::{InDomain, MarginScratch, Power};
use super::voronoi_cell::{voronoi_cell, CellScratch};
use super::warm::{Moved, WarmStart};
use super::weighted_sums::WeightedSums;

/// A floor on the cells' masses below which a diagram is of no use to its caller
/// ([`super::trial_diagram`]): the first cell found under it stops every batch.
pub(super) struct MassFloor {
    pub(super) mass: f64,
    pub(super) below: AtomicBool,
}

/// What every cell of one diagram computation shares: the sites, their index, the winding
/// numbers of the sites whose cells are computed, and the number of sites of the whole
/// problem (more than `sites.len()` when `sites` is a partition with its halo).
pub(super) struct Visit<'a, const D: usize> {
    pub(super) sites: &'a [[f64; D]],
    /// Filled on first use when the cells start warm ([`super::knn::DeferredIndex`]).
    pub(super) index: IndexRef<'a, D>,
    /// Indexed like `sites`; only the entries of the sites visited are read.
    pub(super) windings: &'a [Option<i32>],
    /// The weights of a power diagram, indexed like `sites`.
    pub(super) power: Option<Power<'a, D>>,
    /// A power diagram of the same sites whose neighbours start each power cell
    /// ([`super::Request::power_start`]).
    pub(super) power_start: Option<&'a Diagram<D>>,
    pub(super) total_sites: usize,
    /// A previous diagram's near-site lists and how far the sites moved since.
    pub(super) warm: Option<(&'a WarmStart<D>, &'a Moved)>,
    /// Record each cell's near sites for the next diagram.
    pub(super) record: bool,
    /// Keep each cell's reach ([`Batch::reach2`]): a part's cells and the periodic box's
    /// bands need it, a whole diagram does not.
    pub(super) reach: bool,
    /// Stop at the first cell below this mass ([`super::trial_diagram`]).
    pub(super) floor: Option<&'a MassFloor>,
}

impl<const D: usize> Visit<'_, D>
where
    Euclid: Space<D>,
{
    /// Power cell `i` from [`Visit::power_start`]'s neighbours (`Power::hinted_cell`), in
    /// `buffer`; `None` without a start, or for a cell left to the stream.
    /// With stored margins, the cell's is tried first; a margin taken is left in `record`
    /// (`Power::hinted_cell`). With `part` (a convex domain, the site strictly inside), a
    /// cell spread too far is certified over its part in the domain, cut in `part.0`.
    fn started_cell<'c, C: ConvexCell<D>, K: DomainKind<D>>(
        &self,
        domain: &K,
        i: usize,
        buffer: &'c mut Option<C>,
        record: &mut MarginScratch<D>,
        part: Option<(&mut Option<C>, &mut Vec<u32>)>,
    ) -> Option<&'c C> {
        record.recorded = false;
        record.skipped = false;
        let (power, start) = (self.power.as_ref()?, self.power_start?);
        let neighbours =
            &start.neighbor_sites[start.neighbor_offsets[i]..start.neighbor_offsets[i + 1]];
        let bounds = domain.start(self.sites[i]);
        let cell = buffer.get_or_insert_with(|| C::from_box(&bounds));
        let margin = power.margin(i);
        let in_domain =
            part.map(|(copy, candidates)| InDomain::new(domain, self.sites[i], copy, candidates));
        power
            .hinted_cell(
                cell,
                &bounds,
                self.sites,
                i,
                neighbours,
                margin.as_ref(),
                record,
                power.records(),
                in_domain,
            )
            .then_some(&*cell)
    }

    /// The cells of the sites `visit`, in that order, measured in batches of [`BATCH`] in
    /// parallel; errors are kept in their batch.
    pub(super) fn batches<C: ConvexCell<D>, K: DomainKind<D>>(
        &self,
        domain: &K,
        visit: &[u32],
        integrand: Option<&dyn FaceIntegrand<D>>,
        keep_cells: bool,
        weighted: &WeightedSums<D>,
    ) -> Vec<Batch<D, C>> {
        let convex = domain.is_convex();
        // The lists recorded are about as long as the ones read (cold: a guess, 2D's).
        let near_per_cell = self.warm.map_or(16, |(w, _)| w.mean_list_len());
        visit
            .par_chunks(BATCH)
            .enumerate()
            .map_init(
                || {
                    let mut measuring = MeasureScratch::default();
                    measuring.faces.weighted = weighted.clone();
                    (
                        CellScratch::default(),
                        measuring,
                        (None, None, Vec::new()),
                        MarginScratch::default(),
                    )
                },
                |(scratch, measuring, (hinted, part, candidates), margin), (first, chunk)| {
                    let mut batch = Batch::new(chunk.len(), integrand.is_some());
                    if self.record {
                        batch.reserve_lists(chunk.len(), near_per_cell);
                    }
                    for (visited, &i) in (first * BATCH..).zip(chunk) {
                        if self.floor.is_some_and(|f| f.below.load(Ordering::Relaxed)) {
                            break;
                        }
                        let i = i as usize;
                        let winding = self.windings[i];
                        // A power cell is not cut to the domain, only bounded by its part
                        // there (`InDomain`).
                        let convex_inside = convex && winding == Some(1);
                        let warm = self
                            .warm
                            .and_then(|(w, moved)| w.certified(i, visited, moved));
                        let part = convex_inside.then_some((&mut *part, &mut *candidates));
                        let started = self.started_cell(domain, i, hinted, margin, part);
                        let (cell, inside) = match started.map_or_else(
                            || {
                                voronoi_cell::<D, C, K>(
                                    domain,
                                    self.index,
                                    self.sites,
                                    self.power.as_ref(),
                                    self.total_sites,
                                    i,
                                    convex_inside,
                                    warm,
                                    self.record,
                                    scratch,
                                )
                            },
                            |cell| Ok((cell, cell.is_empty())),
                        ) {
                            Ok(found) => found,
                            Err(e) => {
                                batch.fail(i, e);
                                continue;
                            }
                        };
                        let row = integrand.map(|integrand| FaceRow { integrand, site: i });
                        measuring.faces.weighted.start_cell(self.sites[i]);
                        // The clip may start its cones from the site, with the site's
                        // winding number, only if the site lies in its cell: the
                        // boundary it looks for is that near the cell. A power cell
                        // without its site is measured from a point of its own, as is
                        // the cell of a site on the boundary (winding `None`).
                        let winding = match self.power {
                            Some(_) if cell.excludes(&[[0.0; D]]) => None,
                            _ => winding,
                        };
                        let moments = if inside {
                            measure(cell, row, &mut measuring.faces)
                        } else {
                            domain.clip(cell, self.sites[i], winding, row, measuring)
                        };
                        if let Some(f) = self.floor.filter(|f| moments.mass < f.mass) {
                            f.below.store(true, Ordering::Relaxed);
                        }
                        batch.push(i, moments, &mut measuring.faces, integrand.is_some());
                        batch.margins.push(i, margin);
                        if keep_cells {
                            batch.cells.push(cell.clone());
                        }
                        if self.reach {
                            batch.reach2.push(scratch.reach2());
                        }
                        if self.record {
                            let (near, complete2, warm) = scratch.record();
                            batch.near_counts.push(near.len() as u32);
                            batch.near.extend_from_slice(near);
                            batch.near_complete2.push(complete2);
                            batch.near_rings.push(scratch.record_ring());
                            let triangles = scratch.record_triangles();
                            batch.near_triangle_counts.push(triangles.len() as u32);
                            batch.near_triangles.extend_from_slice(triangles);
                            batch.ring_cells += usize::from(scratch.rebuilt());
                            batch.warm_cells += usize::from(warm);
                        }
                    }
                    batch.shrink();
                    batch
                },
            )
            .collect()
    }
}

/// The batches, or the error of the first offending site in index order among them.
pub(super) fn without_errors<const D: usize, C>(
    mut batches: Vec<Batch<D, C>>,
) -> Result<Vec<Batch<D, C>>, CoreError> {
    let first_error = batches
        .iter()
        .filter_map(|b| b.error.as_ref().map(|(i, _)| *i))
        .min();
    if let Some(first) = first_error {
        let batch = batches
            .iter_mut()
            .find(|b| b.error.as_ref().is_some_and(|(i, _)| *i == first))
            .expect("the batch of the first error");
        return Err(batch.error.take().expect("its error").1);
    }
    Ok(batches)
}
