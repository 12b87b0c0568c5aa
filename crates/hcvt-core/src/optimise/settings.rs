//! What a CVT run is asked for: the method, the stopping rule and its tolerance, and the
//! limits; by value or by name (the binding's).

use crate::density::Density;
use crate::error::CoreError;

use super::stopping::{Frame, Rule};

/// Which iteration to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Quasi-Newton with a line search (Liu et al. 2009): one diagram per evaluation.
    Lbfgs,
    /// Lloyd's fixed-point iteration `x_i ← c_i`: one diagram per iteration.
    Lloyd,
    /// Newton with the exact Hessian, truncated CG in a trust region ([`newton`](super::newton)).
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

/// Parameters of [`cvt`](super::cvt).
#[derive(Debug, Clone, Copy)]
pub struct Settings<'a, const D: usize> {
    /// [`Method::Lbfgs`], [`Method::Lloyd`] or [`Method::Newton`].
    pub method: Method,
    /// The stopping rule ([`stopping`](super::stopping)).
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
