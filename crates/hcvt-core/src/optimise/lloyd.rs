//! Lloyd steps held inside the domain, and reseeding of empty cells.

use rayon::prelude::*;

use crate::diagram::DomainKind;
use crate::geometry::{add, scale, Euclid, Space};

use crate::moments::Moments;

use super::point::Point;

/// Halvings of a move that leaves the domain before the site stays where it is.
const MAX_HALVINGS: usize = 30;

/// Lloyd's update `x_i ← c_i`, held inside the domain by [`hold_inside`]. Any move towards
/// `c_i` lowers `∫_{Ω_i} |x − x_i|²` for the old cells, and the new cells lower it again, so
/// the energy never increases. Empty cells keep their site.
pub fn lloyd_sites<const D: usize, K: DomainKind<D>>(domain: &K, point: &Point<D>) -> Vec<[f64; D]>
where
    Euclid: Space<D>,
{
    let shifts: Vec<[f64; D]> = centroid_shifts(point.diagram.mass_moments())
        .into_iter()
        .map(|s| s.unwrap_or([0.0; D]))
        .collect();
    lloyd_step(domain, &point.sites, &shifts)
}

/// The Lloyd step over plain per-site arrays: each site moved by its `shifts[i] = c_i − x_i`
/// as far as [`hold_inside`] lets it. [`lloyd_sites`] in one process, and each part of a
/// partitioned run (`hcvt.partition`), call this, so both move every site alike, bit for bit.
pub fn lloyd_step<const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    shifts: &[[f64; D]],
) -> Vec<[f64; D]>
where
    Euclid: Space<D>,
{
    let mut moves = shifts.to_vec();
    hold_inside(domain, sites, &mut moves);
    // On the sphere `retract(x + (M/A − x)) = M/|M|`, the constrained centroid.
    sites
        .iter()
        .zip(&moves)
        .map(|(&x, &m)| domain.retract(add(x, m)))
        .collect()
}

/// `c_i − x_i = m1_i / m_i` of each cell from its moments about its site (ρ-weighted with a
/// density), `None` for an empty cell ([`Moments::centroid`]).
pub fn centroid_shifts<const D: usize>(moments: &[Moments<D>]) -> Vec<Option<[f64; D]>> {
    moments.iter().map(Moments::centroid).collect()
}

/// Shorten each site's move `x_i → x_i + d_i` to the largest of `d_i, d_i/2, d_i/4, …`
/// that ends inside the domain (or on its boundary), or to nothing.
///
/// In a non-convex domain a centroid, or an L-BFGS step, can lie across a notch or a thin
/// wall. Shortening only the moves that leave keeps one site from throttling the step of
/// all the others (a line search would shorten them all alike).
pub fn hold_inside<const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    moves: &mut [[f64; D]],
) where
    Euclid: Space<D>,
{
    moves.par_iter_mut().zip(sites).for_each(|(m, &site)| {
        let mut t = 1.0;
        for _ in 0..MAX_HALVINGS {
            if inside_or_on(domain, &domain.retract(add(site, scale(*m, t)))) {
                *m = scale(*m, t);
                return;
            }
            t *= 0.5;
        }
        *m = [0.0; D];
    });
}

/// Fraction of the way towards its centroid that a pinned site cannot move (2^-20).
const PIN_FRACTION: f64 = 1.0 / 1_048_576.0;

/// Sites pinned against the boundary: the centroid of the cell lies outside the domain and
/// even `2^-20` of the way towards it leaves the domain.
///
/// Sites are kept inside, so at a CVT of a non-convex domain whose cell's centroid lies
/// across a notch, a site sits on the boundary with a gradient that never vanishes; the
/// stopping rule leaves such sites out. Only cells that touch the boundary can have their
/// centroid outside (the others are convex and inside), so only they are tested.
pub fn pinned_sites<const D: usize, K: DomainKind<D>>(domain: &K, point: &Point<D>) -> Vec<bool>
where
    Euclid: Space<D>,
{
    let shifts = centroid_shifts(point.diagram.mass_moments());
    pinned(
        domain,
        &point.sites,
        &shifts,
        &point.diagram.boundary_measure,
    )
}

/// [`pinned_sites`] over plain per-site arrays: `shifts` from [`centroid_shifts`], and the
/// measure of each cell's boundary on the domain's boundary. A partitioned run calls this
/// per part (`hcvt.partition`).
pub fn pinned<const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    shifts: &[Option<[f64; D]>],
    boundary_measure: &[f64],
) -> Vec<bool>
where
    Euclid: Space<D>,
{
    (sites, shifts, boundary_measure)
        .into_par_iter()
        .map(|(&site, &shift, &measure)| {
            let Some(shift) = shift else {
                return false;
            };
            // Retracted: on the sphere a region's centroid is `M/|M|` (the identity
            // elsewhere, no arithmetic).
            measure > 0.0
                && domain.locate(&domain.retract(add(site, shift))) == Some(0)
                && !inside_or_on(
                    domain,
                    &domain.retract(add(site, scale(shift, PIN_FRACTION))),
                )
        })
        .collect()
}

/// Not strictly outside: winding number non-zero, or on the boundary (`None`), where the
/// diagram accepts a site.
fn inside_or_on<const D: usize, K: DomainKind<D>>(domain: &K, p: &[f64; D]) -> bool {
    domain.locate(p) != Some(0)
}

/// New sites when some cells are empty, `None` when none is.
///
/// A site strictly inside the domain always has a cell of positive measure, and the
/// iterations keep sites inside, so this is a safety net: a site on the boundary, or a
/// mass that underflowed. An empty cell has `m_i = 0` and `g_i = 0` and would never move
/// again (ALGORITHMS §3). Deterministic rule: the `k`-th empty site in index order goes to
/// the `k`-th largest cell (ties by index), a quarter spacing `h` from that cell's site
/// along the first of `+e_1, −e_1, +e_2, …` that ends strictly inside the domain.
pub fn reseed_empty<const D: usize, K: DomainKind<D>>(
    domain: &K,
    point: &Point<D>,
    h: f64,
) -> Option<Vec<[f64; D]>>
where
    Euclid: Space<D>,
{
    let moments = &point.diagram.moments;
    let empty: Vec<usize> = (0..moments.len())
        .filter(|&i| moments[i].mass.is_nan() || moments[i].mass <= 0.0)
        .collect();
    if empty.is_empty() {
        return None;
    }
    let mut donors: Vec<usize> = (0..moments.len())
        .filter(|&i| moments[i].mass > 0.0)
        .collect();
    if donors.is_empty() {
        return None;
    }
    donors.sort_by(|&a, &b| moments[b].mass.total_cmp(&moments[a].mass).then(a.cmp(&b)));
    let mut sites = point.sites.clone();
    for (k, &i) in empty.iter().enumerate() {
        let donor = point.sites[donors[k % donors.len()]];
        // Several rounds over the donors use different directions, so no two reseeded sites
        // coincide.
        let first = k / donors.len();
        let placed = (0..2 * D).map(|r| (first + r) % (2 * D)).find_map(|r| {
            let sign = if r % 2 == 0 { 1.0 } else { -1.0 };
            let mut candidate = donor;
            candidate[r / 2] += sign * 0.25 * h;
            let candidate = domain.retract(candidate);
            (domain.locate(&candidate).is_some_and(|w| w != 0)).then_some(candidate)
        });
        if let Some(p) = placed {
            sites[i] = p;
        }
    }
    Some(sites)
}
