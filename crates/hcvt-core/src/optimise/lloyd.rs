//! Lloyd steps held inside the domain, and reseeding of empty cells.

use rayon::prelude::*;

use crate::domain::{Boundary, WindingNumber};
use crate::geometry::{add, scale, Euclid, Space};

use super::Point;

/// Halvings of a Lloyd move before a site whose centroid lies outside stays where it is.
const MAX_HALVINGS: usize = 30;

/// Lloyd's update `x_i ← c_i`, except that a site whose centroid lies outside a non-convex
/// domain moves by the largest of `1, 1/2, 1/4, …` of the way that ends inside (or not at
/// all). Any move towards `c_i` lowers `∫_{Ω_i} |x − x_i|²` for the old cells, and the new
/// cells lower it again, so the energy never increases. Empty cells keep their site.
pub fn lloyd_sites<const D: usize>(boundary: &Boundary<D>, point: &Point<D>) -> Vec<[f64; D]>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    point
        .sites
        .par_iter()
        .zip(&point.diagram.moments)
        .map(|(&site, m)| {
            let Some(shift) = m.centroid() else {
                return site;
            };
            let mut t = 1.0;
            for _ in 0..MAX_HALVINGS {
                let candidate = add(site, scale(shift, t));
                if inside_or_on(boundary, &candidate) {
                    return candidate;
                }
                t *= 0.5;
            }
            site
        })
        .collect()
}

/// Not strictly outside: winding number non-zero, or on the boundary (`None`), where the
/// diagram accepts a site.
fn inside_or_on<const D: usize>(boundary: &Boundary<D>, p: &[f64; D]) -> bool
where
    Euclid: WindingNumber<D>,
{
    Euclid::winding_number(boundary, p) != Some(0)
}

/// New sites when some cells are empty, `None` when none is.
///
/// A site strictly inside the domain always has a cell of positive measure, and the
/// iterations keep sites inside, so this is a safety net: a site on the boundary, or a
/// mass that underflowed. An empty cell has `m_i = 0` and `g_i = 0` and would never move
/// again (ALGORITHMS §3). Deterministic rule: the `k`-th empty site in index order goes to
/// the `k`-th largest cell (ties by index), a quarter spacing `h` from that cell's site
/// along the first of `+e_1, −e_1, +e_2, …` that ends strictly inside the domain.
pub fn reseed_empty<const D: usize>(
    boundary: &Boundary<D>,
    point: &Point<D>,
    h: f64,
) -> Option<Vec<[f64; D]>>
where
    Euclid: Space<D> + WindingNumber<D>,
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
            (Euclid::winding_number(boundary, &candidate).is_some_and(|w| w != 0))
                .then_some(candidate)
        });
        if let Some(p) = placed {
            sites[i] = p;
        }
    }
    Some(sites)
}
