//! The 3D convex cell in the dual representation of Ray et al. 2018 ("Meshless Voronoi on
//! the GPU") and geogram's `ConvexCell`: the cell is a list of planes, and each vertex is a
//! triangle of three plane indices. Clipping removes the triangles whose vertex lies
//! beyond the new plane and cones the boundary edges of the removed region to it.
//!
//! Why this representation: the topology is combinatorial (triangles of plane indices),
//! so faces can never disagree about a shared vertex; each vertex is computed once, when
//! its triangle is created, so every face that uses it sees the same bits.

use super::convex_cell::{ConvexCell, Face};
use crate::geometry::{add, dot, norm2, scale, sub, Aabb, HalfSpace};
use crate::moments::{FaceMoments, Moments};

/// A plane of the cell, `normal · x <= offset`, and what made it. Vertices are computed
/// once, when their triangle is made, never from the planes.
#[derive(Debug, Clone, Copy)]
struct Plane {
    normal: [f64; 3],
    offset: f64,
    face: Face,
}

/// Convex polyhedron relative to its site.
///
/// `triangles[t] = [a, b, c]` are the planes meeting at vertex `vertices[t]`, ordered
/// counter-clockwise seen from outside; an empty triangle list is the empty cell.
#[derive(Debug, Default)]
pub struct PolyhedronCell {
    planes: Vec<Plane>,
    triangles: Vec<[u16; 3]>,
    /// `neighbors[t][k]`: the triangle across edge `triangles[t][k] -> triangles[t][k + 1]`.
    neighbors: Vec<[u32; 3]>,
    vertices: Vec<[f64; 3]>,
    /// Largest `|v|²` over the vertices, kept up to date by every change: the driver asks
    /// for it after each clip, and most clips change nothing.
    max_dist2: f64,
}

/// Buffers of a clip that changes the cell, one set per thread: cells are made and cloned
/// by the thousand, and buffers of their own would grow anew in each.
#[derive(Debug)]
struct Scratch {
    /// Per triangle: the signed distance of its vertex beyond the clipping plane.
    dist: Vec<f64>,
    /// How far beyond the plane a vertex must lie to be removed.
    tol: f64,
    /// Boundary edges of the removed region.
    rim: Vec<RimEdge>,
    /// The rim in cycle order.
    cycle: Vec<RimEdge>,
    /// Per plane: the rim edge starting at it, or `NO_EDGE`; all `NO_EDGE` between clips.
    rim_from: Vec<u32>,
    /// Slots of the removed triangles, refilled by the new ones.
    free: Vec<usize>,
    /// Largest `|v|²` over the kept vertices.
    kept_dist2: f64,
}

/// No rim edge starts at this plane.
const NO_EDGE: u32 = u32::MAX;

impl Scratch {
    const fn new() -> Self {
        Self {
            dist: Vec::new(),
            tol: 0.0,
            rim: Vec::new(),
            cycle: Vec::new(),
            rim_from: Vec::new(),
            free: Vec::new(),
            kept_dist2: 0.0,
        }
    }
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = const { std::cell::RefCell::new(Scratch::new()) };
}

/// A directed edge `a -> b` (two planes) of a removed triangle whose neighbour across is
/// kept, and the new vertex where the clipping plane cuts the primal edge `a ∩ b`.
#[derive(Debug, Clone, Copy)]
struct RimEdge {
    a: u16,
    b: u16,
    vertex: [f64; 3],
    /// The kept triangle across the edge, and the index of the edge in it.
    kept: u32,
    kept_edge: u8,
}

impl Clone for PolyhedronCell {
    /// With room to grow: a copy is made to be clipped further.
    fn clone(&self) -> Self {
        fn roomy<T: Copy>(v: &[T]) -> Vec<T> {
            let mut out = Vec::with_capacity(v.len() + CLONE_HEADROOM);
            out.extend_from_slice(v);
            out
        }
        Self {
            planes: roomy(&self.planes),
            triangles: roomy(&self.triangles),
            neighbors: roomy(&self.neighbors),
            vertices: roomy(&self.vertices),
            max_dist2: self.max_dist2,
        }
    }

