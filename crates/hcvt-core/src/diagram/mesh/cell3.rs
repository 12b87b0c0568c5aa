//! The faces of one 3D clipped cell `C ∩ Ω` (DESIGN §9): (a) each boundary triangle `T`
//! near the cell clipped by the convex cell `C`, and (b) each bisector face `F` of `C`
//! restricted to `Ω` in its plane, where `Ω`'s slice is bounded by the segments where the
//! nearby triangles cross that plane.

use super::key::{Gen, Key};
use super::planar::{bridge_holes, clip_ring, Node, PlanarScratch, Segment};
use super::{bisector_side, gen_of, CellFaces, CellGeometry, Side};
use crate::diagram::clip::boundary_candidates;
use crate::diagram::convex_cell::{ConvexCell, Face};
use crate::diagram::polygon_clip::clip_polygon;
use crate::diagram::polyhedron_cell::PolyhedronCell;
use crate::domain::{Solid, WindingNumber};
use crate::geometry::{add, cross, dot, sub, Euclid, Space};

/// The sites and, for a power diagram, their weights.
type Generators<'a> = (&'a [[f64; 3]], Option<&'a [f64]>);

/// Buffers of one thread's 3D cells.
#[derive(Debug, Default)]
pub(crate) struct Scratch3 {
    faces: Vec<(u16, u32, u32)>,
    rings: Vec<u32>,
    keys: Vec<Key>,
    /// Per vertex of the cell: unknown (-1), outside (0) or inside (1) the domain.
    status: Vec<i8>,
    candidates: Vec<u32>,
    ring: Vec<Node<3>>,
    edge_gens: Vec<Gen>,
    segments: Vec<Segment<3>>,
    planar: PlanarScratch<3>,
    loops: Vec<(Node<3>, super::planar::EdgeOf)>,
    ends: Vec<usize>,
    polygon: Vec<BoundaryNode>,
    clipped: Vec<BoundaryNode>,
    sides: Vec<(f64, bool)>,
}

/// A vertex of a boundary triangle being clipped: position relative to the site, name,
/// the mesh vertex it is (if any), and what the edge leaving it lies on.
#[derive(Debug, Clone, Copy)]
struct BoundaryNode {
    x: [f64; 3],
    key: Key,
    vertex: Option<u32>,
    out: Gen,
}

/// The projection to two coordinates that keeps counter-clockwise seen from `+normal`
/// counter-clockwise: drop the normal's largest component.
fn projector(normal: [f64; 3]) -> impl Fn([f64; 3]) -> [f64; 2] {
    let a = (0..3)
        .max_by(|&p, &q| normal[p].abs().total_cmp(&normal[q].abs()))
        .unwrap_or(2);
    let (mut u, mut v) = ((a + 1) % 3, (a + 2) % 3);
    if normal[a] < 0.0 {
        std::mem::swap(&mut u, &mut v);
    }
    move |x: [f64; 3]| [x[u], x[v]]
}

impl CellGeometry<3> for PolyhedronCell {
    type Scratch = Scratch3;

    fn clipped_faces(
        &self,
        boundary: &Solid,
        sites: &[[f64; 3]],
        weights: Option<&[f64]>,
        i: usize,
        winding: Option<i32>,
        out: &mut CellFaces<3>,
        s: &mut Scratch3,
    ) {
        let site = sites[i];
        let ci = i as u32;
        let vertices = self.vertices();
        s.faces.clear();
        s.rings.clear();
        self.face_rings(&mut s.faces, &mut s.rings);
        s.keys.clear();
        s.keys.extend((0..vertices.len() as u32).map(|t| {
            let gens = self.vertex_planes(t).map(|p| gen_of(self.plane(p).0, p));
            Key::meet(ci, &gens)
        }));
        s.candidates.clear();
        if !self.is_empty() {
            boundary_candidates(boundary, self, site, &mut s.candidates);
        }
        if s.candidates.is_empty() {
            if winding == Some(1) {
                // Inside the domain: the convex cell is the clipped cell.
                for &(p, a, b) in &s.faces {
                    if let Face::Neighbor(j) = self.plane(p).0 {
                        let ring = &s.rings[a as usize..b as usize];
                        out.push_face(
                            Side::Neighbor(j),
                            ring.iter()
                                .map(|&t| (s.keys[t as usize], add(site, vertices[t as usize]))),
                        );
                    }
                }
            }
            return;
        }
        s.status.clear();
        s.status.resize(vertices.len(), -1);
        for f in 0..s.faces.len() {
            let (p, a, b) = s.faces[f];
            if let (Face::Neighbor(j), h) = self.plane(p) {
                self.bisector_face(
                    boundary,
                    (sites, weights),
                    i,
                    j,
                    h.normal,
                    (p, a, b),
                    out,
                    s,
                );
            }
        }
        for k in 0..s.candidates.len() {
            let t = s.candidates[k];
            self.boundary_piece(boundary, (sites, weights), i, t, out, s);
        }
    }
}

