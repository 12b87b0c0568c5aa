//! The drivers: the whole diagram ([`clipped_diagram`]; [`trial_diagram`], stopped below a
//! mass floor) and a part's cells ([`clipped_cells`]): validation, the sites' Morton order
//! and index, batches of cells ([`super::visit`]), assembly in index order.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::density::Density;
use crate::error::CoreError;
use crate::geometry::{scale, Euclid, Space};

use super::convex_cell::ConvexCell;
use super::domain_kind::DomainKind;
use super::knn::{DeferredIndex, IndexRef, SiteIndex};
use super::order::morton_order;
use super::output::{assemble, Clipped, Diagram, PartCells};
use super::periodic_box;
use super::power::{Margins, Power, PowerWhole, SiteBlocks};
use super::request::{checked_part, checked_weights, checked_windings, Options, Request};
use super::visit::{without_errors, MassFloor, Visit};
use super::warm::WarmStart;
use super::weighted;
use super::weighted_sums::WeightedSums;

/// The clipped Voronoi diagram of `sites` in `domain`, with what `request` asks for.
///
/// Errors name the first offending site in index order: non-finite coordinates, a site
/// outside the domain (unless allowed), two coinciding sites; with a density also a point
/// where it is not finite and positive: a site or a boundary vertex (a polynomial; also a
/// cell whose mean density is not positive), or a node (a field).
pub fn clipped_diagram<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    request: &Request<'_, D>,
) -> Result<Clipped<D, C>, CoreError>
where
    Euclid: Space<D>,
{
    clipped_diagram_kept::<D, C, K>(domain, sites, request, None)
}

/// [`clipped_diagram`], reading (or, the first time, keeping) what it computes of the sites
/// alone in `setup` ([`SiteSetup`]).
pub(crate) fn clipped_diagram_kept<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    request: &Request<'_, D>,
    setup: Option<&mut SiteSetup<D>>,
) -> Result<Clipped<D, C>, CoreError>
where
    Euclid: Space<D>,
{
    clipped_diagram_above::<D, C, K>(domain, sites, request, None, None, &mut None, setup)?
        .ok_or_else(|| CoreError::InvalidSettings {
            reason: "a diagram without a mass floor stopped below one".into(),
        })
}

/// What a diagram computes of its sites alone, whatever their weights: their Morton order,
/// winding numbers (checked) and index, and the power diagrams' block grid. The diagrams
/// of one optimal transport (up to a dozen, of the same sites) keep them from the first
/// (and the grid from the first power diagram): computing them again for each of the 8
/// diagrams of a transport at 10,000 sites was 7.3% of its instructions
/// (`docs/results/transport.txt` §15). Empty until a diagram fills it; read only by
/// diagrams of as many sites with the same options (its holder's to give the same sites).
#[derive(Default)]
pub(crate) struct SiteSetup<const D: usize> {
    kept: Option<KeptSites<D>>,
}

struct KeptSites<const D: usize> {
    options: Options,
    order: Vec<u32>,
    windings: Vec<Option<i32>>,
    index: SiteIndex<D>,
    /// The power diagrams' grid, kept by the first.
    blocks: Option<SiteBlocks<D>>,
}

/// [`clipped_diagram`] of a trial of optimal transport's damped Newton step (DESIGN §14),
/// or `None` as soon as a cell's mass (its volume: without a density) is found below
/// `floor`, the step's guard, when the caller would reject the trial whatever the other
/// cells: their cells are not computed. Why: the rejected trials traced (uniform sites,
/// equal masses, 10,000 and 100,000) failed the guard, each a whole power diagram. With a
/// density the floor is not applied (the cells' masses are weighed after the clip). The
/// answer does not depend on the thread count: `None` exactly when some cell of the
/// whole diagram is below the floor.
///
/// With `margins` (power cells started from [`Request::power_start`]): cells certified
/// by stored margins instead of their scan, and the margins this diagram's scans took
/// (`Power::hinted_cell`, the same cells bit for bit), returned with it.
pub(crate) fn trial_diagram<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    request: &Request<'_, D>,
    floor: f64,
    margins: Option<&MarginRequest<'_, D>>,
    setup: &mut SiteSetup<D>,
) -> Result<Option<Trial<D, C>>, CoreError>
where
    Euclid: Space<D>,
{
    let floor = MassFloor {
        mass: floor,
        below: AtomicBool::new(false),
    };
    let floor = request.density.is_none().then_some(&floor);
    let mut taken = None;
    let out = clipped_diagram_above::<D, C, K>(
        domain,
        sites,
        request,
        floor,
        margins,
        &mut taken,
        Some(setup),
    )?;
    Ok(out.map(|clipped| (clipped, taken)))
}

