//! Capacity-constrained CVTs: sites at the centroids of power cells whose volumes (masses,
//! with a density) are prescribed (DESIGN §14; Bourne, Kok, Roper and Spanjer 2020).
//!
//! **The alternation** (Bourne et al. 2020, their Lloyd-type algorithm): for the present
//! sites, the weights whose power diagram gives every cell its volume
//! ([`optimal_transport_from`], damped Newton, warm-started from the previous weights);
//! then every site to its power cell's centroid ([`lloyd::lloyd_sites`], held inside the
//! domain); repeat. Each half lowers `Σ_i ∫_{Ω_i} |x − z_i|²` over partitions of the
//! prescribed volumes, so the iteration converges (linearly, as Lloyd's does). Warm
//! starting matters: the sites move little between iterations, so one or two Newton steps
//! restore the volumes where a cold start from zero weights takes five to ten.
//!
//! **L-BFGS on the transport cost** ([`Method::Lbfgs`]). The same fixed point is a
//! stationary point of `W(X) = min Σ_i ∫_{Ω_i} |x − z_i|²` over the partitions of the
//! prescribed volumes, whose gradient is `2 ν_i (z_i − c_i)` (the envelope theorem: the
//! optimal weights do not move it), the CVT energy's with the power cells. So the
//! existing L-BFGS step ([`super::lbfgs::step`]: its direction preconditioned by
//! `1/(2 m_i)`, whose first step is the alternation's, and its line search) runs on `W`,
//! each trial a warm-started transport, with the Kantorovich dual as the energy
//! ([`transport`]). It is `hcvt.cvt`'s default: 13-15x fewer outer iterations, 8-10x
//! less time (periodic square, 200 sites: 177 against 2,675; periodic cube, 300 grains:
//! 430 against 5,821, `benchmarks/polycrystal.py --n 300 --methods lbfgs lloyd`).
//!
//! **Newton on the sites with the weights eliminated** ([`Method::Newton`]). The Hessian of
//! `W` is `H_zz + B L⁻¹ Bᵀ` ([`Reduction`]): `H_zz` the CVT Hessian of the power diagram at
//! fixed weights (Liu et al.'s face terms: a power face moves with the sites as a
//! bisector does), `L = ∂m/∂w` the transport's Laplacian, and `B = ∂g/∂w`,
//! `B_ij = ∫_{F_ij} (x − z_i) / |z_j − z_i|` (`B_ii = −Σ_j B_ij`): the weights follow the
//! sites by `dw = L⁻¹ Bᵀ dz` (from `m(z, w) = ν`). The existing trust-region step
//! ([`super::newton::step`]) runs on `W` with that Hessian, each trial a warm-started
//! transport, so it sees the negative curvature near which L-BFGS slowed down (docs/guide/
//! volumes.md). Each accepted point costs one more diagram, with the Hessian's face terms.
//!
//! **Stopping.** After the transport of iteration `k`, its diagram has every cell within
//! `volume_tol` of its target, relatively, and the stopping rule (the default scale-free
//! RMS gap, [`super::stopping`]) is measured between those sites and those cells'
//! centroids; the run stops when both hold, returning those sites, weights and cells. So
//! the returned diagram satisfies both conditions at once.

use std::ops::ControlFlow;

use crate::diagram::{clipped_diagram, ConvexCell, DomainKind, Request as DiagramRequest};
use crate::error::CoreError;
use crate::geometry::{Euclid, Space};

use super::hessian::{Hessian, HessianTerms};
use super::history::{Observer, Outcome, Step, StopReason, Tracker};
use super::lbfgs::{self, Evaluator, LineSearch, Memory};
use super::lloyd;
use super::newton::{self, TrustRegion};
use super::point::{Point, PointRequest, ENERGY_NOISE};
use super::reduction::Reduction;
use super::run::along_morton_curve;
use super::settings::{Method, Settings};
use super::transport::{optimal_transport_from, TransportSettings};

/// Default tolerance on `max_i |V_i − v_i| / v_i`.
pub const DEFAULT_VOLUME_TOL: f64 = 1e-8;

