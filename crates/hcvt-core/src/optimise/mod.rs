//! Centroidal Voronoi tessellations: energy, gradient, Lloyd and L-BFGS (DESIGN §4).
//!
//! The CVT energy is taken about the sites, `E(X) = Σ_i ∫_{Ω_i} |x − x_i|² dx`, and its
//! gradient is `∂E/∂x_i = 2 m_i (x_i − c_i) = −2 ∫_{Ω_i} (x − x_i) dx` (Du, Faber and
//! Gunzburger 1999; the boundary terms cancel). Both come exactly from one clipped diagram,
//! whose moments are already site-relative: `E_i = tr M2_i`, `g_i = −2 m1_i`.
//!
//! | module    | step                                                                  |
//! |-----------|-----------------------------------------------------------------------|
//! | [`lbfgs`] | L-BFGS direction (memory 7, preconditioned by `1/(2 m_i)`) and its strong-Wolfe line search |
//! | [`lloyd`] | Lloyd's `x_i ← c_i`, held inside the domain; reseeding of empty cells |
//! | [`newton`] | Newton with the exact Hessian: truncated CG in a trust region (often 2–5× fewer diagrams) |
//! | [`hessian`] | the exact Hessian, summed by the diagram over the faces between cells; its product |
//! | `capacity` | capacity-constrained CVTs: sites at the centroids of power cells of prescribed volumes, by Bourne et al.'s alternation ([`capacity_cvt`]) |
//! | `transport` | prescribed masses: the weights of a power diagram by damped Newton on the graph Laplacian ([`optimal_transport`], DESIGN §14) |
//!
//! **Stopping rules** ([`stopping`], DESIGN §7). By default a run stops when the RMS over
//! the sites of the scale-free gap `|x_i − c_i| / V_i^{1/d}` is below the tolerance; the
//! paper's `‖g‖/‖X‖ < 1e-10` in the input coordinates is selectable by name
//! ([`Rule::Paper`]). Every record holds both, and the largest gap. A run that no longer
//! moves (no site by more than round-off, the energy unchanged within it) for a few
//! iterations restarts its memory once, then stops as [`StopReason::Stalled`]
//! ([`stopping::Stall`]) rather than running to `max_iter`.
//!
//! **Round-off.** Near a minimum, energy differences between line-search trials sink into
//! round-off once the gap is about `√eps`. The line search then also accepts a step whose
//! energy is no higher within [`ENERGY_NOISE`] if the exact directional derivative shows
//! the decrease (the approximate Wolfe conditions of Hager and Zhang 2005). If it still
//! finds no step, the iteration is a Lloyd step, which needs no energy comparison, and
//! L-BFGS restarts with an empty memory.
//!
//! **Non-convex domains.** Before the line search, each site's move is shortened by halving
//! until it ends inside the domain ([`lloyd::hold_inside`]; a Lloyd step does the same), so
//! one site facing a notch does not throttle everyone's step. A trial that still puts a
//! site outside (the path of a shorter step can leave a non-convex domain) is infeasible:
//! the line search treats it as a step too long and shortens it. Sites never leave the
//! domain, so no cell is empty; should one be (a site on the boundary), the site is
//! reseeded deterministically ([`lloyd::reseed_empty`]).
//!
//! Every step is sequential over the sites in index order and the diagram does not depend
//! on the thread count, so neither does the result.

mod capacity;
#[cfg(test)]
mod central_difference;
mod hessian;
pub mod lbfgs;
pub mod lloyd;
mod newton;
mod reduction;
mod stopping;
mod transport;

use std::ops::ControlFlow;
use std::time::Instant;

use crate::density::Density;
use crate::diagram::{
    clipped_diagram, morton_order, ConvexCell, Diagram, DomainKind, FaceIntegrand,
    Request as DiagramRequest, WarmStart,
};
use crate::error::CoreError;
use crate::geometry::{Euclid, Space};
pub use capacity::{capacity_cvt, Capacity, CapacityRecord, CapacitySettings, DEFAULT_VOLUME_TOL};
use hessian::{Hessian, HessianTerms};
use lbfgs::{LineSearch, Memory};
use newton::TrustRegion;
pub use stopping::{Frame, Measures, Rule};
use stopping::{Stall, Stalled};
pub use transport::{
    optimal_transport, optimal_transport_from, set_stored_margins, Transport, TransportRecord,
    TransportSettings,
};