    /// Reuses this cell's buffers: the driver clones a cell once per boundary piece.
    fn clone_from(&mut self, source: &Self) {
        self.planes.clone_from(&source.planes);
        self.triangles.clone_from(&source.triangles);
        self.neighbors.clone_from(&source.neighbors);
        self.vertices.clone_from(&source.vertices);
        self.max_dist2 = source.max_dist2;
    }
}

/// Spare capacity of a cloned cell's arrays, so that its first clips do not reallocate.
const CLONE_HEADROOM: usize = 32;

/// Scratch of [`PolyhedronCell::for_each_ring`].
#[derive(Default)]
struct WalkBuffers {
    first: Vec<u32>,
    ring: Vec<u32>,
}

thread_local! {
    static WALK_BUFFERS: std::cell::RefCell<WalkBuffers> = std::cell::RefCell::default();
}

/// Planes a cell may have: plane indices are `u16`.
const MAX_PLANES: usize = u16::MAX as usize;

impl PolyhedronCell {
    /// Vertices relative to the site; vertex `t` is where the planes of triangle `t` meet.
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    /// Call `f(face, polygon)` for every face with at least three vertices; the polygon is
    /// counter-clockwise seen from outside, relative to the site. Vertices where more than
    /// three planes meet appear once per triangle, so a polygon may repeat a point.
    pub fn for_each_polygon(&self, mut f: impl FnMut(Face, &[[f64; 3]])) {
        let mut polygon = Vec::new();
        self.for_each_ring(|face, ring| {
            polygon.clear();
            polygon.extend(ring.iter().map(|&t| self.vertices[t as usize]));
            f(face, &polygon);
        });
    }

    /// [`PolyhedronCell::walk_faces`] with per-thread buffers: every cell of every diagram
    /// is walked. A nested walk (from inside `f`) finds them taken and uses fresh ones.
    fn for_each_ring(&self, mut f: impl FnMut(Face, &[u32])) {
        WALK_BUFFERS.with(|cell| {
            let mut fresh = WalkBuffers::default();
            let mut taken = cell.try_borrow_mut();
            let b = match taken.as_deref_mut() {
                Ok(b) => b,
                Err(_) => &mut fresh,
            };
            self.walk_faces(&mut b.first, &mut b.ring, |plane, ring| {
                f(self.planes[plane as usize].face, ring);
            });
        });
    }

    /// Moments of the cone from the site over the face with vertices `ring`, fanned from
    /// its first vertex `v_0`, and the face's area.
    ///
    /// Each fan triangle `(v_0, a, b)` needs one cross product `c = (a - v_0) × (b - v_0)`:
    /// `c / 2` is its vector area and `v_0 · c = det[v_0 a b]` six times its cone's volume.
    /// With `s = v_0 + a + b` the cone's second moment is `mass (|s|² + |v_0|² + |a|² +
    /// |b|²) / 20`, the sum of the six products `u · w` of `tetra_moments` rewritten.
    fn fan(&self, ring: &[u32]) -> (Moments<3>, f64) {
        let v = |k: usize| self.vertices[ring[k] as usize];
        let v0 = v(0);
        let n0 = norm2(v0);
        let (mut a, mut na) = (v(1), norm2(v(1)));
        let mut m = Moments::zero();
        let mut area = [0.0; 3];
        for k in 2..ring.len() {
            let b = v(k);
            let nb = norm2(b);
            let c = cross(sub(a, v0), sub(b, v0));
            area = add(area, c);
            let mass = dot(v0, c) / 6.0;
            let s = add(add(v0, a), b);
            m.mass += mass;
            m.first = add(m.first, scale(s, mass / 4.0));
            m.second += mass * (norm2(s) + n0 + na + nb) / 20.0;
            (a, na) = (b, nb);
        }
        (m, 0.5 * norm2(area).sqrt())
    }

