//! Warm-started diagrams (issue 32): each cell's nearest-site stream answered from the
//! sites that were near it in the previous diagram, bit for bit the cold stream.
//!
//! A cell reads the sites in increasing distance (ties by index) up to some distance `R`
//! ([`super::knn::NearSites::vouched2`]). The previous diagram remembers, per site, a list
//! of sites holding every site within `ρ_i` of it (`ρ_i` a little beyond the distance the
//! cell read). When site `i` has moved by `δ_i` and every site that was within
//! `ρ_i + max_j δ_j` of it by at most `δ` (a grid of the largest moves, [`MoveGrid`]), a
//! site `j` missing from the list was beyond `ρ_i` and is now beyond `ρ_i − δ_i − δ` from
//! site `i`: the list is complete within that *certified* distance, and the stream takes
//! its sites from it, sorted as the grid sorts them. A cell that asks farther falls back to the
//! grid ([`super::knn::IndexRef::near_warm`]). The cells are therefore the cold cells
//! bit for bit whatever the previous diagram was; only the time changes.
//!
//! A canonical cell's list starts with its ring, its neighbours face after face: the next
//! diagram first tries to rebuild the cell from them without clipping ([`super::ring`]).

use rayon::prelude::*;

use crate::geometry::{next_in_box, norm2, sub, Aabb, Lattice};

/// The previous diagram's near-site lists, in the order it visited its sites, for
/// [`super::Request::warm`]. Empty (the default) starts cold; a state of another number
/// of sites is ignored.
///
/// The lists are kept in visiting order (slot `k` is site `order[k]`'s), as the batches
/// recorded them: the next diagram visits the sites in the same order and reads slot
/// after slot, where a copy into site order held 2% of a warm 2D diagram's instructions.
#[derive(Debug, Clone, Default)]
pub struct WarmStart<const D: usize> {
    /// The sites of the diagram that recorded the lists, in visiting order, `L`.
    sites: Vec<[f64; D]>,
    /// The list of slot `k` is `near[offsets[k]..offsets[k + 1]]` (its site included).
    offsets: Vec<usize>,
    near: Vec<u32>,
    /// Per slot, every site within this squared distance of its site is on its list, `L²`.
    complete2: Vec<f64>,
    /// Per slot, how many sites at the head of its list are its cell's ring (the
    /// neighbours of a canonical cell, face after face: [`super::ring`]); 0 for none.
    rings: Vec<u8>,
    /// The vertex triangles of slot `k`'s ring (3D, [`super::ConvexCell::ring`]):
    /// `triangles[triangle_offsets[k]..triangle_offsets[k + 1]]`.
    triangles: Vec<[u8; 3]>,
    triangle_offsets: Vec<u32>,
    /// The order the diagram visited the sites in (Morton), which the next one reuses:
    /// the sites moved little, and the order only decides which cells share a cache.
    order: Vec<u32>,
    /// Cells of the recording diagram whose nearest sites came from the warm start alone.
    warm_cells: usize,
    /// Of those, the cells rebuilt from their ring ([`super::ring`]).
    ring_cells: usize,
}

/// How far the sites moved since a [`WarmStart`] was recorded: per slot, the squared
/// distance within which its list still holds every site (`L²`; 0 when nothing is),
/// worked out once for the whole diagram: each cell reads its one entry, where working
/// it out again from the movements and the lists' radii held 3% of a warm 2D diagram's
/// samples (`perf`, square 20k), mostly waiting on those arrays.
pub(super) struct Moved {
    certified2: Vec<f64>,
    /// Per site, its slot, when the diagram visits the sites in another order than the
    /// recording one (a sampled density keeps the cold order); `None` when it visits
    /// them in the same order, slot by slot.
    slots: Option<Vec<u32>>,
}

/// A cold cell remembers the sites within this factor of the distance it read, so that
/// the next diagrams' sites can move by a fraction of it and still be certified: about
/// 1.56 times the sites read in 2D (1.95 in 3D), gathered once per refresh.
const MARGIN: f64 = 1.25;

/// Relative slack on distances for their rounding (a few ulps each; generous).
const ROUNDING: f64 = 1e-9;

impl<const D: usize> WarmStart<D> {
    /// Nothing remembered: the next diagram starts cold.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sites remembered.
    pub fn len(&self) -> usize {
        self.sites.len()
    }