/// Energy tolerance of the line search relative to `|E|`: 40 times the round-off of the
/// energy (translating the domain and 2,000 random sites changed `E` by at most 2.4e-14
/// relative, star and bunny), far below any decrease that L-BFGS makes before the gap
/// reaches `√eps`.
pub const ENERGY_NOISE: f64 = 1e-12;

/// Which iteration to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Quasi-Newton with a line search (Liu et al. 2009): one diagram per evaluation.
    Lbfgs,
    /// Lloyd's fixed-point iteration `x_i ← c_i`: one diagram per iteration.
    Lloyd,
    /// Newton with the exact Hessian, truncated CG in a trust region ([`newton`]).
    Newton,
}

impl Method {
    /// `"lbfgs"`, `"lloyd"` or `"newton"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Lbfgs => "lbfgs",
            Self::Lloyd => "lloyd",
            Self::Newton => "newton",
        }
    }

    /// The method of that name ([`Method::as_str`]).
    pub fn from_name(name: &str) -> Result<Self, CoreError> {
        [Self::Lbfgs, Self::Lloyd, Self::Newton]
            .into_iter()
            .find(|m| m.as_str() == name)
            .ok_or_else(|| CoreError::InvalidSettings {
                reason: format!("method must be 'lbfgs', 'lloyd' or 'newton', got {name:?}"),
            })
    }
}

/// Parameters of [`cvt`].
#[derive(Debug, Clone, Copy)]
pub struct Settings<'a, const D: usize> {
    /// [`Method::Lbfgs`], [`Method::Lloyd`] or [`Method::Newton`].
    pub method: Method,
    /// The stopping rule ([`stopping`]).
    pub rule: Rule,
    /// Stop when the rule's value drops below this ([`Rule::default_tol`]).
    pub tol: f64,
    /// Stop after this many iterations (steps) at most.
    pub max_iter: usize,
    /// Number of L-BFGS correction pairs kept (geogram's HLBFGS uses 7).
    pub memory: usize,
    /// Most diagrams one line search may compute.
    pub max_line_evaluations: usize,
    /// The density ρ of the energy `Σ_i ∫ ρ |x − x_i|²` (DESIGN §8); `None` for ρ = 1.
    pub density: Option<&'a Density<'a, D>>,
    /// Where the sites' coordinates sit in the input's, for the paper's rule ([`Frame`]).
    pub frame: Frame,
    /// Sites held where they start, one flag per site in the caller's order (`None`: all
    /// free). A fixed site never moves: its gradient row is zero, so L-BFGS's direction,
    /// line search and correction pairs leave it out; Lloyd leaves it; the stopping
    /// measures count the free sites only. Newton refuses it.
    pub fixed: Option<&'a [bool]>,
}

impl<const D: usize> Default for Settings<'_, D> {
    fn default() -> Self {
        Self {
            method: Method::Lbfgs,
            rule: Rule::Gap,
            tol: Rule::Gap.default_tol(),
            max_iter: 10_000,
            memory: 7,
            max_line_evaluations: 20,
            density: None,
            frame: Frame::default(),
            fixed: None,
        }
    }
}

/// The settings a caller names (the binding's `cvt_2d`, `hcvt.cvt` and the partitioned
/// run): checked once, here.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Named {
    /// The method.
    pub method: Method,
    /// The stopping rule.
    pub rule: Rule,
    /// Its tolerance, the rule's default when none was given.
    pub tol: f64,
    /// Most iterations.
    pub max_iter: usize,
    /// L-BFGS pairs kept.
    pub memory: usize,
}

impl Named {
    /// Method and rule by name, `tol` (default by rule) a number `>= 0`, `max_iter >= 0`,
    /// `memory >= 1`; counts are signed so that a negative one is named, not wrapped.
    pub fn parse(
        method: &str,
        rule: &str,
        tol: Option<f64>,
        max_iter: i64,
        memory: i64,
    ) -> Result<Self, CoreError> {
        let method = Method::from_name(method)?;
        let rule = Rule::from_name(rule)?;
        let tol = tol.unwrap_or_else(|| rule.default_tol());
        if tol.is_nan() || tol < 0.0 {
            return Err(CoreError::InvalidSettings {
                reason: format!("tol must be a number >= 0, got {tol}"),
            });
        }
        let (Ok(max_iter), Ok(memory @ 1..)) = (usize::try_from(max_iter), usize::try_from(memory))
        else {
            return Err(CoreError::InvalidSettings {
                reason: format!("need max_iter >= 0 and memory >= 1, got {max_iter}, {memory}"),
            });
        };
        Ok(Self {
            method,
            rule,
            tol,
            max_iter,
            memory,
        })
    }

