//! Newton's method on the CVT energy in a trust region: the exact
//! [`Hessian`](super::hessian::Hessian) from the same diagram as the gradient, and a step
//! from truncated conjugate gradients preconditioned by `1/(2 m_i)` (Steihaug 1983;
//! Nocedal and Wright, *Numerical Optimization*, Algorithms 4.1 and 7.2).
//!
//! Why: L-BFGS spends most of its diagrams in a long, flat tail in which the sites slowly
//! rearrange (1,000 random sites in the square: 407 diagrams, the energy still falling by
//! 1e-3 of itself after 130 of them). The Hessian sees that valley's curvature at once.
//! Its cost per iteration is small beside a diagram: each face's second moment, and a
//! sparse product with about 7 (2D) or 16 (3D) blocks per row per CG iteration.
//!
//! Why a trust region rather than the line search: the Hessian is indefinite for much of
//! the run (CG met negative curvature after 3 to 5 products on 10,000 random sites in the
//! star), and a line search along the truncated direction needed 2 diagrams per step. The
//! region follows negative curvature to its edge and rejects a step with one diagram.
//!
//! The region is a ball in the norm `‖p‖_M = √(Σ 2 m_i |p_i|²)` of the preconditioner,
//! each site's term scaled by its stiffness (below), first as large as the Lloyd step. CG
//! stops inside it at relative residual `η` ([`forcing`]: the forcing sequence of Nocedal
//! and Wright, made scale-free with the RMS gap). Trials that put
//! a site outside the domain are rejected like steps that raise the energy. Near the
//! minimum, where energy differences are round-off, a step is judged by the gradient
//! instead (module docs of [`super`], "Round-off").
//!
//! **Sampled density.** With a density sampled by a quadrature rule on the sphere, the
//! energy is not the potential of the gradient: each is the rule's sum over the cell's
//! fan, and the rule's error moves with the sites. On the 800/3,200 km band (161 sites,
//! stalled at RMS gap 2.6e-3) the energy's derivative along `−g` missed `g·v` by 24%,
//! along a random direction by 10x; near the energy's minimum the gradient is not small.
//! So a step there (`by_gradient`) is also accepted when the gradient's dual norm falls by
//! [`ACCEPT`] of what the model `g + Hs` predicts, and the region grows by the better of
//! the two ratios. The hierarchy's 78-site level of the 30/240 km band (30 to 240 km
//! cells) then reaches RMS gap 1e-2 in 84 iterations instead of stalling at 3.8e-2 after
//! 100 (`tests/test_sphere_density.py`). It does not cure the coarsest graded problems:
//! on cells wider than the density's ramp the Hessian (of the exact energy) is far from
//! the Jacobian of the sampled gradient and Newton still stalls near gap 1e-3.
//!
//! **Stiffness.** Late in a run the gradient sits on a few sites (on 10,000 random sites in
//! the star, 1% of the sites carry half of `‖g‖²` from the 20th step on) where cells
//! rearrange and the quadratic model holds only over short moves, while the rest of the
//! sites still drift by tenths of a spacing and the model holds for them. One radius for
//! all made everyone crawl at the pace of the worst site. So the region's norm is
//! `‖p‖ = √(Σ 2 m_i w_i |p_i|²)` with a stiffness `w_i ≥ 1` per site: after each trial
//! diagram, a site whose new gradient misses the model's `g_i + (Hs)_i` by more than half
//! of `|(Hs)_i|` gets 4× stiffer, one within a quarter relaxes 2× towards 1. The miss
//! is per site and costs one Hessian product. Diagrams over square 1k and 5k and star 2k
//! and 10k, seeds 7–9: 2,609 → 1,729; ball 1k and 5k, seeds 0–1: 1,090 → 600.

use crate::error::CoreError;
use crate::geometry::norm2;

use super::lbfgs::{dot_rows, mass_preconditioner, moved, Evaluator};
use super::point::Point;
use super::steihaug::{steihaug, step_norm2};
use super::stopping::Measures;

/// Accept a step when the energy falls by at least this fraction of the model's decrease.
const ACCEPT: f64 = 0.1;

/// Grow the region after a step at its edge whose energy fell by more than this fraction
/// of the model's decrease ...
const GOOD: f64 = 0.9;
/// ... by this factor. Nocedal and Wright's 0.75 and 2 grew the region on a step with ratio
/// 0.6-0.8 and the next step was rejected: while cells rearrange, runs cycled through
/// "ratio 1, ratio 0.7, rejected" (one diagram in four wasted). Medians of diagrams over
/// seeds 0-9 (`benchmarks/newton_variants.py`, docs/results/newton_variants.txt):
/// square 1k 97 → 74.5, square 5k 153.5 → 139, star 2k 100 → 89, star 10k 202 → 190.5,
/// ball 1k 137.5 → 116, ball 5k 240 → 207.5, at the same CG work per diagram or less.
const GROW: f64 = 1.5;