impl PolyhedronCell {
    /// (b): the face of `C` on plane `p` (the bisector with site `j`, outward `normal`),
    /// with ring `rings[a..b]`, restricted to the domain.
    #[allow(clippy::too_many_arguments)]
    fn bisector_face(
        &self,
        boundary: &Solid,
        (sites, weights): Generators<'_>,
        i: usize,
        j: u32,
        normal: [f64; 3],
        (p, a, b): (u16, u32, u32),
        out: &mut CellFaces<3>,
        s: &mut Scratch3,
    ) {
        let site = sites[i];
        let ci = i as u32;
        let vertices = self.vertices();
        let proj = projector(normal);
        let ring = &s.rings[a as usize..b as usize];
        s.ring.clear();
        s.ring.extend(ring.iter().map(|&t| Node {
            p: proj(vertices[t as usize]),
            x: vertices[t as usize],
            key: s.keys[t as usize],
        }));
        // Edge k lies on the other plane that its two vertices share.
        s.edge_gens.clear();
        for k in 0..ring.len() {
            let (u, w) = (
                self.vertex_planes(ring[k]),
                self.vertex_planes(ring[(k + 1) % ring.len()]),
            );
            let q = u
                .iter()
                .copied()
                .find(|&q| q != p && w.contains(&q))
                .unwrap_or(p);
            s.edge_gens.push(gen_of(self.plane(q).0, q));
        }
        s.segments.clear();
        for &t in &s.candidates {
            if let Some(seg) = slice(boundary, (sites, weights), i, j, t, normal, &proj) {
                s.segments.push(seg);
            }
        }
        let (status, rings_ref) = (&mut s.status, ring);
        let inside = || {
            for &t in rings_ref {
                let known = &mut status[t as usize];
                if *known < 0 {
                    let w = Euclid::winding_number(boundary, &add(site, vertices[t as usize]));
                    *known = match w {
                        Some(0) => 0,
                        Some(_) => 1,
                        None => continue,
                    };
                }
                return *known == 1;
            }
            false
        };
        let (edge_gens, segments) = (&s.edge_gens, &s.segments);
        let cross_key = |k: usize, seg: usize| {
            Key::meet(
                ci,
                &[Gen::Site(j), edge_gens[k], Gen::Elem(segments[seg].elem)],
            )
        };
        s.loops.clear();
        s.ends.clear();
        out.open += clip_ring(
            &s.ring,
            segments,
            cross_key,
            inside,
            &mut s.planar,
            &mut s.loops,
            &mut s.ends,
        );
        bridge_holes(&mut s.loops, &mut s.ends);
        let mut begin = 0;
        for &end in &s.ends {
            out.push_face(
                Side::Neighbor(j),
                s.loops[begin..end]
                    .iter()
                    .map(|(n, _)| (n.key, add(site, n.x))),
            );
            begin = end;
        }
    }

