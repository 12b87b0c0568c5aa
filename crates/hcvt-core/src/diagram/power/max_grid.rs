//! The sites' grid of blocks with the largest weight per block and per coarse block: how
//! far a power cell must look for the sites that can cut it (module docs of [`super`]).

use std::ops::ControlFlow;

use crate::geometry::next_in_box;

/// Sites per block of [`MaxGrid`], about.
const SITES_PER_BLOCK: f64 = 8.0;

/// Blocks read along each axis on either side of a point's own by [`MaxGrid::reach`];
/// farther, the global bound `radius(w_max)` is used instead. A power cell's first bounds
/// are for the radius of the domain's box: read block by block, they covered the whole
/// grid, and took 43% of the time of optimal transport at 10,000 sites. The cell's stop
/// is recomputed as its radius shrinks (`voronoi_cell`), so the blocks are read once it
/// is small.
const MAX_SPAN: usize = 8;

/// The largest weight in each block of a uniform grid over the sites' box.
#[derive(Debug, Clone)]
pub(super) struct MaxGrid<const D: usize> {
    lo: [f64; D],
    /// Side of a block, `L`.
    pub(super) side: f64,
    dims: [usize; D],
    /// Per axis `k`, the blocks' boundaries `lo_k + i·side` for `i` in `0..=dims_k`, the
    /// first `−∞` and the last `+∞` (the edge blocks reach out to infinity): `near2`, a
    /// tenth of the scans' instructions, reads them rather than computing them with a
    /// branch at each use (the same operations: the same values bit for bit).
    edges: [Vec<f64>; D],
    /// Per block, row-major with axis 0 fastest; `-∞` for an empty block.
    max: Vec<f64>,
    /// The sites of block `b` are `members[starts[b]..starts[b + 1]]`, in index order.
    starts: Vec<u32>,
    pub(super) members: Vec<u32>,
    /// The sites and weights of `members`, in their order: the second pass reads a block's
    /// members in a row rather than each site and weight from wherever its index is.
    pub(super) member_sites: Vec<[f64; D]>,
    pub(super) member_weights: Vec<f64>,
    /// The largest weight per coarse block of `COARSE^D` blocks, row-major like `max`.
    coarse_dims: [usize; D],
    coarse_max: Vec<f64>,
}

/// The grid of [`MaxGrid`] over some sites, kept for the power diagrams of the same sites
/// with other weights ([`Power::on_blocks`]): locating the sites in it again took 1.4% of
/// a transport's instructions at 10,000 sites (its 7 power diagrams).
///
/// [`Power::on_blocks`]: super::Power::on_blocks
#[derive(Debug, Clone)]
pub(in crate::diagram) struct SiteBlocks<const D: usize>(pub(super) MaxGrid<D>);

/// Blocks per coarse block of [`MaxGrid`] along each axis: the second pass
/// ([`Power::clip_heavier`]) reads the blocks of a coarse block only if its largest weight
/// can reach the cell. Reading every block within the bound for `w_max` took a third of a
/// power diagram's time at 10,000 sites (169 blocks a cell).
///
/// [`Power::clip_heavier`]: super::Power::clip_heavier
const COARSE: usize = 4;

/// What the cells of a part of a power diagram need of the whole problem
/// ([`clipped_cells`]): its sites' box, their number and their largest weight. The
/// part's grid ([`MaxGrid`]) is then the whole problem's, block for block, so its second
/// pass clips the heavier sites in the same order; every block's largest weight is taken
/// as `max_weight` (the part does not hold every site of a block), an upper bound that
/// only reads more blocks: the sites clipped, and their order, are those of the whole
/// problem whenever the part holds every site within the cell's reach.
///
/// [`clipped_cells`]: crate::diagram::clipped_cells
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerWhole<const D: usize> {
    /// The smallest coordinate of all the problem's sites along each axis, `L`.
    pub lo: [f64; D],
    /// The largest, `L`.
    pub hi: [f64; D],
    /// The number of the problem's sites.
    pub sites: usize,
    /// The largest weight of all, `L²`.
    pub max_weight: f64,
}

impl<const D: usize> PowerWhole<D> {
    /// The whole problem's box, count and largest weight, as [`Power::new`] takes them.
    ///
    /// [`Power::new`]: super::Power::new
    pub fn of(sites: &[[f64; D]], weights: &[f64]) -> Self {
        Self {
            lo: std::array::from_fn(|k| sites.iter().fold(f64::INFINITY, |m, s| m.min(s[k]))),
            hi: std::array::from_fn(|k| sites.iter().fold(f64::NEG_INFINITY, |m, s| m.max(s[k]))),
            sites: sites.len(),
            max_weight: weights.iter().fold(f64::NEG_INFINITY, |m, &w| m.max(w)),
        }
    }
}

