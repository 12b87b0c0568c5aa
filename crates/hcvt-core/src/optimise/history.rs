//! A run's history: each iterate's record (energy, mean G, the stopping measures, time,
//! diagrams so far, the step that made it), the tracker that takes them and tells the
//! observer, and the outcome.

use std::ops::ControlFlow;
use std::time::Instant;

use crate::diagram::{ConvexCell, Diagram, DomainKind, WarmStart};
use crate::error::CoreError;
use crate::geometry::{Euclid, Space};

use super::hessian::Hessian;
use super::lloyd;
use super::point::{evaluate_warm, Point, PointRequest};
use super::stopping::{self, Frame, Measures};

/// Why [`cvt`](super::cvt) stopped.
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

/// What [`cvt`](super::cvt) returns.
#[derive(Debug, Clone)]
pub struct Outcome<const D: usize> {
    /// Final sites, `L`.
    pub sites: Vec<[f64; D]>,
    /// Their clipped diagram.
    pub diagram: Diagram<D>,
    /// The energy's Hessian at the final sites, for [`Method::Newton`](super::Method::Newton).
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
pub(super) struct Tracker<'a, const D: usize> {
    /// What each evaluation computes: the Hessian for Newton, the density.
    pub(super) request: PointRequest<'a, D>,
    /// Mean spacing `h`, `L`.
    pub(super) h: f64,
    /// When the run started.
    pub(super) start: Instant,
    /// Diagrams so far.
    pub(super) evaluations: usize,
    /// One record per iterate, the start first.
    pub(super) history: Vec<Record>,
    /// For the paper's rule, measured in the input's coordinates.
    pub(super) frame: Frame,
    /// The last diagram's near-site lists, which start the next one warm.
    pub(super) warm: WarmStart<D>,
    /// The fixed sites (index in the run's order, position): put back before every
    /// diagram and given a zero gradient row after it (empty: all sites free).
    pub(super) held: Vec<(usize, [f64; D])>,
}

impl<'a, const D: usize> Tracker<'a, D> {
    /// A run of `n` sites in `domain` that has computed nothing yet, its clock started.
    pub(super) fn new<K: DomainKind<D>>(
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

    pub(super) fn evaluate<C: ConvexCell<D>, K: DomainKind<D>>(
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
    pub(super) fn record<K: DomainKind<D>>(
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
