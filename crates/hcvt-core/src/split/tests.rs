//! Cuts of cells whose parts are known in closed form.

use super::*;
use crate::geometry::dot;

/// A prism over the polygon `base` (counter-clockwise in the xy plane) from z = 0 to
/// z = 1: vertex `i` of `base` at the bottom is point `i`, at the top `n + i`. Faces:
/// bottom, top, then one quad per edge of `base`, all on the boundary.
fn prism(base: &[[f64; 2]]) -> (Vec<[f64; 3]>, Loops) {
    let n = base.len() as u32;
    let mut points: Vec<[f64; 3]> = base.iter().map(|p| [p[0], p[1], 0.0]).collect();
    points.extend(base.iter().map(|p| [p[0], p[1], 1.0]));
    let mut faces = Loops::default();
    faces.push(&(0..n).rev().collect::<Vec<_>>());
    faces.push(&(n..2 * n).collect::<Vec<_>>());
    for a in 0..n {
        let b = (a + 1) % n;
        faces.push(&[a, b, n + b, n + a]);
    }
    (points, faces)
}

const SQUARE: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];

fn boundary_cut(points: &[[f64; 3]], faces: &Loops, plane: Plane) -> Option<Cut> {
    let ghosts = vec![None; faces.len()];
    let cell = Cell {
        points,
        faces,
        ghosts: &ghosts,
        ghost_centroids: &[],
    };
    cut_cell(&cell, plane).unwrap()
}

fn assert_close(a: [f64; 3], b: [f64; 3]) {
    let gap = (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max);
    assert!(gap < 1e-12, "{a:?} != {b:?}");
}

/// The unit cube halved at x = 0.5: four crossings, two parts of six faces each (the
/// four cut sides give two pieces each, the section bounds both), centroids at x = 0.25
/// and 0.75.
#[test]
fn a_cube_cut_in_half_gives_two_boxes() {
    let (points, faces) = prism(&SQUARE);
    let plane = Plane {
        normal: [1.0, 0.0, 0.0],
        origin: [0.5, 0.3, 0.7],
    };
    let cut = boundary_cut(&points, &faces, plane).expect("a cut");
    assert_eq!(cut.parts, 2);
    assert_eq!(cut.crossings.len(), 4);
    for c in &cut.crossings {
        assert_eq!(c.point[0], 0.5, "{c:?}");
    }
    // 2 sides whole, 4 sides in two pieces, one section.
    assert_eq!(cut.faces.len(), 2 + 4 * 2 + 1);
    let section = cut.faces.len() - 1;
    assert_eq!(cut.source[section], None);
    let plus = cut.part[section];
    assert_eq!(cut.across[section], Across::Part(1 - plus));
    for part in 0..2 {
        let own = cut.part.iter().filter(|&&p| p == part).count();
        assert_eq!(own + usize::from(part != plus), 6, "part {part}");
    }
    assert_close(cut.quality.centroids[plus as usize], [0.75, 0.5, 0.5]);
    assert_close(cut.quality.centroids[1 - plus as usize], [0.25, 0.5, 0.5]);
    // The section's loop faces out of the + part: along -x.
    let ring: Vec<[f64; 3]> = cut
        .faces
        .get(section)
        .iter()
        .map(|&v| cut.crossings[v as usize - points.len()].point)
        .collect();
    assert!(newell_x(&ring) < 0.0);
    assert_eq!(cut.failing, cut.quality.bad.iter().filter(|&&b| b).count());
}

fn newell_x(ring: &[[f64; 3]]) -> f64 {
    (0..ring.len())
        .map(|i| {
            let (p, q) = (ring[i], ring[(i + 1) % ring.len()]);
            p[1] * q[2] - p[2] * q[1]
        })
        .sum()
}

/// A plane beside the cell, or one through a face moved off it but still outside, cuts
/// nothing; one through the bottom face moved by 1e-5 of the size would cut a slab
/// checkMesh calls a sliver (aspect ratio 1e5), so it cuts nothing either; one through a
/// corner is moved by 1e-5 and cuts off a small tetrahedron.
#[test]
fn a_plane_missing_the_cell_cuts_nothing() {
    let (points, faces) = prism(&SQUARE);
    let beside = Plane {
        normal: [0.0, 0.0, 1.0],
        origin: [0.0, 0.0, 2.0],
    };
    assert!(boundary_cut(&points, &faces, beside).is_none());
    let on_top = Plane {
        normal: [0.0, 0.0, 1.0],
        origin: [0.0, 0.0, 1.0],
    };
    assert!(boundary_cut(&points, &faces, on_top).is_none());
    let on_bottom = Plane {
        normal: [0.0, 0.0, 1.0],
        origin: [0.5, 0.5, 0.0],
    };
    assert!(boundary_cut(&points, &faces, on_bottom).is_none());
    let diagonal = [1.0 / 3f64.sqrt(); 3];
    let at_corner = Plane {
        normal: diagonal,
        origin: [0.0; 3],
    };
    let cut = boundary_cut(&points, &faces, at_corner).expect("moved in and cut");
    assert_eq!(cut.crossings.len(), 3);
    assert!(cut
        .crossings
        .iter()
        .all(|c| (dot(c.point, diagonal) - 1e-5).abs() < 1e-15));
    let flat = Plane {
        normal: [0.0; 3],
        origin: [0.5; 3],
    };
    assert!(boundary_cut(&points, &faces, flat).is_none());
}

