//! Property tests (proptest, fixed seed, shrinking): for arbitrary polygons and sites the
//! core returns a diagram whose cell volumes sum to the domain's, with finite moments, or a
//! `CoreError`; never a panic. Plus the regressions these properties found.
//!
//! `PROPTEST_CASES` sets the number of cases per property (default 1,000 here; 3,000 in all).

use crate::common::{data_3d, read_mesh};

use hcvt_core::{
    clipped_diagram, CoreError, Diagram, Options, Polygon, PolygonCell, PolyhedronCell, Request,
    Solid,
};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

fn config() -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(1000);
    Config {
        cases,
        rng_seed: RngSeed::Fixed(0x5eed_c0de),
        failure_persistence: None,
        ..Config::default()
    }
}

/// Closed ring of segments over `vertices` in order.
fn ring(vertices: Vec<[f64; 2]>) -> Result<Polygon, CoreError> {
    let n = vertices.len() as u32;
    let segments = (0..n).map(|i| [i, (i + 1) % n]).collect();
    Polygon::new(vertices, segments)
}

/// A simple, counter-clockwise ring, star-shaped about `offset`: vertex `i` of `k` at
/// angle `(i + u_i) 2π / k` with `u_i` in [0.25, 0.75), so that consecutive angles differ
/// by less than π (else the ring may cross itself), and radius `r_i` in [0.2, 1].
fn star(parts: &[(f64, f64)], scale: f64, offset: [f64; 2]) -> Vec<[f64; 2]> {
    let k = parts.len() as f64;
    parts
        .iter()
        .enumerate()
        .map(|(i, &(u, r))| {
            let a = (i as f64 + u) * std::f64::consts::TAU / k;
            [
                offset[0] + scale * r * a.cos(),
                offset[1] + scale * r * a.sin(),
            ]
        })
        .collect()
}

/// Σ volume = V to 1e-12 relative plus 1e-14 diag^d (sliver round-off, see
/// tests/test_properties.py), and every moment finite.
fn check<const D: usize>(
    result: Result<hcvt_core::Diagram<D>, CoreError>,
    volume: f64,
    box_measure: f64,
) -> Result<(), TestCaseError> {
    let Ok(d) = result else {
        return Ok(()); // a CoreError is a documented answer
    };
    let mut total = 0.0;
    for m in &d.moments {
        prop_assert!(m.mass.is_finite() && m.second.is_finite(), "{m:?}");
        prop_assert!(m.first.iter().all(|x| x.is_finite()), "{m:?}");
        prop_assert!(
            m.mass == 0.0 || m.dimensionless_second_moment().is_some_and(f64::is_finite),
            "G of {m:?}"
        );
        total += m.mass;
    }
    let tol = 1e-12 * volume + 1e-14 * box_measure;
    prop_assert!((total - volume).abs() <= tol, "Σ = {total}, V = {volume}");
    Ok(())
}

fn sites_from(ratios: &[(f64, f64)], lo: [f64; 2], hi: [f64; 2]) -> Vec<[f64; 2]> {
    ratios
        .iter()
        .map(|&(u, v)| [lo[0] + (hi[0] - lo[0]) * u, lo[1] + (hi[1] - lo[1]) * v])
        .collect()
}

