//! When a CVT has converged: the two stopping rules of DESIGN §7 and the measures behind them.
//!
//! **Default, scale-free ([`Rule::Gap`]).** Each site's gap to its centroid in units of its
//! own cell's size, `r_i = |x_i − c_i| / h_i` with `h_i = V_i^{1/d}`; stop when the RMS of
//! `r` over the sites is below the tolerance ([`DEFAULT_GAP_TOL`]). It does not change with
//! the unit, the position or the shape of the domain, nor with `n`: it reads the same for
//! the 20 × 20 square and for Staten Island in State Plane feet (coordinates near 9e5). The
//! largest gap is reported beside it.
//!
//! **The paper's, to the letter ([`Rule::Paper`]).** `‖g‖/‖X‖ < tol` with the gradient
//! `g_i = 2 m_i (x_i − c_i)` and the sites `X` in the input coordinates (§5.4 of the paper,
//! after Quinn et al. 2012; the paper stops at 1e-10). It grows as `L^d` with the unit and
//! changes with a translation, so it only means something beside the paper's own figures
//! in the paper's own coordinates: it is what our timings against the paper are measured by.
//!
//! Both leave out the sites pinned against the boundary of a non-convex domain with their
//! centroid outside ([`super::lloyd::pinned_sites`]), whose gradient cannot vanish while
//! sites stay inside; they are counted and reported. (In a convex domain no site is pinned,
//! so the paper's rule is then exactly the paper's.)

use crate::error::CoreError;
use crate::geometry::{norm2, sub};

use super::point::Point;

/// Default tolerance of [`Rule::Gap`] on `RMS_i |x_i − c_i| / h_i`.
///
/// Chosen from measurements (`benchmarks/stopping.py`, `docs/results.md`, "Stopping rule"):
/// over 24 runs from random starts in the square, the star and the ball, mean G once the RMS
/// gap first falls below 1e-7 is within 3.3e-9 of its value at the paper's rule, and the
/// largest gap is then at most 1.1e-5 (at 1e-5, mean G is still up to 5.7e-6 away).
pub const DEFAULT_GAP_TOL: f64 = 1e-7;

/// Default tolerance of [`Rule::Paper`] on `‖g‖/‖X‖`: the paper's.
pub const DEFAULT_PAPER_TOL: f64 = 1e-10;

/// Which quantity decides that a CVT has converged (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rule {
    /// `RMS_i |x_i − c_i| / h_i < tol`, scale-free (the default).
    #[default]
    Gap,
    /// `‖g‖/‖X‖ < tol` in the input coordinates (the paper's rule).
    Paper,
}

impl Rule {
    /// `"gap"` or `"paper"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Gap => "gap",
            Self::Paper => "paper",
        }
    }

    /// The rule of that name ([`Rule::as_str`]).
    pub fn from_name(name: &str) -> Result<Self, CoreError> {
        [Self::Gap, Self::Paper]
            .into_iter()
            .find(|r| r.as_str() == name)
            .ok_or_else(|| CoreError::InvalidSettings {
                reason: format!("rule must be 'gap' or 'paper', got {name:?}"),
            })
    }

    /// The tolerance used when none is given.
    pub fn default_tol(self) -> f64 {
        match self {
            Self::Gap => DEFAULT_GAP_TOL,
            Self::Paper => DEFAULT_PAPER_TOL,
        }
    }

    /// The value of `measures` that this rule compares with its tolerance.
    pub fn value(self, measures: &Measures) -> f64 {
        match self {
            Self::Gap => measures.rms_gap,
            Self::Paper => measures.grad_norm,
        }
    }
}

/// Where the core's coordinates sit in the input's: `x = scale · x' + centre`.
///
/// The Python package computes every domain in its own frame (`hcvt.geometry.frame`: the
/// domain about its centre at a size near 1, `scale` a power of two). The paper's rule is
/// defined in the input coordinates, so [`Measures::of_in`] measures `‖g‖/‖X‖` there;
/// the gaps are scale-free and need no frame. `centre` has 3 entries; 2D uses the first 2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// `s > 0`, `L`.
    pub scale: f64,
    /// `c`, `L`.
    pub centre: [f64; 3],
}

impl Default for Frame {
    /// The identity: the core's coordinates are the input's.
    fn default() -> Self {
        Self {
            scale: 1.0,
            centre: [0.0; 3],
        }
    }
}

/// How far sites are from their centroids, by every rule; all dimensionless except
/// `grad_norm`, which is in `L^d` (the paper's rule is not scale-free).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measures {
    /// `√(mean_i r_i²)`, `r_i = |x_i − c_i| / V_i^{1/d}`, over the counted sites.
    pub rms_gap: f64,
    /// `max_i r_i` over the counted sites.
    pub max_gap: f64,
    /// `‖g‖/‖X‖` in the input coordinates, `g` over the counted sites, `X` over all.
    pub grad_norm: f64,
    /// Sites left out as pinned.
    pub pinned: usize,
}

