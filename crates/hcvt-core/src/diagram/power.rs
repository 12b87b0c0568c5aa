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
//!
//! **Stored margins.** A cell certified by the scan can keep a margin ([`Margins`]) that
//! lets the trials of later Newton steps skip the scan when their weights moved little
//! ([`Power::hinted_cell`], the proof there): the same cells bit for bit.

use std::ops::ControlFlow;

use crate::geometry::{add, dot, next_in_box, norm2, sub, Aabb, HalfSpace};

use super::convex_cell::{ConvexCell, Face};

/// The weights of a power diagram, one per site of the computation (a periodic box's
/// images carry their site's), `L²`: cell `i` is `{x : |x − z_i|² − w_i ≤ |x − z_j|² − w_j}`.
#[derive(Debug, Clone)]
pub(super) struct Power<'a, const D: usize> {
    weights: &'a [f64],
    /// `max_j w_j`.
    max: f64,
    grid: MaxGrid<D>,
    /// Stored margins of earlier diagrams of the same sites and, per iterate they were
    /// taken at, `max_j (w_j − w_k,j)` ([`Power::hinted_cell`]).
    margins: Option<&'a Margins<D>>,
    margin_dmax: &'a [f64],
    /// Take the margins of the cells certified by their scan.
    record: bool,
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
    /// Per axis `k`, the blocks' boundaries `lo_k + i·side` for `i` in `0..=dims_k`, the
    /// first `−∞` and the last `+∞` (the edge blocks reach out to infinity): `near2`, a
    /// tenth of the scans' instructions, reads them rather than computing them with a
    /// branch at each use (the same operations: the same values bit for bit).
    edges: [Vec<f64>; D],
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