/// What [`capacity_cvt`] is asked for.
#[derive(Debug, Clone, Copy)]
pub struct CapacitySettings<'a, const D: usize> {
    /// The sites' stopping rule and tolerance, most outer iterations (`max_iter`), the
    /// density the volumes are masses of, and the frame; `method` [`Method::Lloyd`] (the
    /// alternation) or [`Method::Lbfgs`] (with `memory` and `max_line_evaluations`).
    pub cvt: Settings<'a, D>,
    /// Stop only when every cell's volume is within this of its target, relatively.
    pub volume_tol: f64,
    /// Scale the volumes to the domain's volume (mass with a density): relative sizes.
    pub normalise: bool,
    /// Most Newton steps of one transport.
    pub transport_max_iter: usize,
}

/// The transport of one outer iteration (one per history record).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CapacityRecord {
    /// `max_i |V_i − v_i| / v_i` of this iteration's diagram.
    pub max_volume_error: f64,
    /// Newton steps the transport took.
    pub newton_steps: usize,
}

/// What [`capacity_cvt`] returns.
#[derive(Debug, Clone)]
pub struct Capacity<const D: usize> {
    /// Sites, their power diagram, history and stop reason, as a CVT's.
    pub outcome: Outcome<D>,
    /// The final power diagram's weights, `L²`.
    pub weights: Vec<f64>,
    /// The volumes aimed at (scaled when normalised), `L^d` (`ρ·L^d` with a density).
    pub targets: Vec<f64>,
    /// One per record of `outcome.history`.
    pub transport: Vec<CapacityRecord>,
}

/// Sites at the centroids of power cells of volumes `volumes` (one per site; masses with
/// a density), from `sites`: Bourne et al.'s alternation ([`Method::Lloyd`]) or L-BFGS on
/// the transport cost ([`Method::Lbfgs`]; module docs).
///
/// `observer` sees every outer iteration's record and sites (the first transport's
/// first), as [`super::cvt`]'s does; `Break` stops the run.
///
/// Errors: Newton; volumes of the wrong length, not finite and
/// positive (naming the row), or not summing to the domain's volume unless normalised;
/// those of [`optimal_transport_from`] and of the diagram.
pub fn capacity_cvt<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    volumes: &[f64],
    settings: &CapacitySettings<'_, D>,
    observer: &mut Observer<'_, D>,
) -> Result<Capacity<D>, CoreError>
where
    Euclid: Space<D>,
{
    check_arguments(settings, sites.len(), volumes)?;
    let mut transport = Vec::new();
    let (outcome, mut columns) =
        along_morton_curve::<D, C, K>(domain, sites, observer, |along_curve, order, observe| {
            let volumes: Vec<f64> = order.iter().map(|&i| volumes[i as usize]).collect();
            let run = alternate::<D, C, K>(domain, along_curve, &volumes, settings, observe)?;
            transport = run.transport;
            Ok((run.outcome, vec![run.weights, run.targets]))
        })?;
    let targets = columns.pop().unwrap_or_default();
    let weights = columns.pop().unwrap_or_default();
    Ok(Capacity {
        outcome,
        weights,
        targets,
        transport,
    })
}

/// The method (Newton without a density) and one finite, positive volume per
/// site, checked in the caller's order so that the row named is the caller's.
fn check_arguments<const D: usize>(
    settings: &CapacitySettings<'_, D>,
    n: usize,
    volumes: &[f64],
) -> Result<(), CoreError> {
    if settings.cvt.method == Method::Newton && settings.cvt.density.is_some() {
        return Err(CoreError::InvalidSettings {
            reason: "prescribed volumes with a density take method 'lloyd' or 'lbfgs': \
                     the reduced Newton ('newton') has no density yet"
                .into(),
        });
    }
    if settings.cvt.fixed.is_some_and(|f| f.contains(&true)) {
        return Err(CoreError::InvalidSettings {
            reason: "prescribed volumes do not hold fixed sites yet".into(),
        });
    }
    if volumes.len() != n {
        return Err(CoreError::InvalidWeights {
            reason: format!(
                "volumes: expected one per site ({n}), got {}",
                volumes.len()
            ),
        });
    }
    if let Some(i) = volumes.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(CoreError::InvalidWeights {
            reason: format!("volume {i} must be finite and positive, got {}", volumes[i]),
        });
    }
    Ok(())
}

/// A point of the alternation: sites with the power diagram that gives their cells the
/// volumes, and that transport's weights and figures.
struct Solved<const D: usize> {
    point: Point<D>,
    transport: Transported,
}

