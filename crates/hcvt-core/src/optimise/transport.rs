//! Semi-discrete optimal transport: the weights whose power diagram gives each cell a
//! prescribed mass (DESIGN §14).
//!
//! The weights maximise the concave `g(w) = Σ_i w_i ν_i + Σ_i ∫_{Ω_i(w)} (|x − z_i|² − w_i) ρ`,
//! whose gradient is `ν − m(w)` (`m_i` the mass of power cell `i`) and whose Hessian is
//! minus the graph Laplacian `L` of the power diagram with edge weights
//! `c_ij = ∫_{F_ij} ρ / (2|z_i − z_j|)`: moving `w_j` by `δ` moves the face `F_ij` by
//! `δ / (2|z_i − z_j|)` into cell `i`. So `m(w + δ) ≈ m(w) + L δ`, and Newton's step solves
//! `L δ = ν − m(w)`.
//!
//! **Damping** (Kitagawa, Mérigot and Thibert 2019, Algorithm 1): from `w = 0` (every
//! cell non-empty), a step `w + t δ` is taken with `t = t₀, t₀/2, t₀/4, …` (`t₀ ≤ 1`,
//! [`first_trial_length`]), the first `t` for
//! which every cell keeps at least `ε = ½ min(min_i m_i(0), min_i ν_i)` and
//! `‖ν − m‖` drops to at most `(1 − t/2)` of what it was. Their theorem: the iteration
//! converges globally, and locally quadratically (`t = 1`).
//!
//! **Linear solver: sparse Cholesky (faer), conjugate gradients as the fallback.** `L` is
//! symmetric positive semi-definite with the constants as kernel (a connected diagram) and
//! `ν − m` sums to zero, so the system is consistent. In 2D it is solved directly
//! (`Laplacian::direct`): the symmetrised `L` with the weight of its best-connected cell
//! held fixed, factorised by faer's supernodal Cholesky after an AMD ordering (17 to 21
//! entries a row in the factor at 10,000 sites; an earlier step's ordering is reused
//! while its factor stays within 10% of that size, [`analyse`]), serially. Later steps
//! first solve by conjugate gradients preconditioned by the last factor, an earlier step's
//! matrix (`Kept::preconditioned`), to the inexact-Newton goal below, and factorise afresh
//! only if 30 iterations do not reach it, or once near the solution
//! ([`REFACTORISE_BELOW`]). Why: factorising every
//! step (AMD, symbolic and numeric) took a third of the transport's samples at 10,000
//! sites (perf, one thread); with the kept factor one factorisation served the whole run
//! at 10,000 and 100,000 sites in the square and the L-shape (10 to 20 iterations a step,
//! solving to a fiftieth of the goal), CPU time 6.4 to 4.6 s in the L-shape at 100,000
//! (`docs/results/transport.txt`). Its residual is then checked
//! cell by cell against the inexact-Newton goal below and, if short of it, polished by
//! the conjugate gradients, which also solve every system the factorisation does not take:
//! a face graph that is not connected, or a factor fuller than `MAX_FILL_PER_ROW` (3D:
//! 200 to 250 entries a row at 5,000 sites in the unit cube, where CG needs 6 to 104
//! iterations a step). Why: profiled (perf, one thread, equal masses in the unit square),
//! diagonal-preconditioned CG took about a quarter of the run at 10,000 sites (1,831
//! iterations over 7 steps) and over half at 100,000 (5,166 iterations), its iterations
//! growing with the diagram's diameter; the factorisation took none of them, and the exact
//! steps converged in one Newton step (and diagram) fewer. Measured figures: the guide's
//! volumes page. With one weight fixed CG had emptied a cell (5,000 random sites: the
//! fixed row's equation holds only through the sum of the others' small residuals); a
//! direct solve leaves round-off there.
//!
//! The conjugate gradients are preconditioned by `L`'s diagonal and solve the singular
//! system as it is (Kaasschieter 1988; a drift along the kernel shifts every weight
//! alike, which changes no cell), only as accurately as the step needs (inexact Newton:
//! each cell's residual within `min(0.1, e) · e` of its target, `e` the present largest
//! relative error, or `tol / 10` once that is within `10 tol`). Tried for them and not kept: symmetric successive over-relaxation in
//! the Morton order (2.5-fold fewer iterations at 10,000 sites, each 3.5 times dearer:
//! no faster), and fusing each iteration's eight passes over the rows into three (CG's
//! share of samples unchanged). Products run in parallel rows and every dot product is
//! summed in index order, and the factorisation runs on one thread: the weights do not
//! depend on the thread count.
//!
//! **Diagrams.** The sites do not move: each trial diagram starts every cell from its
//! neighbours in the last accepted diagram (`Request::power_start`), then certifies it by
//! the blocks of sites near it (`diagram::power`, `Power::hinted_cell`): the exact power
//! cells, equal to the streamed ones to round-off. Why: at convergence (10,000 sites,
//! equal masses) 76% of the power cells do not hold their own site, and a cell's stream
//! from its site read some 40 sites against some 12 for a Voronoi cell; started from its
//! neighbours, a cell clips by about 6 and tests some 20 more by a bound. The transport's
//! CPU time at 10,000 sites fell from 0.51 to 0.35 s in the square (the whole run, one
//! thread, `docs/results/transport.txt`). The first diagram (zero weights: the Voronoi
//! diagram, or given weights) is streamed. A trial stops at the first cell found below
//! the guard's floor (`diagram::trial_diagram`): the rejected trials traced (the square
//! at 10,000 sites, the L-shape at 100,000) failed the guard, not the decrease, and each
//! paid a whole diagram; stopped, one costs a fraction (CPU time 4.5-4.9 to 3.8-4.0 s in
//! the L-shape at 100,000, two rejected trials of ten diagrams; the same weights bit for
//! bit; `docs/results/transport.txt` §8-9).
//!
//! **Stored margins.** In a Newton step whose iterate is expected close to the solution
//! ([`MARGINS_BELOW`], [`expected_error`]), a trial's cells certified by their scan also
//! keep a margin: their vertices, the sites of their faces, and the least value over those
//! vertices of the half-spaces' functions of the other sites near them
//! (`Power::hinted_cell`, ot5's proof in `docs/results/transport.txt` §11). A later
//! trial's cell whose hint-clipped polygon lies within a small distance of the margin's
//! vertices, with the weights moved by little since, is then the exact cell without the
//! scan: the same cell bit for bit (every clip of the scan would have found every vertex
//! inside), so the same weights ([`set_stored_margins`] turns it off for the test that
//! says so). Why: the scan was ~40% of the extension's samples at 10,000 sites; 97.5-99.7%
//! of the cells of the last two or three trials pass (10,000 and 100,000 sites, square and
//! L-shape); CPU time of the transport on one thread 0-5% lower in the square at 10,000
//! sites, 13-14% in the L-shape, 4.5% in the square at 100,000 (§14).
//!
//! **Set-up kept.** What a diagram computes of the sites alone (their Morton order,
//! winding numbers, nearest-site index and the power diagrams' block grid) is computed by
//! the first diagram and kept for every trial (`diagram::SiteSetup`): at 10,000 sites it
//! was 7.3% of the transport's instructions, computed again for each of its 8 diagrams
//! (`docs/results/transport.txt` §15). The same cells, so the same weights bit for bit.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};
use rayon::prelude::*;

