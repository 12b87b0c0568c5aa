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
//! while its factor stays within 10% of that size, `factor::analyse`), serially. Later steps
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
//!
//! The files: this one holds the damped Newton iteration and its diagrams; [`laplacian`]
//! the Laplacian, its product and the conjugate gradients; [`factor`] the sparse Cholesky
//! solve with the ordering and factor kept from step to step.

mod factor;
mod laplacian;

use factor::Kept;
use laplacian::dot;
pub(super) use laplacian::{to_neighbor, Laplacian};

use std::sync::atomic::{AtomicBool, Ordering};

use crate::density::Density;
use crate::diagram::{
    clipped_diagram_kept, trial_diagram, Clipped, ConvexCell, Diagram, DomainKind, FaceIntegrals,
    FaceIntegrand, MarginRequest, Margins, Matrix, Request as DiagramRequest, SiteSetup,
};
use crate::error::CoreError;
use crate::geometry::{Euclid, Space};
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
    STORED_MARGINS.store(on, Ordering::Relaxed);
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
    let use_margins = STORED_MARGINS.load(Ordering::Relaxed);
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
        let laplacian = Laplacian::new(&current.diagram, current.face_mass.as_ref(), sites, domain);
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
