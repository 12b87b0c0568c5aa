//! The surface itself: its triangles, checked on construction and indexed by a BVH, its
//! border, area and first moment.

use std::collections::HashMap;

use crate::domain::TriangleSet;
use crate::error::CoreError;
use crate::geometry::{add, cross, norm2, scale, sub};

/// A surface of triangles in 3D: closed or open, any number of components, checked
/// (finite, indices in range, no degenerate or repeated triangles, every edge in at most
/// two triangles, consistently oriented) and indexed by a BVH.
#[derive(Debug, Clone)]
pub struct Surface {
    /// The triangles, their vertices and BVH (which also finds nearest points).
    pub(super) set: TriangleSet,
    /// Per triangle, whether its edge `k` (from vertex `k` to `k + 1`) lies in no other
    /// triangle: the surface's border.
    pub(super) border: Vec<[bool; 3]>,
    pub(super) area: f64,
    pub(super) first: [f64; 3],
    /// Newton's Hessian with the flat weight on its arcs ([`HessianArcs`]), for a test.
    ///
    /// [`HessianArcs`]: measure::HessianArcs
    #[cfg(test)]
    pub(super) flat_arcs: bool,
}

/// `count` offenders and the first, as an error.
fn refuse(what: &str, count: usize, first: String) -> CoreError {
    CoreError::InvalidSurface {
        reason: format!("{count} {what}, first {first}"),
    }
}

impl Surface {
    /// Check and index a surface of `triangles` (vertex indices) over `vertices`.
    ///
    /// Refuses an empty surface, non-finite coordinates, indices out of range, degenerate
    /// triangles (a repeated vertex or zero area), triangles repeated on the same three
    /// vertices, non-manifold edges (in three or more triangles) and edges two triangles
    /// run the same way (inconsistent orientation): each with the count and the first.
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Result<Self, CoreError> {
        crate::domain::check_indexed(&vertices, &triangles)?;
        let corners = |t: &[u32; 3]| t.map(|v| vertices[v as usize]);
        let degenerate: Vec<usize> = (0..triangles.len())
            .filter(|&f| {
                let [a, b, c] = triangles[f];
                let p = corners(&triangles[f]);
                a == b || b == c || c == a || norm2(cross(sub(p[1], p[0]), sub(p[2], p[0]))) == 0.0
            })
            .collect();
        if let Some(&f) = degenerate.first() {
            return Err(refuse(
                "degenerate triangle(s) (a repeated vertex or zero area)",
                degenerate.len(),
                format!("face {f} {:?}", triangles[f]),
            ));
        }
        let mut seen: HashMap<[u32; 3], usize> = HashMap::with_capacity(triangles.len());
        let mut repeated = Vec::new();
        for (f, t) in triangles.iter().enumerate() {
            let mut key = *t;
            key.sort_unstable();
            if let Some(&g) = seen.get(&key) {
                repeated.push((g, f));
            } else {
                seen.insert(key, f);
            }
        }
        if let Some(&(g, f)) = repeated.first() {
            return Err(refuse(
                "repeated triangle(s) on the same vertices",
                repeated.len(),
                format!("faces {g} and {f}"),
            ));
        }
        // Directed edges: each at most once (else two triangles run it the same way), and
        // each undirected edge in at most two triangles.
        let mut directed: HashMap<(u32, u32), usize> = HashMap::with_capacity(3 * triangles.len());
        let mut undirected: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
        let (mut flipped, mut nonmanifold) = (Vec::new(), Vec::new());
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if let Some(&g) = directed.get(&(a, b)) {
                    flipped.push((a, b, g, f));
                }
                directed.insert((a, b), f);
                let count = undirected.entry((a.min(b), a.max(b))).or_insert(0);
                *count += 1;
                if *count == 3 {
                    nonmanifold.push((a.min(b), a.max(b)));
                }
            }
        }
        if let Some(&(a, b)) = nonmanifold.first() {
            return Err(refuse(
                "non-manifold edge(s) (in three or more triangles)",
                nonmanifold.len(),
                format!("edge ({a}, {b})"),
            ));
        }
        if let Some(&(a, b, g, f)) = flipped.first() {
            return Err(refuse(
                "edge(s) run the same way by two triangles (inconsistent orientation; \
                 flip one side)",
                flipped.len(),
                format!("edge ({a}, {b}) in faces {g} and {f}"),
            ));
        }
        let border = triangles
            .iter()
            .map(|t| std::array::from_fn(|k| !directed.contains_key(&(t[(k + 1) % 3], t[k]))))
            .collect();
        let (mut area, mut first) = (0.0, [0.0; 3]);
        for t in &triangles {
            let p = corners(t);
            let a = 0.5 * norm2(cross(sub(p[1], p[0]), sub(p[2], p[0]))).sqrt();
            area += a;
            first = add(first, scale(add(add(p[0], p[1]), p[2]), a / 3.0));
        }
        Ok(Self {
            set: TriangleSet::new(vertices, triangles)?,
            border,
            area,
            first,
            #[cfg(test)]
            flat_arcs: false,
        })
    }

    /// The surface whose Hessian weighs its arcs as if flat (`2/|q|`, [`HessianArcs`]):
    /// what the tests show the finite differences reject.
    ///
    /// [`HessianArcs`]: measure::HessianArcs
    #[cfg(test)]
    pub(crate) fn with_flat_arcs(mut self) -> Self {
        self.flat_arcs = true;
        self
    }

    /// The vertices, as given.
    pub fn vertices(&self) -> &[[f64; 3]] {
        self.set.vertices()
    }

    /// The triangles (vertex indices), as given.
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.set.triangles()
    }

    /// The triangles as a [`TriangleSet`]: nearest points on the surface.
    pub fn triangle_set(&self) -> &TriangleSet {
        &self.set
    }

    /// The total area, `L²`: the sum of the triangles' areas in index order.
    pub fn area(&self) -> f64 {
        self.area
    }

    /// `∫ x dA` over the surface (3,), `L³`.
    pub fn first_moment(&self) -> [f64; 3] {
        self.first
    }

    /// Whether edge `k` of triangle `t` lies on the surface's border.
    pub fn is_border(&self, t: u32, k: usize) -> bool {
        self.border[t as usize][k]
    }
}