use crate::density::Density;
use crate::diagram::{
    clipped_diagram_kept, trial_diagram, Clipped, ConvexCell, Diagram, DomainKind, FaceIntegrals,
    FaceIntegrand, MarginRequest, Margins, Matrix, Request as DiagramRequest, SiteSetup,
};
use crate::error::CoreError;
use crate::geometry::{norm2, sub, Euclid, Space};
use crate::moments::FaceMoments;

/// What [`optimal_transport`] is asked for.
#[derive(Debug, Clone, Copy)]
pub struct TransportSettings<'a, const D: usize> {
    /// Stop when every cell's mass is within `tol` of its target, relatively:
    /// `max_i |m_i − ν_i| / ν_i ≤ tol`.
    pub tol: f64,
    /// Most Newton steps.
    pub max_iter: usize,
    /// The density ρ the masses are measured with (ρ = 1 when `None`).
    pub density: Option<&'a Density<'a, D>>,
    /// Scale the masses to the domain's mass `∫_Ω ρ` (relative masses); otherwise their
    /// sum must be the domain's mass to `1e-9` relative.
    pub normalise: bool,
}

/// One Newton step of [`optimal_transport`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransportRecord {
    /// `max_i |m_i − ν_i| / ν_i` before the step.
    pub max_error: f64,
    /// The step length `t` taken (1 for a full Newton step).
    pub step: f64,
    /// Conjugate-gradient iterations the step's linear solve took.
    pub cg_iterations: usize,
    /// Diagrams computed for the step (halvings + 1).
    pub diagrams: usize,
    /// The smallest cell mass after the step, `ρ·L^d`.
    pub min_mass: f64,
    /// Cells of the accepted diagram certified by a stored margin instead of their scan
    /// (`diagram::power`, `Power::hinted_cell`).
    pub margin_cells: usize,
}

/// Whether trial diagrams take and use stored margins ([`set_stored_margins`]).
static STORED_MARGINS: AtomicBool = AtomicBool::new(true);

/// Turn the stored margins of the trial diagrams on (the default) or off: the weights
/// are the same bit for bit either way (a test switch; `Power::hinted_cell`'s proof).
#[doc(hidden)]
pub fn set_stored_margins(on: bool) {
    STORED_MARGINS.store(on, AtomicOrdering::Relaxed);
}

/// Margins are taken in a Newton step whose iterate is expected to have a largest relative
/// error below this ([`expected_error`]; and above the tolerance: a step expected to end
/// the run takes none). Why: a margin certifies the cells of the next trial when the
/// weights move little since, i.e. when its iterate is close to the solution: from the
/// iterate of error 1.8e-3, 99.6% of the next trial's cells (5,000 sites, square); from
/// that of error 0.1, none (`docs/results/transport.txt` §11, §14), and taking margins
/// widens the scan of every cell (about 40% more time in the certificate).
const MARGINS_BELOW: f64 = 0.05;

/// The Newton step whose iterate is expected ([`expected_error`]) to have a largest relative
/// error below this factorises its own Laplacian afresh, once a run, instead of solving by
/// conjugate gradients preconditioned by the first step's factor ([`Kept::has_factor`]);
/// the later steps are preconditioned by the fresh factor. Why: near the solution the faces barely move, so the fresh factor is
/// nearly the later matrices' own: the square at 10,000 sites took 0, 3 and 4 iterations
/// in its last three steps where the first step's factor took 11, 16 and 18 (69 in all,
/// then 31; 12 runs of 10,000 sites, square and L-shape: 699 then 259, the same Newton
/// steps and diagrams), and the triangular solves of those iterations cost more than one
/// factorisation: 3.9% fewer instructions in the whole run (`docs/results/transport.txt`
/// §17). At 100,000 sites too, where the factor is supernodal: its triangular solves took
/// 28% of the run's instructions (faer's per-supernode dispatch), one factorisation the
/// cost of about 3 iterations; the square with ρ = 1 + x + 2y² took 22 iterations where
/// it took 70, 14% fewer instructions (CPU −7% under load), the L-shape 25 for 67, the
/// same Newton steps and diagrams, uniform and polynomial (§21). (An earlier measure,
/// CPU 3.84 against 3.51 s in the square, under load, had kept it to simplicial factors.)
const REFACTORISE_BELOW: f64 = 0.05;

/// The largest relative error expected after a full Newton step from `error`, the step
/// before having started from `previous`: quadratic convergence with the constant that
/// step showed, `error · (error / previous)²`. The errors of the benchmark's runs (equal
/// masses; square and L-shape, 10,000 and 100,000 sites) fall 3 to 100 times below this
/// once it is under 0.05.
fn expected_error(error: f64, previous: Option<f64>) -> f64 {
    previous.map_or(f64::INFINITY, |p| error * (error / p).powi(2))
}

/// The Newton goal at or above which [`preconditioned_goal`] asks a tenth of it, not a
/// fiftieth: the steps far from the solution (errors above ~0.03).
const EARLY_GOAL: f64 = 1e-3;