    /// [`Settings`] with these and the defaults for the rest.
    pub fn settings<'a, const D: usize>(
        &self,
        density: Option<&'a Density<'a, D>>,
    ) -> Settings<'a, D> {
        Settings {
            method: self.method,
            rule: self.rule,
            tol: self.tol,
            max_iter: self.max_iter,
            memory: self.memory,
            density,
            ..Settings::default()
        }
    }
}

/// What [`evaluate`] computes besides the diagram, energy and gradient.
#[derive(Debug, Clone, Copy, Default)]
pub struct PointRequest<'a, const D: usize> {
    /// The energy's [`Hessian`] too (for Newton): its face terms are summed in the
    /// diagram's pass over the faces ([`HessianTerms`]).
    pub hessian: bool,
    /// The density ρ (DESIGN §8): energy and gradient from the ρ-weighted moments, and the
    /// Hessian with `2 m_i` the ρ-weighted mass and its face terms weighted by ρ on each
    /// face (exact for a polynomial; a sampled field has no Hessian, [`cvt`] refuses Newton
    /// with one).
    pub density: Option<&'a Density<'a, D>>,
}

/// Why [`cvt`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// The rule's value fell below `tol`.
    Converged,
    /// `max_iter` iterations were made first.
    MaxIter,
    /// The observer asked to stop.
    Interrupted,
    /// The sites no longer moved and the energy no longer changed beyond round-off, before
    /// and after a restart ([`stopping::Stall`]).
    Stalled,
}

impl StopReason {
    /// `"converged"`, `"max_iter"`, `"interrupted"` or `"stalled"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::MaxIter => "max_iter",
            Self::Interrupted => "interrupted",
            Self::Stalled => "stalled",
        }
    }
}

/// How an iterate was reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// The initial sites.
    Start,
    /// An L-BFGS step with its line search.
    Lbfgs,
    /// A Lloyd step (the method, or the fallback of a failed line search).
    Lloyd,
    /// A Newton step, accepted by its trust region.
    Newton,
    /// Sites of empty cells were moved ([`lloyd::reseed_empty`]).
    Reseed,
}

impl Step {
    /// `"start"`, `"lbfgs"`, `"lloyd"`, `"newton"` or `"reseed"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Start => "start",
            Self::Lbfgs => "lbfgs",
            Self::Lloyd => "lloyd",
            Self::Newton => "newton",
            Self::Reseed => "reseed",
        }
    }
}

/// The state after one iteration; `history[k]` follows `k` iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// CVT energy about the sites, `L^(d+2)`.
    pub energy: f64,
    /// Mean dimensionless second moment over the cells (paper eq. 3).
    pub mean_g: f64,
    /// Distances of the sites from their centroids, by every rule ([`Measures`]).
    pub measures: Measures,
    /// Wall time since the start, seconds.
    pub seconds: f64,
    /// Diagrams computed so far.
    pub evaluations: usize,
    /// How this iterate was reached.
    pub step: Step,
}

/// What [`cvt`] returns.
#[derive(Debug, Clone)]
pub struct Outcome<const D: usize> {
    /// Final sites, `L`.
    pub sites: Vec<[f64; D]>,
    /// Their clipped diagram.
    pub diagram: Diagram<D>,
    /// The energy's Hessian at the final sites, for [`Method::Newton`].
    pub hessian: Option<Hessian<D>>,
    /// One record per iterate, the initial sites first.
    pub history: Vec<Record>,
    /// Why the iteration stopped.
    pub stop_reason: StopReason,
}

impl<const D: usize> Outcome<D> {
    /// Iterations made (steps taken).
    pub fn iterations(&self) -> usize {
        self.history.len().saturating_sub(1)
    }

    /// Diagrams computed.
    pub fn evaluations(&self) -> usize {
        self.history.last().map_or(0, |r| r.evaluations)
    }
}