/// CG's relative residual `η = min(1/2, √RMS gap)` at a point with `measures`.
///
/// Nocedal and Wright's `min(1/2, √‖g‖)` gives superlinear convergence but depends on the
/// unit; the RMS gap is the gradient per site relative to its cell (`|g_i| / (2 m_i h_i)`),
/// so the same sequence is free of unit and `n`.
pub fn forcing(measures: &Measures) -> f64 {
    measures.rms_gap.sqrt().min(0.5)
}

/// The trust region's radius and per-site stiffness, kept from step to step.
#[derive(Debug, Clone, Default)]
pub struct TrustRegion {
    radius: Option<f64>,
    /// Per-site factor `w_i ≥ 1` of the region's norm (module docs, "Stiffness").
    stiffness: Vec<f64>,
    /// The first region is as large as the model's own step ([`TrustRegion::open`]).
    open_start: bool,
}

impl TrustRegion {
    /// A region whose first radius is the length of the model's unconstrained step
    /// (truncated CG without a bound), when CG meets no negative curvature; the usual
    /// Lloyd-step radius otherwise, and from then on the usual updates. For a domain
    /// without boundary whose runs often start near a CVT ([`DomainKind::trusts_newton`]:
    /// the sphere from icosahedral sites, whose Newton step is ~30 Lloyd steps long and
    /// took five doubling steps to reach: 40,962 sites converged in 5 diagrams, not 9).
    ///
    /// [`DomainKind::trusts_newton`]: crate::DomainKind::trusts_newton
    pub fn open() -> Self {
        Self {
            open_start: true,
            ..Self::default()
        }
    }
}

/// One Newton step from `point` (whose diagram carries the Hessian) in `region`: the next
/// point, or `None` if `max_trials` diagrams found no
/// acceptable step. Sites marked `frozen` do not move: those pinned against the boundary
/// ([`super::lloyd::pinned_sites`]), whose gradient cannot vanish and would otherwise
/// spend the region on moves out of the domain (on 1,000 sites of a polygon with notches
/// the run did not converge in 2,000 steps). `hold` shortens moves that would leave the
/// domain; `eval` computes a diagram, `None` when the sites are infeasible. `noise` is the
/// energy's round-off. `by_gradient`: a step is also accepted when the gradient falls as
/// the model predicts (module docs, "Sampled density").
#[allow(clippy::too_many_arguments)] // the step's inputs, each used once
pub fn step<const D: usize>(
    point: &Point<D>,
    frozen: &[bool],
    region: &mut TrustRegion,
    forcing: f64,
    max_trials: usize,
    noise: f64,
    by_gradient: bool,
    hold: &dyn Fn(&mut [[f64; D]]),
    eval: &mut Evaluator<'_, D>,
) -> Result<Option<Point<D>>, CoreError> {
    // A zero weight keeps a site out of the CG iteration: its moves stay zero.
    let mut precondition = mass_preconditioner(point);
    for (w, &f) in precondition.iter_mut().zip(frozen) {
        if f {
            *w = 0.0;
        }
    }
    let g_norm2 = gradient_norm2(&point.gradient, &precondition);
    let n = point.sites.len();
    if region.stiffness.len() != n {
        region.stiffness = vec![1.0; n];
    }
    let mut radius = region.radius.unwrap_or_else(|| g_norm2.sqrt());
    if std::mem::take(&mut region.open_start) {
        let free = steihaug(
            &point.gradient,
            &mut |v, out| point.hessian_product_into(v, out),
            &precondition,
            f64::INFINITY,
            forcing,
        );
        if !free.at_edge {
            // Slightly larger: the same CG iterations then end inside the region.
            radius = step_norm2(&free.moves, &precondition).sqrt() * (1.0 + 1e-9);
        }
    }
    for _ in 0..max_trials {
        // The region's norm and CG's preconditioner must match (Steihaug).
        let weighted: Vec<f64> = precondition
            .iter()
            .zip(&region.stiffness)
            .map(|(p, w)| p / w)
            .collect();
        let mut model = steihaug(
            &point.gradient,
            &mut |v, out| point.hessian_product_into(v, out),
            &weighted,
            radius,
            forcing,
        );
        let before = model.moves.clone();
        hold(&mut model.moves);
        let Some(hs) = point.hessian_product(&model.moves) else {
            break;
        };
        if model.moves != before {
            // Held moves are another step: its own model decrease.
            model.decrease =
                -(dot_rows(&point.gradient, &model.moves) + 0.5 * dot_rows(&model.moves, &hs));
        }
        let length = step_norm2(&model.moves, &weighted).sqrt();
        let trial = eval(moved(&point.sites, 1.0, &model.moves))?;
        let Some(trial) = trial else {
            radius = 0.25 * length;
            continue;
        };
        adapt_stiffness(&mut region.stiffness, point, &trial, &hs);
        let actual = point.energy - trial.energy;
        let mut accepted = if model.decrease <= noise * point.energy.abs() {
            // Round-off: no energy rise beyond it, and a smaller gradient.
            actual >= -noise * point.energy.abs()
                && gradient_norm2(&trial.gradient, &precondition) < g_norm2
        } else {
            actual >= ACCEPT * model.decrease
        };
        let mut ratio = actual / model.decrease;
        if by_gradient {
            // The model's gradient after the step is g + Hs: its predicted fall of the
            // gradient's dual norm against the actual one (module docs, "Sampled density").
            let predicted = g_norm2 - gradient_norm2(&model_gradient(point, &hs), &precondition);
            if predicted > 0.0 {
                let fell = g_norm2 - gradient_norm2(&trial.gradient, &precondition);
                let gradient_ratio = fell / predicted;
                accepted |= gradient_ratio >= ACCEPT;
                ratio = ratio.max(gradient_ratio);
            }
        }
        // Nocedal and Wright's Algorithm 4.1 with a stricter, smaller growth ([`GROW`]).
        // Shrinking to 1/2 instead of 1/4 cost 10-45% more diagrams on 10,000 sites in the
        // star.
        if !accepted || ratio < 0.25 {
            radius = 0.25 * length;
        } else if ratio > GOOD && model.at_edge {
            radius *= GROW;
        }
        if accepted {
            region.radius = Some(radius);
            return Ok(Some(trial));
        }
    }
    region.radius = None;
    Ok(None)
}

