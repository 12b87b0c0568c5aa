//! The strong-Wolfe line search (module docs of [`super`]).

use crate::error::CoreError;
use crate::optimise::point::ENERGY_NOISE;

/// A negative slope (NaN is not one).
pub(super) fn is_descent(slope: f64) -> bool {
    slope < 0.0
}

/// `φ(t) ↦ (state, φ, φ')`, or `None` for an infeasible `t`.
pub type LineFunction<'a, T> = dyn FnMut(f64) -> Result<Option<(T, f64, f64)>, CoreError> + 'a;

/// Parameters of the strong-Wolfe line search on `φ(t) = E(x + t p)`.
#[derive(Debug, Clone, Copy)]
pub struct LineSearch {
    /// Sufficient decrease `φ(t) ≤ φ(0) + c1 t φ'(0)` (1e-4, as HLBFGS and libLBFGS).
    pub c1: f64,
    /// Curvature `|φ'(t)| ≤ c2 |φ'(0)|` (0.9, the quasi-Newton choice).
    pub c2: f64,
    /// Hager–Zhang's `δ`: the approximate condition asks `φ'(t) ≤ (1 − 2δ) |φ'(0)|`.
    pub delta: f64,
    /// Energy round-off allowance relative to `|φ(0)|`.
    pub noise: f64,
    /// Most evaluations of `φ`.
    pub max_evaluations: usize,
}

impl LineSearch {
    /// The usual constants with at most `max_evaluations` evaluations.
    pub fn new(max_evaluations: usize) -> Self {
        Self {
            c1: 1e-4,
            c2: 0.9,
            delta: 0.1,
            noise: ENERGY_NOISE,
            max_evaluations: max_evaluations.max(1),
        }
    }

    /// The constants of the backtracking search of a partitioned run (`hcvt.distributed`,
    /// [`LineSearch::accepts`]): as [`LineSearch::new`] but `δ = c1`, with which its runs
    /// were recorded (a step within round-off must then be all but as steep as the start).
    pub fn backtracking(max_evaluations: usize) -> Self {
        Self {
            delta: 1e-4,
            ..Self::new(max_evaluations)
        }
    }

    /// Sufficient decrease `φ(t) ≤ φ(0) + c1 t φ'(0)`, or, with `φ(t)` no higher than `φ(0)`
    /// within round-off (`noise |φ(0)|`), the approximate condition of Hager and Zhang
    /// `φ'(t) ≤ (1 − 2δ) |φ'(0)|` (module docs of [`super`], "Round-off").
    pub fn decreases(&self, phi0: f64, slope0: f64, t: f64, value: f64, slope: f64) -> bool {
        value <= phi0 + self.c1 * t * slope0
            || (value <= phi0 + self.noise * phi0.abs()
                && slope <= (1.0 - 2.0 * self.delta) * -slope0)
    }

    /// Whether a backtracking search (the partitioned run's, which halves `t` from 1 until
    /// this holds) accepts the step `t` with `φ(t) = value`, `φ'(t) = slope`: sufficient
    /// decrease, or within round-off the approximate condition with the curvature
    /// condition's lower side `φ'(t) ≥ c2 φ'(0)`.
    pub fn accepts(&self, phi0: f64, slope0: f64, t: f64, value: f64, slope: f64) -> bool {
        self.decreases(phi0, slope0, t, value, slope)
            && (value <= phi0 + self.c1 * t * slope0 || self.c2 * slope0 <= slope)
    }

