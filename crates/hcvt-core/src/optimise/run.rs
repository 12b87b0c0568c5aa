//! The CVT driver: the sites along a Morton curve, then Lloyd, L-BFGS or Newton steps
//! until the stopping rule holds, the observer stops the run or `max_iter`.

use crate::density::Density;
use crate::diagram::{
    clipped_diagram, morton_order, ConvexCell, DomainKind, Request as DiagramRequest,
};
use crate::error::CoreError;
use crate::geometry::{Euclid, Space};

use super::history::{Observer, Outcome, Record, Step, StopReason, Tracker};
use super::lbfgs::{self, LineSearch, Memory};
use super::lloyd;
use super::newton::{self, TrustRegion};
use super::point::{Point, PointRequest, ENERGY_NOISE};
use super::settings::{Method, Settings};
use super::stopping::{Measures, Stall, Stalled};

/// A CVT from `sites`: Lloyd, L-BFGS or Newton until the stopping rule's value is below
/// `tol` ([`stopping`](super::stopping)) or `max_iter`.
///
/// `observer` sees every record (the initial sites first) with the current sites, and stops
/// the run by returning `ControlFlow::Break` (the binding does so on Ctrl-C, or when the
/// Python callback asks).
///
/// The run holds the sites in the order of a Morton curve through their starting
/// positions, so that sites near in space are near in memory (the diagram's rows, the
/// Hessian's products); the observer and the outcome see the caller's order. Sums over
/// sites (energy, norms) run in the run's order.
///
/// In a periodic box ([`crate::PeriodicBox`]) sites move freely across the periodic sides:
/// the iterates are not wrapped (the L-BFGS memory takes differences of them; the diagram
/// takes a site anywhere along a periodic axis), [`crate::DomainKind::locate`] finds every
/// point of the torus inside, so no site is held or pinned at a side, and the observer and
/// the outcome see the sites wrapped into the box. Newton is refused there for now.
///
/// Errors: those of the first diagram (sites outside the domain, coinciding, non-finite),
/// naming sites in the caller's order. Later steps keep the sites inside the domain and
/// distinct, so they do not fail.
/// With a density ρ in `settings` (DESIGN §8), the energy is `Σ_i ∫ ρ |x − x_i|²`: Lloyd
/// moves each site to its ρ-weighted centroid, L-BFGS follows the ρ-weighted gradient
/// `2 m_i (x_i − c_i)`, and both stopping rules apply unchanged (the gap's `V_i` stays
/// geometric). Newton's Hessian weighs its face terms by ρ on each face, exactly for a
/// polynomial; with a sampled field Newton is refused in a flat domain (its face terms
/// would need the field on every face too). On the sphere both are sampled, the arcs by
/// Gauss–Legendre at nodes asked of the field in the diagram's one call.
pub fn cvt<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    settings: &Settings<'_, D>,
    observer: &mut Observer<'_, D>,
) -> Result<Outcome<D>, CoreError>
where
    Euclid: Space<D>,
{
    if settings.method == Method::Newton && !domain.sums_hessian() {
        return Err(CoreError::InvalidSettings {
            reason: "Newton's Hessian is not summed on a region of the sphere yet: use \
                     method 'lbfgs' or 'lloyd'"
                .into(),
        });
    }
    if settings.density.is_some()
        && settings.method == Method::Newton
        && !domain.sums_weighted_hessian()
    {
        return Err(CoreError::InvalidDensity {
            reason: "Newton's Hessian is not weighted by a density on a triangle surface: use \
                     method 'lbfgs' or 'lloyd'"
                .into(),
        });
    }
    // On the sphere every density is sampled, and its arcs too (`sphere.rs`).
    if matches!(settings.density, Some(Density::Sampled { .. }))
        && settings.method == Method::Newton
        && domain.cell_dim() == D
    {
        return Err(CoreError::InvalidDensity {
            reason: "Newton needs the Hessian, which is weighted exactly only by a polynomial \
                     density: use method 'lbfgs' or 'lloyd' with a function"
                .into(),
        });
    }
    if domain.periodic().is_some() && settings.method == Method::Newton {
        return Err(CoreError::InvalidSettings {
            reason: "Newton is not offered in a periodic box yet (only with volumes=): use \
                     method 'lbfgs' or 'lloyd'"
                .into(),
        });
    }
    check_fixed(settings, sites.len())?;
    along_morton_curve::<D, C, K>(domain, sites, observer, |along_curve, order, observe| {
        let fixed: Option<Vec<bool>> = settings
            .fixed
            .map(|f| order.iter().map(|&i| f[i as usize]).collect());
        let out =
            cvt_in_order::<D, C, K>(domain, along_curve, settings, fixed.as_deref(), observe)?;
        Ok((out, Vec::new()))
    })
    .map(|(out, _)| out)
}

