//! Exact winding numbers: is a point inside the domain, outside, or on its boundary?

use super::Boundary;
use crate::geometry::{add, dot, norm2, scale, sub, Aabb, Euclid};

/// Winding number of a point with respect to a closed oriented boundary.
pub trait WindingNumber<const D: usize>: crate::geometry::Space<D> {
    /// The winding number of `p` (1 inside a valid domain, 0 outside), or `None` when `p`
    /// lies exactly on the boundary: looked up in the boundary's
    /// [`WindingGrid`](super::winding_grid::WindingGrid) when it has one and knows, else
    /// [`WindingNumber::ray_winding_number`]. The same answer either way.
    fn winding_number(boundary: &Boundary<D>, p: &[f64; D]) -> Option<i32>
    where
        Euclid: WindingNumber<D>,
    {
        match boundary.winding_grid().and_then(|grid| grid.lookup(p)) {
            Some(w) => Some(w),
            None => Euclid::ray_winding_number(boundary, p),
        }
    }

    /// The winding number of `p` by a ray cast, decided with exact predicates.
    fn ray_winding_number(boundary: &Boundary<D>, p: &[f64; D]) -> Option<i32>;
}

impl WindingNumber<2> for Euclid {
    /// Crossings of the ray from `p` towards `+x` (Sunday's rule: upward crossings with `p`
    /// on the left count +1, downward with `p` on the right −1), the candidate segments
    /// from the BVH, every side test exact (`orient2d`).
    fn ray_winding_number(boundary: &Boundary<2>, p: &[f64; 2]) -> Option<i32> {
        let bounds = boundary.bounds();
        let ray = Aabb {
            lo: *p,
            hi: [bounds.hi[0].max(p[0]), p[1]],
        };
        let mut candidates = Vec::new();
        boundary.bvh().query(&ray, &mut candidates);
        let c = |v: &[f64; 2]| robust::Coord { x: v[0], y: v[1] };
        let mut winding = 0;
        for t in candidates {
            let [a, b] = boundary.simplex(t);
            let orient = robust::orient2d(c(&a), c(&b), c(p));
            if orient == 0.0 && Aabb::of_points([&a, &b]).overlaps(&Aabb { lo: *p, hi: *p }) {
                return None;
            }
            if a[1] <= p[1] {
                if b[1] > p[1] && orient > 0.0 {
                    winding += 1;
                }
            } else if b[1] <= p[1] && orient < 0.0 {
                winding -= 1;
            }
        }
        Some(winding)
    }
}

