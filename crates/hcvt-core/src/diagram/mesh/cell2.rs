//! The edges of one 2D clipped cell `C ∩ Ω` (DESIGN §9): the convex cell's edges inside
//! the domain and the boundary segments inside the convex cell, stitched into loops by
//! the same planar clip that restricts a 3D cell's bisector faces.

use super::key::{Gen, Key};
use super::planar::{clip_ring, EdgeOf, Node, PlanarScratch, Segment};
use super::{gen_of, CellFaces, CellGeometry, Side};
use crate::diagram::clip::boundary_candidates;
use crate::diagram::convex_cell::Face;
use crate::diagram::polygon_cell::PolygonCell;
use crate::domain::{Polygon, WindingNumber};
use crate::geometry::{add, sub, Euclid};

/// Buffers of one thread's 2D cells.
#[derive(Debug, Default)]
pub(crate) struct Scratch2 {
    ring: Vec<Node<2>>,
    gens: Vec<Gen>,
    candidates: Vec<u32>,
    segments: Vec<Segment<2>>,
    planar: PlanarScratch<2>,
    loops: Vec<(Node<2>, EdgeOf)>,
    ends: Vec<usize>,
}

impl CellGeometry<2> for PolygonCell {
    type Scratch = Scratch2;

    fn clipped_faces(
        &self,
        boundary: &Polygon,
        sites: &[[f64; 2]],
        _weights: Option<&[f64]>,
        i: usize,
        winding: Option<i32>,
        out: &mut CellFaces<2>,
        s: &mut Scratch2,
    ) {
        let site = sites[i];
        let ci = i as u32;
        let (vertices, faces) = (self.vertices(), self.faces());
        let m = vertices.len();
        if m < 3 {
            return;
        }
        s.gens.clear();
        s.gens
            .extend(faces.iter().enumerate().map(|(k, &f)| gen_of(f, k as u16)));
        s.ring.clear();
        s.ring.extend((0..m).map(|k| Node {
            p: vertices[k],
            x: vertices[k],
            key: Key::meet(ci, &[s.gens[(k + m - 1) % m], s.gens[k]]),
        }));
        s.candidates.clear();
        boundary_candidates(boundary, self, site, &mut s.candidates);
        s.loops.clear();
        s.ends.clear();
        if s.candidates.is_empty() {
            if winding != Some(1) {
                return;
            }
            s.loops
                .extend((0..m).map(|k| (s.ring[k], EdgeOf::Ring(k as u32))));
            s.ends.push(m);
        } else {
            s.segments.clear();
            for &t in &s.candidates {
                let [a, b] = boundary.simplices()[t as usize];
                let [va, vb] = boundary.simplex(t).map(|v| sub(v, site));
                s.segments.push(Segment {
                    a: Node {
                        p: va,
                        x: va,
                        key: Key::vertex(a),
                    },
                    b: Node {
                        p: vb,
                        x: vb,
                        key: Key::vertex(b),
                    },
                    elem: t,
                });
            }
            let (gens, segments) = (&s.gens, &s.segments);
            let inside = || {
                vertices
                    .iter()
                    .find_map(|&v| Euclid::winding_number(boundary, &add(site, v)))
                    .is_some_and(|w| w != 0)
            };
            out.open += clip_ring(
                &s.ring,
                segments,
                |k, seg| Key::meet(ci, &[gens[k], Gen::Elem(segments[seg].elem)]),
                inside,
                &mut s.planar,
                &mut s.loops,
                &mut s.ends,
            );
        }
        let mut begin = 0;
        for &end in &s.ends {
            let cycle = &s.loops[begin..end];
            for (k, &(from, on)) in cycle.iter().enumerate() {
                let to = cycle[(k + 1) % cycle.len()].0;
                let side = match on {
                    EdgeOf::Ring(e) => match faces[e as usize] {
                        Face::Neighbor(j) => Side::Neighbor(j),
                        // A box side lies outside the domain: only round-off puts it here.
                        _ => continue,
                    },
                    EdgeOf::Segment(q) => Side::Boundary(s.segments[q as usize].elem),
                };
                out.push_face(
                    side,
                    [(from.key, add(site, from.x)), (to.key, add(site, to.x))].into_iter(),
                );
            }
            begin = end;
        }
    }
}