    /// Nothing remembered.
    pub fn is_empty(&self) -> bool {
        self.sites.is_empty()
    }

    /// Cells of the diagram that recorded this state whose nearest sites came from its
    /// predecessor's lists alone (the others asked the index).
    pub fn warm_cells(&self) -> usize {
        self.warm_cells
    }

    /// Of [`WarmStart::warm_cells`], the cells rebuilt from their previous ring without
    /// clipping.
    pub fn ring_cells(&self) -> usize {
        self.ring_cells
    }

    /// Bytes held, for the memory accounts.
    pub fn bytes(&self) -> usize {
        self.sites.len() * std::mem::size_of::<[f64; D]>()
            + self.offsets.len() * std::mem::size_of::<usize>()
            + self.near.len() * std::mem::size_of::<u32>()
            + self.complete2.len() * std::mem::size_of::<f64>()
            + self.rings.len()
            + self.triangles.len() * 3
            + self.triangle_offsets.len() * std::mem::size_of::<u32>()
            + self.order.len() * std::mem::size_of::<u32>()
    }

    /// The mean length of the lists, rounded up (0 when empty).
    pub(super) fn mean_list_len(&self) -> usize {
        self.near.len().div_ceil(self.sites.len().max(1))
    }

    /// The order the recording diagram visited its sites in.
    pub(super) fn order(&self) -> &[u32] {
        &self.order
    }

    /// How far `sites` moved from the remembered ones; `None` when the state is for
    /// another number of sites (or empty). `same_order`: the diagram visits the sites in
    /// [`WarmStart::order`] and looks its lists up by its visiting position.
    pub(super) fn moved(&self, sites: &[[f64; D]], same_order: bool) -> Option<Moved> {
        if self.sites.is_empty() || self.sites.len() != sites.len() {
            return None;
        }
        let each: Vec<f64> = (self.sites.par_iter().zip(&self.order))
            .map(|(&old, &i)| norm2(sub(sites[i as usize], old)).sqrt() * (1.0 + ROUNDING))
            .collect();
        let most = each.iter().fold(0.0, |m: f64, &d| m.max(d));
        if !most.is_finite() {
            return None;
        }
        // A site missing from list `k` (radius `c`) that moved by at most `most` and now
        // lies within `c` of site `k` was within `c + most` of it: the largest move among
        // the sites there bounds them all.
        let grid = MoveGrid::new(&self.sites, &each);
        let certified2: Vec<f64> = (self.complete2.par_iter().zip(&each).zip(&self.sites))
            .map(|((&complete2, &moved), &site)| {
                let reach = complete2.sqrt() + most;
                let others = grid.as_ref().and_then(|g| g.most_within(site, reach));
                certified2(complete2, moved + others.unwrap_or(most))
            })
            .collect();
        // Large steps (Newton's and L-BFGS's early ones) leave few lists certified: the
        // failed attempts and the refreshed lists would cost more than a cold diagram.
        // A list likely still certifies its cell when its certified radius is at least
        // the part of the list's radius a cold cell reads (`1 / MARGIN`).
        let likely = (self.complete2.iter().zip(&certified2))
            .filter(|&(&complete2, &certified2)| {
                certified2 > 0.0 && certified2 * MARGIN * MARGIN >= complete2
            })
            .count();
        if 2 * likely < sites.len() {
            return None;
        }
        let slots = (!same_order).then(|| {
            let mut slots = vec![0; sites.len()];
            for (k, &i) in self.order.iter().enumerate() {
                slots[i as usize] = k as u32;
            }
            slots
        });
        Some(Moved { certified2, slots })
    }

