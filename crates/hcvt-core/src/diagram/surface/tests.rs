use crate::diagram::driver::clipped_diagram;
use crate::diagram::polyhedron_cell::PolyhedronCell;
use crate::diagram::request::Request;
use crate::error::CoreError;
use crate::geometry::{add, cross, dot, scale, sub};

use super::delaunay::SAME_POINT;
use super::noting::Noting;
use super::*;

/// An open grid of `k × k` squares in the plane `z = 0`, each split into two triangles,
/// bent up along x by `bend` (a roof) so that it is not flat.
fn roof(k: usize, bend: f64) -> Surface {
    let mut v = Vec::new();
    for j in 0..=k {
        for i in 0..=k {
            let x = i as f64 / k as f64;
            v.push([x, j as f64 / k as f64, bend * (0.5 - (x - 0.5).abs())]);
        }
    }
    let id = |i: usize, j: usize| (j * (k + 1) + i) as u32;
    let mut t = Vec::new();
    for j in 0..k {
        for i in 0..k {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Surface::new(v, t).unwrap()
}

fn sites(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = crate::sample::Lcg::new(seed);
    (0..n)
        .map(|_| [rng.unit(), rng.unit(), 0.3 * rng.unit() - 0.1])
        .collect()
}

#[test]
fn cells_tile_an_open_surface() {
    let s = roof(8, 0.6);
    let sites = sites(300, 5);
    let d = clipped_diagram::<3, PolyhedronCell, _>(&s, &sites, &Request::default())
        .unwrap()
        .diagram;
    let total: f64 = d.moments.iter().map(|m| m.mass).sum();
    assert!(
        (total - s.area()).abs() <= 1e-13 * s.area(),
        "{total} vs {}",
        s.area()
    );
    let first = d.moments.iter().zip(&sites).fold([0.0; 3], |acc, (m, z)| {
        add(acc, add(m.first, scale(*z, m.mass)))
    });
    for (got, want) in first.iter().zip(s.first_moment()) {
        assert!((got - want).abs() <= 1e-13);
    }
    // The border: four sides, the two across the roof's slopes longer.
    let border: f64 = d.boundary_measure.iter().sum();
    let want = 2.0 + 2.0 * 2.0 * (0.25f64 + 0.09).sqrt();
    assert!((border - want).abs() <= 1e-12, "{border} vs {want}");
    // Shared arcs are seen alike from both sides.
    for i in 0..sites.len() {
        for at in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
            let j = d.neighbor_sites[at] as usize;
            let back = (d.neighbor_offsets[j]..d.neighbor_offsets[j + 1])
                .find(|&b| d.neighbor_sites[b] as usize == i)
                .map(|b| d.neighbor_measures[b]);
            let m = d.neighbor_measures[at];
            assert!(back.is_some_and(|b| (b - m).abs() <= 1e-12), "{i} {j}");
        }
    }
}

/// The pieces are the measure's: the diagram is the plain one bit for bit, each
/// cell's pieces sum (fanned) to its area and first moment, every piece lies in its
/// triangle's plane and runs counter-clockwise about its normal, and the pieces of
/// all cells cover each triangle's area; a site given twice is refused, not a panic.
#[test]
fn pieces_are_the_measures_and_tile_the_triangles() {
    let s = roof(8, 0.6);
    let sites = sites(300, 5);
    let plain = clipped_diagram::<3, PolyhedronCell, _>(&s, &sites, &Request::default());
    let p = s.pieces(&sites).unwrap();
    assert_eq!(plain.unwrap().diagram.moments, p.diagram.moments);
    let m = p.cells.len();
    assert!(m > 300 && p.offsets.len() == m + 1 && p.triangles.len() == m);
    assert!(p.cells.windows(2).all(|w| w[0] <= w[1]));
    let mut area = vec![0.0; sites.len()];
    let mut first = vec![[0.0; 3]; sites.len()];
    let mut covered = vec![0.0; s.triangles().len()];
    for k in 0..m {
        let nodes = &p.points[p.offsets[k]..p.offsets[k + 1]];
        let [a, b, c] = s.corners(p.triangles[k]);
        let normal = cross(sub(b, a), sub(c, a));
        let unit = scale(normal, 1.0 / norm2(normal).sqrt());
        assert!(nodes.len() >= 3);
        for x in nodes {
            assert!(
                dot(unit, sub(*x, a)).abs() < 1e-14,
                "piece {k} off its plane"
            );
        }
        for j in 1..nodes.len() - 1 {
            let twice = cross(sub(nodes[j], nodes[0]), sub(nodes[j + 1], nodes[0]));
            assert!(dot(twice, unit) >= -1e-15, "piece {k} turns clockwise");
            let (i, da) = (p.cells[k] as usize, 0.5 * dot(twice, unit));
            area[i] += da;
            covered[p.triangles[k] as usize] += da;
            let mid = scale(add(add(nodes[0], nodes[j]), nodes[j + 1]), da / 3.0);
            first[i] = add(first[i], mid);
        }
    }
    for (i, moments) in p.diagram.moments.iter().enumerate() {
        assert!((area[i] - moments.mass).abs() <= 1e-14, "cell {i}");
        // The moments are about the site.
        let about = sub(first[i], scale(sites[i], area[i]));
        assert!(norm2(sub(about, moments.first)) <= 1e-28, "cell {i}");
    }
    for (t, got) in covered.iter().enumerate() {
        let [a, b, c] = s.corners(t as u32);
        let whole = 0.5 * norm2(cross(sub(b, a), sub(c, a))).sqrt();
        assert!(
            (got - whole).abs() <= 1e-14,
            "triangle {t}: {got} of {whole}"
        );
    }
    let mut twice = sites.clone();
    twice[7] = twice[3];
    assert!(matches!(
        s.pieces(&twice),
        Err(CoreError::DuplicateSites { .. })
    ));
}

/// [`Noting`] is the surface as a domain, plus the triangles each cell's measure met:
/// its diagram equals the surface's bit for bit (every method `Surface` overrides is
/// forwarded: one left out would show here), and the meeting points from the noted
/// triangles equal those of a fresh walk of the BVH, for every cell.
#[test]
fn noted_triangles_give_the_walks_diagram_and_meeting_points() {
    let s = roof(8, 0.6);
    let sites = sites(300, 5);
    let request = Request {
        keep_cells: true,
        ..Default::default()
    };
    let plain = clipped_diagram::<3, PolyhedronCell, _>(&s, &sites, &request).unwrap();
    let noting = Noting::new(&s, false, sites.len());
    let noted = clipped_diagram::<3, PolyhedronCell, _>(&noting, &sites, &request).unwrap();
    let (a, b) = (&plain.diagram, &noted.diagram);
    assert_eq!(a.moments, b.moments);
    assert_eq!(a.neighbor_offsets, b.neighbor_offsets);
    assert_eq!(a.neighbor_sites, b.neighbor_sites);
    assert_eq!(a.neighbor_measures, b.neighbor_measures);
    assert_eq!(a.boundary_measure, b.boundary_measure);
    let met = noting.into_notes();
    let same = SAME_POINT * s.set.bvh().bounds().diagonal();
    let mut replays = 0;
    for (i, cell) in noted.cells.iter().enumerate() {
        // Some sites off the roof have cells that miss it: nothing noted, nothing met.
        let noted = met[&sites[i].map(f64::to_bits)].as_ref();
        let triangles = noted.map(|n| n.triangles.as_slice());
        assert!(triangles.is_some(), "cell {i} not noted");
        replays += usize::from(triangles.is_some_and(|t| !t.is_empty()));
        let walked = s.meeting_points(i as u32, cell, sites[i], same, None);
        let replayed = s.meeting_points(i as u32, cell, sites[i], same, triangles);
        assert_eq!(walked, replayed, "cell {i}");
    }
    // Every cell with an area replayed its noted triangles (here 135 of the 300).
    let with_area = b.moments.iter().filter(|m| m.mass > 0.0).count();
    assert!(
        replays == with_area && replays > 100,
        "{replays} of {with_area}"
    );
}

/// Three sites whose cells meet at `(0.5, 0.5, 0)` in the flat square `roof(k, 0.0)`
/// (split on the diagonal `y = x`, so the point is on an input edge for `k = 1` and an
/// input vertex for `k = 2`), in every order, and mirrored (the other diagonal): one
/// triangle, counter-clockwise about `+z`, no triple repeated. The first set has the
/// bisector of two sites along the diagonal (exactly); the second has the meeting
/// point on it up to rounding (sites on a circle about it).
#[test]
fn three_cells_meeting_on_an_input_edge_or_vertex_give_one_triangle() {
    let on_circle = |deg: f64| {
        let a = deg.to_radians();
        [0.5 + 0.3 * a.cos(), 0.5 + 0.3 * a.sin(), 0.0]
    };
    let sets = [
        [[0.2, 0.5, 0.0], [0.8, 0.5, 0.0], [0.5, 0.8, 0.0]],
        [on_circle(10.0), on_circle(130.0), on_circle(250.0)],
        [on_circle(45.0), on_circle(165.0), on_circle(285.0)],
    ];
    let orders = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    for k in [1, 2] {
        let s = roof(k, 0.0);
        for set in &sets {
            for mirror in [false, true] {
                for order in orders {
                    let sites: Vec<[f64; 3]> = order
                        .iter()
                        .map(|&o| {
                            let [x, y, z] = set[o];
                            [if mirror { 1.0 - x } else { x }, y, z]
                        })
                        .collect();
                    let rdt = s.restricted_delaunay(&sites).unwrap();
                    let case = format!("k {k} {set:?} mirror {mirror} order {order:?}");
                    assert_eq!(rdt.triangles.len(), 1, "{case}: {:?}", rdt.triangles);
                    assert!(rdt.repeated.is_empty(), "{case}");
                    let [a, b, c] = rdt.triangles[0].map(|v| sites[v as usize]);
                    assert!(cross(sub(b, a), sub(c, a))[2] > 0.0, "{case}");
                    let p = rdt.points[0];
                    assert!(norm2(sub(p, [0.5, 0.5, 0.0])) < 1e-24, "{case}: {p:?}");
                }
            }
        }
    }
}

/// Sites on a triangular lattice whose cells all meet on the vertical edges of a flat
/// grid (x multiples of 1/12): the triangles are the Delaunay triangles with their
/// circumcentre in the square, found by brute force (empty circumcircles), each once.
#[test]
fn lattice_cells_meeting_on_grid_edges_give_the_delaunay_triangles() {
    let s = roof(12, 0.0);
    let mut sites = Vec::new();
    for j in 0..6 {
        let (shift, count) = if j % 2 == 0 { (0.5, 6) } else { (1.0, 5) };
        for i in 0..count {
            sites.push([(i as f64 + shift) / 6.0, (j as f64 + 0.5) / 6.0, 0.0]);
        }
    }
    let mut want = Vec::new();
    let n = sites.len();
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                let [p, q, r] = [sites[a], sites[b], sites[c]];
                let (bx, by, cx, cy) = (q[0] - p[0], q[1] - p[1], r[0] - p[0], r[1] - p[1]);
                let d = 2.0 * (bx * cy - by * cx);
                if d.abs() < 1e-12 {
                    continue;
                }
                let (b2, c2) = (bx * bx + by * by, cx * cx + cy * cy);
                let centre = [
                    p[0] + (cy * b2 - by * c2) / d,
                    p[1] + (bx * c2 - cx * b2) / d,
                    0.0,
                ];
                let r2 = norm2(sub(centre, p));
                let inside = centre[..2].iter().all(|&x| (0.0..=1.0).contains(&x));
                if inside && sites.iter().all(|&z| norm2(sub(z, centre)) > r2 - 1e-12) {
                    want.push([a as u32, b as u32, c as u32]);
                }
            }
        }
    }
    assert!(want.len() > 40);
    let rdt = s.restricted_delaunay(&sites).unwrap();
    assert!(rdt.repeated.is_empty());
    let mut got: Vec<[u32; 3]> = rdt
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| sites[v as usize]);
            assert!(cross(sub(b, a), sub(c, a))[2] > 0.0, "{t:?}");
            let mut k = *t;
            k.sort_unstable();
            k
        })
        .collect();
    got.sort_unstable();
    assert_eq!(got, want);
}

#[test]
fn bad_surfaces_are_refused_by_name() {
    let v = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 0.0, 0.0],
    ];
    let err = Surface::new(v.clone(), vec![[0, 1, 3]]).unwrap_err();
    assert!(err.to_string().contains("degenerate"), "{err}");
    let err = Surface::new(v.clone(), vec![[0, 1, 2], [0, 1, 2]]).unwrap_err();
    assert!(err.to_string().contains("repeated"), "{err}");
    let err = Surface::new(v.clone(), vec![[0, 1, 2], [1, 0, 2]]).unwrap_err();
    assert!(err.to_string().contains("repeated"), "{err}");
    let w = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let err = Surface::new(w.clone(), vec![[0, 1, 2], [0, 1, 3]]).unwrap_err();
    assert!(err.to_string().contains("orientation"), "{err}");
    let err = Surface::new(w, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap_err();
    assert!(err.to_string().contains("non-manifold"), "{err}");
}
