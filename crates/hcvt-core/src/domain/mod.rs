//! The domain: a region given only by its oriented boundary.
//!
//! In 2D the boundary is a set of segments (outer rings counter-clockwise, holes
//! clockwise); in 3D a set of triangles, counter-clockwise seen from outside. Either way
//! it is a closed, oriented `(d-1)`-cycle, which is all the exact clipping of DESIGN §3
//! needs: the signed cones from any point sum to the indicator of the domain.

mod bvh;
mod closest;
mod winding;
mod winding_grid;

use std::collections::HashMap;

use crate::error::CoreError;
use crate::geometry::{dot, sub, Aabb, Euclid, Space};
use crate::moments::{ConeMoments, Moments};
pub use bvh::Bvh;
pub use closest::TriangleSet;
pub use winding::{generalized_winding_number, WindingNumber};

/// A domain bounded by a closed, oriented cycle of `(D-1)`-simplices.
#[derive(Debug, Clone)]
pub struct Boundary<const D: usize> {
    vertices: Vec<[f64; D]>,
    simplices: Vec<[u32; D]>,
    bvh: Bvh<D>,
    moments: Moments<D>,
    /// Per BVH node, the far-field summary of its simplices for the generalised winding
    /// number, built on first use.
    dipoles: std::sync::OnceLock<Vec<winding::Dipole<D>>>,
    /// Whether the domain is convex (see [`Boundary::is_convex`]), decided on first use.
    convex: std::sync::OnceLock<bool>,
    /// Winding numbers of the buckets of a grid that the boundary misses, built on first use.
    winding_grid: std::sync::OnceLock<winding_grid::WindingGrid<D>>,
    /// Winding numbers asked for before the grid was built (shared by clones, which ask
    /// about the same domain).
    winding_queries: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

/// A polygonal domain: segments `[a, b]` with the interior on their left.
pub type Polygon = Boundary<2>;
/// A solid: triangles `[a, b, c]` counter-clockwise seen from outside.
pub type Solid = Boundary<3>;

impl Polygon {
    /// A polygon from closed rings of vertices, each ring's last vertex joined to its
    /// first: outer rings counter-clockwise, holes clockwise ([`Boundary::new`] checks).
    pub fn from_rings(rings: &[&[[f64; 2]]]) -> Result<Self, CoreError> {
        let mut vertices = Vec::new();
        let mut segments = Vec::new();
        for ring in rings {
            let start = vertices.len() as u32;
            let n = ring.len() as u32;
            vertices.extend_from_slice(ring);
            segments.extend((0..n).map(|k| [start + k, start + (k + 1) % n]));
        }
        Self::new(vertices, segments)
    }
}

/// Refuses an empty list of simplices, non-finite coordinates and out-of-range indices:
/// what every set of simplices over vertices (a boundary, a surface) is checked for first.
pub(crate) fn check_indexed<const D: usize, const K: usize>(
    vertices: &[[f64; D]],
    simplices: &[[u32; K]],
) -> Result<(), CoreError> {
    if simplices.is_empty() {
        return Err(CoreError::EmptyBoundary);
    }
    for (index, v) in vertices.iter().enumerate() {
        if let Some(&value) = v.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::NonFiniteVertex { index, value });
        }
    }
    for (element, s) in simplices.iter().enumerate() {
        if let Some(&vertex) = s.iter().find(|&&v| v as usize >= vertices.len()) {
            return Err(CoreError::VertexIndexOutOfRange {
                element,
                vertex,
                count: vertices.len(),
            });
        }
    }
    Ok(())
}