/// The goal of the conjugate gradients preconditioned by the kept factor
/// ([`Kept::preconditioned`]) in a Newton step whose inexact-Newton goal is `goal`, the
/// run's last goal (`tol / 10`) when `last`. Sharper than the goal: at the goal alone the
/// L-shape at 100,000 sites took 9 Newton steps and 12 diagrams where the exact solves
/// took 7 and 10 (each step's error falling less while large); a fiftieth of it takes
/// the exact solves' steps (a thousandth too, with 100 iterations against 80). A tenth
/// for the early steps (goal ≥ [`EARLY_GOAL`]): the same steps and diagrams, 15% fewer
/// iterations, in the benchmark's runs (square and L-shape, uniform and polynomial
/// density, 10,000 and 100,000 sites) and 24 seeded ones at 10,000 (a third of the goal
/// took a Newton step more in the L-shape at 100,000). The last step's goal as it is:
/// its error lands 50 to 100 times below `tol` all the same (`docs/results/transport.txt`
/// §17, §19).
fn preconditioned_goal(goal: f64, last: bool) -> f64 {
    if last {
        goal
    } else if goal >= EARLY_GOAL {
        goal / 10.0
    } else {
        (goal * 0.02).max(goal.min(1e-12))
    }
}

/// What [`optimal_transport`] returns.
#[derive(Debug, Clone)]
pub struct Transport<const D: usize> {
    /// The weights, one per site, `L²`: their power diagram gives the masses.
    pub weights: Vec<f64>,
    /// The power diagram of `weights`.
    pub diagram: Diagram<D>,
    /// The masses aimed at (scaled when normalised), `ρ·L^d`.
    pub targets: Vec<f64>,
    /// `max_i |m_i − ν_i| / ν_i` of `diagram`.
    pub max_error: f64,
    /// One record per Newton step.
    pub history: Vec<TransportRecord>,
    /// `max_error ≤ tol`.
    pub converged: bool,
}

/// Halvings of a Newton step before the run gives up: `t = 2⁻⁴⁰` moves nothing.
const MAX_HALVINGS: usize = 40;

/// The weights of the power diagram of `sites` in `domain` whose cell `i` has mass
/// `masses[i]` (with `settings.density`, `∫ρ` over it), by damped Newton from zero weights.
///
/// Errors: those of the diagram; masses of the wrong length, not finite and positive, or
/// not summing to the domain's mass; a domain that takes no weights (the sphere); a
/// density in a periodic box; a step that cannot keep every cell from emptying
/// (`InvalidSettings`, naming the step).
pub fn optimal_transport<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    masses: &[f64],
    settings: &TransportSettings<'_, D>,
) -> Result<Transport<D>, CoreError>
where
    Euclid: Space<D>,
{
    optimal_transport_from::<D, C, K>(domain, sites, masses, None, settings)
}