/// `settings.fixed`, if given, has one flag per site, and Newton is not asked to hold
/// any (its trust-region step has no rows to leave out yet).
fn check_fixed<const D: usize>(settings: &Settings<'_, D>, n: usize) -> Result<(), CoreError> {
    let Some(fixed) = settings.fixed else {
        return Ok(());
    };
    if fixed.len() != n {
        return Err(CoreError::ShapeMismatch {
            what: "fixed, one flag per site",
            expected: n,
            got: fixed.len(),
        });
    }
    if settings.method == Method::Newton && fixed.contains(&true) {
        return Err(CoreError::InvalidSettings {
            reason: "Newton does not hold fixed sites yet: use method 'lbfgs' or 'lloyd'".into(),
        });
    }
    Ok(())
}

/// Per-site columns of a run besides its sites (weights, target volumes), in the run's
/// order; [`along_morton_curve`] hands them back in the caller's.
type SiteColumns = Vec<Vec<f64>>;

/// `run` with the sites in the order of a Morton curve through their starting positions
/// (`run` gets them, that order as indices into the caller's, and an observer that sees
/// the caller's order); its outcome and per-site columns back in the caller's order. In a
/// periodic box the iterates are not wrapped (the L-BFGS memory differences them; the
/// diagram takes any site along a periodic axis), what the caller sees is. On an error,
/// the first offending site in the caller's order, as a diagram of them names it.
pub(super) fn along_morton_curve<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    observer: &mut Observer<'_, D>,
    run: impl FnOnce(
        Vec<[f64; D]>,
        &[u32],
        &mut Observer<'_, D>,
    ) -> Result<(Outcome<D>, SiteColumns), CoreError>,
) -> Result<(Outcome<D>, SiteColumns), CoreError>
where
    Euclid: Space<D>,
{
    let wrap = |x: [f64; D]| domain.periodic().map_or(x, |torus| torus.wrap(x));
    let order = morton_order(&sites);
    let along_curve: Vec<[f64; D]> = order.iter().map(|&i| sites[i as usize]).collect();
    let mut caller_order = vec![[0.0; D]; sites.len()];
    let mut observe = |record: &Record, held: &[[f64; D]]| {
        for (&i, &x) in order.iter().zip(held) {
            caller_order[i as usize] = wrap(x);
        }
        observer(record, &caller_order)
    };
    match run(along_curve, &order, &mut observe) {
        Ok((out, columns)) => {
            let mut sites = vec![[0.0; D]; out.sites.len()];
            for (&i, &x) in order.iter().zip(&out.sites) {
                sites[i as usize] = wrap(x);
            }
            let columns = columns
                .into_iter()
                .map(|column| {
                    let mut back = vec![0.0; column.len()];
                    for (&i, &v) in order.iter().zip(&column) {
                        back[i as usize] = v;
                    }
                    back
                })
                .collect();
            let (diagram, faces) = out.diagram.reordered_faces(&order);
            Ok((
                Outcome {
                    sites,
                    diagram,
                    hessian: out.hessian.map(|h| h.reordered(&order, &faces)),
                    history: out.history,
                    stop_reason: out.stop_reason,
                },
                columns,
            ))
        }
        Err(e) => match clipped_diagram::<D, C, K>(domain, &sites, &DiagramRequest::default()) {
            Err(first) => Err(first),
            Ok(_) => Err(e),
        },
    }
}

