//! Deterministic pseudo-random points for tests, examples and benchmarks: the same points
//! on every platform and with every version of every crate (no RNG dependency).
//!
//! Not part of the API: compiled for this crate's unit tests, and with the cargo feature
//! `sample`, which the integration tests and examples turn on through the crate's
//! dev-dependency on itself.

use crate::diagram::DomainKind;

/// Knuth's 64-bit linear congruential generator (MMIX constants).
///
/// # Example
///
/// ```
/// use hcvt_core::sample::Lcg;
///
/// let mut a = Lcg::new(7);
/// let x = a.unit();
/// assert!((0.0..1.0).contains(&x));
/// assert_eq!(Lcg::new(7).unit(), x); // deterministic
/// ```
#[derive(Debug, Clone)]
pub struct Lcg {
    state: u64,
}

impl Lcg {
    /// The generator started at `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next number, uniform in `[0, 1)` on a grid of `2^-53`.
    pub fn unit(&mut self) -> f64 {
        self.state = self
            .state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` points strictly inside `boundary` (winding number 1), uniform by rejection in its
/// bounding box, drawn from [`Lcg::new`]`(seed)`.
pub fn interior_sites<const D: usize, K: DomainKind<D>>(
    boundary: &K,
    n: usize,
    seed: u64,
) -> Vec<[f64; D]> {
    let mut rng = Lcg::new(seed);
    let b = boundary.bounds();
    let mut sites = Vec::with_capacity(n);
    while sites.len() < n {
        let p: [f64; D] = std::array::from_fn(|k| b.lo[k] + rng.unit() * (b.hi[k] - b.lo[k]));
        if boundary.locate(&p) == Some(1) {
            sites.push(p);
        }
    }
    sites
}
