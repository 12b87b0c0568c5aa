//! The nearest point of a set of triangles to each query point, through a BVH: where a
//! surface CVT projects its sites at the end (DESIGN §12), and what a Hausdorff distance
//! between two surfaces samples.

use rayon::prelude::*;

use super::Bvh;
use crate::error::CoreError;
use crate::geometry::{add, dot, norm2, scale, sub, Aabb};

/// The point of triangle `(a, b, c)` nearest `p` (Ericson, "Real-Time Collision
/// Detection", §5.1.5: by the Voronoi regions of the vertices, edges and face).
pub fn closest_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return add(a, scale(ab, d1 / (d1 - d3)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return add(a, scale(ac, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return add(b, scale(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = 1.0 / (va + vb + vc);
    add(a, add(scale(ab, vb * denom), scale(ac, vc * denom)))
}

/// Squared distance from `p` to the box `b` (0 inside).
fn box_distance2(b: &Aabb<3>, p: [f64; 3]) -> f64 {
    norm2::<3>(std::array::from_fn(|k| {
        (b.lo[k] - p[k]).max(p[k] - b.hi[k]).max(0.0)
    }))
}

/// A BVH over triangles that answers nearest-point queries; the triangles need no
/// checks beyond finite coordinates and indices in range.
#[derive(Debug, Clone)]
pub struct TriangleSet {
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    bvh: Bvh<3>,
}

/// Below this many points [`TriangleSet::closest_all`] runs on the calling thread: handing
/// a few points to a thread pool and back costs more than they do (under load,
/// milliseconds a call: `hcvt.surface.tighten` asks for a few points at a time, thousands
/// of times).
const SERIAL_CLOSEST: usize = 256;

impl TriangleSet {
    /// Index `triangles` over `vertices`: finite coordinates, indices in range, at least
    /// one triangle.
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Result<Self, CoreError> {
        super::check_indexed(&vertices, &triangles)?;
        let boxes = triangles
            .iter()
            .map(|t| Aabb::of_points(t.iter().map(|&v| &vertices[v as usize])))
            .collect();
        Ok(Self {
            bvh: Bvh::new(boxes),
            vertices,
            triangles,
        })
    }

    /// The vertices, as given.
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    /// The triangles (vertex indices), as given.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The BVH over the triangles.
    pub fn bvh(&self) -> &Bvh<3> {
        &self.bvh
    }

    /// The corners of triangle `t`.
    pub fn corners(&self, t: u32) -> [[f64; 3]; 3] {
        self.triangles[t as usize].map(|v| self.vertices[v as usize])
    }

    /// The nearest point of the triangles to `p`, and its triangle (the least index among
    /// equally near ones).
    ///
    /// Depth first, the nearer child first: the first leaves reached bound the distance,
    /// which prunes most of the rest (a walk in the tree's fixed order met the nearest
    /// triangle late: bunny, 35,000 points, 2.3 s under load). The answer does not depend
    /// on the order: every box no farther than the best so far is opened, and ties go to
    /// the least index.
    pub fn closest(&self, p: [f64; 3]) -> ([f64; 3], u32) {
        let mut best = (f64::INFINITY, p, 0u32);
        let bvh = &self.bvh;
        if bvh.is_empty() {
            return (best.1, best.2);
        }
        // (squared distance to the node's box, node); a median-split tree is at most
        // 32 deep for u32 indices, so the stack stays short.
        let mut stack: Vec<(f64, usize)> = Vec::with_capacity(64);
        stack.push((box_distance2(&bvh.node_bounds(0), p), 0));
        while let Some((d2, node)) = stack.pop() {
            if d2 > best.0 {
                continue;
            }
            match bvh.children(node) {
                Some((a, b)) => {
                    let near_a = (box_distance2(&bvh.node_bounds(a), p), a);
                    let near_b = (box_distance2(&bvh.node_bounds(b), p), b);
                    let (near, far) = if near_a.0 <= near_b.0 {
                        (near_a, near_b)
                    } else {
                        (near_b, near_a)
                    };
                    for child in [far, near] {
                        if child.0 <= best.0 {
                            stack.push(child);
                        }
                    }
                }
                None => {
                    for &t in bvh.node_items(node) {
                        let [a, b, c] = self.corners(t);
                        let q = closest_on_triangle(p, a, b, c);
                        let d2 = norm2(sub(q, p));
                        if d2 < best.0 || (d2 == best.0 && t < best.2) {
                            best = (d2, q, t);
                        }
                    }
                }
            }
        }
        (best.1, best.2)
    }

    /// Whether [`TriangleSet::closest_all`] of `count` points runs in parallel: from
    /// [`SERIAL_CLOSEST`] points on. A caller that would hand the work to a thread pool
    /// (the Python binding) asks first: below, the hand-off costs more than the points.
    pub fn closest_in_parallel(count: usize) -> bool {
        count >= SERIAL_CLOSEST
    }

    /// [`TriangleSet::closest`] of every point, in parallel for many points
    /// ([`TriangleSet::closest_in_parallel`]; each point alone either way: the result
    /// does not depend on the threads).
    pub fn closest_all(&self, points: &[[f64; 3]]) -> Vec<([f64; 3], u32)> {
        if Self::closest_in_parallel(points.len()) {
            points.par_iter().map(|&p| self.closest(p)).collect()
        } else {
            points.iter().map(|&p| self.closest(p)).collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_points_match_brute_force() {
        let mut rng = crate::sample::Lcg::new(3);
        let vertices: Vec<[f64; 3]> = (0..60)
            .map(|_| [rng.unit(), rng.unit(), rng.unit()])
            .collect();
        let triangles: Vec<[u32; 3]> = (0..40).map(|k| [k, k + 7, k + 13]).collect();
        let set = TriangleSet::new(vertices.clone(), triangles.clone()).unwrap();
        // The least squared distance over every triangle, and the least index reaching it.
        let brute_force = |p: [f64; 3]| {
            let mut best = (f64::INFINITY, 0u32);
            for (k, t) in triangles.iter().enumerate() {
                let [a, b, c] = t.map(|v| vertices[v as usize]);
                let d2 = norm2(sub(closest_on_triangle(p, a, b, c), p));
                if d2 < best.0 {
                    best = (d2, k as u32);
                }
            }
            best
        };
        for _ in 0..200 {
            let p = [
                2.0 * rng.unit() - 0.5,
                2.0 * rng.unit() - 0.5,
                2.0 * rng.unit() - 0.5,
            ];
            let (q, t) = set.closest(p);
            let brute = brute_force(p);
            assert_eq!((norm2(sub(q, p)), t), brute);
        }
        // Ties: at a shared vertex every triangle round it is as near; the least index wins.
        for v in [7usize, 13, 20, 33] {
            let (q, t) = set.closest(vertices[v]);
            assert_eq!((norm2(sub(q, vertices[v])), t), brute_force(vertices[v]));
            assert_eq!(q, vertices[v]);
        }
        // Each region of the triangle's closed form against a fine grid of its points.
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        for p in [
            [0.2, 0.2, 1.0],
            [2.0, -1.0, 0.5],
            [-1.0, -1.0, 0.0],
            [0.8, 0.8, -0.3],
        ] {
            let q = closest_on_triangle(p, a, b, c);
            let mut best = f64::INFINITY;
            for i in 0..=200 {
                for j in 0..=(200 - i) {
                    let x = [i as f64 / 200.0, j as f64 / 200.0, 0.0];
                    best = best.min(norm2(sub(x, p)));
                }
            }
            assert!(norm2(sub(q, p)) <= best + 1e-12, "{p:?}");
        }
    }
}