    /// Site `i`'s remembered list and the squared distance within which it still holds
    /// every site after `moved`; `None` when nothing is certified. `visited`: the cell's
    /// position in the diagram's visiting order (its slot when that is the recording
    /// diagram's order).
    pub(super) fn certified(
        &self,
        i: usize,
        visited: usize,
        moved: &Moved,
    ) -> Option<WarmList<'_>> {
        let k = moved
            .slots
            .as_ref()
            .map_or(visited, |slots| slots[i] as usize);
        let certified2 = moved.certified2[k];
        let triangles = match self.triangle_offsets.get(k..k + 2) {
            Some(&[from, to]) => &self.triangles[from as usize..to as usize],
            _ => &[],
        };
        (certified2 > 0.0).then(|| WarmList {
            near: &self.near[self.offsets[k]..self.offsets[k + 1]],
            ring: usize::from(self.rings[k]),
            triangles,
            certified2,
        })
    }

    /// The state of `sites` from their lists in visiting order `order`: site `order[k]`'s
    /// is `near[offsets[k]..offsets[k + 1]]`, complete within `complete2[k]`, its first
    /// `rings.0[k]` sites its cell's ring, whose triangles are
    /// `rings.1[rings.2[k]..rings.2[k + 1]]`.
    pub(super) fn from_lists(
        sites: &[[f64; D]],
        offsets: Vec<usize>,
        near: Vec<u32>,
        complete2: Vec<f64>,
        rings: (Vec<u8>, Vec<[u8; 3]>, Vec<u32>),
        order: Vec<u32>,
    ) -> Self {
        let (rings, triangles, triangle_offsets) = rings;
        Self {
            sites: order.iter().map(|&i| sites[i as usize]).collect(),
            offsets,
            near,
            complete2,
            rings,
            triangles,
            triangle_offsets,
            order,
            warm_cells: 0,
            ring_cells: 0,
        }
    }

    /// The state with the counts of cells its diagram computed warm, and of those rebuilt
    /// from their ring.
    pub(super) fn with_counts(self, warm_cells: usize, ring_cells: usize) -> Self {
        Self {
            warm_cells,
            ring_cells,
            ..self
        }
    }
}

/// A cell's remembered near sites ([`WarmStart::certified`]).
#[derive(Debug, Clone, Copy)]
pub struct WarmList<'a> {
    /// Sites holding every site within `certified2` of the cell's site (itself included),
    /// its ring first.
    pub near: &'a [u32],
    /// How many sites at the head of `near` are the ring of the cell's previous, canonical
    /// form (0: none).
    pub ring: usize,
    /// The ring's vertex triangles (3D; [`super::ConvexCell::ring`]).
    pub triangles: &'a [[u8; 3]],
    /// `L²`.
    pub certified2: f64,
}

/// The squared distance within which a list complete within `complete2` (`L²`) still
/// holds every site once its site moved and every other site that can have come near it
/// moved by at most `moved` in all (`L`): 0 when nothing is certified. When site `i` has
/// moved by `δ_i` and those sites by at most `δ`, a site missing from the list was beyond
/// its radius and is now beyond `radius − δ_i − δ` from site `i`.
fn certified2(complete2: f64, moved: f64) -> f64 {
    let complete = complete2.sqrt() * (1.0 - ROUNDING);
    let r = (complete - moved) * (1.0 - ROUNDING);
    if r > 0.0 {
        r * r
    } else {
        0.0
    }
}

/// Sites per bucket of a [`MoveGrid`], on average over its box.
const SITES_PER_BUCKET: usize = 4;

/// Most buckets along an axis a list's reach may span in a [`MoveGrid`] before its bound
/// falls back to the largest move of all (after a long step of one site the reach spans
/// the domain; a list's own reach spans 2 or 3).
const MAX_BUCKETS_PER_AXIS: usize = 6;

/// The largest move of the remembered sites per bucket of a uniform grid over their old
/// positions: a bound on the moves of the sites that can have come near a list's site.
/// Why: with one bound for all (the largest move of any site), one site of a Newton step
/// moving a third of a spacing, while the rest moved a hundredth, left too few lists
/// certified and the whole diagram started cold (of a square 1k run's cells, 43% came
/// from their ring, against 95-97% in Lloyd's late iterates).
struct MoveGrid<const D: usize> {
    buckets: Lattice<D>,
    /// Per bucket, the largest move of a site in it, `L`.
    most: Vec<f64>,
}

impl<const D: usize> MoveGrid<D> {
    /// The grid of `moves[k]` at `sites[k]`; `None` when the sites span no box (one site,
    /// or all in one point).
    fn new(sites: &[[f64; D]], moves: &[f64]) -> Option<Self> {
        let bounds = Aabb::of_points(sites);
        let extent = sub(bounds.hi, bounds.lo);
        if !extent.iter().all(|e| e.is_finite()) || extent.iter().all(|&e| e <= 0.0) {
            return None;
        }
        let target = (sites.len() / SITES_PER_BUCKET).max(1);
        let buckets = Lattice::new(bounds.lo, extent, target);
        let mut most = vec![0.0f64; buckets.len()];
        for (p, &moved) in sites.iter().zip(moves) {
            let at = buckets.index(buckets.coordinates(p));
            most[at] = most[at].max(moved);
        }
        Some(Self { buckets, most })
    }

