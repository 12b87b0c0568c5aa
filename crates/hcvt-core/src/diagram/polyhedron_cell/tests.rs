//! The 3D convex cell against closed forms: boxes, corners cut off, lattice cells, and the
//! divergence theorem on random clips.

use super::*;

/// Area of a planar polygon in space, `|Σ (v_k - v_0) × (v_{k+1} - v_0)| / 2`.
fn polygon_area(poly: &[[f64; 3]]) -> f64 {
    let mut s = [0.0; 3];
    for k in 1..poly.len().saturating_sub(1) {
        s = add(s, cross(sub(poly[k], poly[0]), sub(poly[k + 1], poly[0])));
    }
    0.5 * norm2(s).sqrt()
}

/// Index of the triangle holding the directed edge `a -> b`.
fn triangle_with_edge(c: &PolyhedronCell, a: u16, b: u16) -> Option<usize> {
    c.triangles
        .iter()
        .position(|&[x, y, z]| (x == a && y == b) || (y == a && z == b) || (z == a && x == b))
}

fn cube(lo: f64, hi: f64) -> PolyhedronCell {
    PolyhedronCell::from_box(&Aabb {
        lo: [lo; 3],
        hi: [hi; 3],
    })
}

#[test]
fn box_moments_and_faces() {
    let c = PolyhedronCell::from_box(&Aabb {
        lo: [-0.2, -0.3, -0.4],
        hi: [0.8, 0.7, 0.6],
    });
    let m = c.moments();
    assert!((m.mass - 1.0).abs() < 1e-15);
    let centroid = m.centroid().unwrap();
    assert!(norm2(sub(centroid, [0.3, 0.2, 0.1])) < 1e-30);
    let g = m.dimensionless_second_moment().unwrap();
    assert!((g - 1.0 / 12.0).abs() < 1e-15, "G = {g}");
    let mut area = 0.0;
    let mut faces = 0;
    c.for_each_face(|f, a| {
        assert_eq!(f, Face::Box);
        area += a;
        faces += 1;
    });
    assert_eq!(faces, 6);
    assert!((area - 6.0).abs() < 1e-14);
}

#[test]
fn cutting_a_corner_leaves_a_tetrahedron_and_the_rest() {
    // The plane x + y + z <= 1 through three corners-adjacent points of [0, 1]³ keeps
    // everything but the corner (1,1,1) region; its complement is the tetrahedron beyond.
    let mut c = cube(0.0, 1.0);
    c.clip(
        &HalfSpace {
            normal: [1.0, 1.0, 1.0],
            offset: 2.5,
        },
        Face::Neighbor(3),
    );
    // The cut-off corner tetrahedron has legs 0.5: volume 0.5³/6.
    let m = c.moments();
    assert!((m.mass - (1.0 - 0.125 / 6.0)).abs() < 1e-15, "{}", m.mass);
    let mut cut = 0.0;
    c.for_each_face(|f, a| {
        if f == Face::Neighbor(3) {
            cut += a;
        }
    });
    // Equilateral triangle with side 0.5·√2.
    let side: f64 = 0.5 * 2f64.sqrt();
    assert!((cut - 3f64.sqrt() / 4.0 * side * side).abs() < 1e-15);
    // The opposite half-space keeps exactly that tetrahedron.
    let mut t = cube(0.0, 1.0);
    t.clip(
        &HalfSpace {
            normal: [-1.0, -1.0, -1.0],
            offset: -2.5,
        },
        Face::Cone,
    );
    let mt = t.moments();
    assert!((mt.mass - 0.125 / 6.0).abs() < 1e-16, "{mt:?} {t:?}");
    let ct = mt.centroid().unwrap();
    assert!(
        ct.iter().all(|x| (x - (1.0 - 0.125)).abs() < 1e-15),
        "{ct:?}"
    );
    c.clip(
        &HalfSpace {
            normal: [-1.0, 0.0, 0.0],
            offset: -2.0,
        },
        Face::Cone,
    );
    assert!(c.is_empty());
}