impl<const D: usize> Boundary<D>
where
    Euclid: Space<D> + ConeMoments<D>,
{
    /// Check and index a boundary.
    ///
    /// Refuses non-finite coordinates, out-of-range indices, an empty boundary, a boundary
    /// that is not a closed cycle (some oriented facet without its reverse), and one that
    /// encloses no positive volume (inside out). It does not look for self-intersections:
    /// the front ends (shapely in 2D, the mesh checks in 3D) do.
    pub fn new(vertices: Vec<[f64; D]>, simplices: Vec<[u32; D]>) -> Result<Self, CoreError> {
        check_indexed(&vertices, &simplices)?;
        check_closed(&simplices)?;
        let boxes = simplices
            .iter()
            .map(|s| Aabb::of_points(s.iter().map(|&v| &vertices[v as usize])))
            .collect();
        let bvh = Bvh::new(boxes);
        let mut boundary = Self {
            vertices,
            simplices,
            bvh,
            moments: Moments::zero(),
            dipoles: std::sync::OnceLock::new(),
            convex: std::sync::OnceLock::new(),
            winding_grid: std::sync::OnceLock::new(),
            winding_queries: Default::default(),
        };
        boundary.moments = boundary.integrate_from(boundary.bvh.bounds().center());
        let moments = boundary.moments;
        if moments.mass.is_nan() || moments.mass <= 0.0 {
            return Err(CoreError::NonPositiveVolume {
                volume: moments.mass,
            });
        }
        Ok(boundary)
    }

    /// Moments of the enclosed region about `origin`: the sum of the signed cones from
    /// `origin` over the boundary (DESIGN §3 with `w = 0` taken far away).
    fn integrate_from(&self, origin: [f64; D]) -> Moments<D> {
        let mut total = Moments::zero();
        for t in 0..self.simplices.len() as u32 {
            let p = self.simplex(t).map(|v| crate::geometry::sub(v, origin));
            total.add_scaled(&Euclid::cone_moments(&p), 1.0);
        }
        total
    }
}

impl<const D: usize> Boundary<D>
where
    Euclid: Space<D>,
{
    /// Vertex coordinates.
    pub fn vertices(&self) -> &[[f64; D]] {
        &self.vertices
    }

    /// Oriented boundary simplices (vertex indices).
    pub fn simplices(&self) -> &[[u32; D]] {
        &self.simplices
    }

    /// The vertices of simplex `t`.
    #[inline]
    pub fn simplex(&self, t: u32) -> [[f64; D]; D] {
        let s = &self.simplices[t as usize];
        std::array::from_fn(|k| self.vertices[s[k] as usize])
    }

    /// The BVH over the boundary simplices.
    pub fn bvh(&self) -> &Bvh<D> {
        &self.bvh
    }

    /// Per-node far-field summaries of the boundary (see [`winding::Dipole`]).
    pub(crate) fn dipoles(&self) -> &[winding::Dipole<D>] {
        self.dipoles.get_or_init(|| winding::dipoles(self))
    }

    /// Bounding box of the domain.
    pub fn bounds(&self) -> Aabb<D> {
        self.bvh.bounds()
    }

    /// Volume (area in 2D) of the domain.
    pub fn volume(&self) -> f64 {
        self.moments.mass
    }

    /// Moments of the domain about the centre of its bounding box.
    pub fn moments(&self) -> Moments<D> {
        self.moments
    }

    /// Centre of the bounding box, the origin of [`Boundary::moments`].
    pub fn moments_origin(&self) -> [f64; D] {
        self.bvh.bounds().center()
    }

    /// First moment `∫ x dx` about the coordinate origin.
    pub fn first_moment(&self) -> [f64; D] {
        let o = self.moments_origin();
        std::array::from_fn(|k| self.moments.first[k] + self.moments.mass * o[k])
    }
}

/// Most (simplex, vertex) side tests [`Boundary::is_convex`] spends before it answers
/// `false`: the test is quadratic, and only a fast path depends on it.
const CONVEXITY_BUDGET: usize = 1 << 24;