    /// A step `t > 0` satisfying the strong Wolfe conditions, or, with energies equal to
    /// round-off, the approximate ones. After `max_evaluations` trials without one, the
    /// best trial that satisfied the decrease condition, and `None` if none did.
    ///
    /// `phi(t)` returns the state at `t` with `φ(t)` and `φ'(t)`, or `None` when `t` is
    /// infeasible; then every longer step is taken to be infeasible too.
    pub fn search<T>(
        &self,
        phi0: f64,
        slope0: f64,
        phi: &mut LineFunction<'_, T>,
    ) -> Result<Option<T>, CoreError> {
        let noise = self.noise * phi0.abs();
        let decreases =
            |t: f64, value: f64, slope: f64| self.decreases(phi0, slope0, t, value, slope);
        let flat = |slope: f64| slope.abs() <= self.c2 * slope0.abs();
        // `lo`: the best step so far, satisfying the decrease condition; `hi`: the other end
        // of a bracket holding acceptable steps, once one is known.
        let mut lo = Trial::start(phi0, slope0);
        let mut hi: Option<Trial<T>> = None;
        let mut t = 1.0;
        for _ in 0..self.max_evaluations {
            let Some((state, value, slope)) = phi(t)? else {
                let infeasible = Trial::infeasible(t);
                t = next_in_bracket(&lo, &infeasible);
                hi = Some(infeasible);
                continue;
            };
            let trial = Trial::at(t, value, slope, state);
            if !decreases(t, value, slope) || value > lo.value + noise {
                hi = Some(trial);
            } else if flat(slope) {
                return Ok(trial.state);
            } else {
                // The minimum lies on the side of `trial` where φ decreases.
                if let Some(h) = &hi {
                    if slope * (h.t - trial.t) >= 0.0 {
                        hi = Some(std::mem::replace(&mut lo, trial));
                    } else {
                        lo = trial;
                    }
                } else if slope >= 0.0 {
                    hi = Some(std::mem::replace(&mut lo, trial));
                } else {
                    lo = trial;
                }
            }
            t = match &hi {
                Some(h) => {
                    if (h.t - lo.t).abs() <= 1e-12 * lo.t.max(h.t) {
                        break;
                    }
                    next_in_bracket(&lo, h)
                }
                None => extrapolate(slope0, &lo),
            };
        }
        // Out of trials: the best step that lowered the energy, if any (its pair is kept
        // only if it has positive curvature), rather than none.
        Ok(lo.state)
    }
}

/// A trial step with `φ` and `φ'`; infeasible ones have infinite values.
#[derive(Debug)]
struct Trial<T> {
    t: f64,
    value: f64,
    slope: f64,
    state: Option<T>,
}

impl<T> Trial<T> {
    fn start(value: f64, slope: f64) -> Self {
        Self {
            t: 0.0,
            value,
            slope,
            state: None,
        }
    }

    fn at(t: f64, value: f64, slope: f64, state: T) -> Self {
        Self {
            t,
            value,
            slope,
            state: Some(state),
        }
    }

    fn infeasible(t: f64) -> Self {
        Self {
            t,
            value: f64::INFINITY,
            slope: f64::NAN,
            state: None,
        }
    }
}

/// A longer step while every trial still descends steeply: where the secant of `φ'`
/// through the start and `lo` vanishes, kept within 1.5 to 4 times `lo` (Moré and
/// Thuente extrapolate up to 4 times).
fn extrapolate<T>(start_slope: f64, lo: &Trial<T>) -> f64 {
    let secant = if lo.slope > start_slope {
        lo.t * start_slope / (start_slope - lo.slope)
    } else {
        f64::INFINITY
    };
    secant.clamp(1.5 * lo.t, 4.0 * lo.t)
}

/// The next trial strictly inside the bracket `[lo, hi]` (either order), in its middle 80 %.
fn next_in_bracket<T>(lo: &Trial<T>, hi: &Trial<T>) -> f64 {
    let width = hi.t - lo.t;
    // Derivatives along the bracket, from lo towards hi: lo's is negative by construction.
    let (d_lo, d_hi) = (lo.slope * width.signum(), hi.slope * width.signum());
    let fraction = if !hi.value.is_finite() {
        0.5
    } else if d_hi > 0.0 && d_lo < 0.0 {
        // φ' changes sign: the secant of φ' (exact for a quadratic, and it uses only the
        // derivatives, which stay accurate when energy differences are round-off).
        d_lo / (d_lo - d_hi)
    } else {
        // Quadratic through φ(lo), φ'(lo), φ(hi).
        let curvature = hi.value - lo.value - d_lo * width.abs();
        if curvature > 0.0 {
            -d_lo * width.abs() / (2.0 * curvature)
        } else {
            0.5
        }
    };
    lo.t + fraction.clamp(0.1, 0.9) * width
}