/// The model's gradient `g + Hs` after the step `s` from `point`, `hs = Hs`.
fn model_gradient<const D: usize>(point: &Point<D>, hs: &[[f64; D]]) -> Vec<[f64; D]> {
    (point.gradient.iter().zip(hs))
        .map(|(g, h)| std::array::from_fn(|k| g[k] + h[k]))
        .collect()
}

/// Site `i`'s model failed when its gradient after the step is farther than this from the
/// model's `g_i + (Hs)_i`, relative to the model's change `|(Hs)_i|` plus a floor.
const MODEL_FAILED: f64 = 0.5;
/// Site `i`'s model held when its gradient after the step is nearer than this (same units).
const MODEL_HELD: f64 = 0.25;
/// The floor, a fraction of the RMS of `|(Hs)_i|`: sites the step barely touched are not
/// judged on round-off.
const STIFFNESS_FLOOR: f64 = 0.3;
/// How a failed site's stiffness grows.
const STIFFEN: f64 = 4.0;
/// How a held site's stiffness relaxes back towards 1.
const RELAX: f64 = 0.5;
/// Bound on the stiffness: a site never gets stuck for good.
const MAX_STIFFNESS: f64 = 1e8;

/// Stiffen the region at the sites where the quadratic model of the step `s` from `point`
/// to `trial` failed, and relax it where the model held (module docs, "Stiffness").
/// `hs` is `H s`.
fn adapt_stiffness<const D: usize>(
    stiffness: &mut [f64],
    point: &Point<D>,
    trial: &Point<D>,
    hs: &[[f64; D]],
) {
    let rms = (hs.iter().map(|v| norm2(*v)).sum::<f64>() / hs.len().max(1) as f64).sqrt();
    let floor = STIFFNESS_FLOOR * rms;
    for (i, w) in stiffness.iter_mut().enumerate() {
        let miss: [f64; D] =
            std::array::from_fn(|k| trial.gradient[i][k] - point.gradient[i][k] - hs[i][k]);
        let error = norm2(miss).sqrt() / (norm2(hs[i]).sqrt() + floor);
        if error > MODEL_FAILED {
            *w = (*w * STIFFEN).min(MAX_STIFFNESS);
        } else if error < MODEL_HELD {
            *w = (*w * RELAX).max(1.0);
        }
    }
}

/// `Σ_i w_i |g_i|²` with `w = 1/(2 m)`: the squared dual norm of a gradient.
fn gradient_norm2<const D: usize>(g: &[[f64; D]], w: &[f64]) -> f64 {
    g.iter().zip(w).map(|(x, &w)| w * norm2(*x)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagram::Diagram;

    fn point(gradient: Vec<[f64; 2]>) -> Point<2> {
        Point {
            sites: vec![[0.0; 2]; gradient.len()],
            diagram: Diagram::default(),
            hessian: None,
            energy: 0.0,
            gradient,
        }
    }

    #[test]
    fn stiffness_grows_where_the_model_failed_and_relaxes_where_it_held() {
        let g = vec![[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]];
        let hs = [[1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]];
        // New gradients: the model's g + Hs exactly; missing it by 3|Hs|; by 0.4|Hs| (in
        // between); by 0.1|Hs|.
        let misses = [0.0, 3.0, 0.4, 0.1];
        let trial: Vec<[f64; 2]> = g
            .iter()
            .zip(misses)
            .map(|(g, m)| [g[0] + 1.0 + m, g[1]])
            .collect();
        let mut stiffness = vec![4.0, 4.0, 4.0, 1.0];
        adapt_stiffness(&mut stiffness, &point(g), &point(trial), &hs);
        // The floor (0.3 of the RMS |Hs|, here 0.3) widens |Hs| = 1 to 1.3.
        assert_eq!(stiffness, vec![2.0, 16.0, 4.0, 1.0]);
    }
}
