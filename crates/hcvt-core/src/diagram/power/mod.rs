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

mod margins;
mod max_grid;

pub use margins::Margins;
pub(super) use margins::{MarginRows, MarginScratch, StoredMargin};
use max_grid::MaxGrid;
pub use max_grid::PowerWhole;
pub(super) use max_grid::SiteBlocks;

use std::ops::ControlFlow;

use crate::geometry::{add, dot, norm2, sub, Aabb, HalfSpace};

use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;

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

/// `R + √(R² + Δ)` for the cell radius `r` (`r2 = R²`) and a weight excess `Δ = w_j − w_i`:
/// no site of that excess farther from the site can cut the cell; `None` when none can.
fn cut_reach(r: f64, r2: f64, excess: f64) -> Option<f64> {
    let s = r2 + excess;
    (s >= 0.0).then(|| r + s.sqrt())
}

/// Relative margin on a squared reach for the rounding of its roots.
const ROUNDING: f64 = 1e-12;

/// `r2`, or `bound2` when that is smaller (a `NaN` `r2` kept): a cell's squared radius
/// about its site, bounded by that of its part in the domain ([`InDomain`]).
pub(super) fn at_most(r2: f64, bound2: f64) -> f64 {
    if r2 > bound2 {
        bound2
    } else {
        r2
    }
}

/// The part of a power cell in a convex domain, for its bounds only: a copy of the cell
/// cut by the boundary planes near it ([`super::DomainKind::cut_convex`]). The cell keeps
/// the power diagram's faces (its boundary is measured by [`super::DomainKind::clip`], which
/// also measures a cell without its site), but no point of it outside the copy is measured,
/// so the copy's radius bounds how far the cell must look for the sites that cut what is.
/// Without it a cell at a ball's boundary reached out to the corners of its box: at 20,000
/// sites 3% of a transport trial's cells streamed most of the sites and took two thirds of
/// its time (docs/results/transport.txt §23).
pub(super) struct InDomain<'b, const D: usize, K, C> {
    domain: &'b K,
    /// The cell's site, `L`.
    site: [f64; D],
    copy: &'b mut Option<C>,
    candidates: &'b mut Vec<u32>,
}

impl<'b, const D: usize, K: DomainKind<D>, C: ConvexCell<D>> InDomain<'b, D, K, C> {
    /// The parts of the cells of `site` (strictly inside the convex `domain`), cut in
    /// `copy`; `candidates` is a buffer.
    pub(super) fn new(
        domain: &'b K,
        site: [f64; D],
        copy: &'b mut Option<C>,
        candidates: &'b mut Vec<u32>,
    ) -> Self {
        Self {
            domain,
            site,
            copy,
            candidates,
        }
    }

    /// `cell` (relative to the site) cut to the domain, in the copy.
    pub(super) fn of(&mut self, cell: &C) -> &C {
        let copy = self.copy.get_or_insert_with(|| cell.clone());
        copy.clone_from(cell);
        self.domain.cut_convex(copy, self.site, self.candidates);
        copy
    }
}

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
    /// index order. Stops at an empty cell. `bound2`: a bound on the squared radius of the
    /// cell's part in the domain ([`InDomain`]; infinite for none).
    pub(super) fn clip_heavier<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        sites: &[[f64; D]],
        i: usize,
        covered2: f64,
        bound2: f64,
    ) {
        let own = self.weights[i];
        let site = sites[i];
        let grid = &self.grid;
        let radius2 = at_most(cell.max_dist2(), bound2);
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
                    *radius2 = at_most(cell.max_dist2(), bound2);
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
    pub(super) fn hinted_cell<C: ConvexCell<D>, K: DomainKind<D>>(
        &self,
        cell: &mut C,
        start: &Aabb<D>,
        sites: &[[f64; D]],
        i: usize,
        neighbours: &[u32],
        margin: Option<&StoredMargin<'_, D>>,
        record: &mut MarginScratch<D>,
        take: bool,
        mut in_domain: Option<InDomain<'_, D, K, C>>,
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
        let span2 = (HINT_SPAN * grid.side).powi(2);
        let spread_about = |cell: &C, centre: [f64; D]| {
            cell.vertices()
                .iter()
                .fold(0.0, |m: f64, &v| m.max(norm2(sub(v, centre))))
        };
        let mut centre = cell.vertex_mean();
        let mut rho2 = spread_about(cell, centre);
        // Bounds on the cell's part in the domain (infinite: the cell's own). A cell spread
        // too far (at a convex domain's boundary, open to its box) is certified over that
        // part alone, without stored margins (their proof reads the whole cell).
        let (mut rho_bound2, mut bound2) = (f64::INFINITY, f64::INFINITY);
        if rho2 > span2 {
            let part = in_domain.as_mut().map(|d| d.of(cell));
            let Some(part) = part.filter(|p| !p.is_empty()) else {
                return false;
            };
            centre = part.vertex_mean();
            rho2 = spread_about(part, centre);
            (rho_bound2, bound2) = (rho2, part.max_dist2());
            if rho2 > span2 {
                return false;
            }
        }
        let bounded = bound2 < f64::INFINITY;
        let spread2 = |cell: &C| at_most(spread_about(cell, centre), rho_bound2);
        if !bounded && margin.is_some_and(|m| self.margin_holds(cell, i, neighbours, m)) {
            record.skipped = true;
            return true;
        }
        let (rho, radius2) = (rho2.sqrt(), at_most(cell.max_dist2(), bound2));
        let Some(mut outer) = cut_reach(rho, radius2, self.slack(i)) else {
            return true; // no site can cut (cannot happen for a cell holding a point)
        };
        let recording = take && !bounded;
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
                    *radius2 = at_most(cell.max_dist2(), bound2);
                }
                ControlFlow::Continue(())
            },
        );
        match scanned {
            ControlFlow::Break(done) => done,
            ControlFlow::Continue(()) => {
                if recording {
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