#[cfg(test)]
mod tests {
    use super::*;

    type Phi<'a> = LineFunction<'a, ()>;

    fn run(search: &LineSearch, phi0: f64, slope0: f64, phi: &mut Phi<'_>) -> Option<f64> {
        let mut last = f64::NAN;
        let mut wrapped = |t: f64| {
            last = t;
            phi(t)
        };
        search
            .search(phi0, slope0, &mut wrapped)
            .unwrap()
            .map(|()| last)
    }

    #[test]
    fn quadratic_is_solved_by_the_first_secant() {
        // φ(t) = (t - 3)², φ'(0) = -6. With c2 = 0.9, t = 1 would do (|φ'(1)| = 4 ≤ 5.4);
        // with c2 = 0.1 the search must extrapolate past 3 and zoom back by the secant.
        let search = LineSearch {
            c2: 0.1,
            ..LineSearch::new(20)
        };
        let mut count = 0;
        let mut phi = |t: f64| {
            count += 1;
            Ok(Some(((), (t - 3.0) * (t - 3.0), 2.0 * (t - 3.0))))
        };
        let t = run(&search, 9.0, -6.0, &mut phi).unwrap();
        assert!((t - 3.0).abs() < 0.3 * 0.1 * 6.0, "t = {t}");
        assert!(count <= 4, "{count} evaluations");
    }

    #[test]
    fn infeasible_steps_are_shortened() {
        // φ(t) = (t - 3)², but every t > 0.7 is infeasible.
        let search = LineSearch::new(30);
        let mut phi =
            |t: f64| Ok((t <= 0.7).then_some(((), (t - 3.0) * (t - 3.0), 2.0 * (t - 3.0))));
        // t = 1 is infeasible; steps in [0.3, 0.7] are feasible and flat (|φ'| ≤ 0.9·6).
        let t = run(&search, 9.0, -6.0, &mut phi).unwrap();
        assert!((0.3..=0.7).contains(&t), "t = {t}");
    }

    #[test]
    fn round_off_energies_are_judged_by_the_derivative() {
        // φ has a minimum at t = 2 below the round-off of φ(0) = 1: energies say nothing,
        // the derivative says where the minimum is.
        let search = LineSearch {
            c2: 0.1,
            ..LineSearch::new(20)
        };
        let scale = 1e-18;
        let mut phi = |t: f64| {
            let noise = if (t * 1e3) as i64 % 2 == 0 {
                1e-16
            } else {
                -1e-16
            };
            let value = 1.0 + scale * (t - 2.0) * (t - 2.0) + noise;
            Ok(Some(((), value, 2.0 * scale * (t - 2.0))))
        };
        let t = run(&search, 1.0 + 4.0 * scale, -4.0 * scale, &mut phi).unwrap();
        assert!((t - 2.0).abs() <= 0.1 * 2.0, "t = {t}");
    }

    #[test]
    fn out_of_trials_the_best_decrease_is_kept() {
        // φ(t) = 1 - t never flattens: trials 1, then 4 (extrapolated) and 16; the last is best.
        let search = LineSearch::new(3);
        let mut phi = |t: f64| Ok(Some((t, 1.0 - t, -1.0)));
        assert_eq!(search.search(1.0, -1.0, &mut phi).unwrap(), Some(16.0));
        // φ(t) = 1 + t from a wrong slope: nothing decreases, so no step at all.
        let mut phi = |t: f64| Ok(Some((t, 1.0 + t, 1.0)));
        assert_eq!(search.search(1.0, -1.0, &mut phi).unwrap(), None);
    }
}