proptest! {
    #![proptest_config(config())]

    /// Star polygons, tiny, huge or far from the origin; sites anywhere in the box (some
    /// outside), lattice-aligned with the box, on vertices, duplicated.
    #[test]
    fn star_polygons_give_exact_diagrams_or_errors(
        parts in prop::collection::vec((0.25f64..0.75, 0.2f64..1.0), 3..12),
        scale in prop::sample::select(vec![1.0, 1e-3, 1e3]),
        offset in prop::sample::select(vec![[0.0, 0.0], [1e6, -1e6], [-3.5, 2.25]]),
        ratios in prop::collection::vec((0.0f64..=1.0, 0.0f64..=1.0), 1..30),
        lattice in 0usize..5,
        on_vertex in any::<bool>(),
        duplicate in any::<bool>(),
    ) {
        let vertices = star(&parts, scale, offset);
        prop_assume!(vertices.len() >= 3);
        let Ok(domain) = ring(vertices.clone()) else { return Ok(()) };
        let b = domain.bounds();
        let mut sites = sites_from(&ratios, b.lo, b.hi);
        for i in 0..=lattice {
            for j in 0..=lattice {
                let m = lattice.max(1) as f64;
                sites.push(sites_from(&[(i as f64 / m, j as f64 / m)], b.lo, b.hi)[0]);
            }
        }
        if on_vertex {
            sites.push(vertices[0]);
        }
        if duplicate {
            sites.push(sites[0]);
        }
        let measure = b.diagonal().powi(2);
        let options = Options { allow_outside: true };
        let result = clipped_diagram::<2, PolygonCell, _>(&domain, &sites, &Request { options, ..Request::default() }).map(|c| c.diagram);
        if duplicate {
            let is_duplicate_error = matches!(result, Err(CoreError::DuplicateSites { .. }));
            prop_assert!(is_duplicate_error);
        }
        check(result, domain.volume(), measure)?;
        // Without allow_outside: the same or SiteOutsideDomain.
        let strict = clipped_diagram::<2, PolygonCell, _>(&domain, &sites, &Request::default()).map(|c| c.diagram);
        check(strict, domain.volume(), measure)?;
    }

    /// Any finite or non-finite coordinates for the boundary and the sites: an answer.
    #[test]
    fn arbitrary_floats_never_panic(
        vertices in prop::collection::vec(prop::array::uniform2(any::<f64>()), 0..6),
        sites in prop::collection::vec(prop::array::uniform2(any::<f64>()), 0..5),
    ) {
        if let Ok(domain) = ring(vertices) {
            let b = domain.bounds();
            let measure = (b.hi[0] - b.lo[0]) * (b.hi[1] - b.lo[1]);
            let options = Options { allow_outside: true };
            let result = clipped_diagram::<2, PolygonCell, _>(&domain, &sites, &Request { options, ..Request::default() }).map(|c| c.diagram);
            // Self-intersecting rings are the front end's to refuse: only no panic here.
            let _ = (result, measure);
        }
    }

    /// The box [0, 2] x [0, 1] x [0, 1] with sites on a lattice aligned with its faces, on
    /// its vertices, edges and faces, outside it, and duplicated.
    #[test]
    fn box_with_degenerate_sites(
        ratios in prop::collection::vec(prop::array::uniform3(0.0f64..=1.0), 0..12),
        lattice in 1usize..4,
        special in prop::collection::vec(prop::array::uniform3(0usize..3), 0..6),
        outside in any::<bool>(),
    ) {
        let solid = cuboid([2.0, 1.0, 1.0]);
        let mut sites: Vec<[f64; 3]> = ratios.iter().map(|r| [2.0 * r[0], r[1], r[2]]).collect();
        let m = lattice as f64;
        for i in 0..=lattice {
            for j in 0..=lattice {
                sites.push([2.0 * i as f64 / m, j as f64 / m, 0.5]);
            }
        }
        // 0, 1/2 and 1 of each side: corners, edge midpoints, face centres, the centre.
        sites.extend(special.iter().map(|s| [s[0] as f64, s[1] as f64 / 2.0, s[2] as f64 / 2.0]));
        if outside {
            sites.push([2.5, 0.5, 0.5]);
        }
        let options = Options { allow_outside: true };
        let result = clipped_diagram::<3, PolyhedronCell, _>(&solid, &sites, &Request { options, ..Request::default() }).map(|c| c.diagram);
        check(result, 2.0, 6.0f64.powf(1.5))?;
    }
}

/// Axis-aligned box `[0, s₀] x [0, s₁] x [0, s₂]` as 12 outward triangles.
fn cuboid(s: [f64; 3]) -> Solid {
    Solid::cuboid([0.0; 3], s).unwrap()
}

/// The icosphere of ../shared/data/3d/sphere.ply (ASCII PLY), or None without the data.
fn sphere() -> Option<Solid> {
    Some(read_mesh(&data_3d()?.join("sphere.ply")))
}

/// Found by tests/test_properties.py: one site at the centroid of face 199 of the sphere,
/// which rounds to 1e-17 outside the face. The site was the apex of the cones, and the
/// sides of the cone through face 199 nearly coincided with its plane: volume -3.6
/// instead of 4.15. Now such an apex is refused (`APEX_CLEARANCE`).
#[test]
fn site_within_round_off_of_a_face_regression() {
    let Some(solid) = sphere() else {
        eprintln!("skipped: ../shared/data/3d/sphere.ply not found");
        return;
    };
    let options = Options {
        allow_outside: true,
    };
    for t in [0u32, 1, 199, 500, 1000] {
        let tri = solid.simplex(t);
        let site: [f64; 3] = std::array::from_fn(|k| (tri[0][k] + tri[1][k] + tri[2][k]) / 3.0);
        let d = clipped_diagram::<3, PolyhedronCell, _>(
            &solid,
            &[site],
            &Request {
                options,
                ..Request::default()
            },
        )
        .map(|c| c.diagram)
        .unwrap();
        let v = d.moments[0].mass;
        assert!(
            (v - solid.volume()).abs() <= 1e-12 * solid.volume(),
            "face {t}: cell volume {v}, domain {}",
            solid.volume()
        );
    }
}

