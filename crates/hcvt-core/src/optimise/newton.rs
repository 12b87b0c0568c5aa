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

use crate::diagram::Matrix;
use crate::error::CoreError;
use crate::geometry::{dot, norm2};

use super::lbfgs::{axpy, dot_rows, mass_preconditioner, moved, Evaluator};
use super::{Measures, Point};

/// Experimental variants (temporary): comma-separated flags in `HCVT_NEWTON_VARIANT`.
fn variant(flag: &str) -> bool {
    std::env::var("HCVT_NEWTON_VARIANT")
        .map(|v| v.split(',').any(|f| f == flag))
        .unwrap_or(false)
}

fn variant_value(flag: &str) -> Option<f64> {
    let v = std::env::var("HCVT_NEWTON_VARIANT").ok()?;
    v.split(',')
        .find_map(|f| f.strip_prefix(flag).and_then(|x| x.strip_prefix('=')))
        .and_then(|x| x.parse().ok())
}

fn debug(msg: std::fmt::Arguments<'_>) {
    if std::env::var_os("HCVT_NEWTON_DEBUG").is_some() {
        eprintln!("{msg}");
    }
}

/// A per-site preconditioner: `1/(2 m_i)` times the identity, or the inverse of the
/// Hessian's diagonal block where it is well positive definite.
enum Precondition<const D: usize> {
    Mass(Vec<f64>),
    Blocks(Vec<Matrix<D>>),
}

impl<const D: usize> Precondition<D> {
    #[inline]
    fn apply(&self, i: usize, r: [f64; D]) -> [f64; D] {
        match self {
            Self::Mass(w) => r.map(|x| w[i] * x),
            Self::Blocks(b) => std::array::from_fn(|k| dot(b[i][k], r)),
        }
    }

    fn scaled(&self, stiffness: &[f64]) -> Self {
        match self {
            Self::Mass(w) => Self::Mass(w.iter().zip(stiffness).map(|(p, s)| p / s).collect()),
            Self::Blocks(b) => Self::Blocks(
                b.iter()
                    .zip(stiffness)
                    .map(|(m, s)| m.map(|row| row.map(|x| x / s)))
                    .collect(),
            ),
        }
    }

    /// `Σ_i p_iᵀ P_i⁻¹ p_i` over the sites that move.
    fn step_norm2(&self, p: &[[f64; D]]) -> f64 {
        match self {
            Self::Mass(w) => step_norm2(p, w),
            Self::Blocks(b) => p
                .iter()
                .zip(b)
                .filter(|(_, m)| m[0][0] > 0.0)
                .map(|(x, m)| dot(*x, solve_spd(m, *x)))
                .sum(),
        }
    }

    /// `Σ_i g_iᵀ P_i g_i`.
    fn dual_norm2(&self, g: &[[f64; D]]) -> f64 {
        match self {
            Self::Mass(w) => gradient_norm2(g, w),
            Self::Blocks(_) => g
                .iter()
                .enumerate()
                .map(|(i, x)| dot(*x, self.apply(i, *x)))
                .sum(),
        }
    }
}

/// Cholesky factor of a symmetric matrix, `None` unless its pivots exceed `floor`.
fn cholesky<const D: usize>(a: &Matrix<D>, floor: f64) -> Option<Matrix<D>> {
    let mut l = [[0.0; D]; D];
    for r in 0..D {
        for c in 0..=r {
            let mut s = a[r][c];
            for k in 0..c {
                s -= l[r][k] * l[c][k];
            }
            if r == c {
                if !(s > floor) {
                    return None;
                }
                l[r][r] = s.sqrt();
            } else {
                l[r][c] = s / l[c][c];
            }
        }
    }
    Some(l)
}

/// `A⁻¹ b` for a symmetric positive definite `a`.
fn solve_spd<const D: usize>(a: &Matrix<D>, b: [f64; D]) -> [f64; D] {
    let Some(l) = cholesky(a, 0.0) else {
        return [0.0; D];
    };
    let mut y = [0.0; D];
    for r in 0..D {
        let mut s = b[r];
        for k in 0..r {
            s -= l[r][k] * y[k];
        }
        y[r] = s / l[r][r];
    }
    let mut x = [0.0; D];
    for r in (0..D).rev() {
        let mut s = y[r];
        for k in r + 1..D {
            s -= l[k][r] * x[k];
        }
        x[r] = s / l[r][r];
    }
    x
}