/// [`optimal_transport`] from the weights `start` (one per site, every cell non-empty;
/// zero when `None`): a warm start, as the capacity-constrained CVT's alternation takes
/// from its previous sites (`capacity`). The guard's floor is then half the smaller of the
/// start's least mass and the least target.
pub fn optimal_transport_from<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    masses: &[f64],
    start: Option<&[f64]>,
    settings: &TransportSettings<'_, D>,
) -> Result<Transport<D>, CoreError>
where
    Euclid: Space<D>,
{
    let n = sites.len();
    if domain.cell_dim() != D {
        return Err(CoreError::InvalidWeights {
            reason: "optimal transport needs power diagrams, which the sphere does not take".into(),
        });
    }
    if !(settings.tol > 0.0 && settings.tol.is_finite()) {
        return Err(CoreError::InvalidSettings {
            reason: format!("tol must be positive and finite, got {}", settings.tol),
        });
    }
    if masses.len() != n {
        return Err(CoreError::InvalidWeights {
            reason: format!("masses: expected one per site ({n}), got {}", masses.len()),
        });
    }
    if let Some(i) = masses.iter().position(|m| !(m.is_finite() && *m > 0.0)) {
        return Err(CoreError::InvalidWeights {
            reason: format!("mass {i} must be finite and positive, got {}", masses[i]),
        });
    }
    let mut weights = match start {
        Some(w) if w.len() != n => {
            return Err(CoreError::InvalidWeights {
                reason: format!(
                    "start weights: expected one per site ({n}), got {}",
                    w.len()
                ),
            })
        }
        Some(w) => w.to_vec(),
        None => vec![0.0; n],
    };
    // The fill-reducing ordering and symbolic factorisation of earlier steps.
    let mut ordering = Kept::default();
    // The sites' order, windings and index, computed by the first diagram for every other.
    let mut setup = SiteSetup::default();
    // A warm start may be the answer already: its diagram takes the moments a returned
    // diagram needs ([`Evaluation::has_moments`]).
    let mut current = Evaluation::new::<C, K>(
        domain,
        sites,
        &weights,
        settings.density,
        start.is_some(),
        &mut setup,
    )?;
    let total: f64 = current.masses.iter().sum();
    let given: f64 = masses.iter().sum();
    let targets: Vec<f64> = if settings.normalise {
        masses.iter().map(|m| m * (total / given)).collect()
    } else if ((given - total) / total).abs() > 1e-9 {
        return Err(CoreError::InvalidWeights {
            reason: format!(
                "the masses sum to {given}, the domain's mass is {total}: they must agree \
                 (to 1e-9 relative), or be normalised"
            ),
        });
    } else {
        masses.to_vec()
    };
    // The guard of Kitagawa, Mérigot and Thibert: no cell emptier than half of the smaller
    // of its start (all non-empty at zero weights) and its target.
    let start_min = current.masses.iter().fold(f64::INFINITY, |m, &x| m.min(x));
    let target_min = targets.iter().fold(f64::INFINITY, |m, &x| m.min(x));
    if start_min <= 0.0 || start_min.is_nan() {
        let i = current.masses.iter().position(|&m| m <= 0.0).unwrap_or(0);
        return Err(CoreError::InvalidWeights {
            reason: format!(
                "cell {i} is empty at zero weights (a site outside the domain?): the damped \
                 Newton iteration starts from non-empty cells"
            ),
        });
    }
    let floor = 0.5 * start_min.min(target_min);
    let mut history = Vec::new();
    let mut error = max_error(&current.masses, &targets);
    // The step length tried first ([`first_trial_length`]).
    let mut first_trial = first_trial_length(start.is_some());
    // Stored margins of the cells (`Power::hinted_cell`) and the iterates they were taken at.
    let use_margins = STORED_MARGINS.load(AtomicOrdering::Relaxed);
    let mut margins: Option<Margins<D>> = None;
    let mut iterates: Vec<Vec<f64>> = Vec::new();
    // Whether the factor was refreshed near the solution ([`REFACTORISE_BELOW`]).
    let mut refreshed = false;
    while error > settings.tol && history.len() < settings.max_iter {
        let residual: Vec<f64> = targets
            .iter()
            .zip(&current.masses)
            .map(|(t, m)| t - m)
            .collect();
        let laplacian = Laplacian::new(&current, sites, domain);
        // Inexact Newton: the linear model's error in each cell's mass a fraction
        // min(0.1, error) of the present one (superlinear convergence); a tenth of the
        // tolerance once that comes within ten times it, so that a step that can end the
        // run does (10,000 sites in the square, CG preconditioned by the last factor: a
        // goal of 2.8e-10 left 1.1e-10 against tol = 1e-10, a Newton step and a diagram
        // more).
        let model = error * error.min(0.1);
        let last = model <= 10.0 * settings.tol;
        let goal = if last { 0.1 * settings.tol } else { model };
        let expected = expected_error(error, history.last().map(|r: &TransportRecord| r.max_error));
        let refresh = !refreshed && expected < REFACTORISE_BELOW && ordering.has_factor();
        refreshed |= refresh;
        let (start, preconditioned) = match laplacian.direct(
            &residual,
            &targets,
            preconditioned_goal(goal, last),
            &mut ordering,
            refresh,
        ) {
            Some((x, iterations)) => (Some(x), iterations),
            None => (None, 0),
        };
        let (direction, cg_iterations) = laplacian.solve(&residual, &targets, goal, start);
        let cg_iterations = cg_iterations + preconditioned;
        let norm = norm_of(&residual);
        let record = (use_margins && expected < MARGINS_BELOW && expected > settings.tol)
            .then_some(iterates.len() as u32);
        let mut step = first_trial;
        let mut diagrams = 0;
        let accepted = loop {
            let trial: Vec<f64> = weights
                .iter()
                .zip(&direction)
                .map(|(w, d)| w + step * d)
                .collect();
            // Each cell starts from its neighbours in the last accepted diagram; a trial
            // with a cell below the guard is rejected as soon as that cell is found.
            let dmax: Vec<f64> = iterates
                .iter()
                .map(|w| (trial.iter().zip(w)).fold(f64::NEG_INFINITY, |m, (t, w)| m.max(t - w)))
                .collect();
            let margin_request = MarginRequest {
                stored: margins.as_ref(),
                dmax: &dmax,
                record,
            };
            // The trials of the step expected to end the run take the cells' moments
            // ([`Evaluation::has_moments`]).
            let evaluation = Evaluation::trial::<C, K>(
                domain,
                sites,
                &trial,
                (settings.density, last),
                &current.diagram,
                floor,
                use_margins.then_some(&margin_request),
                &mut setup,
            )?;
            diagrams += 1;
            if let Some((evaluation, taken)) = evaluation {
                let min_mass = evaluation
                    .masses
                    .iter()
                    .fold(f64::INFINITY, |m, &x| m.min(x));
                let left: Vec<f64> = targets
                    .iter()
                    .zip(&evaluation.masses)
                    .map(|(t, m)| t - m)
                    .collect();
                if min_mass >= floor && norm_of(&left) <= (1.0 - 0.5 * step) * norm {
                    break Some((trial, evaluation, min_mass, taken));
                }
            }
            if diagrams > MAX_HALVINGS {
                break None;
            }
            step *= 0.5;
        };
        let Some((trial, evaluation, min_mass, taken)) = accepted else {
            return Err(CoreError::InvalidSettings {
                reason: format!(
                    "optimal transport: Newton step {} found no step keeping every cell above \
                     {floor:e} that lowers the mass error (max relative error {error:e})",
                    history.len()
                ),
            });
        };
        history.push(TransportRecord {
            max_error: error,
            step,
            cg_iterations,
            diagrams,
            min_mass,
            margin_cells: taken.as_ref().map_or(0, Margins::skipped),
        });
        if let (Some(_), Some(taken)) = (record, taken) {
            margins = Some(match margins {
                Some(old) => old.merged(&taken),
                None => taken,
            });
            iterates.push(trial.clone());
        }
        first_trial = 1.0;
        weights = trial;
        current = evaluation;
        error = max_error(&current.masses, &targets);
    }
    if !current.has_moments {
        // The run ended where it was not expected to: the last diagram again, with the
        // moments (each cell from its own neighbours). No floor: a cell's mass is never
        // below −∞ (not even a sliver's round-off below 0), so a diagram always comes back.
        current = Evaluation::trial::<C, K>(
            domain,
            sites,
            &weights,
            (settings.density, true),
            &current.diagram,
            f64::NEG_INFINITY,
            None,
            &mut setup,
        )?
        .expect("no floor to fall below")
        .0;
        error = max_error(&current.masses, &targets);
    }
    Ok(Transport {
        weights,
        diagram: current.diagram,
        targets,
        max_error: error,
        converged: error <= settings.tol,
        history,
    })
}

/// The step length the first Newton step tries first: `1` from given weights, `1/2` from
/// zero weights; every later step tries `1` first. Why: each trial costs a power diagram,
/// nearly all of the run's time, and from zero weights (the Voronoi cells, their masses 3
/// to 5 times off their targets somewhere) the full step was rejected and the half step
/// taken in every run measured (uniform random sites, equal masses: 10,000, 30,000 and
/// 100,000 in the unit square, 10,000 and 100,000 in the L-shape): one diagram of 8 to 11
/// saved, the iterates the same. Tried and not kept: a later step trying twice the length
/// its predecessor took (the L-shape at 100,000 sites then took 8 Newton steps instead of
/// 7, for the same 11 diagrams, and 8% more time). The iteration is still Kitagawa,
/// Mérigot and Thibert's: any first trial `≤ 1` halved until the guard and the decrease
/// hold keeps their convergence, and the steps are full ones near the solution.
fn first_trial_length(warm: bool) -> f64 {
    if warm {
        1.0
    } else {
        0.5
    }
}

/// `max_i |m_i − ν_i| / ν_i`.
fn max_error(masses: &[f64], targets: &[f64]) -> f64 {
    masses
        .iter()
        .zip(targets)
        .fold(0.0, |e, (m, t)| e.max((m - t).abs() / t))
}

fn norm_of(v: &[f64]) -> f64 {
    dot(v, v).sqrt()
}

