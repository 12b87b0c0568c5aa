//! Helpers shared by the integration tests.

use hcvt_core::domain::{Boundary, WindingNumber};
use hcvt_core::geometry::{Euclid, Space};

/// `n` deterministic pseudo-random sites strictly inside `boundary`, by rejection in its
/// bounding box (a 64-bit LCG, so the sites do not depend on a crate's RNG version).
pub fn interior_sites<const D: usize>(boundary: &Boundary<D>, n: usize, seed: u64) -> Vec<[f64; D]>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let mut state = seed;
    let mut rand = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let b = boundary.bounds();
    let mut sites = Vec::with_capacity(n);
    while sites.len() < n {
        let p: [f64; D] = std::array::from_fn(|k| b.lo[k] + rand() * (b.hi[k] - b.lo[k]));
        if Euclid::winding_number(boundary, &p) == Some(1) {
            sites.push(p);
        }
    }
    sites
}
