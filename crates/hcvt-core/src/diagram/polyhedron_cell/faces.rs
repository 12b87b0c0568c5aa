//! The faces of a [`PolyhedronCell`]: walked as rings of vertices around each plane (O(1)
//! per step through the triangles' adjacency), and integrated as fans of triangles for the
//! cell's moments, the face measures and the face moments (DESIGN §3).

use super::PolyhedronCell;
use crate::diagram::convex_cell::Face;
use crate::diagram::scratch::with_scratch;
use crate::geometry::{add, cross, dot, norm2, scale, sub};
use crate::moments::{FaceMoments, Moments};

/// Scratch of [`PolyhedronCell::for_each_ring`].
#[derive(Default)]
struct WalkBuffers {
    first: Vec<u32>,
    ring: Vec<u32>,
}

thread_local! {
    static WALK_BUFFERS: std::cell::RefCell<WalkBuffers> = std::cell::RefCell::default();
}

/// A triangle of a face's fan: its vertices `(v_0, a, b)` relative to the site, `L`, and
/// their squared lengths, `L²`.
struct FanTriangle {
    vertices: [[f64; 3]; 3],
    norms2: [f64; 3],
}

/// Adds to `m` the cone from the site over the fan triangle `t`, `c` its doubled vector
/// area ([`PolyhedronCell::fan`]).
#[inline]
fn add_cone(m: &mut Moments<3>, t: &FanTriangle, c: [f64; 3]) {
    let [v0, a, b] = t.vertices;
    let [n0, na, nb] = t.norms2;
    let mass = dot(v0, c) / 6.0;
    let s = add(add(v0, a), b);
    m.mass += mass;
    m.first = add(m.first, scale(s, mass / 4.0));
    m.second += mass * (norm2(s) + n0 + na + nb) / 20.0;
}

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

    /// The planes meeting at vertex `t` (counter-clockwise seen from outside), for the
    /// combinatorial vertex keys of the conforming mesh (`diagram::mesh`).
    pub(crate) fn vertex_planes(&self, t: u32) -> [u16; 3] {
        self.triangles[t as usize]
    }

    /// What made plane `p`, and its half-space `normal · x <= offset` (relative to the site).
    pub(crate) fn plane(&self, p: u16) -> (Face, crate::geometry::HalfSpace<3>) {
        let plane = &self.planes[p as usize];
        let h = crate::geometry::HalfSpace {
            normal: plane.normal,
            offset: plane.offset,
        };
        (plane.face, h)
    }

    /// Every face as its plane and its ring of vertices (triangle indices, counter-clockwise
    /// seen from outside), appended to `out` as `(plane, ring start, ring end)` into `rings`.
    pub(crate) fn face_rings(&self, out: &mut Vec<(u16, u32, u32)>, rings: &mut Vec<u32>) {
        let (mut first, mut ring) = (Vec::new(), Vec::new());
        self.walk_faces(&mut first, &mut ring, |plane, ring| {
            let start = rings.len() as u32;
            rings.extend_from_slice(ring);
            out.push((plane, start, rings.len() as u32));
        });
    }

    /// [`PolyhedronCell::walk_faces`] with per-thread buffers: every cell of every diagram
    /// is walked. A nested walk (from inside `f`) finds them taken and uses fresh ones.
    pub(super) fn for_each_ring(&self, mut f: impl FnMut(Face, &[u32])) {
        with_scratch(&WALK_BUFFERS, |b| {
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
    pub(super) fn fan(&self, ring: &[u32]) -> (Moments<3>, f64) {
        let mut m = Moments::zero();
        let mut area = [0.0; 3];
        self.for_each_fan_triangle(ring, |triangle, c| {
            area = add(area, c);
            add_cone(&mut m, triangle, c);
        });
        (m, 0.5 * norm2(area).sqrt())
    }

    /// [`PolyhedronCell::fan`]'s cone moments with the face's own moments about the site
    /// (for the Hessian), summed over the same fan triangles in one pass: each triangle's
    /// cross product serves both. Two passes computed it twice: a Newton run of ball 1k
    /// (seed 0, one thread, callgrind) took 9,662M instructions then, 9,529M now, for the
    /// same bits.
    pub(super) fn fan_moments(&self, ring: &[u32]) -> (Moments<3>, FaceMoments<3>) {
        let mut m = Moments::zero();
        let mut face = FaceMoments::zero();
        self.for_each_fan_triangle(ring, |triangle, c| {
            add_cone(&mut m, triangle, c);
            let area = 0.5 * norm2(c).sqrt();
            face.add_scaled(&FaceMoments::simplex(&triangle.vertices, area), 1.0);
        });
        (m, face)
    }

    /// `f(triangle, c)` for each triangle `(v_0, v_{k-1}, v_k)` of the fan of `ring` from
    /// its first vertex, `c = (v_{k-1} − v_0) × (v_k − v_0)`.
    #[inline]
    fn for_each_fan_triangle(&self, ring: &[u32], mut f: impl FnMut(&FanTriangle, [f64; 3])) {
        let v = |k: usize| self.vertices[ring[k] as usize];
        let v0 = v(0);
        let n0 = norm2(v0);
        let (mut a, mut na) = (v(1), norm2(v(1)));
        for k in 2..ring.len() {
            let b = v(k);
            let nb = norm2(b);
            let c = cross(sub(a, v0), sub(b, v0));
            let triangle = FanTriangle {
                vertices: [v0, a, b],
                norms2: [n0, na, nb],
            };
            f(&triangle, c);
            (a, na) = (b, nb);
        }
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
    pub(super) fn walk_faces(
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
}