/// Block-Jacobi: the inverse of each site's symmetrised diagonal block `H_ii` where its
/// smallest eigenvalue exceeds `floor · 2 m_i`, else `1/(2 m_i)`; zero for frozen sites.
fn block_jacobi<const D: usize>(point: &Point<D>, mass: &[f64], floor: f64) -> Precondition<D> {
    let Some(h) = point.hessian.as_ref() else {
        return Precondition::Mass(mass.to_vec());
    };
    let blocks = h
        .diagonal
        .iter()
        .zip(mass)
        .map(|(b, &w)| {
            let id = |r: usize, c: usize| if r == c { 1.0 } else { 0.0 };
            if w == 0.0 {
                return [[0.0; D]; D];
            }
            let sym: Matrix<D> =
                std::array::from_fn(|r| std::array::from_fn(|c| 0.5 * (b[r][c] + b[c][r])));
            let shifted: Matrix<D> =
                std::array::from_fn(|r| std::array::from_fn(|c| sym[r][c] - floor / w * id(r, c)));
            if cholesky(&shifted, 0.0).is_none() {
                return std::array::from_fn(|r| std::array::from_fn(|c| w * id(r, c)));
            }
            let columns: [[f64; D]; D] =
                std::array::from_fn(|c| solve_spd(&sym, std::array::from_fn(|r| id(r, c))));
            std::array::from_fn(|r| std::array::from_fn(|c| 0.5 * (columns[c][r] + columns[r][c])))
        })
        .collect();
    Precondition::Blocks(blocks)
}

/// Most CG iterations per step.
pub const MAX_CG_ITERATIONS: usize = 200;

/// Accept a step when the energy falls by at least this fraction of the model's decrease.
const ACCEPT: f64 = 0.1;

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
    /// Energies of the last accepted points (non-monotone variant).
    recent: Vec<f64>,
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

/// A step of the quadratic model: the moves, the model's decrease, whether it reached
/// the region's edge.
struct ModelStep<const D: usize> {
    moves: Vec<[f64; D]>,
    decrease: f64,
    at_edge: bool,
    iterations: usize,
}

