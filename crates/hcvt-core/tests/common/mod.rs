//! Helpers shared by the integration tests.

use hcvt_core::domain::{Boundary, Solid, WindingNumber};
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

/// The unit cube with its top face (z = 1) pushed in to a point at z = 0.8: not convex.
#[allow(dead_code)] // not every test file uses it
pub fn dented_cube() -> Solid {
    let solid = Solid::cuboid([0.0; 3], [1.0; 3]).unwrap();
    let mut vertices = solid.vertices().to_vec();
    vertices.push([0.5, 0.5, 0.8]);
    let mut faces: Vec<[u32; 3]> = solid
        .simplices()
        .iter()
        .copied()
        .filter(|t| !t.iter().all(|&v| v >= 4))
        .collect();
    faces.extend([[4, 5, 8], [5, 7, 8], [7, 6, 8], [6, 4, 8]]);
    Solid::new(vertices, faces).unwrap()
}