    /// [`PolyhedronCell::fan`]'s cone moments with the face's own moments about the site
    /// (for the Hessian), summed over the same fan triangles.
    fn fan_moments(&self, ring: &[u32]) -> (Moments<3>, FaceMoments<3>) {
        let v = |k: usize| self.vertices[ring[k] as usize];
        let v0 = v(0);
        let mut face = FaceMoments::zero();
        for k in 2..ring.len() {
            let (a, b) = (v(k - 1), v(k));
            let area = 0.5 * norm2(cross(sub(a, v0), sub(b, v0))).sqrt();
            face.add_scaled(&FaceMoments::simplex(&[v0, a, b], area), 1.0);
        }
        (self.fan(ring).0, face)
    }

    /// The closed, outward boundary triangulation of the cell: every face fanned from its
    /// first vertex, as indices into [`PolyhedronCell::vertices`], appended to `out`.
    pub fn boundary_triangles(&self, out: &mut Vec<[u32; 3]>) {
        let (mut first, mut ring) = (Vec::new(), Vec::new());
        self.walk_faces(&mut first, &mut ring, |_, ring| {
            for k in 1..ring.len() - 1 {
                out.push([ring[0], ring[k], ring[k + 1]]);
            }
        });
    }

    /// Walk each face in plane order and hand `f(plane, ring)` its vertices (triangle
    /// indices) counter-clockwise from outside, starting at the first triangle holding the
    /// plane; faces with fewer than three vertices are skipped. From vertex `(p, q, r)` the
    /// next vertex of face `p` is its neighbour across the edge `r -> p`, the triangle
    /// `(p, r, s)`: the adjacency makes each step O(1), with no sorting or searching.
    fn walk_faces(
        &self,
        first: &mut Vec<u32>,
        ring: &mut Vec<u32>,
        mut f: impl FnMut(u16, &[u32]),
    ) {
        const NONE: u32 = u32::MAX;
        first.clear();
        first.resize(self.planes.len(), NONE);
        for (t, tri) in self.triangles.iter().enumerate() {
            for &p in tri {
                if first[p as usize] == NONE {
                    first[p as usize] = t as u32;
                }
            }
        }
        for (p, &start) in first.iter().enumerate() {
            if start == NONE {
                continue;
            }
            ring.clear();
            let mut at = start as usize;
            // A consistent adjacency comes back to `start`; the bound only guards the loop.
            for _ in 0..self.triangles.len() {
                ring.push(at as u32);
                let k = self.triangles[at].iter().position(|&x| x as usize == p);
                let next = self.neighbors[at][(k.unwrap_or(0) + 2) % 3] as usize;
                if next == start as usize || next >= self.triangles.len() {
                    break;
                }
                at = next;
            }
            if ring.len() >= 3 {
                f(p as u16, ring);
            }
        }
    }

    /// The vertex where the segment from `inside` (distance `d_in <= 0`) to `outside`
    /// (`d_out > 0`) meets the plane. Interpolating along the old edge keeps the new vertex
    /// on it even when the three planes are nearly dependent.
    #[inline]
    fn crossing(inside: [f64; 3], outside: [f64; 3], d_in: f64, d_out: f64) -> [f64; 3] {
        let t = d_in / (d_in - d_out);
        add(inside, scale(sub(outside, inside), t))
    }