/// Summed in index order: the same bits on any number of threads.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The power diagram of some weights: its masses and, per face entry, `∫_F ρ` (with a
/// density that weighs faces, from [`FaceMass`]; else the face measures).
struct Evaluation<const D: usize> {
    diagram: Diagram<D>,
    masses: Vec<f64>,
    face_mass: Option<FaceIntegrals<D>>,
    /// Whether `diagram` holds its cells' weighted moments, not their masses alone: what
    /// a returned diagram needs (its centroids, energy, gradient). A polynomial density's
    /// trial diagrams sum the masses alone ([`FaceMass::cell_moments`]) but in the Newton
    /// step expected to end the run; when another ends it, its diagram is computed again.
    /// Why: summing the moments took 8% of a run's instructions with ρ = 1 + x + 2y² (the
    /// square at 10,000 sites, 7 diagrams), the masses alone by 2 points a face 40% of
    /// that: 3.4% fewer in all, 4.1% in the L-shape, the same Newton steps and diagrams
    /// (`docs/results/transport.txt` §21).
    has_moments: bool,
}

impl<const D: usize> Evaluation<D> {
    /// The power diagram of `weights`, keeping what it computes of the sites in `setup`;
    /// with the cells' weighted moments when `moments` ([`Evaluation::has_moments`]).
    fn new<C: ConvexCell<D>, K: DomainKind<D>>(
        domain: &K,
        sites: &[[f64; D]],
        weights: &[f64],
        density: Option<&Density<'_, D>>,
        moments: bool,
        setup: &mut SiteSetup<D>,
    ) -> Result<Self, CoreError>
    where
        Euclid: Space<D>,
    {
        let integrand = density.map(|_| FaceMass::with(moments));
        let request = Self::request(weights, density, integrand.as_ref(), None);
        let clipped = clipped_diagram_kept::<D, C, K>(domain, sites, &request, Some(setup))?;
        Ok(Self::of(clipped, density, moments))
    }

    /// The power diagram of the trial `weights`, each cell started from its neighbours in
    /// `start`, or `None` as soon as a cell's mass is found below `floor`
    /// ([`trial_diagram`]); with `margins`, the margins it took. `density` comes with
    /// whether the cells' weighted moments are summed ([`Evaluation::has_moments`]).
    #[allow(clippy::too_many_arguments)]
    fn trial<C: ConvexCell<D>, K: DomainKind<D>>(
        domain: &K,
        sites: &[[f64; D]],
        weights: &[f64],
        (density, moments): (Option<&Density<'_, D>>, bool),
        start: &Diagram<D>,
        floor: f64,
        margins: Option<&MarginRequest<'_, D>>,
        setup: &mut SiteSetup<D>,
    ) -> Result<Option<(Self, Option<Margins<D>>)>, CoreError>
    where
        Euclid: Space<D>,
    {
        let integrand = density.map(|_| FaceMass::with(moments));
        let request = Self::request(weights, density, integrand.as_ref(), Some(start));
        let clipped = trial_diagram::<D, C, K>(domain, sites, &request, floor, margins, setup)?;
        Ok(clipped.map(|(clipped, taken)| (Self::of(clipped, density, moments), taken)))
    }

    fn request<'a>(
        weights: &'a [f64],
        density: Option<&'a Density<'a, D>>,
        integrand: Option<&'a FaceMass>,
        power_start: Option<&'a Diagram<D>>,
    ) -> DiagramRequest<'a, D> {
        DiagramRequest {
            density,
            weights: Some(weights),
            integrand: integrand.map(|f| f as &dyn FaceIntegrand<D>),
            power_start,
            ..DiagramRequest::default()
        }
    }

    fn of<C>(clipped: Clipped<D, C>, density: Option<&Density<'_, D>>, moments: bool) -> Self {
        let masses = clipped.diagram.masses();
        Self {
            diagram: clipped.diagram,
            masses,
            face_mass: density.map(|_| clipped.face_integrals),
            has_moments: moments || !matches!(density, Some(Density::Polynomial(_))),
        }
    }
}

/// `∫_F ρ` over each face between cells, in entry `[0][0]` of its matrix: the integrand
/// sees ρ-weighted face moments (DESIGN §8), whose measure is that integral.
struct FaceMass {
    /// Whether the diagram sums its cells' weighted moments, not their masses alone
    /// ([`FaceIntegrand::reads_cell_masses_only`]).
    cell_moments: bool,
}

impl FaceMass {
    fn with(cell_moments: bool) -> Self {
        Self { cell_moments }
    }
}

impl<const D: usize> FaceIntegrand<D> for FaceMass {
    fn add(
        &self,
        _: usize,
        _: usize,
        _: Option<[f64; D]>,
        sign: f64,
        m: &FaceMoments<D>,
        face: &mut Matrix<D>,
        _: &mut Matrix<D>,
    ) {
        face[0][0] += sign * m.measure;
    }

    fn is_face_mass(&self) -> bool {
        true
    }

    fn reads_cell_masses_only(&self) -> bool {
        !self.cell_moments
    }
}

/// The graph Laplacian of a power diagram, `c_ij = ∫_{F_ij} ρ / (2|z_i − z_j|)`, in the
/// diagram's face list; row 0 held fixed. It is `∂m/∂w`, the Jacobian of the cells'
/// masses in the weights, which the sites' reduced Hessian also solves with
/// (`reduction::Reduction`).
pub(super) struct Laplacian<'a, const D: usize> {
    diagram: &'a Diagram<D>,
    /// `c_e` per face entry (0 for a cell's faces with its own images).
    edge: Cow<'a, [f64]>,
    diagonal: Cow<'a, [f64]>,
}

/// Rows of a Laplacian product per parallel task.
const PRODUCT_ROWS: usize = 2048;

/// `z_j − z_i` across face entry `e` of cell `i` of `diagram`: in a periodic box between
/// the wrapped site `i` and the image of `j` it shares the face with.
pub(super) fn to_neighbor<const D: usize, K: DomainKind<D>>(
    diagram: &Diagram<D>,
    sites: &[[f64; D]],
    domain: &K,
    i: usize,
    e: usize,
) -> [f64; D] {
    let j = diagram.neighbor_sites[e] as usize;
    match domain.periodic() {
        Some(t) => {
            let k = diagram.neighbor_images[e];
            let (zi, zj, l) = (t.wrap(sites[i]), t.wrap(sites[j]), t.periods());
            std::array::from_fn(|m| zj[m] + f64::from(k[m]) * l[m] - zi[m])
        }
        None => sub(sites[j], sites[i]),
    }
}

impl<'a, const D: usize> Laplacian<'a, D> {
    fn new<K: DomainKind<D>>(
        evaluation: &'a Evaluation<D>,
        sites: &[[f64; D]],
        domain: &K,
    ) -> Self {
        let diagram = &evaluation.diagram;
        let (edge, diagonal) =
            Self::couplings(diagram, evaluation.face_mass.as_ref(), sites, domain);
        Self {
            diagram,
            edge: Cow::Owned(edge),
            diagonal: Cow::Owned(diagonal),
        }
    }

