//! The 2D convex cell: a counter-clockwise polygon whose edges remember their face.

use super::convex_cell::{any_by_fours, ConvexCell, Face};
use crate::geometry::{dot, norm2, sub, Aabb, HalfSpace};
use crate::moments::{triangle_moments, FaceMoments, Moments};

/// Convex polygon, counter-clockwise; edge `i` runs from vertex `i` to vertex `i + 1`.
#[derive(Debug, Default)]
pub struct PolygonCell {
    vertices: Vec<[f64; 2]>,
    faces: Vec<Face>,
    // Buffers reused by `clip`, so that clipping allocates only while a cell grows.
    spare_vertices: Vec<[f64; 2]>,
    spare_faces: Vec<Face>,
    // The half-spaces of a ring (`rebuild_from_ring`).
    planes: Vec<HalfSpace<2>>,
}

/// Vertices a new cell has room for: a Voronoi cell has about 6, and allocations were a
/// fifth of a 2D diagram's instructions while cells grew one vertex at a time.
const CAPACITY: usize = 16;

/// By hand: the derived `clone_from` would allocate anew, and the domain clipping clones
/// the cell into one reused piece per boundary element.
impl Clone for PolygonCell {
    fn clone(&self) -> Self {
        let mut c = Self::default();
        c.clone_from(self);
        c
    }

    fn clone_from(&mut self, source: &Self) {
        self.vertices.clone_from(&source.vertices);
        self.faces.clone_from(&source.faces);
    }
}

impl PolygonCell {
    /// Vertices, counter-clockwise, relative to the site.
    pub fn vertices(&self) -> &[[f64; 2]] {
        &self.vertices
    }

    /// `faces()[i]` made the edge from vertex `i` to vertex `i + 1`.
    pub fn faces(&self) -> &[Face] {
        &self.faces
    }

    /// Every vertex inside every half-space of `planes` (those of the faces, in order) but
    /// its own two by `separation`, and every edge counter-clockwise along its line.
    fn stands(&self, planes: &[HalfSpace<2>], separation: f64) -> bool {
        let m = planes.len();
        (0..m).all(|k| {
            let v = self.vertices[k];
            let w = self.vertices[if k + 1 == m { 0 } else { k + 1 }];
            let previous = if k == 0 { m - 1 } else { k - 1 };
            // The outward normal of edge v -> w along the face's own.
            let along = dot([w[1] - v[1], v[0] - w[0]], planes[k].normal) > 0.0;
            along
                && (planes.iter().enumerate()).all(|(l, h)| {
                    l == k
                        || l == previous
                        || dot(h.normal, v) - h.offset < -separation * norm2(h.normal)
                })
        })
    }
}

/// The point where the segment from `a` (signed distance `da`) to `b` (`db`) crosses the line.
#[inline]
fn crossing(a: [f64; 2], b: [f64; 2], da: f64, db: f64) -> [f64; 2] {
    let t = da / (da - db);
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
}

/// The point on the lines of `a` and `b` (Cramer's rule): the canonical vertex between
/// two faces, computed in the faces' order only ([`ConvexCell::canonicalise`]). Not finite
/// when the lines are parallel.
#[inline]
fn meet(a: &HalfSpace<2>, b: &HalfSpace<2>) -> [f64; 2] {
    let (p, q) = (a.normal, b.normal);
    let det = p[0] * q[1] - p[1] * q[0];
    [
        (a.offset * q[1] - b.offset * p[1]) / det,
        (p[0] * b.offset - q[0] * a.offset) / det,
    ]
}

/// The smallest angle between two adjacent faces of a canonical cell, as the sine: nearer
/// parallel, Cramer's rule in [`meet`] would move their vertex by more than 1e-10 of the
/// spacing (the clips interpolate along edges instead), and the cell has no canonical form.
const MIN_SINE: f64 = 1e-6;