/// What a transport found besides its diagram.
struct Transported {
    weights: Vec<f64>,
    targets: Vec<f64>,
    record: CapacityRecord,
    /// Diagrams it computed.
    diagrams: usize,
}

/// The transport of `sites` to `volumes`, from the first weights of `warm` that do (a
/// cell empty at the start, or no convergence, is retried from the next, and last from
/// zero weights, where the damped iteration is proven to converge).
///
/// Its energy is the Kantorovich dual `E + Σ_i w_i (ν_i − m_i)`: the transport cost
/// `Σ_i ∫_{Ω_i} |x − z_i|²` at the exact weights, and stationary in the weights, so that
/// a volume error of `ε` moves it by `O(ε²)` only: line searches can compare it.
fn transport<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    volumes: &[f64],
    warm: &[&[f64]],
    asked: &TransportSettings<'_, D>,
) -> Result<Solved<D>, CoreError>
where
    Euclid: Space<D>,
{
    let mut diagrams = 0;
    let mut solve = |start: Option<&[f64]>| {
        let out = optimal_transport_from::<D, C, K>(domain, &sites, volumes, start, asked);
        if let Ok(t) = &out {
            diagrams += 1 + t.history.iter().map(|r| r.diagrams).sum::<usize>();
        }
        out
    };
    let warmed = (warm.iter()).find_map(|w| solve(Some(w)).ok().filter(|t| t.converged));
    let solved = match warmed {
        Some(t) => t,
        None => solve(None)?,
    };
    let diagram = solved.diagram;
    let masses = diagram.masses();
    let slack: f64 = (solved.weights.iter().zip(&solved.targets).zip(&masses))
        .map(|((w, t), m)| w * (t - m))
        .sum();
    let point = Point {
        gradient: diagram.gradient(),
        energy: diagram.energy() + slack,
        diagram,
        sites,
        hessian: None,
    };
    Ok(Solved {
        point,
        transport: Transported {
            weights: solved.weights,
            targets: solved.targets,
            record: CapacityRecord {
                max_volume_error: solved.max_error,
                newton_steps: solved.history.len(),
            },
            diagrams,
        },
    })
}

/// [`capacity_cvt`] with the sites in the order given.
fn alternate<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    volumes: &[f64],
    settings: &CapacitySettings<'_, D>,
    observer: &mut Observer<'_, D>,
) -> Result<Capacity<D>, CoreError>
where
    Euclid: Space<D>,
{
    let cvt = &settings.cvt;
    let asked = TransportSettings {
        tol: settings.volume_tol,
        max_iter: settings.transport_max_iter,
        density: cvt.density,
        normalise: settings.normalise,
    };
    let request = PointRequest {
        hessian: false,
        density: cvt.density,
    };
    let mut tracker = Tracker::new(domain, sites.len(), request, cvt.frame);
    let mut memory = Memory::new(cvt.memory);
    let search = LineSearch::new(cvt.max_line_evaluations);
    let mut records = Vec::new();
    let newton = cvt.method == Method::Newton;
    let mut region = TrustRegion::default();
    let mut current = transport::<D, C, K>(domain, sites, volumes, &[], &asked)?;
    if newton {
        with_hessian::<D, C, K>(domain, &mut current)?;
    }
    let mut step = Step::Start;
    loop {
        tracker.evaluations += current.transport.diagrams;
        let (record, pinned) = tracker.record(domain, &current.point, step);
        records.push(current.transport.record);
        let stop = if observer(&record, &current.point.sites) == ControlFlow::Break(()) {
            Some(StopReason::Interrupted)
        } else if current.transport.record.max_volume_error <= settings.volume_tol
            && cvt.rule.value(&record.measures) < cvt.tol
        {
            Some(StopReason::Converged)
        } else if tracker.history.len() > cvt.max_iter {
            Some(StopReason::MaxIter)
        } else {
            None
        };
        if let Some(stop_reason) = stop {
            return Ok(Capacity {
                outcome: Outcome {
                    sites: current.point.sites,
                    diagram: current.point.diagram,
                    hessian: None,
                    history: tracker.history,
                    stop_reason,
                },
                weights: current.transport.weights,
                targets: current.transport.targets,
                transport: records,
            });
        }
        let warm = &current.transport.weights;
        let searched = match cvt.method {
            Method::Lbfgs => {
                quasi_newton_step::<D, C, K>(domain, &current, volumes, &asked, |eval, hold| {
                    lbfgs::step(&current.point, &mut memory, &search, hold, eval)
                })?
                .map(|found| (found, Step::Lbfgs))
            }
            Method::Newton => {
                // Sites pinned against a boundary stay, as in the CVT's Newton.
                let (forcing, frozen) = (newton::forcing(&record.measures), &pinned);
                quasi_newton_step::<D, C, K>(domain, &current, volumes, &asked, |eval, hold| {
                    let (trials, noise) = (search.max_evaluations, ENERGY_NOISE);
                    let point = &current.point;
                    newton::step(
                        point,
                        frozen,
                        &mut region,
                        forcing,
                        trials,
                        noise,
                        false,
                        hold,
                        eval,
                    )
                })?
                .map(|found| (found, Step::Newton))
            }
            Method::Lloyd => None,
        };
        (current, step) = match searched {
            Some(((mut next, diagrams), step)) => {
                tracker.evaluations += diagrams;
                if newton {
                    with_hessian::<D, C, K>(domain, &mut next)?;
                }
                (next, step)
            }
            None => {
                memory.clear();
                let sites = lloyd::lloyd_sites(domain, &current.point);
                let mut next = transport::<D, C, K>(domain, sites, volumes, &[warm], &asked)?;
                if newton {
                    with_hessian::<D, C, K>(domain, &mut next)?;
                }
                (next, Step::Lloyd)
            }
        };
    }
}