#[test]
fn planes_through_vertices_and_faces_change_nothing() {
    let mut c = cube(-0.5, 0.5);
    let before = c.moments();
    // A face plane again, and a plane touching one corner only.
    c.clip(
        &HalfSpace {
            normal: [1.0, 0.0, 0.0],
            offset: 0.5,
        },
        Face::Neighbor(1),
    );
    c.clip(
        &HalfSpace {
            normal: [1.0, 1.0, 1.0],
            offset: 1.5,
        },
        Face::Neighbor(2),
    );
    assert_eq!(c.moments(), before);
}

/// Regular cubic grid: the Voronoi cell of a site clipped by its 26 neighbours is the cube.
#[test]
fn cubic_grid_cell_is_a_cube() {
    let mut c = cube(-3.0, 3.0);
    let mut offsets = Vec::new();
    for i in -1..=1 {
        for j in -1..=1 {
            for k in -1..=1 {
                if (i, j, k) != (0, 0, 0) {
                    offsets.push([i as f64, j as f64, k as f64]);
                }
            }
        }
    }
    offsets.sort_by(|a, b| norm2(*a).total_cmp(&norm2(*b)));
    for (n, q) in offsets.iter().enumerate() {
        c.clip(&HalfSpace::bisector(*q), Face::Neighbor(n as u32));
    }
    let m = c.moments();
    assert!((m.mass - 1.0).abs() < 1e-15);
    let g = m.dimensionless_second_moment().unwrap();
    assert!((g - 1.0 / 12.0).abs() < 1e-12);
}

/// Body-centred cubic lattice: the cell is the truncated octahedron.
#[test]
fn bcc_cell_is_a_truncated_octahedron() {
    let mut c = cube(-3.0, 3.0);
    let mut offsets = Vec::new();
    for i in -2..=2 {
        for j in -2..=2 {
            for k in -2..=2 {
                if (i, j, k) != (0, 0, 0) {
                    offsets.push([i as f64, j as f64, k as f64]);
                }
                offsets.push([i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5]);
            }
        }
    }
    offsets.sort_by(|a, b| norm2(*a).total_cmp(&norm2(*b)));
    for (n, q) in offsets.iter().enumerate() {
        c.clip(&HalfSpace::bisector(*q), Face::Neighbor(n as u32));
    }
    let m = c.moments();
    assert!((m.mass - 0.5).abs() < 1e-15, "{}", m.mass);
    let g = m.dimensionless_second_moment().unwrap();
    let exact = 19.0 / (192.0 * 2f64.cbrt());
    assert!((g - exact).abs() < 1e-12, "G = {g}, expected {exact}");
    let mut faces = 0;
    c.for_each_face(|_, a| faces += usize::from(a > 1e-12));
    assert_eq!(faces, 14);
    let c0 = m.centroid().unwrap();
    assert!(norm2(c0) < 1e-28);
}

/// Every triangle's neighbour across edge `a -> b` holds the edge `b -> a` and points back.
fn assert_adjacency_consistent(c: &PolyhedronCell) {
    assert_eq!(c.neighbors.len(), c.triangles.len());
    for (t, tri) in c.triangles.iter().enumerate() {
        for k in 0..3 {
            let s = c.neighbors[t][k] as usize;
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            assert_eq!(
                triangle_with_edge(c, b, a),
                Some(s),
                "triangle {t} edge {k}"
            );
            assert!(c.neighbors[s].contains(&(t as u32)));
        }
    }
}

/// Clipping a random convex cell by random planes: volume agrees with a Monte-Carlo-free
/// check, the divergence theorem over the faces (`V = Σ_f offset_f · area_f / (3 |n_f|)`).
#[test]
fn random_clips_satisfy_the_divergence_theorem() {
    let mut rng = crate::sample::Lcg::new(99);
    let mut rand = || rng.unit() - 0.5;
    assert_adjacency_consistent(&cube(-1.0, 1.0));
    for _ in 0..50 {
        let mut c = cube(-1.0, 1.0);
        let mut planes = Vec::new();
        for _ in 0..30 {
            let n = [rand(), rand(), rand()];
            let h = HalfSpace {
                normal: n,
                offset: 0.3 * norm2(n).sqrt() + 0.3 * rand().abs(),
            };
            planes.push(h);
            c.clip(&h, Face::Neighbor(planes.len() as u32 - 1));
        }
        assert_adjacency_consistent(&c);
        let m = c.moments();
        let mut v = 0.0;
        c.for_each_polygon(|f, poly| {
            let (n, d) = match f {
                Face::Neighbor(j) => (planes[j as usize].normal, planes[j as usize].offset),
                _ => {
                    // Box face: the normal is the axis the polygon is flat in.
                    let e = sub(poly[1], poly[0]);
                    let g = sub(poly[2], poly[0]);
                    let n = cross(e, g);
                    (n, dot(n, poly[0]))
                }
            };
            v += d * polygon_area(poly) / (3.0 * norm2(n).sqrt());
        });
        assert!((m.mass - v).abs() < 1e-13, "{} vs {}", m.mass, v);
        assert!(m.mass > 0.0);
    }
}