/// Sites with their diagram, energy and gradient.
#[derive(Debug, Clone)]
pub struct Point<const D: usize> {
    /// The sites, `L`.
    pub sites: Vec<[f64; D]>,
    /// Their clipped diagram.
    pub diagram: Diagram<D>,
    /// The energy's Hessian, when asked for ([`PointRequest::hessian`]).
    pub hessian: Option<Hessian<D>>,
    /// `E = Σ_i tr M2_i`, summed in index order, `L^(d+2)`.
    pub energy: f64,
    /// `g_i = −2 m1_i`, `L^(d+1)`.
    pub gradient: Vec<[f64; D]>,
}

impl<const D: usize> Point<D> {
    /// The product `H v` of the energy's [`Hessian`] with `v` (one row per site), `None`
    /// unless the point was evaluated with it ([`Hessian::product`]).
    pub fn hessian_product(&self, v: &[[f64; D]]) -> Option<Vec<[f64; D]>> {
        let h = self.hessian.as_ref()?;
        Some(h.product(&self.diagram, v))
    }

    /// [`Point::hessian_product`] into `out` (one row per site); `false` (and `out`
    /// untouched) without the Hessian.
    pub fn hessian_product_into(&self, v: &[[f64; D]], out: &mut [[f64; D]]) -> bool {
        let Some(h) = self.hessian.as_ref() else {
            return false;
        };
        h.product_into(&self.diagram, v, out);
        true
    }
}

/// The diagram of `sites` with its energy and gradient, and what `request` asks for: one
/// diagram computation.
///
/// Errors are the diagram's: a site outside the domain, coinciding or non-finite sites; a
/// density not finite and positive where it is sampled.
pub fn evaluate<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    request: &PointRequest<'_, D>,
) -> Result<Point<D>, CoreError>
where
    Euclid: Space<D>,
{
    evaluate_from::<D, C, K>(domain, sites, request, None)
}

/// [`evaluate`] warm-started from the previous diagram's near-site lists in `warm`
/// (empty: cold), which it replaces by this diagram's: the same point bit for bit, faster
/// when the sites moved little since (issue 32). Lloyd and L-BFGS evaluate this way.
pub fn evaluate_warm<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    request: &PointRequest<'_, D>,
    warm: &mut WarmStart<D>,
) -> Result<Point<D>, CoreError>
where
    Euclid: Space<D>,
{
    evaluate_from::<D, C, K>(domain, sites, request, Some(warm))
}

/// [`evaluate`], warm-started when `warm` is given (and then replaced by this diagram's
/// lists, when the domain kind records them).
fn evaluate_from<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    request: &PointRequest<'_, D>,
    warm: Option<&mut WarmStart<D>>,
) -> Result<Point<D>, CoreError>
where
    Euclid: Space<D>,
{
    let terms = HessianTerms { sites: &sites };
    let integrand = request.hessian.then_some(&terms as &dyn FaceIntegrand<D>);
    let clipped = clipped_diagram::<D, C, K>(
        domain,
        &sites,
        &DiagramRequest {
            integrand,
            density: request.density,
            warm: warm.as_deref(),
            ..DiagramRequest::default()
        },
    )?;
    if let (Some(warm), Some(next)) = (warm, clipped.warm) {
        *warm = next;
    }
    let diagram = clipped.diagram;
    let ambient = diagram.gradient();
    let hessian = request.hessian.then(|| {
        let mut hessian = Hessian::new(&diagram, clipped.face_integrals);
        if domain.cell_dim() != D {
            // On a surface the Riemannian Hessian, along the tangent planes.
            hessian.along(domain, &diagram, &sites, &ambient);
        }
        hessian
    });
    // The gradient along the domain: itself in a flat one, its tangent part on the sphere.
    let gradient = (ambient.into_iter().zip(&sites))
        .map(|(g, &x)| domain.tangent(x, g))
        .collect();
    Ok(Point {
        energy: diagram.energy(),
        gradient,
        hessian,
        diagram,
        sites,
    })
}

/// The mean spacing `h = (V/n)^{1/d}` of `n` sites in `boundary`, `L`: how far a reseeded
/// site moves ([`lloyd::reseed_empty`]).
fn mean_spacing<const D: usize, K: DomainKind<D>>(domain: &K, n: usize) -> f64
where
    Euclid: Space<D>,
{
    stopping::cell_size::<D>(domain.volume() / n.max(1) as f64, domain.cell_dim())
}

/// Mean of `G` over the non-empty cells (paper eq. 3), in the cells' dimension.
fn mean_g<const D: usize, K: DomainKind<D>>(domain: &K, diagram: &Diagram<D>) -> f64 {
    let values: Vec<f64> = diagram
        .moments
        .iter()
        .filter_map(|m| domain.g_value(m))
        .collect();
    values.iter().sum::<f64>() / values.len().max(1) as f64
}