/// Directions tried in turn by the 3D ray test: an axis first (its BVH query is a thin
/// box), then directions with no rational relation to the axes, for when the ray grazes an
/// edge or a vertex.
const RAY_DIRECTIONS: [[f64; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [
        0.577_215_664_901_532_9,
        0.327_148_823_931_579_1,
        0.141_421_356_237_309_5,
    ],
    [
        -0.271_828_182_845_904_5,
        0.680_339_887_498_948_4,
        0.161_803_398_874_989_5,
    ],
    [
        0.295_712_384_199_713_3,
        -0.441_926_189_354_907_2,
        0.795_774_715_459_476_7,
    ],
    [
        -0.707_106_781_186_547_5,
        -0.173_205_080_756_887_7,
        0.367_879_441_171_442_3,
    ],
    [
        0.223_606_797_749_979,
        0.577_350_269_189_625_8,
        -0.909_297_426_825_681_7,
    ],
];

/// What one triangle does to a ray segment.
enum Crossing {
    None,
    /// The segment crosses the triangle's interior; +1 leaving the inner side, -1 entering.
    Signed(i32),
    /// The segment passes through an edge or vertex: try another direction.
    Degenerate,
    /// The start point lies on the triangle.
    OnTriangle,
}

impl WindingNumber<3> for Euclid {
    /// Signed crossings of a segment from `p` to beyond the bounding box with the
    /// boundary triangles (candidates from the BVH), every test an exact `orient3d`. When
    /// the segment passes through an edge or a vertex the next direction of a fixed list is
    /// taken, so the answer is deterministic. `None` exactly when `p` lies on a triangle.
    fn ray_winding_number(boundary: &Boundary<3>, p: &[f64; 3]) -> Option<i32> {
        let bounds = boundary.bounds();
        let reach = 2.0 * (bounds.diagonal() + norm2(sub(*p, bounds.center())).sqrt()) + 1.0;
        let mut candidates = Vec::new();
        let mut fallback = 0;
        for dir in RAY_DIRECTIONS {
            let q = add(*p, scale(dir, reach));
            candidates.clear();
            boundary
                .bvh()
                .query(&Aabb::of_points([p, &q]), &mut candidates);
            let mut winding = 0;
            let mut degenerate = false;
            for &t in &candidates {
                match ray_crossing(&boundary.simplex(t), p, &q) {
                    Crossing::None => {}
                    Crossing::Signed(s) => winding += s,
                    Crossing::Degenerate => {
                        degenerate = true;
                        break;
                    }
                    Crossing::OnTriangle => return None,
                }
            }
            if !degenerate {
                return Some(winding);
            }
            fallback = winding;
        }
        // Every direction grazed an edge: practically impossible for the directions above;
        // the last count is still right unless the graze changed parity.
        Some(fallback)
    }
}

fn coord(v: &[f64; 3]) -> robust::Coord3D<f64> {
    robust::Coord3D {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

/// How the segment `[p, q]` meets triangle `tri` (`q` lies outside every triangle).
fn ray_crossing(tri: &[[f64; 3]; 3], p: &[f64; 3], q: &[f64; 3]) -> Crossing {
    let [a, b, c] = tri.map(|v| coord(&v));
    let (cp, cq) = (coord(p), coord(q));
    // orient3d > 0: p below the counter-clockwise triangle, on its inner side.
    let sp = robust::orient3d(a, b, c, cp);
    if sp == 0.0 {
        return if point_in_coplanar_triangle(tri, p) {
            Crossing::OnTriangle
        } else {
            Crossing::None // the segment leaves the plane at once, outside the triangle
        };
    }
    let sq = robust::orient3d(a, b, c, cq);
    if sq == 0.0 || (sp > 0.0) == (sq > 0.0) {
        return Crossing::None;
    }
    let e = [
        robust::orient3d(cp, cq, a, b),
        robust::orient3d(cp, cq, b, c),
        robust::orient3d(cp, cq, c, a),
    ];
    let pos = e.iter().filter(|&&x| x > 0.0).count();
    let neg = e.iter().filter(|&&x| x < 0.0).count();
    if pos > 0 && neg > 0 {
        Crossing::None
    } else if pos == 3 || neg == 3 {
        Crossing::Signed(if sp > 0.0 { 1 } else { -1 })
    } else {
        Crossing::Degenerate
    }
}

/// Whether `p`, exactly in the plane of `tri`, lies in the closed triangle: exact
/// `orient2d` tests after dropping the axis the triangle is most nearly normal to (dropping
/// a coordinate is exact). A zero-area triangle contains `p` when one of its sides does.
fn point_in_coplanar_triangle(tri: &[[f64; 3]; 3], p: &[f64; 3]) -> bool {
    let n = <Euclid as crate::geometry::Space<3>>::normal(tri);
    let drop = (0..3)
        .max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))
        .unwrap_or(2);
    let project = |v: &[f64; 3]| {
        let (u, w) = match drop {
            0 => (v[1], v[2]),
            1 => (v[2], v[0]),
            _ => (v[0], v[1]),
        };
        robust::Coord { x: u, y: w }
    };
    let [a, b, c] = tri.map(|v| project(&v));
    let pp = project(p);
    let o = [
        robust::orient2d(a, b, pp),
        robust::orient2d(b, c, pp),
        robust::orient2d(c, a, pp),
    ];
    if o.iter().all(|&x| x == 0.0) {
        // Degenerate triangle (or a projection that collapsed it): test each side.
        return tri
            .iter()
            .zip(tri.iter().cycle().skip(1))
            .any(|(u, v)| on_segment(u, v, p));
    }
    !(o.iter().any(|&x| x > 0.0) && o.iter().any(|&x| x < 0.0))
}

/// `p` on the closed segment `[u, v]`, `p` known to be coplanar with it.
fn on_segment(u: &[f64; 3], v: &[f64; 3], p: &[f64; 3]) -> bool {
    let d = sub(*v, *u);
    let e = sub(*p, *u);
    let cross = [
        d[1] * e[2] - d[2] * e[1],
        d[2] * e[0] - d[0] * e[2],
        d[0] * e[1] - d[1] * e[0],
    ];
    let within = (0..3).all(|k| u[k].min(v[k]) <= p[k] && p[k] <= u[k].max(v[k]));
    within && cross == [0.0; 3]
}

/// Far-field summary of the simplices under one BVH node (Barill et al. 2018, first
/// order): their area vector `Σ n_t / 2` placed at their area-weighted centre, and the
/// radius of a ball around that centre holding all of them.
#[derive(Debug, Clone, Copy)]
pub struct Dipole<const D: usize> {
    area_vector: [f64; D],
    center: [f64; D],
    radius: f64,
}

/// The dipole of every BVH node, O(F log F).
pub(crate) fn dipoles<const D: usize>(boundary: &Boundary<D>) -> Vec<Dipole<D>>
where
    Euclid: crate::geometry::Space<D>,
{
    let bvh = boundary.bvh();
    (0..bvh.node_count())
        .map(|i| {
            let items = bvh.node_items(i);
            let mut area_vector = [0.0; D];
            let mut weighted = [0.0; D];
            let mut total = 0.0;
            for &t in items {
                let s = boundary.simplex(t);
                let n = <Euclid as crate::geometry::Space<D>>::normal(&s);
                let area = norm2(n).sqrt();
                let centroid = scale(s.iter().fold([0.0; D], |a, &v| add(a, v)), 1.0 / D as f64);
                area_vector = add(area_vector, scale(n, 0.5));
                weighted = add(weighted, scale(centroid, area));
                total += area;
            }
            let center = if total > 0.0 {
                scale(weighted, 1.0 / total)
            } else {
                bvh.bounds().center()
            };
            let radius = items
                .iter()
                .flat_map(|&t| boundary.simplex(t))
                .map(|v| norm2(sub(v, center)))
                .fold(0.0, f64::max)
                .sqrt();
            Dipole {
                area_vector,
                center,
                radius,
            }
        })
        .collect()
}

/// Nodes farther than this many radii from the query point count by their dipole.
const FAR_FIELD_RADII: f64 = 3.0;

/// Generalised winding number of Jacobson et al. 2013: the solid angle the oriented
/// triangles subtend at `p`, over 4π (Van Oosterom–Strackee formula per triangle), with
/// the BVH nodes far from `p` summarised by their dipoles (Barill et al. 2018).
///
/// 1 inside and 0 outside a closed outward surface (to about 1e-2 from the far field), and
/// close to those values near small holes or overlaps, where the exact integer
/// [`WindingNumber`] flips; this is the inside test for imperfect meshes.
pub fn generalized_winding_number(boundary: &Boundary<3>, p: &[f64; 3]) -> f64 {
    let dipoles = boundary.dipoles();
    let bvh = boundary.bvh();
    let mut total = 0.0;
    bvh.walk(|node, leaf| {
        let Some(d) = dipoles.get(node) else {
            return false;
        };
        let r = sub(d.center, *p);
        let dist2 = norm2(r);
        if dist2 > (FAR_FIELD_RADII * d.radius).powi(2) {
            total += dot(d.area_vector, r) / dist2.powf(1.5);
            return false;
        }
        if leaf {
            for &t in bvh.node_items(node) {
                total += solid_angle(&boundary.simplex(t), p);
            }
            return false;
        }
        true
    });
    total / (4.0 * std::f64::consts::PI)
}

/// Signed solid angle of triangle `tri` seen from `p` (Van Oosterom–Strackee).
fn solid_angle(tri: &[[f64; 3]; 3], p: &[f64; 3]) -> f64 {
    let [a, b, c] = tri.map(|v| sub(v, *p));
    let (la, lb, lc) = (norm2(a).sqrt(), norm2(b).sqrt(), norm2(c).sqrt());
    let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]);
    let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    2.0 * det.atan2(den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::Polygon;

    #[test]
    fn inside_outside_hole_and_boundary() {
        let p = Polygon::from_rings(&[
            &[[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]],
            &[[1.0, 1.0], [1.0, 2.0], [2.0, 2.0], [2.0, 1.0]],
        ])
        .unwrap();
        let w = |x: f64, y: f64| Euclid::winding_number(&p, &[x, y]);
        assert_eq!(w(3.0, 3.0), Some(1));
        assert_eq!(w(1.5, 1.5), Some(0)); // in the hole
        assert_eq!(w(5.0, 1.0), Some(0));
        assert_eq!(w(-1.0, 1.0), Some(0));
        assert_eq!(w(0.5, 2.0), Some(1)); // ray passes through hole vertices at y = 2
        assert_eq!(w(4.0, 2.0), None);
        assert_eq!(w(1.0, 1.5), None);
        assert_eq!(w(0.0, 0.0), None);
    }
}

