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
//! coarse grid ([`MaxGrid`], about 16 sites a block): a site in block `c` can cut only
//! within `R + √(R² + W_c − w_i)` of `z_i` (`W_c` the block's largest weight), and only if
//! the block reaches that near. The stream stops beyond the largest such distance over the
//! blocks, which the global bound limits to a few rings of blocks around the site.

use crate::geometry::{norm2, HalfSpace};

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
const SITES_PER_BLOCK: f64 = 16.0;

/// The largest weight in each block of a uniform grid over the sites' box.
#[derive(Debug, Clone)]
struct MaxGrid<const D: usize> {
    lo: [f64; D],
    /// Side of a block, `L`.
    side: f64,
    dims: [usize; D],
    /// Per block, row-major with axis 0 fastest; `-∞` for an empty block.
    max: Vec<f64>,
}

impl<const D: usize> MaxGrid<D> {
    fn new(sites: &[[f64; D]], weights: &[f64]) -> Self {
        let lo: [f64; D] =
            std::array::from_fn(|k| sites.iter().fold(f64::INFINITY, |m, s| m.min(s[k])));
        let hi: [f64; D] =
            std::array::from_fn(|k| sites.iter().fold(f64::NEG_INFINITY, |m, s| m.max(s[k])));
        let extent: [f64; D] = std::array::from_fn(|k| hi[k] - lo[k]);
        let largest = extent.iter().fold(0.0, |m: f64, &e| m.max(e));
        // The box's volume, its flat sides counted as a hundredth of the largest.
        let volume: f64 = extent.iter().map(|&e| e.max(0.01 * largest)).product();
        let blocks = (sites.len() as f64 / SITES_PER_BLOCK).max(1.0);
        let mut side = (volume / blocks).powf(1.0 / D as f64);
        if !(side > 0.0 && side.is_finite()) {
            side = 1.0; // a single site (or all at one point): one block
        }
        let dims: [usize; D] =
            std::array::from_fn(|k| ((extent[k] / side).floor() as usize + 1).min(1 << 20));
        let mut grid = Self {
            lo,
            side,
            dims,
            max: vec![f64::NEG_INFINITY; dims.iter().product()],
        };
        for (s, &w) in sites.iter().zip(weights) {
            let b = grid.flat(grid.block(s));
            grid.max[b] = grid.max[b].max(w);
        }
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

    /// The largest of `radius(W_c)` over the blocks `c` whose nearest point lies within it
    /// of `p`, each capped by the distance of the block's farthest point; blocks are read
    /// out to `radius(w_max)`, the bound for any block. `radius` is increasing, `None` when
    /// no site of that weight can matter.
    fn reach(&self, p: [f64; D], max: f64, radius: impl Fn(f64) -> Option<f64>) -> f64 {
        let Some(outer) = radius(max) else {
            return 0.0;
        };
        let centre = self.block(&p);
        let span = (outer / self.side).ceil() as usize + 1;
        let from: [usize; D] = std::array::from_fn(|k| centre[k].saturating_sub(span));
        let to: [usize; D] = std::array::from_fn(|k| (centre[k] + span).min(self.dims[k] - 1));
        let mut at = from;
        let mut best: f64 = 0.0;
        loop {
            let w = self.max[self.flat(at)];
            if w > f64::NEG_INFINITY {
                if let Some(r) = radius(w) {
                    let (mut near2, mut far2) = (0.0, 0.0);
                    for k in 0..D {
                        let a = self.lo[k] + at[k] as f64 * self.side;
                        // The last block along an axis reaches the farthest site.
                        let b = if at[k] + 1 == self.dims[k] {
                            f64::INFINITY
                        } else {
                            a + self.side
                        };
                        let a = if at[k] == 0 { f64::NEG_INFINITY } else { a };
                        let gap = (a - p[k]).max(p[k] - b).max(0.0);
                        let far = (p[k] - a).abs().max((b - p[k]).abs());
                        near2 += gap * gap;
                        far2 += far * far;
                    }
                    if near2 < r * r {
                        best = best.max(r.min(far2.sqrt()));
                    }
                }
            }
            // The next block of the cube `from..=to`, axis 0 fastest.
            let mut k = 0;
            loop {
                if k == D {
                    return best;
                }
                if at[k] < to[k] {
                    at[k] += 1;
                    break;
                }
                at[k] = from[k];
                k += 1;
            }
        }
    }
}

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

    /// The squared distance from `site` (site `i`) beyond which no site can cut its cell,
    /// held in the ball of squared radius `radius2` about it (the module's bound, block by
    /// block); a millionth of a millionth more covers the rounding of the roots.
    pub(super) fn reach2(&self, i: usize, site: [f64; D], radius2: f64) -> f64 {
        let own = self.weights[i];
        let r = radius2.sqrt();
        let reach = self.grid.reach(site, self.max, |w| {
            let s = radius2 + (w - own);
            (s >= 0.0).then(|| r + s.sqrt())
        });
        reach * reach * (1.0 + 1e-12)
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
        reach * reach * (1.0 + 1e-12)
    }
}
