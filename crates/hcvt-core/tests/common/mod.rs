//! Helpers shared by the integration tests.

use hcvt_core::domain::Solid;

pub use hcvt_core::sample::interior_sites;

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