impl<const D: usize> MaxGrid<D> {
    /// The grid of `sites` (the whole problem) holding their weights.
    pub(super) fn new(sites: &[[f64; D]], weights: &[f64]) -> Self {
        Self::of_whole(sites, weights, &PowerWhole::of(sites, weights), false)
    }

    /// The grid of the problem `whole` holding `sites` (all or some of its sites), with
    /// each block's largest weight that of its sites, or `whole.max_weight` for every block
    /// (`cap`, a part).
    pub(super) fn of_whole(
        sites: &[[f64; D]],
        weights: &[f64],
        whole: &PowerWhole<D>,
        cap: bool,
    ) -> Self {
        let (lo, hi) = (whole.lo, whole.hi);
        let extent: [f64; D] = std::array::from_fn(|k| hi[k] - lo[k]);
        let largest = extent.iter().fold(0.0, |m: f64, &e| m.max(e));
        // The box's volume, its flat sides counted as a hundredth of the largest.
        let volume: f64 = extent.iter().map(|&e| e.max(0.01 * largest)).product();
        let blocks = (whole.sites as f64 / SITES_PER_BLOCK).max(1.0);
        let mut side = (volume / blocks).powf(1.0 / D as f64);
        if !(side > 0.0 && side.is_finite()) {
            side = 1.0; // a single site (or all at one point): one block
        }
        let dims: [usize; D] =
            std::array::from_fn(|k| ((extent[k] / side).floor() as usize + 1).min(1 << 20));
        let blocks = dims.iter().product();
        let edges = std::array::from_fn(|k| {
            let mut edges: Vec<f64> = (0..=dims[k]).map(|i| lo[k] + i as f64 * side).collect();
            edges[0] = f64::NEG_INFINITY;
            edges[dims[k]] = f64::INFINITY;
            edges
        });
        let mut grid = Self {
            lo,
            side,
            dims,
            edges,
            max: vec![f64::NEG_INFINITY; blocks],
            starts: vec![0; blocks + 1],
            members: vec![0; sites.len()],
            member_sites: Vec::new(),
            member_weights: Vec::new(),
            coarse_dims: std::array::from_fn(|k| dims[k].div_ceil(COARSE)),
            coarse_max: Vec::new(),
        };
        grid.coarse_max = vec![f64::NEG_INFINITY; grid.coarse_dims.iter().product()];
        let owner: Vec<usize> = sites.iter().map(|s| grid.flat(grid.block(s))).collect();
        for ((&b, &w), s) in owner.iter().zip(weights).zip(sites) {
            grid.max[b] = grid.max[b].max(w);
            grid.starts[b + 1] += 1;
            let c = grid.coarse_flat(grid.block(s).map(|x| x / COARSE));
            grid.coarse_max[c] = grid.coarse_max[c].max(w);
        }
        if cap {
            grid.max.fill(whole.max_weight);
            grid.coarse_max.fill(whole.max_weight);
        }
        for b in 0..blocks {
            grid.starts[b + 1] += grid.starts[b];
        }
        let mut next = grid.starts.clone();
        for (j, &b) in owner.iter().enumerate() {
            grid.members[next[b] as usize] = j as u32;
            next[b] += 1;
        }
        grid.member_sites = grid.members.iter().map(|&j| sites[j as usize]).collect();
        grid.member_weights = grid.members.iter().map(|&j| weights[j as usize]).collect();
        grid
    }

    /// This grid (of the same sites) holding `weights` instead: [`MaxGrid::new`]'s grid for
    /// them, its blocks' and coarse blocks' largest weights the same maxima.
    pub(super) fn reweighted(&self, weights: &[f64]) -> Self {
        let member_weights: Vec<f64> = self.members.iter().map(|&j| weights[j as usize]).collect();
        let mut max = vec![f64::NEG_INFINITY; self.max.len()];
        let mut coarse_max = vec![f64::NEG_INFINITY; self.coarse_max.len()];
        let mut at = [0; D];
        for (b, m) in max.iter_mut().enumerate() {
            let own = &member_weights[self.starts[b] as usize..self.starts[b + 1] as usize];
            *m = own.iter().fold(f64::NEG_INFINITY, |m, &w| m.max(w));
            let c = self.coarse_flat(at.map(|x| x / COARSE));
            coarse_max[c] = coarse_max[c].max(*m);
            next_in_box(&mut at, [0; D], self.dims.map(|d| d - 1));
        }
        Self {
            max,
            member_weights,
            coarse_max,
            starts: self.starts.clone(),
            members: self.members.clone(),
            member_sites: self.member_sites.clone(),
            edges: self.edges.clone(),
            ..*self
        }
    }