/// The position of the face of least normal, x first ([`super::convex_cell::normal_order`] by plain
/// comparisons: the normals of a cell are finite).
fn least_normal(planes: &[HalfSpace<2>]) -> usize {
    let mut least = 0;
    for (k, h) in planes.iter().enumerate().skip(1) {
        let (a, b) = (h.normal, planes[least].normal);
        if a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]) {
            least = k;
        }
    }
    least
}

/// Vertex `k` of the faces of `planes` taken from position `first` on: [`meet`] of faces
/// `k − 1` and `k`, into `out`; `false` when two adjacent faces are too near parallel or
/// turn clockwise.
fn canonical_vertices(planes: &[HalfSpace<2>], first: usize, out: &mut Vec<[f64; 2]>) -> bool {
    out.clear();
    let n = planes.len();
    let mut before = &planes[(first + n - 1) % n];
    // Each face's `|normal|²` once, carried to the next vertex.
    let mut before_length = norm2(before.normal);
    let (tail, head) = planes.split_at(first);
    // A chain's `all` runs as two plain loops (rotating the planes cost more: callgrind).
    head.iter().chain(tail).all(|at| {
        let (p, q) = (before.normal, at.normal);
        let at_length = norm2(q);
        let det = p[0] * q[1] - p[1] * q[0];
        if det.is_nan()
            || det <= 0.0
            || det * det <= MIN_SINE * MIN_SINE * before_length * at_length
        {
            return false;
        }
        out.push(meet(before, at));
        (before, before_length) = (at, at_length);
        true
    })
}

/// The neighbour of a face, `None` for the others.
#[inline]
fn neighbour(face: Face) -> Option<u32> {
    match face {
        Face::Neighbor(j) => Some(j),
        _ => None,
    }
}

impl ConvexCell<2> for PolygonCell {
    fn from_box(b: &Aabb<2>) -> Self {
        let mut c = Self {
            vertices: Vec::with_capacity(CAPACITY),
            faces: Vec::with_capacity(CAPACITY),
            spare_vertices: Vec::with_capacity(CAPACITY),
            spare_faces: Vec::with_capacity(CAPACITY),
            planes: Vec::new(),
        };
        c.reset_to_box(b);
        c
    }