impl Measures {
    /// The measures of `point`, leaving out the sites marked in `pinned` and empty cells
    /// (an empty cell has no centroid; it is reseeded before the next step).
    pub fn of<const D: usize>(point: &Point<D>, pinned: &[bool]) -> Self {
        Self::of_in(point, pinned, &Frame::default())
    }

    /// As [`Measures::of`] for a `point` in the core's coordinates of `frame`, with
    /// `grad_norm` in the input's: `g = s^(d+1) g'`, `X = s X' + c`, so
    /// `‖g‖/‖X‖ = s^d · ‖g'‖ / ‖X' + c/s‖` (factor by factor, so that nothing over- or
    /// underflows unless the result does). Bitwise [`Measures::of`] for the identity.
    pub fn of_in<const D: usize>(point: &Point<D>, pinned: &[bool], frame: &Frame) -> Self {
        Self::of_cells(point, pinned, frame, D)
    }

    /// As [`Measures::of_in`] for cells of dimension `dim` (2 on the sphere, where
    /// `point.gradient` is the tangent gradient): there `r_i = |g_i| / (2 m_i) /
    /// V_i^{1/dim}`, the tangent distance to the constrained centroid `∫x/|∫x|` to first
    /// order, and `‖g‖/‖X‖` scales as `s^dim`.
    pub fn of_cells<const D: usize>(
        point: &Point<D>,
        pinned: &[bool],
        frame: &Frame,
        dim: usize,
    ) -> Self {
        let (mut sum_r2, mut max_r, mut counted, mut g2) = (0.0, 0.0_f64, 0usize, 0.0);
        let diagram = &point.diagram;
        for (((m, w), &g), &p) in (diagram.moments.iter())
            .zip(diagram.mass_moments())
            .zip(&point.gradient)
            .zip(pinned)
        {
            if p || m.mass <= 0.0 || w.mass <= 0.0 {
                continue;
            }
            // |x − c| = |m1| / m with m1 the (ρ-weighted) first moment about the site, over
            // the geometric size V^(1/d) of the cell; on a curved domain the tangent part
            // of m1, which is |g| / 2.
            let offset = if dim == D {
                norm2(w.first).sqrt() / w.mass
            } else {
                norm2(g).sqrt() / (2.0 * w.mass)
            };
            let r = offset / cell_size::<D>(m.mass, dim);
            sum_r2 += r * r;
            max_r = max_r.max(r);
            counted += 1;
            g2 += norm2(g);
        }
        let shift: [f64; D] =
            std::array::from_fn(|k| frame.centre.get(k).map_or(0.0, |c| c / frame.scale));
        let x2: f64 = point
            .sites
            .iter()
            .map(|&x| norm2::<D>(std::array::from_fn(|k| x[k] + shift[k])))
            .sum();
        Self {
            rms_gap: (sum_r2 / counted.max(1) as f64).sqrt(),
            max_gap: max_r,
            // Zero for a zero gradient, even with every site at the origin.
            grad_norm: if g2 == 0.0 {
                0.0
            } else {
                (0..dim).fold(g2.sqrt() / x2.sqrt().max(f64::MIN_POSITIVE), |v, _| {
                    v * frame.scale
                })
            },
            pinned: pinned.iter().filter(|&&p| p).count(),
        }
    }
}

/// Consecutive idle iterations ([`Stall::idle`]) after which a run restarts, and after
/// which, once restarted, it stops as stalled.
pub const STALL_ITERATIONS: usize = 3;
/// The largest move of an idle iteration, relative to the mean spacing `h`: round-off
/// (a converging run moves its sites by at least the gap, `1e-7 h` at the default
/// tolerance, in every iteration).
pub const STALL_MOVE: f64 = 1e-12;

/// What a run does after an iteration ([`Stall::after`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stalled {
    /// Go on.
    No,
    /// [`STALL_ITERATIONS`] idle iterations: restart (forget the L-BFGS memory, so that
    /// the next direction is the Lloyd step).
    Restart,
    /// Idle again for as long after the restart: stop.
    Stop,
}

/// Watches for a run that no longer moves (**stalled**): an iteration is idle when no
/// site moves by more than [`STALL_MOVE`]` · h` and the energy changes by no more than
/// its round-off (`noise · |E|`). Fandisk, 20,000 sites, 1,694 of them held on its
/// features: L-BFGS emptied three cells, and every later iteration reseeded them to
/// places where they were empty again, the same energy to the last bit, until
/// `max_iter`. A converging run is never idle, so its results do not change.
#[derive(Debug, Clone, Default)]
pub struct Stall {
    idle: usize,
    restarted: bool,
}

impl Stall {
    /// Whether the step from `(before, e0)` to `(after, e1)` was idle at spacing `h`.
    pub fn idle<const D: usize>(
        before: &[[f64; D]],
        after: &[[f64; D]],
        e0: f64,
        e1: f64,
        h: f64,
        noise: f64,
    ) -> bool {
        let still =
            (before.iter().zip(after)).all(|(&a, &b)| norm2(sub(a, b)) <= (STALL_MOVE * h).powi(2));
        still && (e1 - e0).abs() <= noise * e0.abs()
    }