#[cfg(test)]
mod tests_3d {
    use super::*;
    use crate::domain::Solid;

    /// Axis-aligned cube `[0, 2]³` as 12 outward triangles.
    pub(crate) fn cube() -> Solid {
        Solid::cuboid([0.0; 3], [2.0; 3]).unwrap()
    }

    #[test]
    fn cube_inside_outside_and_on_the_boundary() {
        let c = cube();
        assert!((c.volume() - 8.0).abs() < 1e-15);
        let w = |x: f64, y: f64, z: f64| Euclid::winding_number(&c, &[x, y, z]);
        assert_eq!(w(1.0, 1.0, 1.0), Some(1)); // the +x ray passes through a diagonal edge
        assert_eq!(w(0.5, 0.5, 0.5), Some(1)); // and through the diagonal again
        assert_eq!(w(1.0, 0.3, 1.7), Some(1));
        assert_eq!(w(-1.0, 1.0, 1.0), Some(0));
        assert_eq!(w(3.0, 1.0, 1.0), Some(0));
        assert_eq!(w(1.0, 2.5, 0.0), Some(0)); // ray in the plane of a face, outside it
        assert_eq!(w(2.0, 1.0, 1.0), None);
        assert_eq!(w(1.0, 1.0, 0.0), None); // on a face diagonal
        assert_eq!(w(0.0, 0.0, 0.0), None); // a corner
        assert_eq!(w(1.0, 0.0, 2.0), None); // an edge
    }