    fn block(&self, p: &[f64; D]) -> [usize; D] {
        std::array::from_fn(|k| {
            let x = ((p[k] - self.lo[k]) / self.side).floor();
            (x.max(0.0) as usize).min(self.dims[k] - 1)
        })
    }

    fn flat(&self, b: [usize; D]) -> usize {
        (0..D).rev().fold(0, |f, k| f * self.dims[k] + b[k])
    }

    fn coarse_flat(&self, c: [usize; D]) -> usize {
        (0..D).rev().fold(0, |f, k| f * self.coarse_dims[k] + c[k])
    }

    /// The squared distance from `p` to the nearest point of the blocks `first..=last`.
    pub(super) fn near2(&self, first: [usize; D], last: [usize; D], p: [f64; D]) -> f64 {
        let mut near2 = 0.0;
        for k in 0..D {
            let (a, b) = (self.edges[k][first[k]], self.edges[k][last[k] + 1]);
            let gap = (a - p[k]).max(p[k] - b).max(0.0);
            near2 += gap * gap;
        }
        near2
    }

    /// The largest of `radius(W_c)` over the blocks `c` whose nearest point lies within it
    /// of `p`, each capped by the distance of the block's farthest point; blocks are read
    /// out to `radius(w_max)`, the bound for any block. `radius` is increasing, `None` when
    /// no site of that weight can matter.
    pub(super) fn reach(&self, p: [f64; D], max: f64, radius: impl Fn(f64) -> Option<f64>) -> f64 {
        let Some(outer) = radius(max) else {
            return 0.0;
        };
        if (outer / self.side).ceil() as usize + 1 > MAX_SPAN {
            // Too many blocks to read: the bound for any block, `radius(w_max)`.
            return outer;
        }
        let (from, to) = self.cube(p, outer);
        let mut at = from;
        let mut best: f64 = 0.0;
        loop {
            let w = self.max[self.flat(at)];
            if w > f64::NEG_INFINITY {
                if let Some(r) = radius(w) {
                    let (near2, far2) = self.distances2(at, p);
                    if near2 < r * r {
                        best = best.max(r.min(far2.sqrt()));
                    }
                }
            }
            if !next_in_box(&mut at, from, to) {
                return best;
            }
        }
    }

    /// The squared distances from `p` to the nearest and the farthest point of block `at`
    /// (the first and last blocks along an axis reaching out to infinity: sites beyond the
    /// grid's box fall in them).
    fn distances2(&self, at: [usize; D], p: [f64; D]) -> (f64, f64) {
        let mut far2 = 0.0;
        for k in 0..D {
            let a = self.lo[k] + at[k] as f64 * self.side;
            let b = if at[k] + 1 == self.dims[k] {
                f64::INFINITY
            } else {
                a + self.side
            };
            let a = if at[k] == 0 { f64::NEG_INFINITY } else { a };
            let far = (p[k] - a).abs().max((b - p[k]).abs());
            far2 += far * far;
        }
        (self.near2(at, at, p), far2)
    }

    /// The two-level scan of both passes ([`Power::clip_heavier`], [`Power::hinted_cell`])
    /// over the blocks `from..=to`: each coarse block in order, its blocks in order if
    /// `reach2(state, W, first, last, None)` (its largest weight `W`, its blocks
    /// `first..=last` within the cube) is `Some(coarse2)`, then each member `k` of a block,
    /// in index order, with `member(state, k, block2)` if that block's
    /// `reach2(state, W_b, at, at, Some(coarse2))` is `Some(block2)`; `reach2` sees the
    /// state as `member` left it. Stops at the first `Break`.
    ///
    /// [`Power::clip_heavier`]: super::Power::clip_heavier
    /// [`Power::hinted_cell`]: super::Power::hinted_cell
    pub(super) fn scan<S, B, T: Copy>(
        &self,
        from: [usize; D],
        to: [usize; D],
        state: &mut S,
        reach2: impl Fn(&S, f64, [usize; D], [usize; D], Option<T>) -> Option<T>,
        mut member: impl FnMut(&mut S, usize, T) -> ControlFlow<B>,
    ) -> ControlFlow<B> {
        let (coarse_from, coarse_to) = (from.map(|x| x / COARSE), to.map(|x| x / COARSE));
        let mut coarse = coarse_from;
        loop {
            let first = std::array::from_fn(|k| (coarse[k] * COARSE).max(from[k]));
            let last = std::array::from_fn(|k| (coarse[k] * COARSE + COARSE - 1).min(to[k]));
            let coarse_max = self.coarse_max[self.coarse_flat(coarse)];
            if let Some(coarse2) = reach2(state, coarse_max, first, last, None) {
                let mut at = first;
                loop {
                    let b = self.flat(at);
                    if let Some(block2) = reach2(state, self.max[b], at, at, Some(coarse2)) {
                        for k in self.starts[b] as usize..self.starts[b + 1] as usize {
                            member(state, k, block2)?;
                        }
                    }
                    if !next_in_box(&mut at, first, last) {
                        break;
                    }
                }
            }
            if !next_in_box(&mut coarse, coarse_from, coarse_to) {
                return ControlFlow::Continue(());
            }
        }
    }