/// One step on the transport cost `W(X) = min Σ_i ∫_{Ω_i} |x − z_i|²` over the
/// partitions of the prescribed volumes, whose gradient is `2 ν_i (z_i − c_i)` as the CVT
/// energy's (the envelope theorem): `take_step` is [`super::lbfgs::step`] or
/// [`super::newton::step`], given the evaluation (every trial a warm-started transport)
/// and the hold. The accepted point with the diagrams its trials computed (besides its
/// own), or `None` when the step found no point.
fn quasi_newton_step<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    current: &Solved<D>,
    volumes: &[f64],
    asked: &TransportSettings<'_, D>,
    take_step: impl FnOnce(
        &mut Evaluator<'_, D>,
        &dyn Fn(&mut [[f64; D]]),
    ) -> Result<Option<Point<D>>, CoreError>,
) -> Result<Option<(Solved<D>, usize)>, CoreError>
where
    Euclid: Space<D>,
{
    let weights = &current.transport.weights;
    // With the reduced Hessian, each trial's transport starts from the weights predicted
    // for its moves, `w + L⁻¹ Bᵀ dz` (the first order of `m(z, w) = ν`), not from `w`.
    let reduction = (current.point.hessian.as_ref()).and_then(|h| h.reduction.as_deref());
    let predicted = |sites: &[[f64; D]]| -> Option<Vec<f64>> {
        let r = reduction?;
        let moves: Vec<[f64; D]> = (sites.iter().zip(&current.point.sites))
            .map(|(a, b)| std::array::from_fn(|k| a[k] - b[k]))
            .collect();
        let change = r.weight_change(&current.point.diagram, &moves);
        Some(weights.iter().zip(&change).map(|(w, c)| w + c).collect())
    };
    // Each trial's transport, kept to go with the point the line search accepts.
    let mut trials: Vec<(Vec<[f64; D]>, Transported)> = Vec::new();
    let mut eval = |sites: Vec<[f64; D]>| {
        let start = predicted(&sites);
        let warm: Vec<&[f64]> = start.as_deref().into_iter().chain([&weights[..]]).collect();
        match transport::<D, C, K>(domain, sites, volumes, &warm, asked) {
            Ok(solved) => {
                trials.push((solved.point.sites.clone(), solved.transport));
                Ok(Some(solved.point))
            }
            // Infeasible trials: the line search shortens the step.
            Err(
                CoreError::SiteOutsideDomain { .. }
                | CoreError::DuplicateSites { .. }
                | CoreError::InvalidWeights { .. }
                | CoreError::InvalidSettings { .. },
            ) => Ok(None),
            Err(e) => Err(e),
        }
    };
    let hold = |moves: &mut [[f64; D]]| lloyd::hold_inside(domain, &current.point.sites, moves);
    let Some(point) = take_step(&mut eval, &hold)? else {
        return Ok(None);
    };
    let diagrams: usize = trials.iter().map(|(_, t)| t.diagrams).sum();
    let Some(k) = trials.iter().rposition(|(sites, _)| *sites == point.sites) else {
        return Ok(None);
    };
    let (_, transport) = trials.swap_remove(k);
    let own = transport.diagrams;
    Ok(Some((Solved { point, transport }, diagrams - own)))
}

