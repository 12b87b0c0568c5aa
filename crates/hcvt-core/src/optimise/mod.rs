//! Centroidal Voronoi tessellations: energy, gradient, Lloyd and L-BFGS (DESIGN §4).
//!
//! The CVT energy is taken about the sites, `E(X) = Σ_i ∫_{Ω_i} |x − x_i|² dx`, and its
//! gradient is `∂E/∂x_i = 2 m_i (x_i − c_i) = −2 ∫_{Ω_i} (x − x_i) dx` (Du, Faber and
//! Gunzburger 1999; the boundary terms cancel). Both come exactly from one clipped diagram,
//! whose moments are already site-relative: `E_i = tr M2_i`, `g_i = −2 m1_i`.
//!
//! | module    | step                                                                  |
//! |-----------|-----------------------------------------------------------------------|
//! | `settings` | what a run is asked for: [`Method`], [`Settings`], by value or by name ([`Named`]) |
//! | `point` | an iterate from one clipped diagram: energy, gradient, Hessian ([`Point`], [`evaluate`]) |
//! | `history` | each iterate's [`Record`], the tracker that takes them, the [`Outcome`] |
//! | `run` | the driver: sites along a Morton curve, then the method's steps until the rule holds ([`cvt`]) |
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
//!
//! [`ENERGY_NOISE`]: point::ENERGY_NOISE

mod capacity;
#[cfg(test)]
mod central_difference;
mod hessian;
mod history;
pub mod lbfgs;
pub mod lloyd;
mod newton;
mod point;
mod reduction;
mod run;
mod settings;
mod steihaug;
mod stopping;
mod transport;

pub use capacity::{capacity_cvt, Capacity, CapacityRecord, CapacitySettings, DEFAULT_VOLUME_TOL};
pub use history::{Outcome, Record, Step, StopReason};
pub use point::{evaluate, evaluate_warm, Point, PointRequest};
pub use run::cvt;
pub use settings::{Method, Named, Settings};
pub use stopping::{Frame, Measures, Rule};
pub use transport::{
    optimal_transport, optimal_transport_from, set_stored_margins, Transport, TransportRecord,
    TransportSettings,
};
