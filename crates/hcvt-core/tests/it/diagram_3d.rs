//! The 3D clipped diagram against closed forms (lattices in a cube) and against the
//! domain's own integrals on the real meshes of `../shared/data/3d`.

use crate::common::{data_3d, dented_cube, interior_sites, read_mesh};

use hcvt_core::{clipped_diagram, Diagram, PolyhedronCell, Request, Solid};

/// Axis-aligned box `[0, s]³` as 12 outward triangles.
fn cube(s: f64) -> Solid {
    Solid::cuboid([0.0; 3], [s; 3]).unwrap()
}

fn diagram(solid: &Solid, sites: &[[f64; 3]]) -> Diagram<3> {
    clipped_diagram::<3, PolyhedronCell, _>(solid, sites, &Request::default())
        .unwrap()
        .diagram
}

#[test]
fn cubic_grid_in_a_cube_gives_cubes() {
    let n = 5;
    let solid = cube(1.0);
    let h = 1.0 / n as f64;
    let mut sites = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                sites.push([i, j, k].map(|x| (x as f64 + 0.5) * h));
            }
        }
    }
    let d = diagram(&solid, &sites);
    for (i, m) in d.moments.iter().enumerate() {
        assert!((m.mass - h * h * h).abs() < 1e-15, "cell {i}: {}", m.mass);
        let g = m.dimensionless_second_moment().unwrap();
        assert!((g - 1.0 / 12.0).abs() < 1e-12, "cell {i}: G = {g}");
        assert!(m.first.iter().all(|x| x.abs() < 1e-17), "cell {i}: {m:?}");
    }
    // Interior cells have 6 face neighbours; corner cells 3.
    let degree = |i: usize| {
        (d.neighbor_offsets[i]..d.neighbor_offsets[i + 1])
            .filter(|&k| d.neighbor_measures[k] > 1e-9 * h * h)
            .count()
    };
    assert_eq!(degree(0), 3);
    assert_eq!(degree(n * n + n + 1), 6);
}

#[test]
fn bcc_lattice_in_a_cube_gives_truncated_octahedra() {
    let side = 5.0;
    let solid = cube(side);
    let mut sites = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            for k in 0..5 {
                sites.push([i, j, k].map(|x| x as f64 + 0.25));
                sites.push([i, j, k].map(|x| x as f64 + 0.75));
            }
        }
    }
    let d = diagram(&solid, &sites);
    let exact = 19.0 / (192.0 * 2f64.cbrt());
    let mut interior = 0;
    for (s, m) in sites.iter().zip(&d.moments) {
        // Interior: all 14 lattice neighbours exist (the axis ones are 1 away).
        if s.iter().all(|&x| (1.0..=side - 1.0).contains(&x)) {
            interior += 1;
            let g = m.dimensionless_second_moment().unwrap();
            assert!((g - exact).abs() < 1e-12, "site {s:?}: G = {g}");
            assert!((m.mass - 0.5).abs() < 1e-14);
        }
    }
    assert_eq!(interior, 54);
    let total: f64 = d.moments.iter().map(|m| m.mass).sum();
    assert!(
        (total - side.powi(3)).abs() < 1e-12 * side.powi(3),
        "{total}"
    );
}

#[test]
fn sums_over_cells_match_the_mesh_integrals() {
    let Some(dir) = data_3d() else {
        eprintln!("skipped: ../shared/data/3d not found");
        return;
    };
    for name in ["bunny.off", "fandisk.off", "anchor_dense.off", "cheese.off"] {
        let solid = read_mesh(&dir.join(name));
        for n in [100, 2000] {
            let sites = interior_sites(&solid, n, 7);
            let d = diagram(&solid, &sites);
            let volume: f64 = d.moments.iter().map(|m| m.mass).sum();
            let rel = (volume - solid.volume()).abs() / solid.volume();
            assert!(rel < 1e-12, "{name}, n = {n}: Σ volume off by {rel:e}");
            // First moments about the domain's reference point, summed in index order.
            let o = solid.moments_origin();
            let mut first = [0.0; 3];
            for (m, s) in d.moments.iter().zip(&sites) {
                for k in 0..3 {
                    first[k] += m.first[k] + m.mass * (s[k] - o[k]);
                }
            }
            let want = solid.moments().first;
            let scale = solid.volume() * solid.bounds().diagonal();
            for k in 0..3 {
                let err = (first[k] - want[k]).abs() / scale;
                assert!(
                    err < 1e-12,
                    "{name}, n = {n}: first moment {k} off by {err:e}"
                );
            }
            assert!(d.moments.iter().all(|m| m.mass > 0.0), "{name}: empty cell");
        }
    }
}

/// The octahedron with half-axes 1.3, 0.7 and 1.1: convex, with no two faces coplanar and
/// no face along an axis.
fn octahedron() -> Solid {
    Solid::octahedron([1.3, 0.7, 1.1]).unwrap()
}

/// The same boundary with one unused vertex far outside: no longer found convex, so its
/// diagrams go through the signed cones.
fn with_stray_vertex(solid: &Solid) -> Solid {
    let mut vertices = solid.vertices().to_vec();
    vertices.push([100.0; 3]);
    Solid::new(vertices, solid.simplices().to_vec()).unwrap()
}

#[test]
fn convex_domains_clip_by_their_planes_as_the_cones_do() {
    for solid in [cube(1.0), octahedron()] {
        let cones = with_stray_vertex(&solid);
        assert!(solid.is_convex() && !cones.is_convex());
        let n = 300;
        let sites = interior_sites(&solid, n, 3);
        let (planes, cones) = (diagram(&solid, &sites), diagram(&cones, &sites));
        let v = solid.volume() / n as f64;
        let h = v.cbrt();
        for (i, (a, b)) in planes.moments.iter().zip(&cones.moments).enumerate() {
            assert!((a.mass - b.mass).abs() < 1e-12 * v, "cell {i}: {a:?} {b:?}");
            assert!((a.second - b.second).abs() < 1e-12 * v * h * h, "cell {i}");
            for k in 0..3 {
                assert!((a.first[k] - b.first[k]).abs() < 1e-12 * v * h, "cell {i}");
            }
            let db = planes.boundary_measure[i] - cones.boundary_measure[i];
            assert!(db.abs() < 1e-12 * h * h, "cell {i}: boundary {db:e}");
            // Faces of more than round-off, with their measures.
            let faces = |d: &Diagram<3>| -> Vec<(u32, f64)> {
                (d.neighbor_offsets[i]..d.neighbor_offsets[i + 1])
                    .map(|k| (d.neighbor_sites[k], d.neighbor_measures[k]))
                    .filter(|&(_, m)| m > 1e-9 * h * h)
                    .collect()
            };
            let (fa, fb) = (faces(&planes), faces(&cones));
            assert_eq!(fa.len(), fb.len(), "cell {i}");
            for ((ja, ma), (jb, mb)) in fa.into_iter().zip(fb) {
                assert!(ja == jb && (ma - mb).abs() < 1e-12 * h * h, "cell {i}");
            }
        }
    }
}

#[test]
fn doubly_covered_and_dented_solids_are_not_convex() {
    // The cube's boundary twice: winding number 2 inside.
    let solid = cube(1.0);
    let twice = [solid.simplices(), solid.simplices()].concat();
    assert!(!Solid::new(solid.vertices().to_vec(), twice)
        .unwrap()
        .is_convex());
    let dented = dented_cube();
    assert!((dented.volume() - (1.0 - 0.2 / 3.0)).abs() < 1e-15);
    assert!(!dented.is_convex());
}