    /// One attempt of [`ConvexCell::clip`]: remove the vertices farther than `tol` beyond
    /// `h`. Returns `false`, changing nothing, when the removed region is not a disk.
    fn try_clip(&mut self, h: &HalfSpace<3>, face: Face, tol: f64) -> Option<bool> {
        let dist = |v: &[f64; 3]| dot(h.normal, *v) - h.offset;
        // Most clips of a Voronoi cell change nothing: decide that in one branch-free pass
        // (a plain comparison, cheaper than `f64::max`; a NaN distance removes nothing).
        let farthest = self.vertices.iter().fold(f64::NEG_INFINITY, |m, v| {
            let d = dist(v);
            if d > m {
                d
            } else {
                m
            }
        });
        if farthest <= tol {
            return Some(false);
        }
        SCRATCH.with(|cell| match cell.try_borrow_mut() {
            Ok(mut scratch) => self.cut(h, face, tol, &mut scratch),
            Err(_) => self.cut(h, face, tol, &mut Scratch::new()),
        })
    }

    /// The part of [`PolyhedronCell::try_clip`] that changes the cell.
    fn cut(
        &mut self,
        h: &HalfSpace<3>,
        face: Face,
        tol: f64,
        scratch: &mut Scratch,
    ) -> Option<bool> {
        scratch.dist.clear();
        scratch.free.clear();
        scratch.tol = tol;
        scratch.kept_dist2 = 0.0;
        for (t, v) in self.vertices.iter().enumerate() {
            let d = dot(h.normal, *v) - h.offset;
            scratch.dist.push(d);
            if d > tol {
                scratch.free.push(t);
            } else {
                scratch.kept_dist2 = scratch.kept_dist2.max(norm2(*v));
            }
        }
        if scratch.free.len() == self.triangles.len() {
            self.triangles.clear();
            self.neighbors.clear();
            self.vertices.clear();
            self.max_dist2 = 0.0;
            return Some(true);
        }
        self.find_rim(scratch);
        // The removed region of a convex cell is a disk: its rim is one simple cycle.
        if !order_cycle(scratch, self.planes.len()) {
            return None;
        }
        self.replace_by_rim(scratch, h, face);
        Some(true)
    }

    /// The rim of the removed region `scratch.free` (directed edges of removed triangles
    /// whose neighbour across is kept, each with the new vertex on it).
    fn find_rim(&self, scratch: &mut Scratch) {
        scratch.rim.clear();
        for &t in &scratch.free {
            let tri = self.triangles[t];
            for k in 0..3 {
                let s = self.neighbors[t][k] as usize;
                if s >= self.triangles.len() || scratch.dist[s] > scratch.tol {
                    continue;
                }
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let kept_edge = (0..3)
                    .find(|&j| self.neighbors[s][j] as usize == t)
                    .unwrap_or(0) as u8;
                let (v_in, v_out) = (self.vertices[s], self.vertices[t]);
                let (d_in, d_out) = (scratch.dist[s].min(0.0), scratch.dist[t]);
                scratch.rim.push(RimEdge {
                    a,
                    b,
                    vertex: Self::crossing(v_in, v_out, d_in, d_out),
                    kept: s as u32,
                    kept_edge,
                });
            }
        }
    }