    /// The cube of blocks within `outer` of `p`, as its first and last block.
    ///
    /// Why `span = ⌈outer/side·(1 + 10⁻⁶) + 10⁻⁶⌉` blocks on either side of `p`'s own
    /// suffice: `p` lies in its block `c` along each axis `k` (or beyond the grid's box
    /// on the side its clamped block reaches out, or a rounding of the floor away from
    /// the edge it sits on), so a block `b ≥ c + span + 1` starts at least `span·side`
    /// beyond `p` (`b ≤ c − span − 1` ends that far before it), less the rounding of
    /// `lo + b·side − p`: a few ulps of the grid's extent, `< 2²⁰` blocks, so below
    /// `10⁻⁹·side`. Its squared distance from `p` thus exceeds `outer²(1 + 10⁻⁶)`, more
    /// than every reach its callers test blocks against: each is for a weight at most
    /// `w_max`, or a cell that has only shrunk since `outer` was taken, with a relative
    /// rounding margin `≤ 10⁻¹²` (their roots and squares monotone; a cell's radius grown
    /// by a clip's rounding, a few ulps, is within the `10⁻⁶`). Every block outside the
    /// cube would fail its test: the same blocks are read. (The earlier `⌈outer/side⌉ + 1`
    /// read 25 blocks where 9 can reach, most cells' `outer` being under a side; reading
    /// the 16 others was 2.9% of a transport's instructions.)
    pub(super) fn cube(&self, p: [f64; D], outer: f64) -> ([usize; D], [usize; D]) {
        let centre = self.block(&p);
        let span = (outer / self.side * (1.0 + 1e-6) + 1e-6).ceil();
        let span = if span < 1e9 {
            span as usize
        } else {
            usize::MAX / 4
        };
        let from = std::array::from_fn(|k| centre[k].saturating_sub(span));
        let to = std::array::from_fn(|k| centre[k].saturating_add(span).min(self.dims[k] - 1));
        (from, to)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::Lcg;

    /// A grid's bits: its layout, members and per-block maxima.
    fn bits<const D: usize>(g: &MaxGrid<D>) -> Vec<u64> {
        let floats = (g.lo.iter().chain([&g.side]))
            .chain(&g.max)
            .chain(&g.coarse_max)
            .chain(&g.member_weights)
            .chain(g.edges.iter().flatten())
            .chain(g.member_sites.iter().flatten());
        let counts = (g.dims.iter().chain(&g.coarse_dims)).map(|&d| d as u64);
        let members = g.starts.iter().chain(&g.members).map(|&m| u64::from(m));
        floats
            .map(|x| x.to_bits())
            .chain(counts)
            .chain(members)
            .collect()
    }

    /// A grid reweighted for the same sites is the grid built for the new weights, bit for
    /// bit (the power diagrams of optimal transport's trials share one, `Power::on_blocks`).
    #[test]
    fn a_reweighted_grid_is_the_grid_of_the_new_weights() {
        let mut rng = Lcg::new(5);
        let sites: Vec<[f64; 2]> = (0..3000).map(|_| [rng.unit(), 2.0 * rng.unit()]).collect();
        let first: Vec<f64> = sites.iter().map(|_| rng.unit() - 0.5).collect();
        let other: Vec<f64> = sites.iter().map(|_| 1e-3 * (rng.unit() - 0.5)).collect();
        let grid = MaxGrid::new(&sites, &first);
        assert!(grid.max.len() > 64 && grid.coarse_max.len() > 4);
        assert_eq!(
            bits(&grid.reweighted(&other)),
            bits(&MaxGrid::new(&sites, &other))
        );
        assert_eq!(bits(&grid.reweighted(&first)), bits(&grid));
    }
}