/// Found by tests/test_properties.py: with outside sites allowed, the cell of a site whose
/// Voronoi cell only touches the domain at a point summed to ±3.5e-18, with G = NaN or
/// 1e15. Such cancellation is now an empty cell (mass exactly 0).
#[test]
fn cell_touching_the_domain_at_a_point_is_empty_regression() {
    // The triangle-ish ring shapely made of a hole outside its shell, counter-clockwise.
    let domain = ring(vec![[1.0, 1.0], [0.0, 1.0], [0.75, 0.5], [3.0, -1.0]]).unwrap();
    let b = domain.bounds();
    let mut sites = Vec::new();
    for j in 1..5 {
        for i in 1..5 {
            sites.push([
                b.lo[0] + (b.hi[0] - b.lo[0]) * i as f64 / 5.0,
                b.lo[1] + (b.hi[1] - b.lo[1]) * j as f64 / 5.0,
            ]);
        }
    }
    let d = allowing_outside(&domain, &sites).unwrap();
    for (i, m) in d.moments.iter().enumerate() {
        let g = m.dimensionless_second_moment();
        assert!(
            m.mass == 0.0 || g.is_some_and(|g| g.is_finite() && g < 1.0),
            "cell {i}: {m:?}"
        );
    }
    let total: f64 = d.moments.iter().map(|m| m.mass).sum();
    assert!((total - domain.volume()).abs() < 1e-14, "{total}");
}

/// Found by tests/test_properties.py: a site on the slope-1 edge (0, -1)-(1, 0) whose cell
/// is a square centred on it. The site has no winding number, the cell's vertex mean is
/// the site again, and the nudges all went along (1, 1), staying on the edge: the apex was
/// taken with winding 0 on the boundary and the cell counted 0.24 instead of 0.12.
#[test]
fn apex_nudged_along_the_boundary_regression() {
    let domain = ring(vec![[0.0, -1.0], [1.0, 0.0], [-1.0, 1.0], [0.0, -2.0]]).unwrap();
    let sites = [
        [0.2, -1.4],
        [-0.2, -0.8],
        [0.2, -0.8],
        [0.6, -0.8],
        [0.2, -0.2],
    ];
    let d = allowing_outside(&domain, &sites).unwrap();
    let v: Vec<f64> = d.moments.iter().map(|m| m.mass).collect();
    assert!((v[2] - 0.12).abs() < 1e-15, "{v:?}");
    let total: f64 = v.iter().sum();
    assert!((total - 2.0).abs() < 1e-14, "{total}");
}

/// The diagram of `sites` in `domain`, sites outside allowed.
fn allowing_outside(domain: &Polygon, sites: &[[f64; 2]]) -> Result<Diagram<2>, CoreError> {
    let request = Request {
        options: Options {
            allow_outside: true,
        },
        ..Request::default()
    };
    clipped_diagram::<2, PolygonCell, _>(domain, sites, &request).map(|c| c.diagram)
}

/// Found by tests/test_properties.py: an allowed outside site at 1e10 from the unit square
/// got the cell volume 8193. Sites farther than `FAR_OUTSIDE` box diagonals are refused.
#[test]
fn site_far_outside_is_refused_regression() {
    let domain = ring(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]).unwrap();
    let far = allowing_outside(&domain, &[[1e10, 0.5]]);
    assert!(matches!(
        far,
        Err(CoreError::SiteFarOutside { index: 0, .. })
    ));
    let d = allowing_outside(&domain, &[[50.0, 0.5]]).unwrap();
    assert!(
        (d.moments[0].mass - 1.0).abs() < 1e-12,
        "{:?}",
        d.moments[0]
    );
}

/// Found by tests/test_properties.py: a clip passing within round-off of a cell vertex
/// left an edge of length 1e-17 whose normal pointed anywhere, and `excludes` trusted it:
/// the hypotenuse of the triangle, with an end inside the cell, was skipped and the cell
/// of the site (1.5, -1.55) counted 0 instead of 0.2278 (the second part of the domain
/// widens the box, which puts that vertex there).
#[test]
fn degenerate_cell_edge_excludes_nothing_regression() {
    let v = vec![
        [1.0, -2.0],
        [3.0, 0.0],
        [1.0, 0.0],
        [0.5, 0.0],
        [0.75, 0.25],
        [0.5, 0.25],
    ];
    let s = vec![[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3]];
    let domain = Polygon::new(v, s).unwrap();
    let sites = [[1.5, -1.55], [2.0, -1.55], [1.5, -1.1], [2.0, -1.1]];
    let d = allowing_outside(&domain, &sites).unwrap();
    let v: Vec<f64> = d.moments.iter().map(|m| m.mass).collect();
    assert!((v[0] - 0.2278125).abs() < 1e-14, "{v:?}");
    let total: f64 = v.iter().sum();
    assert!((total - domain.volume()).abs() < 1e-14, "{total}");
}
