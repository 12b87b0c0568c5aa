//! The weights of a power (Laguerre) diagram (DESIGN §14) and how far a power cell must
//! look for the sites that can cut it.
//!
//! Site `j` at `q = z_j − z_i` cuts cell `i` only if some `y` of the cell (relative to
//! `z_i`) has `|y − q|² − w_j < |y|² − w_i`, i.e. `|q|² − 2 q·y < w_j − w_i`. With the cell
//! in the ball `|y| ≤ R` that needs `|q|² − 2R|q| < w_j − w_i`, i.e.
//! `|q| < R + √(R² + w_j − w_i)` (and nothing when `R² + w_j − w_i < 0`). For equal weights
//! this is the Voronoi security radius `2R` (Ray et al. 2018).
//!
//! Bounding `w_j` by the largest weight of all (`w_max`, the 4D lift's bound of Basselin et
//! al. 2021) is exact but far too wide for the weights of optimal transport, which drift
//! over the domain: at 5,000 random sites with random masses `w_max − w_min` was 107 mean
//! squared spacings, every cell streamed the sites within some 12 spacings, and a diagram
//! took 25 times the Voronoi diagram's time. So the weights are also kept per block of a
//! grid ([`MaxGrid`], about 8 sites a block, and per coarse block of `4^D` blocks): a site
//! in block `c` can cut only within `R + √(R² + W_c − w_i)` of `z_i` (`W_c` the block's
//! largest weight), and only if the block reaches that near.
//!
//! **Two passes.** Streaming in order of distance to the largest such bound over the
//! blocks (as before) was driven by the heaviest sites nearby: at 10,000 random sites with
//! the weights of equal masses a power diagram cost 5 to 8 times the Voronoi diagram, 43%
//! of optimal transport's time going to the bound itself (read over every block while the
//! cell was still the domain's box). So a power cell streams its neighbours only to the
//! bound for sites no heavier than its own (`w_j ≤ w_i`: `|q| < 2R`, the Voronoi security
//! radius, [`Power::stream_reach2`]) and then, in a second pass ([`Power::clip_heavier`]),
//! reads the coarse blocks and blocks that can reach it site by site, clipping by each
//! site beyond the stream that lies within its own bound `R + √(R² + w_j − w_i)` (`R` the
//! cell's radius as it shrinks). Exact: a site that can cut the cell is either within the
//! streamed distance or passes that test (its block's and coarse block's bounds are at
//! least its own). With weights 0 no site passes the second test (its bound is the
//! stream's), so the cell is the Voronoi cell bit for bit. The cells are equal to the
//! references of `tests/test_power.py` as before, though not bit for bit the cells of the
//! one-pass stream with weights (the planes are clipped in another order).
//!
//! **Started cells.** Within a Newton iteration (`optimise::transport`) a cell is clipped
//! first by its neighbours in the previous power diagram and then certified by the blocks
//! near the mean of its vertices ([`Power::hinted_cell`], the proof there): no stream from
//! the site, which at convergence lies outside 76% of the cells (10,000 sites, equal
//! masses).

use std::ops::ControlFlow;

use crate::geometry::{add, dot, norm2, sub, Aabb, HalfSpace};

use super::convex_cell::{ConvexCell, Face};

/// The weights of a power diagram, one per site of the computation (a periodic box's
/// images carry their site's), `L²`: cell `i` is `{x : |x − z_i|² − w_i ≤ |x − z_j|² − w_j}`.
#[derive(Debug, Clone)]
pub(super) struct Power<'a, const D: usize> {
    weights: &'a [f64],
    /// `max_j w_j`.
    max: f64,
    grid: MaxGrid<D>,
}

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
struct MaxGrid<const D: usize> {
    lo: [f64; D],
    /// Side of a block, `L`.
    side: f64,
    dims: [usize; D],
    /// Per block, row-major with axis 0 fastest; `-∞` for an empty block.
    max: Vec<f64>,
    /// The sites of block `b` are `members[starts[b]..starts[b + 1]]`, in index order.
    starts: Vec<u32>,
    members: Vec<u32>,
    /// The sites and weights of `members`, in their order: the second pass reads a block's
    /// members in a row rather than each site and weight from wherever its index is.
    member_sites: Vec<[f64; D]>,
    member_weights: Vec<f64>,
    /// The largest weight per coarse block of `COARSE^D` blocks, row-major like `max`.
    coarse_dims: [usize; D],
    coarse_max: Vec<f64>,
}