/// The grid of [`MaxGrid`] over some sites, kept for the power diagrams of the same sites
/// with other weights ([`Power::on_blocks`]): locating the sites in it again took 1.4% of
/// a transport's instructions at 10,000 sites (its 7 power diagrams).
#[derive(Debug, Clone)]
pub(super) struct SiteBlocks<const D: usize>(MaxGrid<D>);

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
    fn reweighted(&self, weights: &[f64]) -> Self {
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
    fn near2(&self, first: [usize; D], last: [usize; D], p: [f64; D]) -> f64 {
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
    fn scan<S, B, T: Copy>(
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
    fn cube(&self, p: [f64; D], outer: f64) -> ([usize; D], [usize; D]) {
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

/// How far a later trial's cell may lie from the cell a margin was taken on
/// ([`Power::hinted_cell`]), in blocks of [`MaxGrid`]: `E`. The scan that takes a margin
/// reads the sites within the reach of a cell grown by this much.
const MARGIN_REACH: f64 = 0.01;

/// How much a later trial may raise a weight against the cell's own, relative to the
/// margin's weights, in squared blocks of [`MaxGrid`]: `B` (about 0.08 mean cell areas).
const MARGIN_WEIGHT: f64 = 0.01;

/// Relative margin of the stored-margin test for the rounding of its terms.
const MARGIN_ROUNDING: f64 = 1e-9;

/// One cell's stored margin as a trial reads it ([`Power::hinted_cell`]): taken at the
/// weights `w_a`, with `dmax = max_j (w'_j − w_a,j)` of the trial's weights `w'`.
#[derive(Debug, Clone, Copy)]
pub(super) struct StoredMargin<'m, const D: usize> {
    /// The least `f_j` over the cell's vertices and its listed non-face sites, `L²`.
    pub s: f64,
    /// The largest distance of those sites from the cell's, `L`.
    pub q: f64,
    /// The cell's own weight `w_a,i`, `L²`.
    pub own: f64,
    /// `max_j (w'_j − w_a,j)`, `L²`.
    pub dmax: f64,
    /// The cell's vertices, relative to its site.
    pub vertices: &'m [[f64; D]],
    /// The sites of its faces.
    pub faces: &'m [u32],
}

/// A cell's margin being taken ([`Power::hinted_cell`] with `record`), and its buffers.
#[derive(Debug, Clone, Default)]
pub(super) struct MarginScratch<const D: usize> {
    /// A record was taken for the last cell.
    pub recorded: bool,
    /// The last cell was certified by its stored margin.
    pub skipped: bool,
    pub s: f64,
    pub q: f64,
    pub own: f64,
    pub vertices: Vec<[f64; D]>,
    pub faces: Vec<u32>,
    /// The listed sites, as indices into the grid's members, each with a lower bound of
    /// its `f_j` over the cell (`−∞` if none was computed).
    list: Vec<(u32, f64)>,
}

/// Stored margins of some cells of a power diagram, in index order, for the trials of
/// later Newton steps of optimal transport (`Power::hinted_cell`, `optimise::transport`).
#[derive(Debug, Clone, Default)]
pub struct Margins<const D: usize> {
    /// Cells of the diagram that took these margins certified by a stored one instead.
    skipped: usize,
    /// Per cell, the iterate its margin was taken at (its caller's numbering), or
    /// `u32::MAX` for none.
    iterate: Vec<u32>,
    own: Vec<f64>,
    s: Vec<f64>,
    q: Vec<f64>,
    vertex_offsets: Vec<usize>,
    vertices: Vec<[f64; D]>,
    face_offsets: Vec<usize>,
    faces: Vec<u32>,
}

/// The margins one batch of cells took, in its visiting order.
#[derive(Debug, Clone, Default)]
pub(super) struct MarginRows<const D: usize> {
    /// Cells certified by their stored margin.
    skipped: usize,
    sites: Vec<u32>,
    values: Vec<[f64; 3]>,
    vertex_counts: Vec<u32>,
    vertices: Vec<[f64; D]>,
    face_counts: Vec<u32>,
    faces: Vec<u32>,
}

impl<const D: usize> MarginRows<D> {
    /// Append cell `i`'s record from `r`, if it took one.
    pub(super) fn push(&mut self, i: usize, r: &MarginScratch<D>) {
        self.skipped += usize::from(r.skipped);
        if !r.recorded {
            return;
        }
        self.sites.push(i as u32);
        self.values.push([r.s, r.q, r.own]);
        self.vertex_counts.push(r.vertices.len() as u32);
        self.vertices.extend_from_slice(&r.vertices);
        self.face_counts.push(r.faces.len() as u32);
        self.faces.extend_from_slice(&r.faces);
    }
}

impl<const D: usize> Margins<D> {
    /// No margins for `n` cells.
    pub fn none(n: usize) -> Self {
        Self {
            skipped: 0,
            iterate: vec![u32::MAX; n],
            own: vec![0.0; n],
            s: vec![0.0; n],
            q: vec![0.0; n],
            vertex_offsets: vec![0; n + 1],
            vertices: Vec::new(),
            face_offsets: vec![0; n + 1],
            faces: Vec::new(),
        }
    }

    /// The cells' number.
    pub fn len(&self) -> usize {
        self.iterate.len()
    }

    /// Cell `i`'s margin, taken at iterate `iterate[i]`, when it has one.
    pub fn iterate(&self, i: usize) -> Option<u32> {
        self.iterate.get(i).copied().filter(|&k| k != u32::MAX)
    }

    /// Cells of the diagram that took these margins certified by a stored one instead of
    /// their scan.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// The records of `rows` (one diagram's batches) for `n` cells, taken at `iterate`
    /// (`u32::MAX`: none were taken, the cells certified by margins are counted).
    pub(super) fn gather<'r>(
        n: usize,
        iterate: u32,
        rows: impl Iterator<Item = &'r MarginRows<D>> + Clone,
    ) -> Self {
        let mut m = Self::none(n);
        for r in rows.clone() {
            m.skipped += r.skipped;
            for (k, &i) in r.sites.iter().enumerate() {
                let i = i as usize;
                m.iterate[i] = iterate;
                [m.s[i], m.q[i], m.own[i]] = r.values[k];
                m.vertex_offsets[i + 1] = r.vertex_counts[k] as usize;
                m.face_offsets[i + 1] = r.face_counts[k] as usize;
            }
        }
        for i in 0..n {
            m.vertex_offsets[i + 1] += m.vertex_offsets[i];
            m.face_offsets[i + 1] += m.face_offsets[i];
        }
        m.vertices = vec![[0.0; D]; m.vertex_offsets[n]];
        m.faces = vec![0; m.face_offsets[n]];
        for r in rows {
            let (mut at_v, mut at_f) = (0, 0);
            for (k, &i) in r.sites.iter().enumerate() {
                let i = i as usize;
                let (v, f) = (r.vertex_counts[k] as usize, r.face_counts[k] as usize);
                let (to_v, to_f) = (m.vertex_offsets[i], m.face_offsets[i]);
                m.vertices[to_v..to_v + v].copy_from_slice(&r.vertices[at_v..at_v + v]);
                m.faces[to_f..to_f + f].copy_from_slice(&r.faces[at_f..at_f + f]);
                at_v += v;
                at_f += f;
            }
        }
        m
    }

    /// Each cell's margin from `fresh` where it has one, else from `self`.
    pub fn merged(&self, fresh: &Self) -> Self {
        let n = fresh.len();
        let pick = |i: usize| {
            if fresh.iterate(i).is_some() || self.len() != n {
                fresh
            } else {
                self
            }
        };
        let mut m = Self::none(n);
        for i in 0..n {
            let from = pick(i);
            m.iterate[i] = from.iterate[i];
            m.s[i] = from.s[i];
            m.q[i] = from.q[i];
            m.own[i] = from.own[i];
            let v = from.vertex_offsets[i]..from.vertex_offsets[i + 1];
            m.vertices.extend_from_slice(&from.vertices[v]);
            m.vertex_offsets[i + 1] = m.vertices.len();
            let f = from.face_offsets[i]..from.face_offsets[i + 1];
            m.faces.extend_from_slice(&from.faces[f]);
            m.face_offsets[i + 1] = m.faces.len();
        }
        m
    }

    /// Cell `i`'s margin for a trial whose weights exceed iterate `k`'s by at most
    /// `dmax[k]` (`max_j (w'_j − w_k,j)`).
    pub(super) fn get(&self, i: usize, dmax: &[f64]) -> Option<StoredMargin<'_, D>> {
        let k = self.iterate(i)? as usize;
        Some(StoredMargin {
            s: self.s[i],
            q: self.q[i],
            own: self.own[i],
            dmax: *dmax.get(k)?,
            vertices: &self.vertices[self.vertex_offsets[i]..self.vertex_offsets[i + 1]],
            faces: &self.faces[self.face_offsets[i]..self.face_offsets[i + 1]],
        })
    }
}

impl<'a, const D: usize> Power<'a, D> {
    /// Weights indexed like `sites` (all finite, checked by the caller).
    pub(super) fn new(weights: &'a [f64], sites: &[[f64; D]]) -> Self {
        Self::on_grid(weights, MaxGrid::new(sites, weights))
    }

    /// [`Power::new`] for the sites whose grid `blocks` holds (another diagram's,
    /// [`Power::blocks`]): the same grid, the sites not located in it again.
    pub(super) fn on_blocks(weights: &'a [f64], blocks: &SiteBlocks<D>) -> Self {
        Self::on_grid(weights, blocks.0.reweighted(weights))
    }

    /// This diagram's grid, for the power diagrams of the same sites with other weights
    /// ([`Power::on_blocks`]).
    pub(super) fn blocks(&self) -> SiteBlocks<D> {
        SiteBlocks(self.grid.clone())
    }

    /// The weights `weights` with `grid` holding them.
    fn on_grid(weights: &'a [f64], grid: MaxGrid<D>) -> Self {
        let max = weights.iter().fold(f64::NEG_INFINITY, |m, &w| m.max(w));
        Self {
            weights,
            max,
            grid,
            margins: None,
            margin_dmax: &[],
            record: false,
        }
    }

    /// Weights indexed like `sites`, some of the sites of the problem `whole` (a part and
    /// its halo): the planes, bounds and order of [`Power::new`] over the whole problem.
    pub(super) fn in_part(weights: &'a [f64], sites: &[[f64; D]], whole: &PowerWhole<D>) -> Self {
        Self {
            weights,
            max: whole.max_weight,
            grid: MaxGrid::of_whole(sites, weights, whole, true),
            margins: None,
            margin_dmax: &[],
            record: false,
        }
    }

    /// These weights with the stored margins `margins` (`dmax` per iterate, see
    /// [`Margins::get`]) and, with `record`, taking margins ([`Power::hinted_cell`]).
    pub(super) fn with_margins(
        self,
        margins: Option<&'a Margins<D>>,
        dmax: &'a [f64],
        record: Option<u32>,
    ) -> Self {
        Self {
            margins,
            margin_dmax: dmax,
            record: record.is_some(),
            ..self
        }
    }

    /// Cell `i`'s stored margin, when it has one.
    pub(super) fn margin(&self, i: usize) -> Option<StoredMargin<'a, D>> {
        self.margins?.get(i, self.margin_dmax)
    }

    /// Whether the cells take margins.
    pub(super) fn records(&self) -> bool {
        self.record
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
        let reach2_of = |&(r, radius2): &(f64, f64), w: f64, first, last, _: Option<f64>| {
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
    ///
    /// **Stored margins** (`docs/results/transport.txt` §11, §14). With `record`, a cell
    /// certified by the whole scan is also described for later trials ([`MarginScratch`]):
    /// the scan reads every site within the reach for a cell grown by `E` and weights
    /// raised by `B` ([`MARGIN_REACH`], [`MARGIN_WEIGHT`]) into its list, and the record
    /// holds the final vertices `V_a`, the sites of the cell's faces `F_a`, the least
    /// `s = min f_j(v)` over `v ∈ V_a` and the listed sites `j ∉ F_a ∪ {i}`, and their
    /// largest `Q = |q_j|` (the clips are those of the scan without `record`: the same cell
    /// bit for bit). With `margin`, such a record taken at weights `w_a`, a later cell
    /// `K'` of weights `w' = w_a + d` (the hint's clips, as above) skips the scan when `F_a`
    /// is in the hint, every vertex of `K'` lies within `e ≤ E` of a vertex of `V_a`,
    /// `b = max_j d_j − d_i ≤ B` and `s − 2Qe − b` exceeds a rounding margin. Why it is the
    /// exact cell and the scan would clip nothing: for a vertex `v'` of `K'` and its nearest
    /// `v ∈ V_a`, a listed `j` outside the hint has `f'_j(v') = f_j(v) − 2q_j·(v' − v) −
    /// (d_j − d_i) ≥ s − 2Qe − b > 0`; an unlisted `j` lies beyond `ρ_a + E +
    /// √((R_a + E)² + W − w_a,i + B)` of `c` (`W` its block's largest `w_a`), while `|v' − c|
    /// ≤ ρ_a + e` and `|v'| ≤ R_a + e`, so `f'_j(v') > 0` as in (b). Every clip of the scan
    /// would thus find every vertex inside and return `false` without touching the cell.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn hinted_cell<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        start: &Aabb<D>,
        sites: &[[f64; D]],
        i: usize,
        neighbours: &[u32],
        margin: Option<&StoredMargin<'_, D>>,
        record: &mut MarginScratch<D>,
        take: bool,
    ) -> bool {
        record.recorded = false;
        record.skipped = false;
        record.list.clear();
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
        if margin.is_some_and(|m| self.margin_holds(cell, i, neighbours, m)) {
            record.skipped = true;
            return true;
        }
        let (rho, radius2) = (rho2.sqrt(), cell.max_dist2());
        let Some(mut outer) = cut_reach(rho, radius2, self.slack(i)) else {
            return true; // no site can cut (cannot happen for a cell holding a point)
        };
        let recording = take;
        let (grow, raise) = (
            MARGIN_REACH * grid.side,
            MARGIN_WEIGHT * grid.side * grid.side,
        );
        // The reach of a cell grown by `grow`, its weights raised by `raise`.
        let wide = |rho: f64, radius2: f64, excess: f64| {
            let r = radius2.sqrt() + grow;
            cut_reach(rho + grow, r * r, excess + raise)
        };
        if recording {
            outer = outer.max(wide(rho, radius2, self.slack(i)).unwrap_or(0.0));
        }
        let at = add(site, centre);
        let (from, to) = grid.cube(at, outer);
        // Within the first squared distance of `c` a site of weight at most `w` in the
        // blocks `first..=last` may cut (−∞ when the blocks lie beyond it, or their coarse
        // block did); within the second it is listed (the first without `record`). `None`
        // when the blocks lie beyond both.
        let reach2_of =
            |&(rho, radius2): &(f64, f64), w: f64, first, last, coarse: Option<(f64, f64)>| {
                let near2 = grid.near2(first, last, at);
                let cut2 = if coarse.is_some_and(|(c, _)| c == f64::NEG_INFINITY) {
                    None
                } else {
                    cut_reach(rho, radius2, w - own).map(|r| r * r * (1.0 + ROUNDING))
                };
                let cut2 = cut2.filter(|&r2| near2 < r2).unwrap_or(f64::NEG_INFINITY);
                if !recording {
                    return (cut2 > f64::NEG_INFINITY).then_some((cut2, cut2));
                }
                let wide2 = wide(rho, radius2, w - own)
                    .map_or(f64::NEG_INFINITY, |r| r * r * (1.0 + ROUNDING))
                    .max(cut2);
                (near2 < wide2).then_some((cut2, wide2))
            };
        let listed = &mut record.list;
        let mut state = (rho, radius2);
        let scanned = grid.scan(
            from,
            to,
            &mut state,
            reach2_of,
            |(rho, radius2), k, (block2, wide2)| {
                let q = sub(grid.member_sites[k], site);
                let from_centre = sub(q, centre);
                let d2 = norm2(from_centre);
                if d2 >= wide2 {
                    return ControlFlow::Continue(());
                }
                // (b) for the site's own weight, at most the block's.
                if d2 >= block2 {
                    if recording {
                        listed.push((k as u32, f64::NEG_INFINITY));
                    }
                    return ControlFlow::Continue(());
                }
                let j = grid.members[k];
                let delta = grid.member_weights[k] - own;
                let (q2, qc) = (norm2(q), dot(q, centre));
                let low = q2 - 2.0 * qc - delta;
                let ball = 2.0 * *rho * q2.sqrt();
                // (a), with a margin for the rounding of every term.
                let margin = HINT_ROUNDING * (q2 + 2.0 * qc.abs() + delta.abs() + ball);
                if recording {
                    // A lower bound of f_j over the ball holding the cell, hence over its
                    // final vertices: `take_margin` evaluates those only below it.
                    listed.push((k as u32, low - ball - margin));
                }
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
            ControlFlow::Continue(()) => {
                if take {
                    self.take_margin(cell, site, i, record);
                }
                true
            }
        }
    }

    /// The record of cell `i` (its final `cell`, site at `site`) from the sites its scan
    /// listed in `r.list` ([`Power::hinted_cell`]).
    fn take_margin<C: ConvexCell<D>>(
        &self,
        cell: &C,
        site: [f64; D],
        i: usize,
        r: &mut MarginScratch<D>,
    ) {
        let grid = &self.grid;
        let own = self.weights[i];
        r.faces.clear();
        cell.for_each_plane(|face, _| {
            if let Face::Neighbor(j) = face {
                r.faces.push(j);
            }
        });
        r.vertices.clear();
        r.vertices.extend_from_slice(cell.vertices());
        let (mut least, mut q2max) = (f64::INFINITY, 0.0_f64);
        // The sites without a positive bound first, then the others whose bound is below
        // the least value so far (the rest cannot lower it).
        for bounded in [false, true] {
            for &(k, lower) in &r.list {
                if (lower > 0.0) != bounded {
                    continue;
                }
                let k = k as usize;
                let j = grid.members[k];
                if j as usize == i || r.faces.contains(&j) {
                    continue;
                }
                let q = sub(grid.member_sites[k], site);
                let q2 = norm2(q);
                q2max = q2max.max(q2);
                if q2 == 0.0 {
                    least = f64::NEG_INFINITY; // a coinciding site: never skip the scan
                }
                if lower >= least {
                    continue;
                }
                let delta = grid.member_weights[k] - own;
                for v in cell.vertices() {
                    least = least.min(q2 - 2.0 * dot(q, *v) - delta);
                }
            }
        }
        r.s = least;
        r.q = q2max.sqrt() * (1.0 + MARGIN_ROUNDING);
        r.own = own;
        r.recorded = true;
    }

    /// Whether the record `m` proves the hint-clipped `cell` of site `i` the exact cell
    /// ([`Power::hinted_cell`]).
    fn margin_holds<C: ConvexCell<D>>(
        &self,
        cell: &C,
        i: usize,
        neighbours: &[u32],
        m: &StoredMargin<'_, D>,
    ) -> bool {
        if m.vertices.is_empty() || !m.faces.iter().all(|j| neighbours.contains(j)) {
            return false;
        }
        let side = self.grid.side;
        let d_i = self.weights[i] - m.own;
        let b = m.dmax - d_i + MARGIN_ROUNDING * (m.dmax.abs() + d_i.abs());
        if b.is_nan() || b > MARGIN_WEIGHT * side * side {
            return false;
        }
        // The largest over the cell's vertices of the squared distance to the nearest
        // stored vertex. `min` and `max` round nothing, so the order of the reads is free
        // and a vertex stops at the first stored vertex within the running largest: it
        // cannot raise it (the same `e2` bit for bit). Each vertex starts at the stored
        // vertex of its own index, its likely nearest (the cell moves little between solves).
        let stored = m.vertices;
        let e2 = cell
            .vertices()
            .iter()
            .enumerate()
            .fold(0.0_f64, |e2, (k, &v)| {
                let (head, tail) = stored.split_at(k % stored.len());
                let mut near2 = f64::INFINITY;
                for &a in tail.iter().chain(head) {
                    near2 = near2.min(norm2(sub(v, a)));
                    if near2 <= e2 {
                        return e2;
                    }
                }
                e2.max(near2)
            });
        let e = e2.sqrt() * (1.0 + MARGIN_ROUNDING);
        if e.is_nan() || e > MARGIN_REACH * side {
            return false;
        }
        let spread = 2.0 * m.q * e;
        let r = cell.max_dist2().sqrt();
        let scale = m.s.abs() + spread + b.abs() + m.q * (m.q + 2.0 * (r + e));
        m.s - spread - b > MARGIN_ROUNDING * scale
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