    #[test]
    fn nested_cube_with_reversed_cavity() {
        // Outer [0, 2]³ and a cavity [0.5, 1.5]³ oriented inward.
        let outer = cube();
        let mut v = outer.vertices().to_vec();
        v.extend(outer.vertices().iter().map(|p| p.map(|x| 0.5 + 0.5 * x)));
        let mut t = outer.simplices().to_vec();
        t.extend(
            outer
                .simplices()
                .iter()
                .map(|s| [s[0] + 8, s[2] + 8, s[1] + 8]),
        );
        let solid = Solid::new(v, t).unwrap();
        assert!((solid.volume() - 7.0).abs() < 1e-14);
        assert_eq!(Euclid::winding_number(&solid, &[1.0, 1.0, 1.0]), Some(0));
        assert_eq!(Euclid::winding_number(&solid, &[0.25, 1.0, 1.0]), Some(1));
        assert_eq!(Euclid::winding_number(&solid, &[1.5, 1.0, 1.0]), None);
        // The BVH far field against the exact sum over every triangle.
        let exact = |p: [f64; 3]| {
            (0..solid.simplices().len() as u32)
                .map(|t| solid_angle(&solid.simplex(t), &p))
                .sum::<f64>()
                / (4.0 * std::f64::consts::PI)
        };
        for (p, w) in [
            ([0.25, 1.0, 1.0], 1.0),
            ([1.0, 1.0, 1.0], 0.0),
            ([3.0, -1.0, 0.5], 0.0),
            ([40.0, 7.0, -3.0], 0.0),
        ] {
            assert!((exact(p) - w).abs() < 1e-12, "{p:?}");
            let g = generalized_winding_number(&solid, &p);
            assert!((g - w).abs() < 1e-2, "{p:?}: {g}");
        }
    }
}