/// Blocks per coarse block of [`MaxGrid`] along each axis: the second pass
/// ([`Power::clip_heavier`]) reads the blocks of a coarse block only if its largest weight
/// can reach the cell. Reading every block within the bound for `w_max` took a third of a
/// power diagram's time at 10,000 sites (169 blocks a cell).
const COARSE: usize = 4;

/// What the cells of a part of a power diagram need of the whole problem
/// ([`super::clipped_cells`]): its sites' box, their number and their largest weight. The
/// part's grid ([`MaxGrid`]) is then the whole problem's, block for block, so its second
/// pass clips the heavier sites in the same order; every block's largest weight is taken
/// as `max_weight` (the part does not hold every site of a block), an upper bound that
/// only reads more blocks: the sites clipped, and their order, are those of the whole
/// problem whenever the part holds every site within the cell's reach.
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
    fn new(sites: &[[f64; D]], weights: &[f64]) -> Self {
        Self::of_whole(sites, weights, &PowerWhole::of(sites, weights), false)
    }

    /// The grid of the problem `whole` holding `sites` (all or some of its sites), with
    /// each block's largest weight that of its sites, or `whole.max_weight` for every block
    /// (`cap`, a part).
    fn of_whole(sites: &[[f64; D]], weights: &[f64], whole: &PowerWhole<D>, cap: bool) -> Self {
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
        let mut grid = Self {
            lo,
            side,
            dims,
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
    fn near2(&self, first: [usize; D], last: [usize; D], p: [f64; D]) -> f64 {
        let mut near2 = 0.0;
        for k in 0..D {
            let a = if first[k] == 0 {
                f64::NEG_INFINITY
            } else {
                self.lo[k] + first[k] as f64 * self.side
            };
            let b = if last[k] + 1 == self.dims[k] {
                f64::INFINITY
            } else {
                self.lo[k] + (last[k] + 1) as f64 * self.side
            };
            let gap = (a - p[k]).max(p[k] - b).max(0.0);
            near2 += gap * gap;
        }
        near2
    }

    /// The largest of `radius(W_c)` over the blocks `c` whose nearest point lies within it
    /// of `p`, each capped by the distance of the block's farthest point; blocks are read
    /// out to `radius(w_max)`, the bound for any block. `radius` is increasing, `None` when
    /// no site of that weight can matter.
    fn reach(&self, p: [f64; D], max: f64, radius: impl Fn(f64) -> Option<f64>) -> f64 {
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
            if !next_block(&mut at, from, to) {
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
    /// `reach2(state, W, first, last)` (its largest weight `W`, its blocks `first..=last`
    /// within the cube) is `Some`, then each member `k` of a block, in index order, with
    /// `member(state, k, block2)` if that block's `reach2` is `Some(block2)`; `reach2` sees
    /// the state as `member` left it. Stops at the first `Break`.
    fn scan<S, B>(
        &self,
        from: [usize; D],
        to: [usize; D],
        state: &mut S,
        reach2: impl Fn(&S, f64, [usize; D], [usize; D]) -> Option<f64>,
        mut member: impl FnMut(&mut S, usize, f64) -> ControlFlow<B>,
    ) -> ControlFlow<B> {
        let (coarse_from, coarse_to) = (from.map(|x| x / COARSE), to.map(|x| x / COARSE));
        let mut coarse = coarse_from;
        loop {
            let first = std::array::from_fn(|k| (coarse[k] * COARSE).max(from[k]));
            let last = std::array::from_fn(|k| (coarse[k] * COARSE + COARSE - 1).min(to[k]));
            let coarse_max = self.coarse_max[self.coarse_flat(coarse)];
            if reach2(state, coarse_max, first, last).is_some() {
                let mut at = first;
                loop {
                    let b = self.flat(at);
                    if let Some(block2) = reach2(state, self.max[b], at, at) {
                        for k in self.starts[b] as usize..self.starts[b + 1] as usize {
                            member(state, k, block2)?;
                        }
                    }
                    if !next_block(&mut at, first, last) {
                        break;
                    }
                }
            }
            if !next_block(&mut coarse, coarse_from, coarse_to) {
                return ControlFlow::Continue(());
            }
        }
    }

    /// The cube of blocks within `outer` of `p`, as its first and last block.
    fn cube(&self, p: [f64; D], outer: f64) -> ([usize; D], [usize; D]) {
        let centre = self.block(&p);
        let span = (outer / self.side).ceil();
        let span = if span < 1e9 {
            span as usize + 1
        } else {
            usize::MAX / 4
        };
        let from = std::array::from_fn(|k| centre[k].saturating_sub(span));
        let to = std::array::from_fn(|k| centre[k].saturating_add(span).min(self.dims[k] - 1));
        (from, to)
    }
}

/// Step `at` to the next block of the cube `from..=to`, axis 0 fastest; false past the last.
fn next_block<const D: usize>(at: &mut [usize; D], from: [usize; D], to: [usize; D]) -> bool {
    for k in 0..D {
        if at[k] < to[k] {
            at[k] += 1;
            return true;
        }
        at[k] = from[k];
    }
    false
}

/// `R + √(R² + Δ)` for the cell radius `r` (`r2 = R²`) and a weight excess `Δ = w_j − w_i`:
/// no site of that excess farther from the site can cut the cell; `None` when none can.
fn cut_reach(r: f64, r2: f64, excess: f64) -> Option<f64> {
    let s = r2 + excess;
    (s >= 0.0).then(|| r + s.sqrt())
}

/// Relative margin on a squared reach for the rounding of its roots.
const ROUNDING: f64 = 1e-12;

/// A hinted cell ([`Power::hinted_cell`]) whose vertices lie farther than this many blocks
/// of [`MaxGrid`] from their mean is left to the stream: the certificate would read every
/// block within that distance (a cell of a non-convex domain open into the domain's box).
const HINT_SPAN: f64 = 2.0;

/// Relative margin of [`Power::hinted_cell`]'s per-site test, on the sum of its terms'
/// magnitudes: generous for their rounding (a few ulps each).
const HINT_ROUNDING: f64 = 1e-9;

impl<'a, const D: usize> Power<'a, D> {
    /// Weights indexed like `sites` (all finite, checked by the caller).
    pub(super) fn new(weights: &'a [f64], sites: &[[f64; D]]) -> Self {
        let max = weights.iter().fold(f64::NEG_INFINITY, |m, &w| m.max(w));
        Self {
            weights,
            max,
            grid: MaxGrid::new(sites, weights),
        }
    }

    /// Weights indexed like `sites`, some of the sites of the problem `whole` (a part and
    /// its halo): the planes, bounds and order of [`Power::new`] over the whole problem.
    pub(super) fn in_part(weights: &'a [f64], sites: &[[f64; D]], whole: &PowerWhole<D>) -> Self {
        Self {
            weights,
            max: whole.max_weight,
            grid: MaxGrid::of_whole(sites, weights, whole, true),
        }
    }

    /// The half-space of cell `i` against site `j` at `q = z_j − z_i`, relative to `z_i`:
    /// `q·y ≤ (|q|² + w_i − w_j) / 2`. Equal weights add an exact zero, so the plane is the
    /// Voronoi bisector bit for bit.
    pub(super) fn bisector(&self, q: [f64; D], i: usize, j: usize) -> HalfSpace<D> {
        HalfSpace {
            normal: q,
            offset: 0.5 * (norm2(q) + (self.weights[i] - self.weights[j])),
        }
    }

    /// The weights, indexed like the sites.
    pub(super) fn weights(&self) -> &'a [f64] {
        self.weights
    }

    /// `w_max − w_i ≥ 0`, `L²`.
    pub(super) fn slack(&self, i: usize) -> f64 {
        self.max - self.weights[i]
    }

    /// The squared distance from site `i` within which its cell, held in the ball of
    /// squared radius `radius2` about the site, streams its neighbours: the bound for
    /// sites no heavier than `w_i`, `(2R)²` (with a rounding margin). The heavier sites
    /// beyond it are [`Power::clip_heavier`]'s.
    pub(super) fn stream_reach2(&self, radius2: f64) -> f64 {
        let r = radius2.sqrt();
        let reach = cut_reach(r, radius2, 0.0).unwrap_or(0.0);
        reach * reach * (1.0 + ROUNDING)
    }

    /// The squared distance from site `i` beyond which no site can cut its cell, held in
    /// the ball of squared radius `radius2` about it: the bound for `w_max`.
    pub(super) fn global_reach2(&self, i: usize, radius2: f64) -> f64 {
        let reach = cut_reach(radius2.sqrt(), radius2, self.slack(i)).unwrap_or(0.0);
        reach * reach * (1.0 + ROUNDING)
    }

    /// The second pass of cell `i` (relative to its site) after its stream read every site
    /// within squared distance `covered2`: clip by each site `j` farther than that which
    /// lies within its own bound `R + √(R² + w_j − w_i)` of the site, `R` the cell's
    /// radius as it shrinks. The blocks are read in order within the bound for `w_max`,
    /// each only if its own largest weight lets one of its sites reach; their sites in
    /// index order. Stops at an empty cell.
    pub(super) fn clip_heavier<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        sites: &[[f64; D]],
        i: usize,
        covered2: f64,
    ) {
        let own = self.weights[i];
        let site = sites[i];
        let grid = &self.grid;
        let radius2 = cell.max_dist2();
        let r = radius2.sqrt();
        let Some(outer) = cut_reach(r, radius2, self.slack(i)) else {
            return;
        };
        if outer * outer * (1.0 + ROUNDING) <= covered2 {
            return; // the stream read every site that can cut the cell
        }
        let (from, to) = grid.cube(site, outer);
        // The squared distance (with the rounding margin) within which a site of weight at
        // most `w` in the blocks `first..=last` can cut the cell, when that reaches beyond
        // the streamed distance and the blocks lie within it; `None` when no such site can.
        let reach2_of = |&(r, radius2): &(f64, f64), w: f64, first, last| {
            let reach = cut_reach(r, radius2, w - own)?;
            let reach2 = reach * reach * (1.0 + ROUNDING);
            (reach2 > covered2 && grid.near2(first, last, site) < reach2).then_some(reach2)
        };
        let mut state = (r, radius2);
        let _ = grid.scan(
            from,
            to,
            &mut state,
            reach2_of,
            |(r, radius2), k, block2| {
                let q = sub(grid.member_sites[k], site);
                let dist2 = norm2(q);
                // Streamed (site `i` itself among them), or beyond the reach of the block's
                // heaviest weight, at least the member's own (rounded operations are monotone,
                // and the cell has only shrunk since): the same sites clipped in the same
                // order, most of the others turned away without a square root.
                if dist2 <= covered2 || dist2 >= block2 {
                    return ControlFlow::Continue(());
                }
                let excess = grid.member_weights[k] - own;
                let j = grid.members[k];
                let Some(reach) = cut_reach(*r, *radius2, excess) else {
                    return ControlFlow::Continue(());
                };
                if dist2 < reach * reach * (1.0 + ROUNDING)
                    && cell.clip(&self.bisector(q, i, j as usize), Face::Neighbor(j))
                {
                    if cell.is_empty() {
                        return ControlFlow::Break(());
                    }
                    *radius2 = cell.max_dist2();
                    *r = radius2.sqrt();
                }
                ControlFlow::Continue(())
            },
        );
    }

    /// Cell `i` (relative to its site) of this power diagram, from a hint: the start box
    /// `start` clipped by the sites `neighbours` (a previous power diagram's neighbours of
    /// the cell, other weights), then certified. `false` when the cell is too large for
    /// the certificate to pay (its vertices farther than [`HINT_SPAN`] blocks from their
    /// mean), or when a site to clip by coincides with site `i`: the caller computes it
    /// by the stream instead (which names coinciding sites); `cell` is then garbage.
    ///
    /// **The certificate.** The power cell in `start` is `start ∩ ⋂_j H_j`, `H_j` the
    /// half-space of site `j` ([`Power::bisector`]); clipping by any of them, in any
    /// order, leaves a polytope `K` holding the cell, equal to it once every other `H_j`
    /// holds `K`. With `q = z_j − z_i`, `Δ = w_j − w_i`, `H_j` is `{y : f_j(y) ≥ 0}` for the
    /// affine `f_j(y) = |q|² − 2 q·y − Δ`. Let `c` be a point (the mean of `K`'s vertices
    /// after the hint's clips, held fixed), `ρ` the largest distance from `c` to a vertex
    /// of `K` and `R` that from the site, both of `K` as it stands when `j` is read (`K`
    /// only shrinks, so they bound the final cell too): `K` lies in the ball `B(c, ρ)`.
    /// (a) Per site: `min_{B(c,ρ)} f_j = |q|² − 2 q·c − Δ − 2ρ|q|`; where this is
    /// non-negative, `H_j ⊇ B(c, ρ) ⊇ K` and `j` cannot cut, so only the sites failing it
    /// (with a rounding margin) are clipped by. (b) Per block of sites of largest weight
    /// `W`: a point `y` of `K` cut off by `j` has `|y − q|² < |y|² + Δ ≤ R² + W − w_i`,
    /// and `|y − q| ≥ |q − c| − ρ`, so `|q − c| < ρ + √(R² + W − w_i)` ([`cut_reach`]):
    /// a (coarse) block farther than that from `c` holds no site that can cut, and is not
    /// read. Every site is thus either clipped by or proven not to cut: the cell is the
    /// exact power cell, whatever the hint (a wrong or empty hint costs time only). An
    /// empty `K` is the empty cell. The planes are clipped in another order than the
    /// stream's, so the cell equals the streamed one to round-off, not bit for bit.
    pub(super) fn hinted_cell<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        start: &Aabb<D>,
        sites: &[[f64; D]],
        i: usize,
        neighbours: &[u32],
    ) -> bool {
        cell.reset_to_box(start);
        let site = sites[i];
        for &j in neighbours {
            if j as usize != i {
                let q = sub(sites[j as usize], site);
                if norm2(q) == 0.0 {
                    return false;
                }
                cell.clip(&self.bisector(q, i, j as usize), Face::Neighbor(j));
            }
        }
        if cell.is_empty() {
            return true;
        }
        let own = self.weights[i];
        let grid = &self.grid;
        let centre = cell.vertex_mean();
        let spread2 = |cell: &C| {
            cell.vertices()
                .iter()
                .fold(0.0, |m: f64, &v| m.max(norm2(sub(v, centre))))
        };
        let rho2 = spread2(cell);
        if rho2 > (HINT_SPAN * grid.side).powi(2) {
            return false;
        }
        let (rho, radius2) = (rho2.sqrt(), cell.max_dist2());
        let Some(outer) = cut_reach(rho, radius2, self.slack(i)) else {
            return true; // no site can cut (cannot happen for a cell holding a point)
        };
        let at = add(site, centre);
        let (from, to) = grid.cube(at, outer);
        // Within this squared distance of `c` a site of weight at most `w` in the blocks
        // `first..=last` may cut; `None` when the blocks lie beyond it.
        let reach2_of = |&(rho, radius2): &(f64, f64), w: f64, first, last| {
            let reach = cut_reach(rho, radius2, w - own)?;
            let reach2 = reach * reach * (1.0 + ROUNDING);
            (grid.near2(first, last, at) < reach2).then_some(reach2)
        };
        let mut state = (rho, radius2);
        let scanned = grid.scan(
            from,
            to,
            &mut state,
            reach2_of,
            |(rho, radius2), k, block2| {
                let q = sub(grid.member_sites[k], site);
                let from_centre = sub(q, centre);
                // (b) for the site's own weight, at most the block's.
                if norm2(from_centre) >= block2 {
                    return ControlFlow::Continue(());
                }
                let j = grid.members[k];
                let delta = grid.member_weights[k] - own;
                let (q2, qc) = (norm2(q), dot(q, centre));
                let low = q2 - 2.0 * qc - delta;
                let ball = 2.0 * *rho * q2.sqrt();
                // (a), with a margin for the rounding of every term.
                let margin = HINT_ROUNDING * (q2 + 2.0 * qc.abs() + delta.abs() + ball);
                if low - ball >= margin || j as usize == i || neighbours.contains(&j) {
                    return ControlFlow::Continue(());
                }
                if q2 == 0.0 {
                    return ControlFlow::Break(false);
                }
                if cell.clip(&self.bisector(q, i, j as usize), Face::Neighbor(j)) {
                    if cell.is_empty() {
                        return ControlFlow::Break(true);
                    }
                    *rho = spread2(cell).sqrt();
                    *radius2 = cell.max_dist2();
                }
                ControlFlow::Continue(())
            },
        );
        match scanned {
            ControlFlow::Break(done) => done,
            ControlFlow::Continue(()) => true,
        }
    }

    /// The squared distance from the vertex `point` of cell `i` (at squared distance
    /// `v2` from its site) beyond which no site has less power there than site `i`:
    /// `|p − z_j|² < v2 − w_i + w_j`, block by block.
    pub(super) fn vertex_reach2(&self, i: usize, point: [f64; D], v2: f64) -> f64 {
        let own = self.weights[i];
        let reach = self.grid.reach(point, self.max, |w| {
            let s = v2 + (w - own);
            (s >= 0.0).then(|| s.sqrt())
        });
        reach * reach * (1.0 + ROUNDING)
    }
}