    /// The Laplacian of `diagram` with the couplings `edge` and their row sums `diagonal`
    /// of [`Laplacian::couplings`].
    pub(super) fn borrowed(diagram: &'a Diagram<D>, edge: &'a [f64], diagonal: &'a [f64]) -> Self {
        Self {
            diagram,
            edge: Cow::Borrowed(edge),
            diagonal: Cow::Borrowed(diagonal),
        }
    }

    /// The couplings `c_e` per face entry of `diagram` (`∫_F ρ` from `face_mass` when
    /// given, else the face measure) and their sums per cell.
    pub(super) fn couplings<K: DomainKind<D>>(
        diagram: &Diagram<D>,
        face_mass: Option<&FaceIntegrals<D>>,
        sites: &[[f64; D]],
        domain: &K,
    ) -> (Vec<f64>, Vec<f64>) {
        let n = diagram.len();
        let mut edge = vec![0.0; diagram.neighbor_sites.len()];
        let mut diagonal = vec![0.0; n];
        for (i, sum) in diagonal.iter_mut().enumerate() {
            let faces = diagram.neighbor_offsets[i]..diagram.neighbor_offsets[i + 1];
            for (e, c) in edge
                .iter_mut()
                .enumerate()
                .take(faces.end)
                .skip(faces.start)
            {
                let j = diagram.neighbor_sites[e] as usize;
                if j == i {
                    continue; // a face with its own image: w_i moves both sides
                }
                let q = to_neighbor(diagram, sites, domain, i, e);
                let mass = match face_mass {
                    Some(f) => f.faces[e][0][0],
                    None => diagram.neighbor_measures[e],
                };
                *c = mass / (2.0 * norm2(q).sqrt());
                *sum += *c;
            }
        }
        (edge, diagonal)
    }

    /// `out = L x`.
    fn product(&self, x: &[f64], out: &mut [f64]) {
        let d = self.diagram;
        out.par_chunks_mut(PRODUCT_ROWS)
            .enumerate()
            .for_each(|(c, rows)| {
                for (k, o) in rows.iter_mut().enumerate() {
                    let i = c * PRODUCT_ROWS + k;
                    let mut sum = self.diagonal[i] * x[i];
                    for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                        sum -= self.edge[e] * x[d.neighbor_sites[e] as usize];
                    }
                    *o = sum;
                }
            });
    }

    /// `δ` with `L δ = b` (`b` summing to zero), by conjugate gradients from `start`
    /// (zero when `None`) preconditioned by the diagonal, until every row's residual is within `goal` of its
    /// cell's target mass, relatively (`|r_i| ≤ goal · ν_i`): an ℓ2 criterion would let
    /// the error of the whole system fall on the smallest cells and empty them in the
    /// step. Returns the iterations taken too.
    pub(super) fn solve(
        &self,
        b: &[f64],
        targets: &[f64],
        goal: f64,
        start: Option<Vec<f64>>,
    ) -> (Vec<f64>, usize) {
        let n = b.len();
        // `b` onto the range of `L`: its mean (round-off) removed.
        let mean = b.iter().sum::<f64>() / n as f64;
        let mut r: Vec<f64> = b.iter().map(|b| b - mean).collect();
        let mut x = match start {
            Some(x) => {
                let mut lx = vec![0.0; n];
                self.product(&x, &mut lx);
                r.iter_mut().zip(&lx).for_each(|(r, l)| *r -= l);
                x
            }
            None => vec![0.0; n],
        };
        let done = |r: &[f64]| r.iter().zip(targets).all(|(r, t)| r.abs() <= goal * t);
        let inverse: Vec<f64> = self
            .diagonal
            .iter()
            .map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 })
            .collect();
        // CG ends in at most n steps in exact arithmetic; the cap stops a stagnating solve.
        let (iterations, _) = conjugate_gradients(
            |p, ap| self.product(p, ap),
            |r, z| {
                z.iter_mut()
                    .zip(r.iter().zip(&inverse))
                    .for_each(|(z, (r, m))| *z = r * m);
            },
            &mut x,
            &mut r,
            done,
            10 * n + 100,
        );
        (x, iterations)
    }
}

/// A factorisation whose factor holds more than this many entries a row (supernodal
/// storage) is not carried out: the conjugate gradients solve the system instead. 2D
/// diagrams gave 17 to 21 with AMD at 10,000 sites; 3D ones 200 to 250 at 5,000, where CG
/// needs only 6 to 104 iterations a step.
const MAX_FILL_PER_ROW: usize = 60;