    /// The largest move of a site whose old position lies within `reach` of `p` (on
    /// every axis: a bound on the ball's), `L`; `None` when that box spans more than
    /// [`MAX_BUCKETS_PER_AXIS`] buckets along an axis. The box is widened by a relative
    /// [`ROUNDING`] so that the rounding of its edges loses no bucket.
    fn most_within(&self, p: [f64; D], reach: f64) -> Option<f64> {
        let lo = &self.buckets.lo;
        let widen = |k: usize| reach + ROUNDING * (reach + p[k].abs() + lo[k].abs());
        let from = self
            .buckets
            .coordinates(&std::array::from_fn(|k| p[k] - widen(k)));
        let to = self
            .buckets
            .coordinates(&std::array::from_fn(|k| p[k] + widen(k)));
        if (0..D).any(|k| to[k] - from[k] >= MAX_BUCKETS_PER_AXIS) {
            return None;
        }
        let mut most = 0.0f64;
        let mut at = from;
        loop {
            most = most.max(self.most[self.buckets.index(at)]);
            if !next_in_box(&mut at, from, to) {
                return Some(most);
            }
        }
    }
}

/// The squared distance a cold cell's list covers, from the distance it read.
pub(super) fn margin2(vouched2: f64) -> f64 {
    vouched2 * MARGIN * MARGIN
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::Lcg;

    /// Random points in the unit box (`flat`: the last axis squeezed to a plane) and a
    /// move per point: small, but one in fifty long.
    fn points<const D: usize>(n: usize, flat: bool, seed: u64) -> (Vec<[f64; D]>, Vec<f64>) {
        let mut rng = Lcg::new(seed);
        let sites: Vec<[f64; D]> = (0..n)
            .map(|_| std::array::from_fn(|k| if flat && k == D - 1 { 0.5 } else { rng.unit() }))
            .collect();
        let moves = (0..n)
            .map(|i| {
                let scale = if i % 50 == 7 { 0.3 } else { 0.003 };
                scale * rng.unit()
            })
            .collect();
        (sites, moves)
    }

    /// The grid's bound against the brute-force largest move within `reach` (per axis):
    /// never below it, and below the largest move of all wherever no long mover is near;
    /// a reach of the domain's size gets none.
    fn check_grid<const D: usize>(flat: bool) {
        let (sites, moves) = points::<D>(2_000, flat, 3);
        let grid = MoveGrid::new(&sites, &moves).expect("a grid");
        let most = moves.iter().fold(0.0, |m: f64, &d| m.max(d));
        // The mean spacing of the points (on their plane when flat): a list's reach is
        // one to three of them.
        let spacing = (1.0 / sites.len() as f64).powf(1.0 / (D - usize::from(flat)) as f64);
        let mut rng = Lcg::new(11);
        let mut tighter = 0;
        for query in 0..400 {
            let p: [f64; D] = if query % 2 == 0 {
                sites[query]
            } else {
                std::array::from_fn(|_| 1.2 * rng.unit() - 0.1)
            };
            let reach = [0.5, 1.5, 3.0][query % 3] * spacing;
            let near = sites
                .iter()
                .zip(&moves)
                .filter(|(s, _)| (0..D).all(|k| (s[k] - p[k]).abs() <= reach))
                .fold(0.0, |m: f64, (_, &d)| m.max(d));
            let bound = grid
                .most_within(p, reach)
                .expect("a list's reach spans few buckets");
            assert!(bound >= near, "query {query}: {bound} < {near}");
            tighter += usize::from(bound < 0.1 * most);
        }
        assert!(
            tighter > 100,
            "only {tighter} of 400 bounds below the largest move"
        );
    }

    #[test]
    fn a_move_grid_bounds_the_moves_near_a_point_2d() {
        check_grid::<2>(false);
        check_grid::<2>(true);
    }

    #[test]
    fn a_move_grid_bounds_the_moves_near_a_point_3d() {
        check_grid::<3>(false);
        check_grid::<3>(true);
    }

    #[test]
    fn no_grid_over_one_point() {
        assert!(MoveGrid::<2>::new(&[[0.5, 0.5]; 3], &[0.1; 3]).is_none());
    }
}