    /// Count one iteration, idle or not, and say what to do.
    pub fn after(&mut self, idle: bool) -> Stalled {
        if !idle {
            self.idle = 0;
            return Stalled::No;
        }
        self.idle += 1;
        if self.idle < STALL_ITERATIONS {
            Stalled::No
        } else if self.restarted {
            Stalled::Stop
        } else {
            self.restarted = true;
            self.idle = 0;
            Stalled::Restart
        }
    }
}

/// `V^{1/dim}`, in a flat domain (`dim == D`) with the exponent a constant: LLVM then
/// turns `powf(V, 1/2)` into a square root, whose bits differ from the library's `pow`
/// (a runtime exponent changed the Newton fingerprint of the star).
pub(super) fn cell_size<const D: usize>(volume: f64, dim: usize) -> f64 {
    if dim == D {
        volume.powf(1.0 / D as f64)
    } else {
        volume.powf(1.0 / dim as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagram::Diagram;
    use crate::moments::Moments;

    /// Two square cells of side 2 (V = 4, h = 2): one with its centroid 0.1 from the site,
    /// one 0.3 away and pinned.
    fn two_cells(scale: f64, shift: [f64; 2]) -> Point<2> {
        let cell = |dx: f64| {
            let mass = 4.0 * scale * scale;
            Moments {
                mass,
                first: [mass * dx * scale, 0.0],
                second: 0.0,
            }
        };
        let diagram = Diagram {
            moments: vec![cell(0.1), cell(0.3)],
            ..Diagram::default()
        };
        let sites = [[1.0, 1.0], [3.0, 1.0]];
        let sites = sites
            .iter()
            .map(|x| [x[0] * scale + shift[0], x[1] * scale + shift[1]]);
        Point {
            sites: sites.collect(),
            gradient: diagram.gradient(),
            energy: 0.0,
            diagram,
            hessian: None,
        }
    }

    #[test]
    fn the_gap_is_free_of_scale_and_position_and_the_paper_norm_is_not() {
        let pinned = [false, true];
        let unit = Measures::of(&two_cells(1.0, [0.0; 2]), &pinned);
        assert!((unit.rms_gap - 0.05).abs() < 1e-15, "{unit:?}");
        assert!((unit.max_gap - 0.05).abs() < 1e-15);
        assert_eq!(unit.pinned, 1);
        // g_0 = 2 m (x − c) = −2 m1 = (−0.8, 0); ‖X‖ = √(2 + 10).
        assert!((unit.grad_norm - 0.8 / 12f64.sqrt()).abs() < 1e-15);

        let moved = Measures::of(&two_cells(1000.0, [9e5, -4e5]), &pinned);
        assert!((moved.rms_gap - unit.rms_gap).abs() < 1e-15 * unit.rms_gap.max(1.0));
        assert!((moved.max_gap - unit.max_gap).abs() < 1e-15);
        assert!(moved.grad_norm > 1e3 * unit.grad_norm);

        // In a frame: the same sites as `moved`, given as x' = (x - c) / s, measure the same.
        let frame = Frame {
            scale: 1000.0,
            centre: [9e5, -4e5, 0.0],
        };
        let framed = Measures::of_in(&two_cells(1.0, [0.0; 2]), &pinned, &frame);
        assert!((framed.grad_norm - moved.grad_norm).abs() <= 1e-14 * moved.grad_norm);
        assert_eq!(framed.rms_gap, unit.rms_gap);
        assert_eq!(
            Measures::of_in(&two_cells(1.0, [0.0; 2]), &pinned, &Frame::default()),
            unit
        );

        let counted = Measures::of(&two_cells(1.0, [0.0; 2]), &[false, false]);
        assert!((counted.rms_gap - ((0.0025 + 0.0225) / 2.0f64).sqrt()).abs() < 1e-15);
        assert!((counted.max_gap - 0.15).abs() < 1e-15);
        assert_eq!(Rule::Gap.value(&counted), counted.rms_gap);
        assert_eq!(Rule::Paper.value(&counted), counted.grad_norm);
    }

    #[test]
    fn a_run_restarts_once_then_stops_when_idle() {
        let x = [[0.5, 0.5], [1.5, 0.5]];
        let h = 1.0;
        assert!(Stall::idle(&x, &x, 2.0, 2.0 + 1e-13, h, 1e-12));
        // A move of 1e-9 h, or an energy change above round-off, is progress.
        let y = [[0.5, 0.5 + 1e-9], [1.5, 0.5]];
        assert!(!Stall::idle(&x, &y, 2.0, 2.0, h, 1e-12));
        assert!(!Stall::idle(&x, &x, 2.0, 2.0 - 1e-11, h, 1e-12));

        let mut stall = Stall::default();
        let mut seen = Vec::new();
        for idle in [true, true, false, true, true, true, true, true, true] {
            seen.push(stall.after(idle));
        }
        use Stalled::*;
        assert_eq!(seen, [No, No, No, No, No, Restart, No, No, Stop]);
    }
}