impl<const D: usize> Laplacian<'_, D> {
    /// `δ` with `L δ = b` by a sparse Cholesky factorisation (faer, serial), or `None`
    /// when it does not apply: a diagram whose face graph is not connected, a factor too
    /// full (`MAX_FILL_PER_ROW`) or a failed factorisation. `L` is singular by the
    /// constants; one weight, of the cell with the largest coupling, is held fixed (its
    /// row and column replaced by the identity): the others' equations then hold to
    /// round-off, and the fixed cell's through their sum, `b` summing to zero. The matrix
    /// is symmetrised, each face's coupling read from its lower-numbered cell and the
    /// diagonal summed from the couplings, so that it is exactly positive semi-definite.
    /// The fill-reducing ordering is AMD's, or an earlier step's while its factor stays
    /// small ([`analyse`]); the symbolic factorisation is the last step's when the matrix
    /// has its pattern ([`Kept`]). Before factorising, the system is solved to `goal`
    /// (relative to `targets`, as [`Laplacian::solve`]) by conjugate gradients
    /// preconditioned by the last factorisation, when there is one
    /// ([`Kept::preconditioned`]), unless `refresh` asks for this matrix's own factor
    /// ([`REFACTORISE_BELOW`]); the iterations are returned with the solution.
    fn direct(
        &self,
        b: &[f64],
        targets: &[f64],
        goal: f64,
        kept: &mut Kept,
        refresh: bool,
    ) -> Option<(Vec<f64>, usize)> {
        let n = b.len();
        if n < 2 {
            return None;
        }
        let held = kept.analysed.as_ref().map(|a| a.fixed).filter(|&f| f < n);
        let (matrix, fixed) = self.grounded(held)?;
        let par = Par::Seq;
        let mean = b.iter().sum::<f64>() / n as f64;
        let mut x: Vec<f64> = b.iter().map(|b| b - mean).collect();
        x[fixed] = 0.0;
        if !refresh {
            if let Some(solved) = kept.preconditioned(&matrix, fixed, &x, targets, goal) {
                return Some(solved);
            }
        }
        let pattern = matrix.symbolic();
        let same = kept.analysed.as_ref().is_some_and(|a| {
            a.fixed == fixed && a.col_ptr == pattern.col_ptr() && a.rows == pattern.row_idx()
        });
        if !same {
            // A refreshed factor takes a fresh ordering: the kept one, the first step's, had
            // let the fill grow past `REUSE_FILL` by then (the benchmark's square and
            // L-shape at 10,000 sites), so its analysis, tried first, was wasted: 2% of
            // the run's instructions.
            if refresh {
                kept.ordering = None;
            }
            let symbolic = analyse(&matrix, &mut kept.ordering)?;
            kept.analysed = Some(Analysed {
                fixed,
                col_ptr: pattern.col_ptr().to_vec(),
                rows: pattern.row_idx().to_vec(),
                symbolic,
            });
        }
        kept.values = None;
        let symbolic = &kept.analysed.as_ref()?.symbolic;
        if symbolic.len_val() > MAX_FILL_PER_ROW * n {
            return None;
        }
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mut memory = MemBuffer::try_new(scratch).ok()?;
        let mut values = vec![0.0; symbolic.len_val()];
        let factor = symbolic
            .factorize_numeric_llt(
                &mut values,
                matrix.as_ref(),
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut memory),
                Default::default(),
            )
            .ok()?;
        factor.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut x, n, 1),
            par,
            MemStack::new(&mut memory),
        );
        if !x.iter().all(|x| x.is_finite()) {
            return None;
        }
        kept.values = Some(values);
        Some((x, 0))
    }

    /// The symmetrised Laplacian's lower triangle in compressed columns with the row and
    /// column of cell `held` (when given), else of the cell with the largest diagonal,
    /// replaced by the identity, and that cell; `None` when the face graph is not
    /// connected (a zero coupling counts as none).
    fn grounded(&self, held: Option<usize>) -> Option<(SparseColMat<usize, f64>, usize)> {
        let d = self.diagram;
        let n = d.len();
        // Each column's couplings to higher-numbered cells, merged (a periodic cell can
        // meet one neighbour through two of its images).
        let mut lower_ptr = Vec::with_capacity(n + 1);
        let mut lower: Vec<(usize, f64)> = Vec::with_capacity(d.neighbor_sites.len() / 2 + n);
        let mut diagonal = vec![0.0; n];
        let mut components = Components::new(n);
        lower_ptr.push(0);
        for i in 0..n {
            let from = lower.len();
            for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                let j = d.neighbor_sites[e] as usize;
                if j > i && self.edge[e] > 0.0 {
                    lower.push((j, self.edge[e]));
                }
            }
            lower[from..].sort_unstable_by_key(|&(j, _)| j);
            let mut kept = from;
            for k in from..lower.len() {
                if kept > from && lower[kept - 1].0 == lower[k].0 {
                    lower[kept - 1].1 += lower[k].1;
                } else {
                    lower[kept] = lower[k];
                    kept += 1;
                }
            }
            lower.truncate(kept);
            for &(j, c) in &lower[from..] {
                diagonal[i] += c;
                diagonal[j] += c;
                components.join(i, j);
            }
            lower_ptr.push(lower.len());
        }
        if !components.connected() {
            return None;
        }
        let fixed = held.unwrap_or_else(|| {
            (0..n).fold(0, |best, i| {
                if diagonal[i] > diagonal[best] {
                    i
                } else {
                    best
                }
            })
        });
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut rows = Vec::with_capacity(lower.len() + n);
        let mut values = Vec::with_capacity(lower.len() + n);
        col_ptr.push(0);
        for i in 0..n {
            rows.push(i);
            if i == fixed {
                values.push(1.0);
            } else {
                values.push(diagonal[i]);
                for &(j, c) in &lower[lower_ptr[i]..lower_ptr[i + 1]] {
                    if j != fixed {
                        rows.push(j);
                        values.push(-c);
                    }
                }
            }
            col_ptr.push(rows.len());
        }
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows);
        Some((SparseColMat::new(pattern, values), fixed))
    }
}

/// An AMD ordering kept from one Newton step to the next ([`analyse`]): `forward[k]` the
/// cell eliminated `k`-th, `inverse` its inverse, and `fill` the entries of the factor it
/// gave when it was computed.
struct Ordering {
    forward: Vec<usize>,
    inverse: Vec<usize>,
    fill: usize,
}

/// What the factorisations of a run keep from step to step: the AMD ordering
/// ([`analyse`]), the last symbolic factorisation with the pattern it was made for, and
/// the last numeric factor, a preconditioner for later steps ([`Kept::preconditioned`]).
/// Why: the symbolic analysis and AMD took 22% of the transport's samples at 100,000
/// sites (perf, one thread, the square, power cells started from their neighbours), and
/// once Newton converges the faces stop changing: the last steps' matrices have the
/// pattern of their predecessors', the weight held fixed being the first step's.
#[derive(Default)]
struct Kept {
    ordering: Option<Ordering>,
    analysed: Option<Analysed>,
    /// The numeric factor of `analysed` (its values), from the last factorisation.
    values: Option<Vec<f64>>,
}

/// Most iterations of [`Kept::preconditioned`] before the system is factorised afresh.
const PRECONDITIONED_ITERATIONS: usize = 30;

impl Kept {
    /// Whether there is a factor, which a fresh one could replace ([`REFACTORISE_BELOW`]).
    fn has_factor(&self) -> bool {
        self.values.is_some() && self.analysed.is_some()
    }