impl<const D: usize> Boundary<D>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    /// The grid of known winding numbers ([`winding_grid`]), built once enough winding
    /// numbers were asked for to pay for it (a small diagram or a single query casts rays).
    pub fn winding_grid(&self) -> Option<&winding_grid::WindingGrid<D>> {
        if let Some(grid) = self.winding_grid.get() {
            return Some(grid);
        }
        let asked = self
            .winding_queries
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if asked < winding_grid::WindingGrid::<D>::worth_after(self) {
            return None;
        }
        Some(self.winding_grid.get_or_init(|| {
            winding_grid::WindingGrid::new(self, |p| Euclid::ray_winding_number(self, p))
        }))
    }

    /// The domain is a convex polytope bounded once by its simplices: the winding number
    /// is 1 inside it, 0 outside, and it is the intersection of the inner half-spaces of
    /// its simplices. Decided exactly on first use, and `false` for boundaries too large to
    /// check within [`CONVEXITY_BUDGET`].
    ///
    /// Exact conditions: a point `c` (the vertex mean) with winding number 1 lies strictly
    /// inside every simplex's hyperplane (so no simplex is degenerate), and no vertex lies
    /// strictly outside one. Then every simplex lies on the boundary of the hull `K` of the
    /// vertices with its normal pointing out of `K`, so the boundary is `m` times that of
    /// `K`; `m` is the winding number at `c`, inside `K`.
    pub fn is_convex(&self) -> bool {
        *self.convex.get_or_init(|| self.check_convex())
    }

    fn check_convex(&self) -> bool {
        if self.simplices.len().saturating_mul(self.vertices.len()) > CONVEXITY_BUDGET {
            return false;
        }
        let n = self.vertices.len().max(1) as f64;
        let c = self
            .vertices
            .iter()
            .fold([0.0; D], |s, v| std::array::from_fn(|k| s[k] + v[k] / n));
        if Euclid::winding_number(self, &c) != Some(1) {
            return false;
        }
        (0..self.simplices.len() as u32).all(|t| {
            let p = self.simplex(t);
            let inside = inside_or_on(&p);
            Euclid::side(&p, &c) < 0.0 && self.vertices.iter().all(inside)
        })
    }
}

/// Whether a point is not strictly outside the oriented hyperplane through `p`: a float
/// test when it is clearly inside, the exact [`Space::side`] otherwise.
fn inside_or_on<const D: usize>(p: &[[f64; D]; D]) -> impl Fn(&[f64; D]) -> bool + '_
where
    Euclid: Space<D>,
{
    let n = Euclid::normal(p);
    let l1 = |v: [f64; D]| v.iter().map(|x| x.abs()).sum::<f64>();
    // The normal's error is a few ulps of the product of the edges' lengths, and the dot
    // product's a few more of that times |q - p_0|: 1e-10 of them is far beyond.
    let scale = 1e-10 * p[1..].iter().map(|&v| l1(sub(v, p[0]))).product::<f64>();
    move |q| {
        let d = sub(*q, p[0]);
        dot(n, d) < -scale * l1(d) || Euclid::side(p, q) <= 0.0
    }
}

/// Check that the oriented boundary of the chain of simplices vanishes: every oriented
/// facet (a vertex in 2D, a directed edge in 3D) is matched by its reverse.
fn check_closed<const D: usize>(simplices: &[[u32; D]]) -> Result<(), CoreError> {
    // Facet k of a simplex drops vertex k and carries sign (-1)^k; its key is the sorted
    // remaining vertices, and sorting flips the sign by the permutation's parity.
    let mut balance: HashMap<[u32; 2], (i64, usize)> = HashMap::new();
    let mut order = 0usize;
    for s in simplices {
        for k in 0..D {
            let mut facet = [u32::MAX; 2];
            let mut len = 0;
            for (j, &v) in s.iter().enumerate() {
                if j != k && len < 2 {
                    facet[len] = v;
                    len += 1;
                }
            }
            let mut sign: i64 = if k % 2 == 0 { 1 } else { -1 };
            if len == 2 && facet[0] > facet[1] {
                facet.swap(0, 1);
                sign = -sign;
            }
            let entry = balance.entry(facet).or_insert((0, order));
            entry.0 += sign;
            order += 1;
        }
    }
    let mut open: Vec<([u32; 2], i64, usize)> = balance
        .into_iter()
        .filter(|(_, (b, _))| *b != 0)
        .map(|(f, (b, o))| (f, b, o))
        .collect();
    if open.is_empty() {
        return Ok(());
    }
    open.sort_by_key(|&(_, _, o)| o);
    let (facet, sign, _) = open[0];
    let edge = match D {
        2 => vec![facet[0]],
        _ if sign > 0 => vec![facet[0], facet[1]],
        _ => vec![facet[1], facet[0]],
    };
    Err(CoreError::OpenBoundary {
        edge,
        count: open.len(),
    })
}