/// Add to `solved`'s point the Hessian of the transport cost in the sites, the weights
/// eliminated ([`Reduction`]): one more diagram, at the transport's weights, that sums
/// the CVT Hessian's face terms.
fn with_hessian<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    solved: &mut Solved<D>,
) -> Result<(), CoreError>
where
    Euclid: Space<D>,
{
    let (sites, weights) = (&solved.point.sites, &solved.transport.weights);
    let terms = HessianTerms { sites };
    let clipped = clipped_diagram::<D, C, K>(
        domain,
        sites,
        &DiagramRequest {
            weights: Some(weights),
            integrand: Some(&terms),
            ..DiagramRequest::default()
        },
    )?;
    let diagram = clipped.diagram;
    let mut hessian = Hessian::new(&diagram, clipped.face_integrals);
    let reduction = Reduction::new(&diagram, &hessian.off_diagonal, sites, weights, domain);
    hessian.reduction = Some(Box::new(reduction));
    solved.point.diagram = diagram;
    solved.point.hessian = Some(hessian);
    solved.transport.diagrams += 1;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagram::{PeriodicBox, PolygonCell, PolyhedronCell};
    use crate::optimise::central_difference::central_difference_error;
    use crate::sample::Lcg;

    /// Relative error of central differences of `W`'s gradient (each side a transport
    /// solved to round-off) along a direction against the reduced Hessian's product, on
    /// random sites of a periodic box (many faces across its sides) with volumes from 0.5
    /// to 1.5 times the mean.
    fn reduced_hessian_error<const D: usize, C: ConvexCell<D>>(
        torus: &PeriodicBox<D>,
        n: usize,
        seed: u64,
    ) -> f64
    where
        Euclid: Space<D>,
    {
        let mut rng = Lcg::new(seed);
        let sites: Vec<[f64; D]> = (0..n)
            .map(|_| std::array::from_fn(|_| rng.unit()))
            .collect();
        let volumes: Vec<f64> = (0..n).map(|_| 0.5 + rng.unit()).collect();
        let asked = TransportSettings {
            tol: 1e-14,
            max_iter: 50,
            density: None,
            normalise: true,
        };
        let mut at = transport::<D, C, _>(torus, sites.clone(), &volumes, &[], &asked).unwrap();
        with_hessian::<D, C, _>(torus, &mut at).unwrap();
        let h = (1.0 / n as f64).powf(1.0 / D as f64);
        let v: Vec<[f64; D]> = (0..n)
            .map(|_| std::array::from_fn(|_| (rng.unit() - 0.5) * 1e-5 * h))
            .collect();
        let warm = at.transport.weights.clone();
        let exact = at.point.hessian_product(&v).unwrap();
        central_difference_error(&sites, &v, &exact, |moved| {
            let solved = transport::<D, C, _>(torus, moved, &volumes, &[&warm], &asked).unwrap();
            solved.point.gradient
        })
    }

    #[test]
    fn the_reduced_hessian_matches_differences_of_the_gradient() {
        let torus = PeriodicBox::new([0.0; 2], [1.0; 2], [true; 2]).unwrap();
        let err = reduced_hessian_error::<2, PolygonCell>(&torus, 60, 1);
        assert!(err < 1e-5, "2D torus: relative error {err:e}");
        let torus = PeriodicBox::new([0.0; 3], [1.0; 3], [true; 3]).unwrap();
        let err = reduced_hessian_error::<3, PolyhedronCell>(&torus, 50, 2);
        assert!(err < 1e-5, "3D torus: relative error {err:e}");
        let slab = PeriodicBox::new([0.0; 3], [1.0; 3], [true, true, false]).unwrap();
        let err = reduced_hessian_error::<3, PolyhedronCell>(&slab, 50, 3);
        assert!(err < 1e-5, "3D slab: relative error {err:e}");
    }
}