/// A trial diagram and the margins it took ([`trial_diagram`]).
pub(crate) type Trial<const D: usize, C> = (Clipped<D, C>, Option<Margins<D>>);

/// The stored margins a trial diagram reads and takes ([`trial_diagram`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct MarginRequest<'a, const D: usize> {
    /// Margins taken by earlier diagrams of the same sites.
    pub stored: Option<&'a Margins<D>>,
    /// Per iterate `k` of `stored`, `max_j (w_j − w_k,j)` of this diagram's weights `w`.
    pub dmax: &'a [f64],
    /// Take the margins of the cells certified by their scan, numbered this iterate.
    pub record: Option<u32>,
}

/// [`clipped_diagram`], or `None` when a cell is below `floor` ([`trial_diagram`]); the
/// margins `margins` asks to take in `taken`; the sites' order, windings, index and power
/// grid from `setup` when it holds them (kept there otherwise).
fn clipped_diagram_above<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    request: &Request<'_, D>,
    floor: Option<&MassFloor>,
    margins: Option<&MarginRequest<'_, D>>,
    taken: &mut Option<Margins<D>>,
    setup: Option<&mut SiteSetup<D>>,
) -> Result<Option<Clipped<D, C>>, CoreError>
where
    Euclid: Space<D>,
{
    let weights = checked_weights(domain, sites.len(), request)?;
    if let Some(Density::PerVertex(values)) = request.density {
        weighted::check_per_vertex(values, domain)?;
    }
    if let Some(torus) = domain.periodic() {
        return periodic_box::clipped_diagram::<D, C>(torus, sites, weights, request).map(Some);
    }
    let density = request.density;
    if let Some(Density::Polynomial(q)) = density {
        weighted::check_polynomial(q, domain, sites)?;
        if q.is_constant() {
            // ρ = c weighs every moment by c: exact, and for ρ = 1 the uniform diagram
            // bit for bit, at the uniform cost.
            let uniform = Request {
                density: None,
                ..*request
            };
            let mut out = clipped_diagram::<D, C, K>(domain, sites, &uniform)?;
            let sums = &mut out.face_integrals;
            for m in sums.cells.iter_mut().chain(sums.faces.iter_mut()) {
                *m = m.map(|row| scale(row, q.constant));
            }
            out.diagram.weighted = weighted::scaled(&out.diagram.moments, q.constant);
            return Ok(Some(out));
        }
    }
    let weighted_sums = WeightedSums::new(density)?;
    // Visit the sites along a Morton curve: neighbouring cells then share index buckets
    // and boundary elements in cache. Results go back to index order afterwards.
    // A warm diagram visits the sites in the previous one's order (the cells do not
    // depend on it); a sampled density is asked for its nodes batch by batch, as cold.
    let sampled = matches!(density, Some(Density::Sampled { .. }));
    let moved = request.warm.and_then(|w| w.moved(sites, !sampled));
    let kept = (setup.as_deref())
        .and_then(|s| s.kept.as_ref())
        .filter(|k| k.options == request.options && k.windings.len() == sites.len());
    let (order, morton) = match (moved.as_ref(), request.warm) {
        (Some(_), Some(warm)) if !sampled => (warm.order().to_vec(), false),
        _ => (
            kept.map_or_else(|| morton_order(sites), |k| k.order.clone()),
            true,
        ),
    };
    let integrand = request.integrand;
    // The winding numbers and the index are dropped before the batches are assembled,
    // when every batch and the whole diagram are alive at once (issue 32: memory), unless
    // `setup` keeps them.
    let power_start = request
        .power_start
        .filter(|d| weights.is_some() && d.len() == sites.len());
    // A power start replaces the warm lists (its cells stream no sites).
    let warm = (request.warm.zip(moved.as_ref())).filter(|_| power_start.is_none());
    let batches = {
        let mut computed = None;
        let (windings, index): (_, IndexRef<'_, D>) = match kept {
            Some(k) => (&k.windings, (&k.index).into()),
            None => {
                let windings = checked_windings(domain, sites, request.options)?;
                // A cold diagram reads the index from its first cell on.
                let index = match warm {
                    Some(_) => DeferredIndex::new(sites)?,
                    None => DeferredIndex::built(sites)?,
                };
                let c = computed.insert((windings, index));
                (&c.0, (&c.1).into())
            }
        };
        let visit = Visit {
            sites,
            index,
            windings,
            power: weights.map(|w| {
                let power = match kept.and_then(|k| k.blocks.as_ref()) {
                    Some(blocks) => Power::on_blocks(w, blocks),
                    None => Power::new(w, sites),
                };
                match (margins, power_start) {
                    (Some(m), Some(_)) => power.with_margins(m.stored, m.dmax, m.record),
                    _ => power,
                }
            }),
            power_start,
            total_sites: sites.len(),
            warm,
            // Sites moved too far are not recorded: the next diagram starts from an empty
            // state and records the lists afresh (cold).
            record: power_start.is_none()
                && request
                    .warm
                    .is_some_and(|w| w.len() != sites.len() || moved.is_some()),
            reach: false,
            floor,
        };
        let batches = visit.batches::<C, K>(
            domain,
            &order,
            integrand,
            request.keep_cells,
            &weighted_sums,
        );
        let blocks = (visit.power.as_ref())
            .filter(|_| kept.is_some_and(|k| k.blocks.is_none()))
            .map(Power::blocks);
        if let Some(setup) = setup {
            match (&mut setup.kept, computed) {
                (None, Some((windings, index))) if morton => {
                    setup.kept = Some(KeptSites {
                        options: request.options,
                        order: order.clone(),
                        windings,
                        index: index.into_built(),
                        blocks: None,
                    });
                }
                (Some(k), _) if blocks.is_some() => k.blocks = blocks,
                _ => {}
            }
        }
        batches
    };
    let mut batches = without_errors(batches)?;
    if floor.is_some_and(|f| f.below.load(Ordering::Relaxed)) {
        return Ok(None);
    }
    if let Some(m) = margins.filter(|_| power_start.is_some()) {
        *taken = Some(Margins::gather(
            sites.len(),
            m.record.unwrap_or(u32::MAX),
            batches.iter().map(|b| &b.margins),
        ));
    }
    if let Some(d @ Density::Sampled { field, .. }) = density {
        let rule = d.rule_in(domain.cell_dim())?;
        weighted::sample(domain, *field, &rule, sites, &mut batches, integrand)?;
    }
    let out = assemble(
        sites,
        order,
        batches,
        integrand.is_some(),
        request.keep_cells,
    );
    if density.is_some() {
        weighted::check_masses(&out.diagram, sites)?;
    }
    let mut out = out;
    if request.warm.is_some() && out.warm.is_none() {
        out.warm = Some(WarmStart::new());
    }
    Ok(Some(out))
}