    /// `x` with `A x = rhs` (`A` the grounded Laplacian `matrix`, lower triangle, cell
    /// `fixed` held; `rhs[fixed] = 0`) by conjugate gradients preconditioned by the last
    /// factorisation, an earlier step's matrix with the same cell held, and the iterations
    /// taken; `None` when there is none or it does not reach `goal` within
    /// [`PRECONDITIONED_ITERATIONS`]. Reached: every row's residual within `goal` of its
    /// cell's target (`|r_i| ≤ goal · ν_i`), the held cell's too (`−Σ r_i`, the columns of
    /// the symmetrised Laplacian summing to zero).
    fn preconditioned(
        &self,
        matrix: &SparseColMat<usize, f64>,
        fixed: usize,
        rhs: &[f64],
        targets: &[f64],
        goal: f64,
    ) -> Option<(Vec<f64>, usize)> {
        let analysed = self.analysed.as_ref().filter(|a| a.fixed == fixed)?;
        let values = self.values.as_ref()?;
        let n = rhs.len();
        if analysed.symbolic.nrows() != n {
            return None;
        }
        let factor = LltRef::new(&analysed.symbolic, values);
        let par = Par::Seq;
        let mut memory =
            MemBuffer::try_new(analysed.symbolic.solve_in_place_scratch::<f64>(1, par)).ok()?;
        let precondition = |r: &[f64], z: &mut [f64]| {
            z.copy_from_slice(r);
            factor.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(z, n, 1),
                par,
                MemStack::new(&mut memory),
            );
        };
        let done = |r: &[f64]| {
            r.iter().zip(targets).all(|(r, t)| r.abs() <= goal * t)
                && r.iter().sum::<f64>().abs() <= goal * targets[fixed]
        };
        let mut x = vec![0.0; n];
        let mut r = rhs.to_vec();
        let (iterations, reached) = conjugate_gradients(
            |p, ap| symmetric_product(matrix, p, ap),
            precondition,
            &mut x,
            &mut r,
            done,
            PRECONDITIONED_ITERATIONS,
        );
        (reached && x.iter().all(|x| x.is_finite())).then_some((x, iterations))
    }
}

/// Preconditioned conjugate gradients on the symmetric positive semi-definite `A`
/// (`product(p, out)`: `out = A p`) with the preconditioner `precondition(r, z)`
/// (`z = M⁻¹ r`, `M` symmetric positive definite): `x` improved in place from its value,
/// `r = b − A x` given and kept, until `done(r)` or after `max_iterations`. Returns the
/// iterations taken and whether `done` was reached; a breakdown (`r·z` or `p·A p` not
/// positive, or NaN: a solution in the kernel, or round-off) ends it unreached. The one
/// CG of both solvers: by the diagonal ([`Laplacian::solve`]) and by the last Cholesky
/// factor ([`Kept::preconditioned`]). Every dot product is summed in index order.
fn conjugate_gradients(
    mut product: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    x: &mut [f64],
    r: &mut [f64],
    done: impl Fn(&[f64]) -> bool,
    max_iterations: usize,
) -> (usize, bool) {
    if done(r) {
        return (0, true);
    }
    let n = r.len();
    let mut z = vec![0.0; n];
    precondition(r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = dot(r, &z);
    for iteration in 1..=max_iterations {
        if rz <= 0.0 || rz.is_nan() {
            return (iteration - 1, false);
        }
        product(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || pap.is_nan() {
            return (iteration - 1, false);
        }
        let alpha = rz / pap;
        x.iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * p);
        r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * a);
        if done(r) {
            return (iteration, true);
        }
        precondition(r, &mut z);
        let rz_next = dot(r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        p.iter_mut().zip(&z).for_each(|(p, z)| *p = z + beta * *p);
    }
    (max_iterations, false)
}

/// `out = A x` for the symmetric `A` of which `matrix` holds the lower triangle.
fn symmetric_product(matrix: &SparseColMat<usize, f64>, x: &[f64], out: &mut [f64]) {
    let (col_ptr, rows, values) = (
        matrix.symbolic().col_ptr(),
        matrix.symbolic().row_idx(),
        matrix.val(),
    );
    out.fill(0.0);
    for (j, &xj) in x.iter().enumerate() {
        let mut sum = 0.0;
        // Column j's rows and values as slices: no bounds check of theirs in the loop.
        let column = col_ptr[j]..col_ptr[j + 1];
        for (&i, &v) in rows[column.clone()].iter().zip(&values[column]) {
            out[i] += v * xj;
            if i != j {
                sum += v * x[i];
            }
        }
        out[j] += sum;
    }
}

/// A symbolic factorisation and the matrix pattern it was made for: the grounded cell and
/// the lower triangle's compressed columns.
struct Analysed {
    fixed: usize,
    col_ptr: Vec<usize>,
    rows: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
}

/// A kept ordering is used while its factor holds at most this factor more entries than
/// when AMD computed it.
const REUSE_FILL: f64 = 1.1;

/// The symbolic Cholesky factorisation of `matrix` (lower triangle) with the ordering kept
/// in `kept` if its factor is at most `REUSE_FILL` times as full as when it was computed,
/// else with a fresh AMD ordering, then kept. Why: AMD took 12% of the transport's time at
/// 100,000 sites (one ordering a step); the faces change little from step to step once
/// Newton converges (72 of 29,641 faces at 10,000 sites in the fourth step, none after),
/// but the first step's ordering kept for all had let the factor grow from 17 to 165
/// entries a row, the faces having moved, hence the check. Tried and not kept: a
/// geometric nested dissection by the sites' coordinates (no AMD at all): its factor,
/// about `n log n`, passed `MAX_FILL_PER_ROW` at 100,000 sites.
fn analyse(
    matrix: &SparseColMat<usize, f64>,
    kept: &mut Option<Ordering>,
) -> Option<SymbolicCholesky<usize>> {
    let n = matrix.ncols();
    if let Some(k) = kept.as_ref().filter(|k| k.forward.len() == n) {
        let reused = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            SymmetricOrdering::Custom(PermRef::new_checked(&k.forward, &k.inverse, n)),
            CholeskySymbolicParams::default(),
        )
        .ok()
        .filter(|s| s.len_val() as f64 <= REUSE_FILL * k.fill as f64);
        if reused.is_some() {
            return reused;
        }
    }
    let fresh = factorize_symbolic_cholesky(
        matrix.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .ok()?;
    *kept = fresh.perm().map(|p| {
        let (forward, inverse) = p.arrays();
        Ordering {
            forward: forward.to_vec(),
            inverse: inverse.to_vec(),
            fill: fresh.len_val(),
        }
    });
    Some(fresh)
}

/// Union–find over the cells, to tell whether the face graph is connected.
struct Components {
    parent: Vec<usize>,
}

impl Components {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn join(&mut self, i: usize, j: usize) {
        let (a, b) = (self.root(i), self.root(j));
        if a != b {
            self.parent[a.max(b)] = a.min(b);
        }
    }

    fn connected(&mut self) -> bool {
        (0..self.parent.len()).all(|i| self.root(i) == 0)
    }
}
