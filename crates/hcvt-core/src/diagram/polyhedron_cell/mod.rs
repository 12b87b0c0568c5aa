//! The 3D convex cell in the dual representation of Ray et al. 2018 ("Meshless Voronoi on
//! the GPU") and geogram's `ConvexCell`: the cell is a list of planes, and each vertex is a
//! triangle of three plane indices. Clipping removes the triangles whose vertex lies
//! beyond the new plane and cones the boundary edges of the removed region to it.
//!
//! Why this representation: the topology is combinatorial (triangles of plane indices),
//! so faces can never disagree about a shared vertex; each vertex is computed once, when
//! its triangle is created, so every face that uses it sees the same bits.
//!
//! `mod.rs` holds the representation, its clipping and [`ConvexCell`]; `faces.rs` walks the
//! faces (their polygons and moments); `canonical.rs` gives a cell its canonical form and
//! rebuilds one from its planes and triangles (warm diagrams); `tests.rs` checks them
//! against closed forms.

mod canonical;
mod faces;
#[cfg(test)]
mod tests;

use super::convex_cell::{any_by_fours, ConvexCell, Face};
use super::scratch::with_scratch;
use crate::geometry::{add, cross, dot, norm2, scale, sub, Aabb, HalfSpace};
use crate::moments::{FaceMoments, Moments};

/// A plane of the cell, `normal · x <= offset`, and what made it. Vertices are computed
/// when their triangle is made, along the old edge; a cell bounded by its neighbours alone
/// then has them recomputed from its planes in its canonical form (`canonical.rs`).
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
    /// The canonical form's buffers (`canonical.rs`), made on first use, not cloned.
    buffers: Option<Box<canonical::Buffers>>,
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

impl Default for Scratch {
    fn default() -> Self {
        Self::new()
    }
}

// This thread's buffers, reused from clip to clip ([`with_scratch`]).
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
            buffers: None,
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

/// Planes a cell may have: plane indices are `u16`.
const MAX_PLANES: usize = u16::MAX as usize;

impl PolyhedronCell {
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
        // Most clips of a Voronoi cell change nothing: decide that in one pass that stops
        // at the first vertex beyond (a NaN distance removes nothing).
        if !any_by_fours(&self.vertices, |v| dot(h.normal, *v) - h.offset > tol) {
            return Some(false);
        }
        with_scratch(&SCRATCH, |scratch| self.cut(h, face, tol, scratch))
    }

    /// The part of [`PolyhedronCell::try_clip`] that changes the cell.
    fn cut(
        &mut self,
        h: &HalfSpace<3>,
        face: Face,
        tol: f64,
        scratch: &mut Scratch,
    ) -> Option<bool> {
        scratch.tol = tol;
        // The distances in one pass without branches, then which side each vertex is on.
        scratch.dist.clear();
        (scratch.dist).extend(self.vertices.iter().map(|v| dot(h.normal, *v) - h.offset));
        scratch.free.clear();
        let mut kept_dist2: f64 = 0.0;
        for (t, (&d, v)) in scratch.dist.iter().zip(&self.vertices).enumerate() {
            if d > tol {
                scratch.free.push(t);
                continue;
            }
            let n2 = norm2(*v);
            if n2 > kept_dist2 {
                // `f64::max` as a plain comparison (which passes over a NaN alike): one
                // instruction on the loop's chain instead of five.
                kept_dist2 = n2;
            }
        }
        scratch.kept_dist2 = kept_dist2;
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
        let mut max_dist2 = scratch.kept_dist2;
        for (k, e) in scratch.cycle.iter().enumerate() {
            let n2 = norm2(e.vertex);
            if n2 > max_dist2 {
                max_dist2 = n2;
            }
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
        self.max_dist2 = max_dist2;
    }
}

impl ConvexCell<3> for PolyhedronCell {
    fn from_box(b: &Aabb<3>) -> Self {
        let mut cell = Self {
            planes: Vec::with_capacity(32),
            triangles: Vec::with_capacity(64),
            neighbors: Vec::with_capacity(64),
            vertices: Vec::with_capacity(64),
            max_dist2: 0.0,
            buffers: None,
        };
        cell.reset_to_box(b);
        cell
    }

    /// Every cell of a diagram starts as a box: refilled in place, its arrays keep the
    /// room they grew to in earlier cells instead of being allocated anew.
    fn reset_to_box(&mut self, b: &Aabb<3>) {
        let Self {
            planes,
            triangles,
            neighbors,
            vertices,
            max_dist2,
            ..
        } = self;
        planes.clear();
        triangles.clear();
        neighbors.clear();
        vertices.clear();
        // Planes 2k and 2k+1 bound axis k below and above.
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
        neighbors.extend(
            triangles
                .iter()
                .enumerate()
                .map(|(c, tri): (usize, &[u16; 3])| {
                    std::array::from_fn(|k| (c ^ (1 << (tri[(k + 2) % 3] / 2))) as u32)
                }),
        );
        *max_dist2 = vertices.iter().map(|&v| norm2(v)).fold(0.0, f64::max);
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

    /// The planes are those the cell holds, as clipped by: `plane` is not needed.
    fn canonicalise(&mut self, _: impl Fn(u32) -> HalfSpace<3>) -> bool {
        self.canonicalise_cell()
    }

    fn rebuild_from_ring(
        &mut self,
        ring: &[u32],
        triangles: &[[u8; 3]],
        plane: impl Fn(u32) -> HalfSpace<3>,
        separation: f64,
    ) -> bool {
        self.rebuild(ring, triangles, plane, separation)
    }

    fn ring(&self, neighbours: &mut Vec<u32>, triangles: &mut Vec<[u8; 3]>) {
        self.canonical_ring(neighbours, triangles);
    }

    fn for_each_plane(&self, mut f: impl FnMut(Face, &HalfSpace<3>)) {
        for p in &self.planes {
            let h = HalfSpace {
                normal: p.normal,
                offset: p.offset,
            };
            f(p.face, &h);
        }
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

    /// The tetrahedra of the moments (`fan`): every face fanned from its first vertex.
    fn for_each_cone(&self, mut f: impl FnMut(&[[f64; 3]; 3], f64)) {
        self.for_each_ring(|_, ring| {
            let v = |k: usize| self.vertices[ring[k] as usize];
            let v0 = v(0);
            for k in 2..ring.len() {
                let (a, b) = (v(k - 1), v(k));
                let det = dot(v0, cross(sub(a, v0), sub(b, v0)));
                f(&[v0, a, b], det / 6.0);
            }
        });
    }

    fn for_each_face_simplex(&self, mut f: impl FnMut(Face, &[[f64; 3]; 3], f64)) {
        self.for_each_ring(|face, ring| {
            let v = |k: usize| self.vertices[ring[k] as usize];
            let v0 = v(0);
            for k in 2..ring.len() {
                let (a, b) = (v(k - 1), v(k));
                f(
                    face,
                    &[v0, a, b],
                    0.5 * norm2(cross(sub(a, v0), sub(b, v0))).sqrt(),
                );
            }
        });
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