/// One Newton step from `point` (whose diagram carries the Hessian) in `region`: the next
/// point, or `None` if `max_trials` diagrams found no
/// acceptable step. Sites marked `frozen` do not move: those pinned against the boundary
/// ([`super::lloyd::pinned_sites`]), whose gradient cannot vanish and would otherwise
/// spend the region on moves out of the domain (on 1,000 sites of a polygon with notches
/// the run did not converge in 2,000 steps). `hold` shortens moves that would leave the
/// domain; `eval` computes a diagram, `None` when the sites are infeasible. `noise` is the
/// energy's round-off.
#[allow(clippy::too_many_arguments)] // the step's inputs, each used once
pub fn step<const D: usize>(
    point: &Point<D>,
    frozen: &[bool],
    region: &mut TrustRegion,
    forcing: f64,
    max_trials: usize,
    noise: f64,
    hold: &dyn Fn(&mut [[f64; D]]),
    eval: &mut Evaluator<'_, D>,
) -> Result<Option<Point<D>>, CoreError> {
    // A zero weight keeps a site out of the CG iteration: its moves stay zero.
    let mut mass = mass_preconditioner(point);
    for (w, &f) in mass.iter_mut().zip(frozen) {
        if f {
            *w = 0.0;
        }
    }
    let g_norm2 = gradient_norm2(&point.gradient, &mass);
    let precondition = if variant("bj") {
        block_jacobi(point, &mass, variant_value("bjfloor").unwrap_or(0.1))
    } else {
        Precondition::Mass(mass.clone())
    };
    let n = point.sites.len();
    if region.stiffness.len() != n {
        region.stiffness = vec![1.0; n];
    }
    let nonmonotone = variant_value("nm").map_or(0, |m| m as usize);
    if region.recent.last() != Some(&point.energy) {
        region.recent.push(point.energy);
    }
    if region.recent.len() > nonmonotone.max(1) {
        region.recent.remove(0);
    }
    let reference = region.recent.iter().copied().fold(point.energy, f64::max);
    if let Some(gap) = variant_value("lloyd") {
        // Lloyd while the RMS gap is above `gap` (forcing is √gap, capped at 1/2).
        if forcing * forcing > gap && forcing < 0.5 || forcing >= 0.5 {
            let moves: Vec<[f64; D]> = point
                .gradient
                .iter()
                .zip(&mass)
                .map(|(g, &w)| g.map(|x| -w * x))
                .collect();
            let mut moves = moves;
            hold(&mut moves);
            if let Some(trial) = eval(moved(&point.sites, 1.0, &moves))? {
                if trial.energy < point.energy {
                    debug(format_args!("newton-lloyd"));
                    return Ok(Some(trial));
                }
            }
        }
    }
    let mut radius = region
        .radius
        .unwrap_or_else(|| precondition.dual_norm2(&point.gradient).sqrt());
    if std::mem::take(&mut region.open_start) {
        let free = steihaug(point, &precondition, f64::INFINITY, forcing);
        if !free.at_edge {
            // Slightly larger: the same CG iterations then end inside the region.
            radius = precondition.step_norm2(&free.moves).sqrt() * (1.0 + 1e-9);
        }
    }
    for _ in 0..max_trials {
        // The region's norm and CG's preconditioner must match (Steihaug).
        let weighted = precondition.scaled(&region.stiffness);
        let mut model = steihaug(point, &weighted, radius, forcing);
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
        let length = weighted.step_norm2(&model.moves).sqrt();
        let trial = eval(moved(&point.sites, 1.0, &model.moves))?;
        let Some(trial) = trial else {
            debug(format_args!(
                "newton-trial cg={} infeasible",
                model.iterations
            ));
            radius = 0.25 * length;
            continue;
        };
        adapt_stiffness(&mut region.stiffness, point, &trial, &hs);
        let actual = point.energy - trial.energy;
        let relaxed = reference - trial.energy;
        let accepted = if model.decrease <= noise * point.energy.abs() {
            // Round-off: no energy rise beyond it, and a smaller gradient.
            actual >= -noise * point.energy.abs()
                && gradient_norm2(&trial.gradient, &mass) < g_norm2
        } else {
            actual >= ACCEPT * model.decrease || relaxed >= ACCEPT * model.decrease
        };
        let ratio = actual.max(relaxed) / model.decrease;
        debug(format_args!(
            "newton-trial cg={} ratio={ratio:.3} edge={} accepted={accepted}",
            model.iterations, model.at_edge
        ));
        // Nocedal and Wright's Algorithm 4.1. Gentler factors (shrink to 1/2, grow by 3)
        // cost 10-45% more diagrams on 10,000 sites in the star.
        let shrink = variant_value("shrink").unwrap_or(0.25);
        let poor = variant_value("poor").unwrap_or(0.25);
        let good = variant_value("good").unwrap_or(0.75);
        let grow = variant_value("grow").unwrap_or(2.0);
        if !accepted || ratio < poor {
            let factor = match variant_value("interp") {
                Some(low) if !accepted && model.decrease > noise * point.energy.abs() => {
                    // E(t) = E0 + gs t + a t² through E(1): its minimiser.
                    let gs = dot_rows(&point.gradient, &model.moves);
                    let a = trial.energy - point.energy - gs;
                    if a > 0.0 {
                        (-gs / (2.0 * a)).clamp(low, 0.5)
                    } else {
                        shrink
                    }
                }
                _ => shrink,
            };
            radius = factor * length;
        } else if ratio > good && model.at_edge {
            radius *= grow;
        }
        if accepted {
            region.radius = Some(radius);
            return Ok(Some(trial));
        }
    }
    region.radius = None;
    Ok(None)
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
    let stiffen = variant_value("stiffen").unwrap_or(STIFFEN);
    for (i, w) in stiffness.iter_mut().enumerate() {
        let miss: [f64; D] =
            std::array::from_fn(|k| trial.gradient[i][k] - point.gradient[i][k] - hs[i][k]);
        let error = norm2(miss).sqrt() / (norm2(hs[i]).sqrt() + floor);
        if error > MODEL_FAILED {
            *w = (*w * stiffen).min(MAX_STIFFNESS);
        } else if error < MODEL_HELD {
            *w = (*w * RELAX).max(1.0);
        }
    }
}