impl Solid {
    /// The axis-aligned box `[lo, hi]` as 12 outward triangles.
    pub fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Result<Self, CoreError> {
        let vertices: Vec<[f64; 3]> = (0..8u32)
            .map(|i| [0, 1, 2].map(|k| if (i >> k) & 1 == 1 { hi[k] } else { lo[k] }))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        Self::new(vertices, triangles)
    }

    /// The octahedron with vertices `±half_axes[k]` on axis `k`, as 8 outward triangles.
    pub fn octahedron(half_axes: [f64; 3]) -> Result<Self, CoreError> {
        // Vertex 2k is +axis k, 2k + 1 is -axis k; the face of signs (sx, sy, sz) is
        // counter-clockwise from outside in the order x, y, z when the signs multiply to +1.
        let vertices = (0..6)
            .map(|v: usize| {
                std::array::from_fn(|k| {
                    let sign = if v % 2 == 0 { 1.0 } else { -1.0 };
                    if k == v / 2 {
                        sign * half_axes[k]
                    } else {
                        0.0
                    }
                })
            })
            .collect();
        let faces = (0..8u32)
            .map(|s| {
                let (x, y, z) = (s & 1, 2 + ((s >> 1) & 1), 4 + ((s >> 2) & 1));
                if s.count_ones() % 2 == 0 {
                    [x, y, z]
                } else {
                    [x, z, y]
                }
            })
            .collect();
        Self::new(vertices, faces)
    }

    /// Pairs `(s, t)`, `s < t`, of triangles sharing no vertex whose interiors cross: an
    /// edge of one passes strictly through the inside of the other (exact `orient3d`).
    /// Touching and coplanar contacts are not reported. At most `max` pairs, in index
    /// order, with the total count.
    ///
    /// Where the surface crosses itself the winding number is 2 or -1, and the diagram
    /// integrates it so (DESIGN §3.6): the front end reports these pairs.
    pub fn crossing_triangles(&self, max: usize) -> (usize, Vec<(u32, u32)>) {
        use rayon::prelude::*;
        let per_triangle: Vec<Vec<u32>> = (0..self.simplices.len() as u32)
            .into_par_iter()
            .map(|s| {
                let mut candidates = Vec::new();
                let a = &self.simplices[s as usize];
                self.bvh.query(
                    &Aabb::of_points(a.iter().map(|&v| &self.vertices[v as usize])),
                    &mut candidates,
                );
                candidates.retain(|&t| {
                    let b = &self.simplices[t as usize];
                    t > s
                        && !a.iter().any(|v| b.contains(v))
                        && triangles_cross(&self.simplex(s), &self.simplex(t))
                });
                candidates
            })
            .collect();
        let total = per_triangle.iter().map(Vec::len).sum();
        let pairs = per_triangle
            .iter()
            .enumerate()
            .flat_map(|(s, ts)| ts.iter().map(move |&t| (s as u32, t)))
            .take(max)
            .collect();
        (total, pairs)
    }
}