    /// Cone the rim to the new plane: one triangle `(a, b, new)` per rim edge, written
    /// into the removed slots first; slots left over (planes that vanished) are dropped.
    fn replace_by_rim(&mut self, scratch: &Scratch, h: &HalfSpace<3>, face: Face) {
        let p = self.planes.len() as u16;
        self.planes.push(Plane {
            normal: h.normal,
            offset: h.offset,
            face,
        });
        // The rim is a cycle in order (`order_cycle`): new triangle k meets triangle k + 1
        // across its edge `b -> p` and triangle k - 1 across `p -> a`.
        let n = scratch.cycle.len();
        let first_new = self.triangles.len();
        let free = &scratch.free;
        let slot = |k: usize| free.get(k).copied().unwrap_or(first_new + k - free.len()) as u32;
        let (mut prev, mut here) = (slot(n - 1), slot(0));
        for (k, e) in scratch.cycle.iter().enumerate() {
            let tri = [e.a, e.b, p];
            let next = if k + 1 < n { slot(k + 1) } else { slot(0) };
            let row = [e.kept, next, prev];
            if let Some(&at) = scratch.free.get(k) {
                self.triangles[at] = tri;
                self.neighbors[at] = row;
                self.vertices[at] = e.vertex;
            } else {
                self.triangles.push(tri);
                self.neighbors.push(row);
                self.vertices.push(e.vertex);
            }
            self.neighbors[e.kept as usize][e.kept_edge as usize] = here;
            (prev, here) = (here, next);
        }
        // Descending order keeps the remaining indices valid under swap_remove; the
        // triangle moved into a freed slot tells its neighbours where it went.
        for &at in scratch.free.iter().skip(n).rev() {
            let last = self.triangles.len() - 1;
            self.triangles.swap_remove(at);
            self.neighbors.swap_remove(at);
            self.vertices.swap_remove(at);
            if at < last {
                for k in 0..3 {
                    let s = self.neighbors[at][k] as usize;
                    if let Some(row) = self.neighbors.get_mut(s) {
                        for x in row.iter_mut() {
                            if *x as usize == last {
                                *x = at as u32;
                            }
                        }
                    }
                }
            }
        }
        self.max_dist2 =
            (scratch.cycle.iter()).fold(scratch.kept_dist2, |m, e| m.max(norm2(e.vertex)));
    }
}

impl ConvexCell<3> for PolyhedronCell {
    fn from_box(b: &Aabb<3>) -> Self {
        // Planes 2k and 2k+1 bound axis k below and above.
        let mut planes = Vec::with_capacity(32);
        for k in 0..3 {
            let axis: [f64; 3] = std::array::from_fn(|j| if j == k { 1.0 } else { 0.0 });
            planes.push(Plane {
                normal: scale(axis, -1.0),
                offset: -b.lo[k],
                face: Face::Box,
            });
            planes.push(Plane {
                normal: axis,
                offset: b.hi[k],
                face: Face::Box,
            });
        }
        let mut triangles = Vec::with_capacity(64);
        let mut vertices = Vec::with_capacity(64);
        for corner in 0..8u16 {
            let bit = |k: u16| (corner >> k) & 1;
            let (x, y, z) = (bit(0), 2 + bit(1), 4 + bit(2));
            // det[n_x n_y n_z] > 0 means (x, y, z) turns counter-clockwise seen from outside.
            let positive = (bit(0) + bit(1) + bit(2)) % 2 == 1;
            triangles.push(if positive { [x, y, z] } else { [x, z, y] });
            vertices.push([
                if bit(0) == 1 { b.hi[0] } else { b.lo[0] },
                if bit(1) == 1 { b.hi[1] } else { b.lo[1] },
                if bit(2) == 1 { b.hi[2] } else { b.lo[2] },
            ]);
        }
        // Edge k of corner c runs along the axis of neither of its planes, that of the
        // third plane `tri[k + 2]`: its other end is the corner across that axis.
        let mut neighbors = Vec::with_capacity(64);
        neighbors.extend(
            triangles
                .iter()
                .enumerate()
                .map(|(c, tri): (usize, &[u16; 3])| {
                    std::array::from_fn(|k| (c ^ (1 << (tri[(k + 2) % 3] / 2))) as u32)
                }),
        );
        let max_dist2 = vertices.iter().map(|&v| norm2(v)).fold(0.0, f64::max);
        Self {
            planes,
            triangles,
            neighbors,
            vertices,
            max_dist2,
        }
    }

