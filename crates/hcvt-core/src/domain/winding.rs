//! Exact winding numbers: is a point inside the domain, outside, or on its boundary?

use super::Boundary;
use crate::geometry::{Aabb, Euclid};

/// Winding number of a point with respect to a closed oriented boundary.
pub trait WindingNumber<const D: usize> {
    /// The winding number of `p` (1 inside a valid domain, 0 outside), or `None` when `p`
    /// lies exactly on the boundary, decided with exact predicates.
    fn winding_number(boundary: &Boundary<D>, p: &[f64; D]) -> Option<i32>;
}

impl WindingNumber<2> for Euclid {
    /// Crossings of the ray from `p` towards `+x` (Sunday's rule: upward crossings with `p`
    /// on the left count +1, downward with `p` on the right −1), the candidate segments
    /// from the BVH, every side test exact (`orient2d`).
    fn winding_number(boundary: &Boundary<2>, p: &[f64; 2]) -> Option<i32> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::Polygon;

    #[test]
    fn inside_outside_hole_and_boundary() {
        let v = vec![
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [0.0, 4.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [2.0, 2.0],
            [2.0, 1.0],
        ];
        let s = vec![
            [0, 1],
            [1, 2],
            [2, 3],
            [3, 0],
            [4, 5],
            [5, 6],
            [6, 7],
            [7, 4],
        ];
        let p = Polygon::new(v, s).unwrap();
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