/// The cell of site 0 among `sites`, clipped by their bisectors in the order given.
fn clipped(sites: &[[f64; 3]], order: &[usize]) -> PolyhedronCell {
    let mut c = cube(-10.0, 10.0);
    for &j in order {
        let q = sub(sites[j], sites[0]);
        c.clip(&HalfSpace::bisector(q), Face::Neighbor(j as u32));
    }
    c
}

fn vertex_bits(c: &PolyhedronCell) -> Vec<[u64; 3]> {
    c.vertices.iter().map(|v| v.map(f64::to_bits)).collect()
}

/// Clipped in two orders, with their neighbours numbered two ways, the canonical cells are
/// equal bit for bit (vertices, triangles, adjacency, moments); rebuilt from the planes
/// and triangles they are the same again; a ring missing a plane or a triangle list of
/// another cell is refused.
#[test]
fn a_canonical_cell_is_the_same_in_any_order_and_rebuilt_from_its_ring() {
    let mut rng = crate::sample::Lcg::new(5);
    let (mut differed, mut canonical) = (0, 0);
    for _ in 0..100 {
        let sites: Vec<[f64; 3]> = (0..40)
            .map(|_| [rng.unit(), rng.unit(), rng.unit()])
            .collect();
        let forward: Vec<usize> = (1..40).collect();
        let backward: Vec<usize> = (1..40).rev().collect();
        let (mut a, mut b) = (clipped(&sites, &forward), clipped(&sites, &backward));
        differed += usize::from(vertex_bits(&a) != vertex_bits(&b));
        let plane = |j: u32| HalfSpace::bisector(sub(sites[j as usize], sites[0]));
        let (made_a, made_b) = (a.canonicalise(plane), b.canonicalise(plane));
        assert_eq!(made_a, made_b);
        if !made_a {
            continue;
        }
        assert!(
            a.planes.iter().all(|p| p.face != Face::Box),
            "cut-away planes dropped"
        );
        canonical += 1;
        assert_eq!(vertex_bits(&a), vertex_bits(&b));
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.neighbors, b.neighbors);
        assert_eq!(a.moments(), b.moments());
        assert_adjacency_consistent(&a);
        let (mut ring, mut triangles) = (Vec::new(), Vec::new());
        a.ring(&mut ring, &mut triangles);
        let mut rebuilt = PolyhedronCell::default();
        assert!(rebuilt.rebuild_from_ring(&ring, &triangles, plane, 1e-9));
        assert_eq!(vertex_bits(&rebuilt), vertex_bits(&a));
        assert_eq!(rebuilt.triangles, a.triangles);
        assert_eq!(rebuilt.neighbors, a.neighbors);
        assert_eq!(rebuilt.moments(), a.moments());
        // A plane dropped from the ring: the triangles name planes it no longer has.
        assert!(!rebuilt.rebuild_from_ring(&ring[1..], &triangles, plane, 1e-9));
        // A neighbour swapped for a site that does not bound the cell.
        if let Some(extra) = (1..40u32).find(|j| !ring.contains(j)) {
            let mut other = ring.clone();
            other[0] = extra;
            assert!(!rebuilt.rebuild_from_ring(&other, &triangles, plane, 1e-9));
        }
    }
    assert!(
        differed > 20,
        "the orders differed in {differed} cells only"
    );
    // Half the sites lie near the unit cube's sides: their cells reach the box (50 here).
    assert!(canonical >= 40, "{canonical} canonical cells");
}