/// The cells of the sites `own` (indices into `sites`), as [`clipped_diagram`] computes
/// them for a problem of `total_sites` sites of which `sites` is a part, with each cell's
/// reach ([`PartCells::reach2`]), under `request`'s options and density (its
/// `keep_cells` and `integrand` are for whole diagrams: asking for them here is an error).
///
/// A cell is the domain's box clipped by the bisectors of the sites streamed in increasing
/// distance (ties by index) until the next is beyond twice the cell's radius, or, once
/// localised, by the nearest sites of its vertices. It only reads the sites within its
/// reach, so it is bitwise the cell of the whole problem when `sites` holds every site of
/// the problem within that distance **and** lists them in the same relative order as the
/// problem (so that ties in distance, and the sorted neighbour lists, agree). The caller
/// grows the halo of the cells whose reach its halo does not cover and computes them again.
/// (On clustered sites the index falls back to a kd-tree, whose order among sites at
/// exactly equal distance is its own: bitwise equality then needs no such ties.)
///
/// With a density, each row's ρ-weighted moments are in [`Diagram::weighted`], integrated
/// over the same signed pieces as [`clipped_diagram`] does, so a certified cell's weighted
/// moments are the whole problem's bit for bit (a sampled density is asked once for the
/// nodes of the own cells; each node's value must depend on the node alone). The reach
/// does not depend on ρ: it is where the cell's *geometry* read sites.
///
/// Errors are [`clipped_diagram`]'s, for the own sites (all sites are checked finite),
/// naming indices into `sites`.
pub fn clipped_cells<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    own: &[u32],
    total_sites: usize,
    request: &Request<'_, D>,
    power_whole: Option<&PowerWhole<D>>,
) -> Result<PartCells<D>, CoreError>
where
    Euclid: Space<D>,
{
    if request.keep_cells || request.integrand.is_some() {
        return Err(CoreError::InvalidSettings {
            reason: "the cells of a part keep no convex cells and sum no face integrand"
                .to_string(),
        });
    }
    if let Some(torus) = domain.periodic() {
        if sites.is_empty() || own.is_empty() {
            return Ok(PartCells::default());
        }
        return periodic_box::clipped_cells::<D, C>(torus, sites, own, total_sites, request);
    }
    let power = part_power(domain, sites, request, power_whole)?;
    let (options, density) = (request.options, request.density);
    if sites.is_empty() || own.is_empty() {
        return Ok(PartCells::default());
    }
    let (windings, _) = checked_part(domain, sites, own, options)?;
    let own_sites: Vec<[f64; D]> = own.iter().map(|&i| sites[i as usize]).collect();
    if let Some(Density::PerVertex(values)) = density {
        weighted::check_per_vertex(values, domain)?;
    }
    if let Some(Density::Polynomial(q)) = density {
        weighted::check_polynomial(q, domain, &own_sites)?;
        if q.is_constant() {
            // As the whole diagram does: the uniform cells, every moment times c.
            let uniform = Request {
                density: None,
                ..*request
            };
            let mut part =
                clipped_cells::<D, C, K>(domain, sites, own, total_sites, &uniform, power_whole)?;
            part.diagram.weighted = weighted::scaled(&part.diagram.moments, q.constant);
            return Ok(part);
        }
    }
    let weighted_sums = WeightedSums::new(density)?;
    let index = SiteIndex::new(sites)?;
    let visit = Visit {
        sites,
        index: (&index).into(),
        windings: &windings,
        power,
        power_start: None,
        total_sites: total_sites.max(sites.len()),
        warm: None,
        record: false,
        reach: true,
        floor: None,
    };
    let mut batches =
        without_errors(visit.batches::<C, K>(domain, own, None, false, &weighted_sums))?;
    if let Some(d @ Density::Sampled { field, .. }) = density {
        let rule = d.rule_in(domain.cell_dim())?;
        weighted::sample(domain, *field, &rule, sites, &mut batches, None)?;
    }
    let rows = own.len();
    let mut reach2 = Vec::with_capacity(rows);
    let mut diagram = Diagram {
        neighbor_offsets: vec![0],
        ..Diagram::default()
    };
    for b in batches {
        let mut at = 0;
        for (k, &count) in b.face_counts.iter().enumerate() {
            let count = count as usize;
            diagram.moments.push(b.moments[k]);
            if density.is_some() {
                diagram.weighted.push(b.weighted[k]);
            }
            diagram.boundary_measure.push(b.boundary_measure[k]);
            (diagram.neighbor_sites).extend_from_slice(&b.neighbor_sites[at..at + count]);
            (diagram.neighbor_measures).extend_from_slice(&b.neighbor_measures[at..at + count]);
            at += count;
            diagram.neighbor_offsets.push(diagram.neighbor_sites.len());
        }
        reach2.extend_from_slice(&b.reach2);
    }
    if density.is_some() {
        weighted::check_masses(&diagram, &own_sites)?;
    }
    Ok(PartCells { diagram, reach2 })
}