/// `Σ_i w_i |g_i|²` with `w = 1/(2 m)`: the squared dual norm of a gradient.
fn gradient_norm2<const D: usize>(g: &[[f64; D]], w: &[f64]) -> f64 {
    g.iter().zip(w).map(|(x, &w)| w * norm2(*x)).sum()
}

/// `Σ_i |p_i|² / w_i` over the sites of positive weight: the squared region norm of a step
/// (frozen sites, of weight 0, do not move).
fn step_norm2<const D: usize>(p: &[[f64; D]], w: &[f64]) -> f64 {
    p.iter()
        .zip(w)
        .filter(|(_, &w)| w > 0.0)
        .map(|(x, &w)| norm2(*x) / w)
        .sum()
}

/// Steihaug's truncated, preconditioned CG on `min g·p + ½ pᵀHp` over `‖p‖_M ≤ radius`
/// (`M` the inverse of the diagonal `precondition`; a zero entry keeps a site still).
///
/// The region norms `‖z‖²_M`, `⟨z, d⟩_M` and `‖d‖²_M` follow from the CG scalars (Conn,
/// Gould and Toint, *Trust-Region Methods*, §7.5.1) instead of three more passes over
/// the sites, and each iteration makes two passes besides the Hessian product.
fn steihaug<const D: usize>(
    point: &Point<D>,
    precondition: &Precondition<D>,
    radius: f64,
    forcing: f64,
) -> ModelStep<D> {
    let g = &point.gradient;
    let n = g.len();
    let mut z = vec![[0.0; D]; n];
    let mut r = g.clone();
    let mut d: Vec<[f64; D]> = r
        .iter()
        .enumerate()
        .map(|(i, v)| precondition.apply(i, *v).map(|x| -x))
        .collect();
    let mut hd = vec![[0.0; D]; n];
    let mut ry = -dot_rows(&r, &d);
    let stop = forcing * forcing * ry;
    let mut decrease = 0.0;
    let (mut zz, mut zd, mut dd) = (0.0, 0.0, ry);
    let step = |z, decrease, at_edge, iterations| ModelStep {
        moves: z,
        decrease,
        at_edge,
        iterations,
    };
    if ry.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return step(z, decrease, false, 0);
    }
    let mut pr = vec![[0.0; D]; n];
    for iteration in 1..=MAX_CG_ITERATIONS {
        if !point.hessian_product_into(&d, &mut hd) {
            break;
        }
        let curvature = dot_rows(&d, &hd);
        let alpha = ry / curvature;
        let inside =
            curvature > 0.0 && zz + 2.0 * alpha * zd + alpha * alpha * dd < radius * radius;
        if !inside {
            // To the edge along d: the positive root of ‖z + τ d‖_M = radius. With r the
            // residual g + Hz, d·r = −ry.
            let tau = (-zd + (zd * zd + dd * (radius * radius - zz)).max(0.0).sqrt()) / dd;
            decrease += tau * ry - 0.5 * tau * tau * curvature;
            axpy(&mut z, tau, &d);
            return step(z, decrease, true, iteration);
        }
        // z += α d, r += α Hd, and the next preconditioned residual's r·Pr, in one pass.
        let mut ry_next = 0.0;
        for i in 0..n {
            for k in 0..D {
                z[i][k] += alpha * d[i][k];
                r[i][k] += alpha * hd[i][k];
            }
            pr[i] = precondition.apply(i, r[i]);
            for k in 0..D {
                ry_next += pr[i][k] * r[i][k];
            }
        }
        decrease += 0.5 * alpha * ry;
        zz += alpha * (2.0 * zd + alpha * dd);
        if ry_next <= stop || iteration == MAX_CG_ITERATIONS {
            return step(z, decrease, false, iteration);
        }
        let beta = ry_next / ry;
        for i in 0..n {
            for k in 0..D {
                d[i][k] = beta * d[i][k] - pr[i][k];
            }
        }
        zd = beta * (zd + alpha * dd);
        dd = ry_next + beta * beta * dd;
        ry = ry_next;
    }
    step(z, decrease, false, MAX_CG_ITERATIONS)
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