/// An L-shaped prism (not convex) cut across both its arms by x + y = 2.6: the tips of the
/// arms are two parts on the + side, the rest the third. Its bottom and top are
/// hexagons the plane crosses four times.
#[test]
fn an_l_shaped_cell_cut_across_both_arms_gives_three_parts() {
    let l_shape = [
        [0.0, 0.0],
        [2.0, 0.0],
        [2.0, 1.0],
        [1.0, 1.0],
        [1.0, 2.0],
        [0.0, 2.0],
    ];
    let (points, faces) = prism(&l_shape);
    let plane = Plane {
        normal: [1.0, 1.0, 0.0],
        origin: [1.3, 1.3, 0.0],
    };
    let cut = boundary_cut(&points, &faces, plane).expect("a cut");
    assert_eq!(cut.parts, 3);
    let sections = cut.source.iter().filter(|s| s.is_none()).count();
    assert_eq!(sections, 2);
    // Tips: triangles (1.6, 1), (2, 0.6), (2, 1) and its mirror, area 0.08 each; the
    // rest: the L (area 3, centroid (5/6, 5/6)) less both. Their volumes are exact, and
    // the tips' centroids; the rest's is off by 8e-4, as OpenFOAM's would be: its bottom
    // and top are not convex, and the fan from their vertex average weighs its triangles
    // by their unsigned areas, which misplaces their centres.
    let tip = [(1.6 + 2.0 + 2.0) / 3.0, (1.0 + 0.6 + 1.0) / 3.0, 0.5];
    let mirror = [tip[1], tip[0], 0.5];
    let rest = (3.0 * 5.0 / 6.0 - 0.08 * (tip[0] + tip[1])) / (3.0 - 0.16);
    let mut parts: Vec<(f64, [f64; 3])> = (cut.quality.volumes.iter().copied())
        .zip(cut.quality.centroids.iter().copied())
        .collect();
    parts.sort_by(|a, b| a.1[0].total_cmp(&b.1[0]));
    for (volume, expected) in [2.84, 0.08, 0.08].iter().zip(&parts) {
        assert!((volume - expected.0).abs() < 1e-12, "{parts:?}");
    }
    assert!((parts[0].1[0] - rest).abs() < 1e-3 && parts[0].1[0] == parts[0].1[1]);
    assert_close(parts[1].1, mirror);
    assert_close(parts[2].1, tip);
    // Each section lies between a tip and the rest.
    let rest_part = cut
        .quality
        .centroids
        .iter()
        .position(|c| (c[0] - rest).abs() < 1e-3)
        .unwrap() as u32;
    for k in 0..cut.faces.len() {
        if cut.source[k].is_none() {
            assert_eq!(cut.across[k], Across::Part(rest_part));
            assert_ne!(cut.part[k], rest_part);
        }
    }
}

/// The batch keeps a row for every plane (None where it cuts nothing), past the first
/// whose cut leaves no failing face.
#[test]
fn the_batch_tries_every_plane() {
    let (points, faces) = prism(&SQUARE);
    let ghosts = vec![None; faces.len()];
    let cell = Cell {
        points: &points,
        faces: &faces,
        ghosts: &ghosts,
        ghost_centroids: &[],
    };
    let plane = |x: f64| Plane {
        normal: [1.0, 0.0, 0.0],
        origin: [x, 0.5, 0.5],
    };
    let tried = cut_cell_by_planes(&cell, &[plane(3.0), plane(0.5), plane(0.25)]).unwrap();
    assert_eq!(tried.len(), 3);
    assert!(tried[0].is_none());
    assert_eq!(tried[1].as_ref().unwrap().failing, 0);
    assert!(tried[2].is_some());
}

/// Bad indices and non-finite planes are errors naming the face or plane, not panics.
#[test]
fn bad_input_is_an_error() {
    let (points, faces) = prism(&SQUARE);
    let ghosts = vec![None; faces.len()];
    let plane = Plane {
        normal: [1.0, 0.0, 0.0],
        origin: [0.5; 3],
    };
    let short = Cell {
        points: &points[..7],
        faces: &faces,
        ghosts: &ghosts,
        ghost_centroids: &[],
    };
    let error = cut_cell(&short, plane).unwrap_err();
    assert!(error.to_string().contains("vertex 7"), "{error}");
    let mut one_ghost = ghosts.clone();
    one_ghost[3] = Some(0);
    let no_centroid = Cell {
        ghosts: &one_ghost,
        points: &points,
        ..short
    };
    let error = cut_cell(&no_centroid, plane).unwrap_err();
    assert!(
        matches!(error, CoreError::InvalidFace { face: 3, .. }),
        "{error}"
    );
    let cell = Cell {
        ghost_centroids: &[[2.0; 3]],
        ..no_centroid
    };
    let nan = Plane {
        normal: [f64::NAN, 0.0, 0.0],
        ..plane
    };
    let error = cut_cell_by_planes(&cell, &[plane, nan]).unwrap_err();
    assert!(matches!(error, CoreError::InvalidPlane { index: 1, .. }));
    assert!(Loops::new(vec![0, 2], vec![0, 1]).is_err());
    assert!(Loops::new(vec![1, 4], vec![0, 1, 2]).is_err());
    assert!(Loops::new(vec![0, 3], vec![0, 1, 2, 3]).is_err());
}
