//! What a caller asks of a diagram ([`Request`], [`Options`]) and the checks of what it
//! gives: the sites against the domain ([`checked_windings`], a part's [`checked_part`])
//! and a power diagram's weights ([`checked_weights`]).

use rayon::prelude::*;

use crate::density::Density;
use crate::error::CoreError;
use crate::geometry::norm2;

use super::domain_kind::DomainKind;
use super::faces::FaceIntegrand;
use super::output::Diagram;
use super::warm::WarmStart;

/// How to treat unusual input.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Options {
    /// Accept sites outside the domain. The cell of such a site is the part of its Voronoi
    /// cell that lies inside the domain: possibly empty, and not containing its site.
    pub allow_outside: bool,
}

/// What [`super::clipped_diagram`] computes besides the diagram, and how it treats unusual input.
#[derive(Clone, Copy, Default)]
pub struct Request<'a, const D: usize> {
    /// How to treat unusual input.
    pub options: Options,
    /// Keep each site's convex cell ([`super::Clipped::cells`]), for pictures and export.
    pub keep_cells: bool,
    /// Sum this integrand over the faces between cells, in the pass that measures them
    /// ([`super::Clipped::face_integrals`]).
    pub integrand: Option<&'a dyn FaceIntegrand<D>>,
    /// With a density ρ (DESIGN §8): each cell's ρ-weighted moments in
    /// [`Diagram::weighted`], integrated over the same signed pieces. A sampled density is
    /// asked for its values once, at every node of the diagram.
    pub density: Option<&'a Density<'a, D>>,
    /// The power (Laguerre) diagram of these weights, one per site, `L²` (DESIGN §14):
    /// cell `i` is `{x : |x − z_i|² − w_i ≤ |x − z_j|² − w_j}`, possibly empty (mass 0, no
    /// faces) and possibly not holding its site. `None`, or all zero, is the Voronoi
    /// diagram bit for bit. Not on the sphere, nor for a part ([`super::clipped_cells`]).
    pub weights: Option<&'a [f64]>,
    /// Start from a previous diagram's near-site lists (an empty [`WarmStart`] starts
    /// cold) and return this diagram's in [`super::Clipped::warm`]: the cells are the cold ones
    /// bit for bit, faster when the sites moved little. Ignored in a periodic box.
    pub warm: Option<&'a WarmStart<D>>,
    /// With [`Request::weights`]: a power diagram of the same sites (other weights, e.g.
    /// the previous Newton step's) whose neighbours each cell is clipped by first, then
    /// certified by the blocks of sites near it (`Power::hinted_cell`): the same cells to
    /// round-off (not bit for bit: the planes come in another order), each cell's
    /// nearest-site stream saved. Ignored without weights, for a part, in a periodic box,
    /// and when its number of cells differs.
    pub power_start: Option<&'a Diagram<D>>,
}

/// The weights of `request` checked against `n` sites in `domain`: `None` when absent or
/// all zero (the Voronoi diagram, on its own code path).
pub(super) fn checked_weights<'a, const D: usize, K: DomainKind<D>>(
    domain: &K,
    n: usize,
    request: &Request<'a, D>,
) -> Result<Option<&'a [f64]>, CoreError> {
    let Some(weights) = request.weights else {
        return Ok(None);
    };
    if weights.len() != n {
        return Err(CoreError::InvalidWeights {
            reason: format!(
                "weights: expected one per site ({n}), got {}",
                weights.len()
            ),
        });
    }
    if let Some(index) = weights.iter().position(|w| !w.is_finite()) {
        return Err(CoreError::InvalidWeights {
            reason: format!("weight {index} is not finite ({})", weights[index]),
        });
    }
    if weights.iter().all(|&w| w == 0.0) {
        return Ok(None);
    }
    if domain.cell_dim() != D {
        return Err(CoreError::InvalidWeights {
            reason: "power diagrams (weights) are not supported on the sphere or a triangle \
                     surface yet"
                .to_string(),
        });
    }
    Ok(Some(weights))
}

/// Check `sites` against `domain` (finite, inside unless allowed, not too far outside)
/// and return the winding number of each (`None` on the boundary). Errors name the first
/// offending site in index order.
pub(crate) fn checked_windings<const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    options: Options,
) -> Result<Vec<Option<i32>>, CoreError> {
    if sites.is_empty() {
        return Err(CoreError::NoSites);
    }
    for (index, s) in sites.iter().enumerate() {
        if let Some(&value) = s.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::NonFiniteSite { index, value });
        }
    }
    if options.allow_outside {
        let b = domain.bounds();
        let size = (0..D).fold(f64::INFINITY, |m, k| m.min(b.hi[k] - b.lo[k]));
        for (index, s) in sites.iter().enumerate() {
            let distance = norm2::<D>(std::array::from_fn(|k| {
                (b.lo[k] - s[k]).max(s[k] - b.hi[k]).max(0.0)
            }))
            .sqrt();
            if distance > FAR_OUTSIDE * size {
                return Err(CoreError::SiteFarOutside {
                    index,
                    point: s.to_vec(),
                    distance,
                    limit: FAR_OUTSIDE,
                });
            }
        }
    }
    let windings: Vec<Option<i32>> = sites.par_iter().map(|s| domain.locate(s)).collect();
    if !options.allow_outside {
        if let Some(index) = windings.iter().position(|w| *w == Some(0)) {
            return Err(CoreError::SiteOutsideDomain {
                index,
                point: sites[index].to_vec(),
            });
        }
    }
    Ok(windings)
}

/// A part's sites checked (all finite, `own` in range, the own sites as a whole
/// problem's; the others are other parts' own): the own sites' winding numbers indexed
/// like `sites` (`None` elsewhere), and which sites are own.
pub(crate) fn checked_part<const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    own: &[u32],
    options: Options,
) -> Result<(Vec<Option<i32>>, Vec<bool>), CoreError> {
    let n = sites.len();
    if let Some(&bad) = own.iter().find(|&&i| i as usize >= n) {
        return Err(CoreError::SiteIndex {
            reason: format!("own site {bad} is not one of the {n} sites"),
        });
    }
    for (index, s) in sites.iter().enumerate() {
        if let Some(&value) = s.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::NonFiniteSite { index, value });
        }
    }
    let own_sites: Vec<[f64; D]> = own.iter().map(|&i| sites[i as usize]).collect();
    let own_windings = checked_windings(domain, &own_sites, options)
        .map_err(|e| e.with_site_rows(|k| own.get(k).map_or(k, |&i| i as usize)))?;
    let mut windings = vec![None; n];
    let mut is_own = vec![false; n];
    for (&i, &w) in own.iter().zip(&own_windings) {
        windings[i as usize] = w;
        is_own[i as usize] = true;
    }
    Ok((windings, is_own))
}

/// How far outside the domain's box an allowed outside site may lie, in units of the
/// box's smallest side. Its cell is cut in coordinates relative to the site, and the
/// moments of pieces at distance `R` carry an error of about `eps·R²`: measured on the
/// unit square, 7e-15 of the area at R = 10, 9e-13 at 100, 6e-11 at 1000, and garbage
/// (volume 8193) at 1e10. The smallest side, not the diagonal: a needle 1 wide and 1.4e14
/// long seen from 9e15 away lost its width to the rounding of the relative coordinates.
pub const FAR_OUTSIDE: f64 = 64.0;