    /// (a): boundary triangle `t` clipped by the planes of the cell's faces.
    fn boundary_piece(
        &self,
        boundary: &Solid,
        (sites, weights): Generators<'_>,
        i: usize,
        t: u32,
        out: &mut CellFaces<3>,
        s: &mut Scratch3,
    ) {
        let site = sites[i];
        let ci = i as u32;
        let tri = boundary.simplices()[t as usize];
        let rel = boundary.simplex(t).map(|v| sub(v, site));
        if self.excludes(&rel) {
            return;
        }
        s.polygon.clear();
        for k in 0..3 {
            s.polygon.push(BoundaryNode {
                x: rel[k],
                key: Key::vertex(tri[k]),
                vertex: Some(tri[k]),
                out: Gen::MeshEdge(tri[k], tri[(k + 1) % 3]),
            });
        }
        for f in 0..s.faces.len() {
            let p = s.faces[f].0;
            let (face, h) = self.plane(p);
            let gen = gen_of(face, p);
            // The side of a node: a mesh vertex against a bisector by the rule both cells
            // share, anything else against the cell's own plane.
            let side = |n: &BoundaryNode| match (n.vertex, face) {
                (Some(v), Face::Neighbor(j)) => bisector_side(
                    sites,
                    weights,
                    i,
                    j as usize,
                    boundary.vertices()[v as usize],
                ),
                _ => (dot(h.normal, n.x) - h.offset, false),
            };
            s.sides.clear();
            s.sides.extend(s.polygon.iter().map(side));
            let sides = &s.sides;
            if sides.iter().all(|&(d, _)| d <= 0.0) {
                continue;
            }
            clip_polygon(
                &s.polygon,
                sides,
                &mut s.clipped,
                |&u, &w, (su, zu), (sw, zw)| {
                    // A mesh vertex on the bisector is where the cut passes.
                    let mut node = if zu {
                        u
                    } else if zw {
                        w
                    } else {
                        let x = match (u.vertex, w.vertex, face) {
                            (Some(a), Some(b), Face::Neighbor(j)) => {
                                edge_crossing(boundary, (sites, weights), i, j, a, b)
                            }
                            _ => {
                                let r = su / (su - sw);
                                std::array::from_fn(|c| u.x[c] + r * (w.x[c] - u.x[c]))
                            }
                        };
                        BoundaryNode {
                            x,
                            key: Key::meet(ci, &[u.out, gen, Gen::Elem(t)]),
                            vertex: None,
                            out: u.out,
                        }
                    };
                    node.out = if su <= 0.0 { gen } else { u.out };
                    node
                },
            );
            std::mem::swap(&mut s.polygon, &mut s.clipped);
            if s.polygon.len() < 3 {
                return;
            }
        }
        out.push_face(
            Side::Boundary(t),
            s.polygon.iter().map(|n| (n.key, add(site, n.x))),
        );
    }
}

/// Where boundary triangle `t` crosses the bisector of sites `i` and `j` (the plane of a
/// face with outward `normal`), as a segment with the domain on its left seen from
/// outside the cell; `None` when it does not cross. Each mesh vertex is put on one side of
/// the bisector by [`bisector_side`], so both cells of the face cut alike.
fn slice(
    boundary: &Solid,
    (sites, weights): Generators<'_>,
    i: usize,
    j: u32,
    t: u32,
    normal: [f64; 3],
    proj: &impl Fn([f64; 3]) -> [f64; 2],
) -> Option<Segment<3>> {
    let site = sites[i];
    let tri = boundary.simplices()[t as usize];
    let abs = boundary.simplex(t);
    let sides = abs.map(|v| bisector_side(sites, weights, i, j as usize, v));
    if sides.iter().all(|s| s.0 > 0.0) || sides.iter().all(|s| s.0 < 0.0) {
        return None;
    }
    let mut ends = [None, None];
    let mut n = 0;
    for k in 0..3 {
        let l = (k + 1) % 3;
        let ((dk, zk), (dl, zl)) = (sides[k], sides[l]);
        if (dk > 0.0) == (dl > 0.0) || n == 2 {
            continue;
        }
        let (x, key) = if zk {
            (sub(abs[k], site), Key::vertex(tri[k]))
        } else if zl {
            (sub(abs[l], site), Key::vertex(tri[l]))
        } else {
            (
                edge_crossing(boundary, (sites, weights), i, j, tri[k], tri[l]),
                Key::meet(i as u32, &[Gen::Site(j), Gen::MeshEdge(tri[k], tri[l])]),
            )
        };
        ends[n] = Some(Node { p: proj(x), x, key });
        n += 1;
    }
    let (Some(mut a), Some(mut b)) = (ends[0], ends[1]) else {
        return None;
    };
    if a.key == b.key {
        return None;
    }
    // The slice runs along normal × n_T: the domain (behind T) is then on its left.
    let along = cross(normal, Euclid::normal(&abs));
    if dot(sub(b.x, a.x), along) < 0.0 {
        std::mem::swap(&mut a, &mut b);
    }
    Some(Segment { a, b, elem: t })
}

/// Where mesh edge `(a, b)` crosses the bisector of sites `i` and `j`, relative to site
/// `i`: interpolated from the smaller vertex index, so that both triangles of the edge
/// (and the slice and the clipped triangle) get the same bits.
fn edge_crossing(
    boundary: &Solid,
    (sites, weights): Generators<'_>,
    i: usize,
    j: u32,
    a: u32,
    b: u32,
) -> [f64; 3] {
    let (a, b) = (a.min(b), a.max(b));
    let vertices = boundary.vertices();
    let (pa, pb) = (vertices[a as usize], vertices[b as usize]);
    let (da, _) = bisector_side(sites, weights, i, j as usize, pa);
    let (db, _) = bisector_side(sites, weights, i, j as usize, pb);
    let r = da / (da - db);
    let (pa, pb) = (sub(pa, sites[i]), sub(pb, sites[i]));
    std::array::from_fn(|c| pa[c] + r * (pb[c] - pa[c]))
}