    fn reset_to_box(&mut self, b: &Aabb<2>) {
        let (lo, hi) = (b.lo, b.hi);
        self.vertices.clear();
        self.vertices
            .extend([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]]);
        self.faces.clear();
        self.faces.extend([Face::Box; 4]);
    }

    /// Sutherland–Hodgman against one half-plane. A vertex exactly on the line counts as
    /// inside, so a cell is never cut twice by the same line.
    fn clip(&mut self, h: &HalfSpace<2>, face: Face) -> bool {
        let n = self.vertices.len();
        let dist = |v: [f64; 2]| dot(h.normal, v) - h.offset;
        // Some vertex not inside (a NaN distance counts as outside).
        if n == 0
            || !any_by_fours(&self.vertices, |&v| {
                let d = dist(v);
                d > 0.0 || d.is_nan()
            })
        {
            return false;
        }
        let mut vertices = std::mem::take(&mut self.spare_vertices);
        let mut faces = std::mem::take(&mut self.spare_faces);
        vertices.clear();
        faces.clear();
        // A convex polygon cut by a line gains at most one vertex.
        vertices.reserve(n + 1);
        faces.reserve(n + 1);
        let next = self.vertices[1..].iter().chain(&self.vertices[..1]);
        let mut di = dist(self.vertices[0]);
        for ((&vi, &fi), &vj) in self.vertices.iter().zip(&self.faces).zip(next) {
            let dj = dist(vj);
            let inside_i = di <= 0.0;
            if inside_i {
                vertices.push(vi);
                faces.push(fi);
            }
            if inside_i && dj > 0.0 {
                // Leaving the half-plane: the next edge lies on the clipping line.
                if di < 0.0 {
                    vertices.push(crossing(vi, vj, di, dj));
                    faces.push(face);
                } else if let Some(last) = faces.last_mut() {
                    *last = face; // vi is on the line already
                }
            } else if !inside_i && dj < 0.0 {
                // Entering it: the edge continues the old one from the crossing point.
                vertices.push(crossing(vi, vj, di, dj));
                faces.push(fi);
            }
            di = dj;
        }
        if vertices.len() < 3 {
            vertices.clear();
            faces.clear();
        }
        self.spare_vertices = std::mem::replace(&mut self.vertices, vertices);
        self.spare_faces = std::mem::replace(&mut self.faces, faces);
        true
    }

    /// Vertex `k` joins the faces of edges `k − 1` and `k`: it is recomputed as [`meet`] of
    /// their half-spaces, in that order, after the edges are rotated to start at the face
    /// of least normal ([`super::convex_cell::normal_order`]).
    fn canonicalise(&mut self, plane: impl Fn(u32) -> HalfSpace<2>) -> bool {
        if self.faces.len() < 3 {
            return false;
        }
        let mut planes = std::mem::take(&mut self.planes);
        planes.clear();
        for &face in &self.faces {
            match neighbour(face) {
                Some(j) => planes.push(plane(j)),
                None => {
                    self.planes = planes;
                    return false;
                }
            }
        }
        let first = least_normal(&planes);
        let mut vertices = std::mem::take(&mut self.spare_vertices);
        let made = canonical_vertices(&planes, first, &mut vertices);
        if made {
            let (tail, head) = self.faces.split_at(first);
            self.spare_faces.clear();
            self.spare_faces.extend(head.iter().chain(tail));
            std::mem::swap(&mut self.faces, &mut self.spare_faces);
            vertices = std::mem::replace(&mut self.vertices, vertices);
        }
        self.spare_vertices = vertices;
        self.planes = planes;
        made
    }

    /// The vertices as [`PolygonCell::canonicalise`] makes them; the cell stands when every
    /// vertex lies inside every other face's half-space by `separation` and every edge
    /// runs counter-clockwise along its line: the polygon is then the intersection of the
    /// half-spaces, with one edge on each (a ring in another order, or with a face that
    /// no longer bounds the cell, puts some vertex outside some half-space).
    fn rebuild_from_ring(
        &mut self,
        ring: &[u32],
        _: &[[u8; 3]],
        plane: impl Fn(u32) -> HalfSpace<2>,
        separation: f64,
    ) -> bool {
        if ring.len() < 3 {
            return false;
        }
        let mut planes = std::mem::take(&mut self.planes);
        planes.clear();
        planes.extend(ring.iter().map(|&j| plane(j)));
        let first = least_normal(&planes);
        planes.rotate_left(first);
        self.faces.clear();
        let rotated = ring[first..].iter().chain(&ring[..first]);
        self.faces.extend(rotated.map(|&j| Face::Neighbor(j)));
        let mut vertices = std::mem::take(&mut self.vertices);
        let made = canonical_vertices(&planes, 0, &mut vertices);
        self.vertices = vertices;
        let stands = made && self.stands(&planes, separation);
        self.planes = planes;
        stands
    }

    fn ring(&self, neighbours: &mut Vec<u32>, _: &mut Vec<[u8; 3]>) {
        neighbours.extend(self.faces.iter().filter_map(|&f| neighbour(f)));
    }

    fn for_each_plane(&self, mut f: impl FnMut(Face, &HalfSpace<2>)) {
        let n = self.vertices.len();
        for i in 0..n {
            let (a, b) = (self.vertices[i], self.vertices[(i + 1) % n]);
            // Counter-clockwise: the outward normal is the edge turned clockwise.
            let normal = [b[1] - a[1], a[0] - b[0]];
            f(self.faces[i], &HalfSpace::through(a, normal));
        }
    }

    fn is_empty(&self) -> bool {
        self.vertices.len() < 3
    }

    fn max_dist2(&self) -> f64 {
        // `f64::max` as a plain comparison (which passes over a NaN alike).
        (self.vertices.iter()).fold(0.0, |m, &v| if norm2(v) > m { norm2(v) } else { m })
    }

    fn bounds(&self) -> Aabb<2> {
        Aabb::of_points(&self.vertices)
    }

    fn vertices(&self) -> &[[f64; 2]] {
        &self.vertices
    }

    /// Tested against the lines through consecutive vertices (counter-clockwise, so the
    /// outside of edge `a -> b` is on its right).
    fn excludes(&self, points: &[[f64; 2]]) -> bool {
        // The edges' normals come from their vertices, and a clip that passes within
        // round-off of a vertex leaves an edge of length 1e-17 whose normal points anywhere:
        // it excluded a segment with an end inside the cell (a cell counted 0 instead of
        // 0.09). Such edges say nothing and are skipped; excluding less is always safe.
        let min_len2 = 1e-8 * self.max_dist2(); // edges shorter than 1e-4 of the radius
        let n = self.vertices.len();
        (0..n).any(|i| {
            let a = self.vertices[i];
            let b = self.vertices[if i + 1 == n { 0 } else { i + 1 }];
            let normal = [b[1] - a[1], a[0] - b[0]];
            norm2(normal) > min_len2 && points.iter().all(|&p| dot(normal, sub(p, a)) > 0.0)
        })
    }

    /// The segment clipped to the cell by each edge's half-plane (Cyrus and Beck), widened
    /// by a margin of `1e-9` of the cell's radius against round-off: the farther end of
    /// what is left. A boundary segment several spacings long that merely grazes a cell
    /// near the boundary then bounds the cell's part in the domain by about the cell's
    /// size, not by the segment's far end.
    fn farthest_on(&self, simplex: &[[f64; 2]; 2]) -> Option<f64> {
        let [a, b] = *simplex;
        let ab = sub(b, a);
        let margin = 1e-9 * self.max_dist2().sqrt();
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let n = self.vertices.len();
        for i in 0..n {
            let v = self.vertices[i];
            let w = self.vertices[if i + 1 == n { 0 } else { i + 1 }];
            // Outward normal of a counter-clockwise edge; inside is n·(x − v) ≤ 0.
            let normal = [w[1] - v[1], v[0] - w[0]];
            let length = norm2(normal).sqrt();
            if length == 0.0 {
                continue;
            }
            let start = dot(normal, sub(a, v)) - margin * length;
            let rate = dot(normal, ab);
            if rate == 0.0 {
                if start > 0.0 {
                    return None;
                }
            } else if rate > 0.0 {
                hi = hi.min(-start / rate);
            } else {
                lo = lo.max(-start / rate);
            }
            if lo > hi {
                return None;
            }
        }
        let at = |t: f64| norm2([a[0] + t * ab[0], a[1] + t * ab[1]]);
        Some(at(lo).max(at(hi)) * (1.0 + 1e-9) + margin * margin)
    }

    fn vertex_mean(&self) -> [f64; 2] {
        let n = self.vertices.len().max(1) as f64;
        let s = self
            .vertices
            .iter()
            .fold([0.0, 0.0], |a, v| [a[0] + v[0], a[1] + v[1]]);
        [s[0] / n, s[1] / n]
    }

    fn moments(&self) -> Moments<2> {
        let mut m = Moments::zero();
        let n = self.vertices.len();
        for i in 0..n {
            let j = if i + 1 == n { 0 } else { i + 1 };
            m.add_scaled(&triangle_moments(self.vertices[i], self.vertices[j]), 1.0);
        }
        m
    }

    fn for_each_cone(&self, mut f: impl FnMut(&[[f64; 2]; 2], f64)) {
        let n = self.vertices.len();
        for i in 0..n {
            let j = if i + 1 == n { 0 } else { i + 1 };
            let (a, b) = (self.vertices[i], self.vertices[j]);
            f(&[a, b], 0.5 * (a[0] * b[1] - a[1] * b[0]));
        }
    }

    fn for_each_face_simplex(&self, mut f: impl FnMut(Face, &[[f64; 2]; 2], f64)) {
        let n = self.vertices.len();
        for i in 0..n {
            let j = if i + 1 == n { 0 } else { i + 1 };
            let (a, b) = (self.vertices[i], self.vertices[j]);
            f(self.faces[i], &[a, b], norm2(sub(b, a)).sqrt());
        }
    }

    fn for_each_face(&self, mut f: impl FnMut(Face, f64)) {
        let n = self.vertices.len();
        for i in 0..n {
            let j = if i + 1 == n { 0 } else { i + 1 };
            f(
                self.faces[i],
                norm2(sub(self.vertices[j], self.vertices[i])).sqrt(),
            );
        }
    }

    fn for_each_face_moments(&self, f: impl FnMut(Face, FaceMoments<2>)) {
        let _ = self.moments_and_face_moments(f);
    }

    fn moments_and_face_moments(&self, mut f: impl FnMut(Face, FaceMoments<2>)) -> Moments<2> {
        let mut m = Moments::zero();
        let n = self.vertices.len();
        for i in 0..n {
            let j = if i + 1 == n { 0 } else { i + 1 };
            let (a, b) = (self.vertices[i], self.vertices[j]);
            f(
                self.faces[i],
                FaceMoments::simplex(&[a, b], norm2(sub(b, a)).sqrt()),
            );
            m.add_scaled(&triangle_moments(a, b), 1.0);
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_on_bounds_the_part_of_a_segment_inside_the_cell() {
        let mut cell = PolygonCell::from_box(&Aabb {
            lo: [-1.0, -1.0],
            hi: [1.0, 1.0],
        });
        cell.clip(
            &HalfSpace {
                normal: [1.0, 1.0],
                offset: 1.0,
            },
            Face::Neighbor(3),
        );
        let inside = |p: [f64; 2]| p[0].abs() <= 1.0 && p[1].abs() <= 1.0 && p[0] + p[1] <= 1.0;
        let segments = [
            [[-5.0, 0.5], [5.0, 0.5]],   // crosses: inside from x = -1 to 0.5
            [[-5.0, -0.9], [0.0, -0.9]], // ends inside
            [[2.0, 2.0], [5.0, 0.0]],    // misses
            [[0.0, 0.0], [0.2, 0.1]],    // inside
        ];
        for seg in segments {
            // The farthest of many points of the segment inside the cell.
            let sampled = (0..=10_000)
                .map(|k| {
                    let t = k as f64 / 10_000.0;
                    let p = [
                        seg[0][0] + t * (seg[1][0] - seg[0][0]),
                        seg[0][1] + t * (seg[1][1] - seg[0][1]),
                    ];
                    inside(p).then(|| norm2(p))
                })
                .fold(None, |m: Option<f64>, d| match (m, d) {
                    (Some(a), Some(b)) => Some(a.max(b)),
                    (a, b) => a.or(b),
                });
            match (cell.farthest_on(&seg), sampled) {
                (None, None) => {}
                (Some(bound), Some(d2)) => {
                    assert!(
                        bound >= d2 && bound <= d2 + 1e-3,
                        "{seg:?}: {bound} vs {d2}"
                    )
                }
                (bound, d2) => panic!("{seg:?}: {bound:?} vs {d2:?}"),
            }
        }
    }

    /// The cell of site 0 among `sites`, clipped by their bisectors in the order given.
    fn clipped(sites: &[[f64; 2]], order: &[usize]) -> PolygonCell {
        let mut c = PolygonCell::from_box(&Aabb {
            lo: [-10.0, -10.0],
            hi: [10.0, 10.0],
        });
        for &j in order {
            c.clip(
                &HalfSpace::bisector(sub(sites[j], sites[0])),
                Face::Neighbor(j as u32),
            );
        }
        c
    }

    fn bits(c: &PolygonCell) -> Vec<[u64; 2]> {
        c.vertices().iter().map(|v| v.map(f64::to_bits)).collect()
    }

    /// Clipped in two orders the cells differ in their last bits; canonical, they are
    /// equal, and the ring rebuilds them bit for bit. A ring out of order, or with a site
    /// that does not bound the cell, is refused.
    #[test]
    fn a_canonical_cell_is_the_same_in_any_order_and_rebuilt_from_its_ring() {
        let mut rng = crate::sample::Lcg::new(7);
        let mut differed = 0;
        for _ in 0..200 {
            let sites: Vec<[f64; 2]> = (0..12).map(|_| [rng.unit(), rng.unit()]).collect();
            let plane = |j: u32| HalfSpace::bisector(sub(sites[j as usize], sites[0]));
            let forward: Vec<usize> = (1..12).collect();
            let backward: Vec<usize> = (1..12).rev().collect();
            let (mut a, mut b) = (clipped(&sites, &forward), clipped(&sites, &backward));
            if a.faces().contains(&Face::Box) {
                continue; // the box bounds it: no canonical form
            }
            differed += usize::from(bits(&a) != bits(&b));
            assert!(a.canonicalise(plane) && b.canonicalise(plane));
            assert_eq!(bits(&a), bits(&b));
            assert_eq!(a.faces(), b.faces());
            let mut ring = Vec::new();
            a.ring(&mut ring, &mut Vec::new());
            let planes: Vec<HalfSpace<2>> = ring.iter().map(|&j| plane(j)).collect();
            assert_eq!(least_normal(&planes), 0, "starts at the least normal");
            let mut rebuilt = PolygonCell::default();
            assert!(rebuilt.rebuild_from_ring(&ring, &[], plane, 1e-9));
            assert_eq!(bits(&rebuilt), bits(&a));
            assert_eq!(rebuilt.faces(), a.faces());
            assert_eq!(rebuilt.moments(), a.moments());
            // Two faces swapped.
            let mut swapped = ring.clone();
            swapped.swap(1, 2);
            assert!(
                !rebuilt.rebuild_from_ring(&swapped, &[], plane, 1e-9),
                "{swapped:?}"
            );
            // A site that does not bound the cell, put in the ring.
            if let Some(extra) = (1..12u32).find(|j| !ring.contains(j)) {
                let mut more = ring.clone();
                more.insert(1, extra);
                assert!(
                    !rebuilt.rebuild_from_ring(&more, &[], plane, 1e-9),
                    "{more:?}"
                );
            }
            // (A face left out makes a larger cell of the other half-spaces: the ring
            // alone cannot tell; its site, on the cell's list, does (`ring_cell`).)
        }
        assert!(
            differed > 20,
            "the orders differed in {differed} cells only"
        );
    }

    #[test]
    fn clipping_a_square_by_a_diagonal_keeps_a_triangle() {
        let mut c = PolygonCell::from_box(&Aabb {
            lo: [-1.0, -1.0],
            hi: [1.0, 1.0],
        });
        let _ = c.clip(
            &HalfSpace {
                normal: [1.0, 1.0],
                offset: 0.0,
            },
            Face::Neighbor(7),
        );
        assert_eq!(c.vertices().len(), 3);
        assert_eq!(c.moments().mass, 2.0);
        let mut diagonal = 0.0;
        c.for_each_face(|f, len| {
            if f == Face::Neighbor(7) {
                diagonal += len;
            }
        });
        assert!((diagonal - 8f64.sqrt()).abs() < 1e-15);
        let _ = c.clip(
            &HalfSpace {
                normal: [-1.0, -1.0],
                offset: -0.5,
            },
            Face::Neighbor(8),
        );
        assert!(c.is_empty());
    }
}