/// [`cvt`] with the sites in the order given; `fixed` flags the sites held still, in
/// that order.
fn cvt_in_order<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    settings: &Settings<'_, D>,
    fixed: Option<&[bool]>,
    observer: &mut Observer<'_, D>,
) -> Result<Outcome<D>, CoreError>
where
    Euclid: Space<D>,
{
    let request = PointRequest {
        hessian: settings.method == Method::Newton,
        density: settings.density,
    };
    let mut tracker = Tracker::new(domain, sites.len(), request, settings.frame);
    tracker.held = (fixed.unwrap_or_default().iter())
        .zip(&sites)
        .enumerate()
        .filter(|(_, (&f, _))| f)
        .map(|(i, (_, &x))| (i, x))
        .collect();
    let mut point = tracker.evaluate::<C, K>(domain, sites)?;
    let mut solver = Solver {
        method: settings.method,
        memory: Memory::new(settings.memory),
        region: if domain.trusts_newton() {
            TrustRegion::open()
        } else {
            TrustRegion::default()
        },
        search: LineSearch::new(settings.max_line_evaluations),
    };
    let (mut record, mut pinned) = tracker.record(domain, &point, Step::Start);
    let mut stall = Stall::default();
    let mut stalled = Stalled::No;
    let stop = loop {
        if observer(&record, &point.sites).is_break() {
            break StopReason::Interrupted;
        }
        if settings.rule.value(&record.measures) < settings.tol {
            break StopReason::Converged;
        }
        if tracker.history.len() > settings.max_iter {
            break StopReason::MaxIter;
        }
        match stalled {
            Stalled::No => {}
            Stalled::Restart => solver.memory.clear(),
            Stalled::Stop => break StopReason::Stalled,
        }
        let h = tracker.h;
        let (next, step) = match lloyd::reseed_empty(domain, &point, h) {
            Some(sites) => {
                solver.memory.clear();
                (tracker.evaluate::<C, K>(domain, sites)?, Step::Reseed)
            }
            None => iterate::<D, C, K>(
                domain,
                &point,
                &mut solver,
                &record.measures,
                &pinned,
                &mut tracker,
            )?,
        };
        let idle = Stall::idle(
            &point.sites,
            &next.sites,
            point.energy,
            next.energy,
            tracker.h,
            ENERGY_NOISE,
        );
        stalled = stall.after(idle);
        point = next;
        (record, pinned) = tracker.record(domain, &point, step);
    };
    Ok(Outcome {
        sites: point.sites,
        diagram: point.diagram,
        hessian: point.hessian,
        history: tracker.history,
        stop_reason: stop,
    })
}

/// Whether some cell of `before` with mass is empty in `after` (the same sites, moved).
fn empties<const D: usize>(before: &Point<D>, after: &Point<D>) -> bool {
    (before.diagram.moments.iter())
        .zip(&after.diagram.moments)
        .any(|(b, a)| b.mass > 0.0 && (a.mass.is_nan() || a.mass <= 0.0))
}

/// The method and what it keeps from step to step.
struct Solver<const D: usize> {
    method: Method,
    memory: Memory<D>,
    region: TrustRegion,
    search: LineSearch,
}

/// One iteration of the solver's method from `point`: an L-BFGS or Newton step, or a Lloyd
/// step when that is the method or when no step was found (module docs, "Round-off").
/// `measures` and `pinned` are those of `point`.
fn iterate<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    point: &Point<D>,
    solver: &mut Solver<D>,
    measures: &Measures,
    pinned: &[bool],
    tracker: &mut Tracker<'_, D>,
) -> Result<(Point<D>, Step), CoreError>
where
    Euclid: Space<D>,
{
    if solver.method != Method::Lloyd {
        // Trial sites are retracted onto the domain (normalised on the sphere; untouched
        // in a flat domain), and moves are taken in the tangent plane before they are
        // held inside (DESIGN §13).
        // With a sampled density on the sphere the energy's rounding by the rule is
        // not smooth: Newton's steps are judged by the gradient too (newton.rs docs).
        let by_gradient = domain.trusts_newton() && tracker.request.density.is_some();
        let mut eval = |mut sites: Vec<[f64; D]>| {
            for x in sites.iter_mut() {
                *x = domain.retract(*x);
            }
            match tracker.evaluate::<C, K>(domain, sites) {
                // A trial that empties a cell is too long: an empty cell's site has no
                // gradient and would never move again. On a surface, where sites are free
                // in space, L-BFGS emptied three cells next to held sites this way
                // (fandisk, 20,000 sites, features 30°), and reseeding them failed.
                Ok(p) if empties(point, &p) => Ok(None),
                Ok(p) => Ok(Some(p)),
                Err(CoreError::SiteOutsideDomain { .. } | CoreError::DuplicateSites { .. }) => {
                    Ok(None)
                }
                Err(e) => Err(e),
            }
        };
        let hold = |moves: &mut [[f64; D]]| {
            for (m, &x) in moves.iter_mut().zip(&point.sites) {
                *m = domain.tangent(x, *m);
            }
            lloyd::hold_inside(domain, &point.sites, moves)
        };
        let next = if solver.method == Method::Newton {
            let forcing = newton::forcing(measures);
            let trials = solver.search.max_evaluations;
            let next = newton::step(
                point,
                pinned,
                &mut solver.region,
                forcing,
                trials,
                ENERGY_NOISE,
                by_gradient,
                &hold,
                &mut eval,
            )?;
            next.map(|p| (p, Step::Newton))
        } else {
            lbfgs::step(point, &mut solver.memory, &solver.search, &hold, &mut eval)?
                .map(|p| (p, Step::Lbfgs))
        };
        if let Some(next) = next {
            return Ok(next);
        }
        solver.memory.clear();
    }
    let sites = lloyd::lloyd_sites(domain, point);
    Ok((tracker.evaluate::<C, K>(domain, sites)?, Step::Lloyd))
}