/// The weights of a part of a power diagram (`request.weights`, indexed like `sites`) with
/// the whole problem's box and largest weight: both or neither. Weights all zero in the
/// part are still a power diagram's when the whole problem's are not (a far heavier site
/// may reach its cells), so the driver passes `whole` only for a power diagram.
fn part_power<'a, const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    request: &Request<'a, D>,
    whole: Option<&PowerWhole<D>>,
) -> Result<Option<Power<'a, D>>, CoreError> {
    let (weights, whole) = match (request.weights, whole) {
        (None, None) => return Ok(None),
        (Some(weights), Some(whole)) => (weights, whole),
        _ => {
            return Err(CoreError::InvalidWeights {
                reason: "the cells of a part of a power diagram take its weights and the whole \
                         problem's box and largest weight, both or neither"
                    .to_string(),
            })
        }
    };
    checked_weights(domain, sites.len(), request)?;
    if domain.cell_dim() != D {
        return Err(CoreError::InvalidWeights {
            reason: "power diagrams (weights) are not supported on the sphere or a triangle \
                     surface yet"
                .to_string(),
        });
    }
    Ok(Some(Power::in_part(weights, sites, whole)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::density::{Field, Quadratic};
    use crate::diagram::output::BATCH;
    use crate::diagram::PolygonCell;
    use crate::domain::Polygon;
    use crate::sample::interior_sites;

    /// Over several batches, the error names the first offending site in index order,
    /// whichever batch met it first.
    #[test]
    fn the_first_duplicate_in_index_order_is_reported() {
        let square = Polygon::new(
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        )
        .unwrap();
        let mut sites = interior_sites(&square, 3 * BATCH, 5);
        sites[2 * BATCH + 1] = sites[2 * BATCH];
        sites[BATCH + 7] = sites[10];
        let error =
            clipped_diagram::<2, PolygonCell, _>(&square, &sites, &Request::default()).unwrap_err();
        match error {
            CoreError::DuplicateSites { first, second, .. } => {
                assert_eq!((first, second), (10, BATCH + 7))
            }
            other => panic!("{other:?}"),
        }
    }

    /// A square with a square hole, split at x = 0.5 into two parts, each computed among
    /// its own sites and a halo within `rho` of its box: every cell whose reach the halo
    /// covers is bitwise the whole diagram's (moments, boundary share, neighbours in the
    /// whole numbering), and with all sites as halo every cell is certified.
    #[test]
    fn a_part_with_a_covering_halo_gives_the_whole_diagrams_cells_bit_for_bit() {
        let holed = Polygon::from_rings(&[
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            &[[0.3, 0.3], [0.3, 0.6], [0.6, 0.6], [0.6, 0.3]],
        ])
        .unwrap();
        let sites = interior_sites(&holed, 2000, 11);
        let whole = clipped_diagram::<2, PolygonCell, _>(&holed, &sites, &Request::default())
            .unwrap()
            .diagram;
        let mut certified = 0;
        for (left, rho) in [(true, 0.05), (false, 0.05), (true, 2.0)] {
            let own_rows: Vec<usize> = (0..sites.len())
                .filter(|&i| (sites[i][0] < 0.5) == left)
                .collect();
            let lo = own_rows.iter().fold([f64::INFINITY; 2], |m, &i| {
                [m[0].min(sites[i][0]), m[1].min(sites[i][1])]
            });
            let hi = own_rows.iter().fold([f64::NEG_INFINITY; 2], |m, &i| {
                [m[0].max(sites[i][0]), m[1].max(sites[i][1])]
            });
            // The part's sites in the whole numbering's order: own and halo together.
            let rows: Vec<usize> = (0..sites.len())
                .filter(|&i| {
                    (0..2).all(|k| sites[i][k] >= lo[k] - rho && sites[i][k] <= hi[k] + rho)
                })
                .collect();
            let local: Vec<[f64; 2]> = rows.iter().map(|&i| sites[i]).collect();
            let own: Vec<u32> = own_rows
                .iter()
                .map(|i| rows.binary_search(i).unwrap() as u32)
                .collect();
            let part = clipped_cells::<2, PolygonCell, _>(
                &holed,
                &local,
                &own,
                sites.len(),
                &Request::default(),
                None,
            )
            .unwrap();
            let mut here = 0;
            for (k, &i) in own_rows.iter().enumerate() {
                if part.reach2[k] >= rho * rho {
                    continue;
                }
                here += 1;
                assert_eq!(part.diagram.moments[k], whole.moments[i], "cell {i}");
                assert_eq!(
                    part.diagram.boundary_measure[k].to_bits(),
                    whole.boundary_measure[i].to_bits()
                );
                let (a, b) = (
                    part.diagram.neighbor_offsets[k],
                    part.diagram.neighbor_offsets[k + 1],
                );
                let (c, d) = (whole.neighbor_offsets[i], whole.neighbor_offsets[i + 1]);
                let mapped: Vec<u32> = part.diagram.neighbor_sites[a..b]
                    .iter()
                    .map(|&j| rows[j as usize] as u32)
                    .collect();
                assert_eq!(mapped, whole.neighbor_sites[c..d], "cell {i}");
                assert_eq!(
                    part.diagram.neighbor_measures[a..b],
                    whole.neighbor_measures[c..d]
                );
            }
            // A halo of a few spacings certifies most cells; the whole set certifies all.
            assert!(
                here > own_rows.len() * 3 / 4,
                "{here} of {}",
                own_rows.len()
            );
            if rho > 1.0 {
                assert_eq!(here, own_rows.len());
            }
            certified += here;
        }
        assert!(certified > sites.len());
    }

    /// A field for the tests: `1 + exp(x) + y²`, one value per node.
    struct ExpField;

    impl Field<2> for ExpField {
        fn values(&self, points: Vec<[f64; 2]>) -> Result<Vec<f64>, CoreError> {
            Ok(points
                .iter()
                .map(|p| 1.0 + p[0].exp() + p[1] * p[1])
                .collect())
        }
    }

    /// With a density, a part's cells among a halo carry the whole diagram's weighted
    /// moments bit for bit wherever the halo covers their reach: a polynomial, a constant
    /// (the uniform cells scaled) and a sampled field.
    #[test]
    fn a_parts_weighted_cells_are_the_whole_diagrams() {
        let square = Polygon::new(
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        )
        .unwrap();
        let sites = interior_sites(&square, 1500, 4);
        let field = ExpField;
        let densities = [
            Density::Polynomial(
                Quadratic::new(1.0, [2.0, -0.5], [[3.0, 0.5], [0.5, 1.0]]).unwrap(),
            ),
            Density::Polynomial(Quadratic::constant(2.5)),
            Density::Sampled {
                field: &field,
                degree: 3,
            },
        ];
        for density in &densities {
            let request = Request {
                density: Some(density),
                ..Request::default()
            };
            let whole = clipped_diagram::<2, PolygonCell, _>(&square, &sites, &request)
                .unwrap()
                .diagram;
            // Part: the sites left of x = 0.4; halo: everything within 0.1 of x = 0.4.
            let rows: Vec<usize> = (0..sites.len()).filter(|&i| sites[i][0] < 0.5).collect();
            let local: Vec<[f64; 2]> = rows.iter().map(|&i| sites[i]).collect();
            let own: Vec<u32> = (0..rows.len() as u32)
                .filter(|&k| local[k as usize][0] < 0.4)
                .collect();
            let part = clipped_cells::<2, PolygonCell, _>(
                &square,
                &local,
                &own,
                sites.len(),
                &request,
                None,
            )
            .unwrap();
            assert_eq!(part.diagram.weighted.len(), own.len());
            let mut exact = 0;
            for (k, &o) in own.iter().enumerate() {
                let x = local[o as usize][0];
                if part.reach2[k].sqrt() >= 0.5 - x {
                    continue;
                }
                let i = rows[o as usize];
                assert_eq!(part.diagram.moments[k], whole.moments[i], "cell {i}");
                assert_eq!(part.diagram.weighted[k], whole.weighted[i], "cell {i}");
                exact += 1;
            }
            assert!(exact > own.len() * 9 / 10, "{exact} of {}", own.len());
        }
    }
}