/// Sees every record with the current sites; `Break` stops the run.
pub type Observer<'a, const D: usize> = dyn FnMut(&Record, &[[f64; D]]) -> ControlFlow<()> + 'a;

/// Counts diagram computations and tells how far the run has come.
struct Tracker<'a, const D: usize> {
    /// What each evaluation computes: the Hessian for Newton, the density.
    request: PointRequest<'a, D>,
    /// Mean spacing `h`, `L`.
    h: f64,
    start: Instant,
    evaluations: usize,
    history: Vec<Record>,
    /// For the paper's rule, measured in the input's coordinates.
    frame: Frame,
    /// The last diagram's near-site lists, which start the next one warm.
    warm: WarmStart<D>,
    /// The fixed sites (index in the run's order, position): put back before every
    /// diagram and given a zero gradient row after it (empty: all sites free).
    held: Vec<(usize, [f64; D])>,
}

impl<'a, const D: usize> Tracker<'a, D> {
    /// A run of `n` sites in `domain` that has computed nothing yet, its clock started.
    fn new<K: DomainKind<D>>(
        domain: &K,
        n: usize,
        request: PointRequest<'a, D>,
        frame: Frame,
    ) -> Self
    where
        Euclid: Space<D>,
    {
        Self {
            request,
            h: mean_spacing(domain, n),
            start: Instant::now(),
            evaluations: 0,
            history: Vec::new(),
            frame,
            warm: WarmStart::new(),
            held: Vec::new(),
        }
    }

    fn evaluate<C: ConvexCell<D>, K: DomainKind<D>>(
        &mut self,
        domain: &K,
        mut sites: Vec<[f64; D]>,
    ) -> Result<Point<D>, CoreError>
    where
        Euclid: Space<D>,
    {
        self.evaluations += 1;
        // Exactly where they started, whatever a step (a Lloyd move, a retraction onto
        // the surface, a reseed) made of them.
        for &(i, x) in &self.held {
            sites[i] = x;
        }
        // Every method's diagrams start warm: a cell that kept its neighbours is rebuilt
        // from its ring without clipping (diagram/ring.rs), bitwise the cold cell. Newton's
        // long steps leave fewer such cells, yet warm runs took 0.92-0.995x the cold
        // instructions in 2D (callgrind: square 1k, 5k, star 2k, 10k) and 0.972x in 3D
        // (ball 1k seed 0: 15.08 -> 14.65 G, the same 118 diagrams).
        // docs/results/newton_variants.txt, round 4.
        let mut point = evaluate_warm::<D, C, K>(domain, sites, &self.request, &mut self.warm)?;
        // A zero row: the two-loop recursion then gives a zero move (its pairs' rows are
        // zero too), and the line search's slopes leave the site out.
        for &(i, _) in &self.held {
            point.gradient[i] = [0.0; D];
        }
        Ok(point)
    }

    /// Record `point` in the history; also returns which sites are pinned
    /// ([`lloyd::pinned_sites`]), which Newton's next step holds still.
    fn record<K: DomainKind<D>>(
        &mut self,
        domain: &K,
        point: &Point<D>,
        step: Step,
    ) -> (Record, Vec<bool>)
    where
        Euclid: Space<D>,
    {
        let pinned = lloyd::pinned_sites(domain, point);
        let dim = domain.cell_dim();
        let measures = if self.held.is_empty() {
            Measures::of_cells(point, &pinned, &self.frame, dim)
        } else {
            // The stopping measures over the free sites only.
            let mut left_out = pinned.clone();
            for &(i, _) in &self.held {
                left_out[i] = true;
            }
            Measures {
                pinned: pinned.iter().filter(|&&p| p).count(),
                ..Measures::of_cells(point, &left_out, &self.frame, dim)
            }
        };
        let record = Record {
            energy: point.energy,
            mean_g: mean_g(domain, &point.diagram),
            measures,
            seconds: self.start.elapsed().as_secs_f64(),
            evaluations: self.evaluations,
            step,
        };
        self.history.push(record);
        (record, pinned)
    }
}

/// A CVT from `sites`: Lloyd, L-BFGS or Newton until the stopping rule's value is below
/// `tol` ([`stopping`]) or `max_iter`.
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
fn along_morton_curve<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
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