    /// Remove the vertices strictly beyond `h`; a vertex exactly on it stays, so a plane
    /// through a vertex leaves the cell as it was.
    ///
    /// Round-off can classify vertices that lie on the plane up to a few ulps
    /// inconsistently (lattices put many planes through one point), so that the removed
    /// region is not a disk. The clip is then retried with a tolerance that keeps such
    /// vertices: the result moves by at most that tolerance, far below the 1e-12 budget.
    fn clip(&mut self, h: &HalfSpace<3>, face: Face) -> bool {
        if self.triangles.is_empty() || self.planes.len() >= MAX_PLANES {
            return false;
        }
        if let Some(changed) = self.try_clip(h, face, 0.0) {
            return changed;
        }
        let scale_len = norm2(h.normal).sqrt() * self.max_dist2().sqrt() + h.offset.abs();
        for rel_tol in [1e-15, 1e-13, 1e-11] {
            if let Some(changed) = self.try_clip(h, face, rel_tol * scale_len) {
                return changed;
            }
        }
        false
    }

    fn is_empty(&self) -> bool {
        self.triangles.len() < 4
    }

    fn max_dist2(&self) -> f64 {
        self.max_dist2
    }

    fn bounds(&self) -> Aabb<3> {
        Aabb::of_points(&self.vertices)
    }

    fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    fn excludes(&self, points: &[[f64; 3]]) -> bool {
        self.planes
            .iter()
            .any(|h| points.iter().all(|&v| dot(h.normal, v) > h.offset))
    }

    fn vertex_mean(&self) -> [f64; 3] {
        let n = self.vertices.len().max(1) as f64;
        let s = self.vertices.iter().fold([0.0; 3], |a, &v| add(a, v));
        scale(s, 1.0 / n)
    }

    /// Fan every face from its first vertex and cone the fan to the site.
    fn moments(&self) -> Moments<3> {
        self.moments_and_faces(|_, _| {})
    }

    fn for_each_face(&self, mut f: impl FnMut(Face, f64)) {
        self.for_each_ring(|face, ring| f(face, self.fan(ring).1));
    }

    fn for_each_face_moments(&self, f: impl FnMut(Face, FaceMoments<3>)) {
        let _ = self.moments_and_face_moments(f);
    }

    fn moments_and_face_moments(&self, mut f: impl FnMut(Face, FaceMoments<3>)) -> Moments<3> {
        let mut m = Moments::zero();
        self.for_each_ring(|face, ring| {
            let (cone, moments) = self.fan_moments(ring);
            f(face, moments);
            m.add_scaled(&cone, 1.0);
        });
        m
    }

    fn moments_and_faces(&self, mut f: impl FnMut(Face, f64)) -> Moments<3> {
        let mut m = Moments::zero();
        self.for_each_ring(|face, ring| {
            let (cone, area) = self.fan(ring);
            f(face, area);
            m.add_scaled(&cone, 1.0);
        });
        m
    }
}

/// Put the rim edges `a -> b` in cycle order into `scratch.cycle`, from the first one
/// found, each starting where the previous ends; `false` unless they form one simple
/// cycle through every edge (each plane starting one edge at most). Linear: the edge
/// starting at each plane is looked up in `scratch.rim_from`, which it leaves cleared.
fn order_cycle(scratch: &mut Scratch, planes: usize) -> bool {
    let Scratch {
        rim,
        cycle,
        rim_from,
        ..
    } = scratch;
    cycle.clear();
    if rim_from.len() < planes {
        rim_from.resize(planes, NO_EDGE);
    }
    let mut simple = !rim.is_empty();
    for (i, e) in rim.iter().enumerate() {
        let from = &mut rim_from[e.a as usize];
        simple &= *from == NO_EDGE;
        *from = i as u32;
    }
    let mut at = 0;
    while simple {
        cycle.push(rim[at]);
        let next = rim_from[rim[at].b as usize];
        if next == NO_EDGE || cycle.len() > rim.len() {
            simple = false;
        } else if next == 0 {
            break;
        }
        at = next as usize;
    }
    for e in rim.iter() {
        rim_from[e.a as usize] = NO_EDGE;
    }
    simple && cycle.len() == rim.len()
}

#[inline]
fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

#[cfg(test)]
mod tests {
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
}