fn coord(v: &[f64; 3]) -> robust::Coord3D<f64> {
    robust::Coord3D {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

/// An edge of either triangle passes strictly through the interior of the other.
fn triangles_cross(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> bool {
    (0..3).any(|k| segment_crosses(&a[k], &a[(k + 1) % 3], b))
        || (0..3).any(|k| segment_crosses(&b[k], &b[(k + 1) % 3], a))
}

/// The open segment `(u, v)` meets the open triangle `tri` in one point.
fn segment_crosses(u: &[f64; 3], v: &[f64; 3], tri: &[[f64; 3]; 3]) -> bool {
    let [p, q, r] = tri.map(|x| coord(&x));
    let (cu, cv) = (coord(u), coord(v));
    let su = robust::orient3d(p, q, r, cu);
    let sv = robust::orient3d(p, q, r, cv);
    if su == 0.0 || sv == 0.0 || (su > 0.0) == (sv > 0.0) {
        return false;
    }
    let e = [
        robust::orient3d(cu, cv, p, q),
        robust::orient3d(cu, cv, q, r),
        robust::orient3d(cu, cv, r, p),
    ];
    e.iter().all(|&x| x > 0.0) || e.iter().all(|&x| x < 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_with_hole() -> Polygon {
        Polygon::from_rings(&[
            &[[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]],
            &[[1.0, 1.0], [1.0, 2.0], [2.0, 2.0], [2.0, 1.0]],
        ])
        .unwrap()
    }

    #[test]
    fn area_and_first_moment_of_square_with_hole() {
        let p = square_with_hole();
        assert_eq!(p.volume(), 15.0);
        // First moment about the box centre (2, 2): the hole at centre (1.5, 1.5) removed.
        let m = p.moments();
        assert!((m.first[0] - 0.5).abs() < 1e-14 && (m.first[1] - 0.5).abs() < 1e-14);
    }

    #[test]
    fn open_and_inside_out_boundaries_are_refused() {
        let v = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]];
        let err = Polygon::new(v.clone(), vec![[0, 1], [1, 2]]).unwrap_err();
        assert!(
            matches!(err, CoreError::OpenBoundary { count: 2, .. }),
            "{err}"
        );
        let err = Polygon::new(v.clone(), vec![[0, 2], [2, 1], [1, 0]]).unwrap_err();
        assert!(matches!(err, CoreError::NonPositiveVolume { .. }), "{err}");
        let err = Polygon::new(v, vec![[0, 1], [1, 7], [7, 0]]).unwrap_err();
        assert!(
            matches!(err, CoreError::VertexIndexOutOfRange { vertex: 7, .. }),
            "{err}"
        );
    }

    #[test]
    fn tetrahedron_volume() {
        let v = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let solid = Solid::new(v.clone(), t.clone()).unwrap();
        assert!((solid.volume() - 1.0 / 6.0).abs() < 1e-16);
        let err = Solid::new(v, t[..3].to_vec()).unwrap_err();
        assert!(
            matches!(err, CoreError::OpenBoundary { count: 3, .. }),
            "{err}"
        );
    }

    #[test]
    fn two_tetrahedra_crossing_are_found() {
        let mut v = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let single = Solid::new(v.clone(), t.clone()).unwrap();
        assert_eq!(single.crossing_triangles(10).0, 0);
        v.extend([
            [0.2, 0.2, 0.2],
            [1.2, 0.2, 0.2],
            [0.2, 1.2, 0.2],
            [0.2, 0.2, 1.2],
        ]);
        let mut both = t.clone();
        both.extend(t.iter().map(|s| s.map(|i| i + 4)));
        let (count, pairs) = Solid::new(v, both).unwrap().crossing_triangles(2);
        assert!(count >= 3, "{count}");
        assert_eq!(pairs.len(), 2);
        assert!(pairs.iter().all(|&(s, t)| s < 4 && t >= 4));
    }
}
