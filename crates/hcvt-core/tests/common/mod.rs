//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};

use hcvt_core::{evaluate, ConvexCell, DomainKind, Euclid, PointRequest, Polygon, Solid, Space};

#[allow(unused_imports)] // not every test file uses it
pub use hcvt_core::sample::interior_sites;

// One check of a Hessian for the unit and the integration tests: the crate's own file.
#[allow(dead_code)]
#[path = "../../src/optimise/central_difference.rs"]
mod central_difference;
#[allow(unused_imports)]
pub use central_difference::central_difference_error;

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

/// Closed rings as one polygon: outer rings counter-clockwise, holes clockwise.
#[allow(dead_code)]
pub fn polygon(rings: &[&[[f64; 2]]]) -> Polygon {
    Polygon::from_rings(rings).unwrap()
}

/// `../shared/data/3d` beside the repository, or `None` where the shared data is absent.
#[allow(dead_code)]
pub fn data_3d() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/3d");
    dir.is_dir().then_some(dir)
}

/// A closed mesh of triangles from an OFF or ASCII PLY file.
#[allow(dead_code)]
pub fn read_mesh(path: &Path) -> Solid {
    let text = std::fs::read_to_string(path).unwrap();
    let (counts, body) = match text.split_once("end_header") {
        Some((header, body)) => {
            let count = |element: &str| -> usize {
                let line = header
                    .lines()
                    .find_map(|l| l.strip_prefix(element))
                    .unwrap();
                line.trim().parse().unwrap()
            };
            (Some((count("element vertex"), count("element face"))), body)
        }
        None => (None, text.trim_start().strip_prefix("OFF").unwrap()),
    };
    let mut tokens = body
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(str::split_whitespace);
    let mut next = || tokens.next().unwrap();
    let (nv, nf): (usize, usize) = counts.unwrap_or_else(|| {
        let counts = (next().parse().unwrap(), next().parse().unwrap());
        next(); // edges
        counts
    });
    let vertices = (0..nv)
        .map(|_| [0; 3].map(|_| next().parse::<f64>().unwrap()))
        .collect();
    let faces = (0..nf)
        .map(|_| {
            assert_eq!(next(), "3");
            [0; 3].map(|_| next().parse::<u32>().unwrap())
        })
        .collect();
    Solid::new(vertices, faces).unwrap()
}

/// Relative error of central differences of the CVT energy's gradient against the exact
/// Hessian product, along a direction made from the sites' own digits (deterministic, in
/// every coordinate) of 1e-6 mean spacings.
#[allow(dead_code)]
pub fn hessian_error<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
) -> f64
where
    Euclid: Space<D>,
{
    let h = (domain.volume() / sites.len() as f64).powf(1.0 / D as f64);
    let with_hessian = PointRequest {
        hessian: true,
        density: None,
    };
    let point = evaluate::<D, C, _>(domain, sites.clone(), &with_hessian).unwrap();
    let v: Vec<[f64; D]> = sites
        .iter()
        .map(|s| s.map(|x| (x * 1e4).sin() * 1e-6 * h))
        .collect();
    let exact = point.hessian_product(&v).unwrap();
    central_difference_error(&sites, &v, &exact, |moved| {
        evaluate::<D, C, _>(domain, moved, &PointRequest::default())
            .unwrap()
            .gradient
    })
}
