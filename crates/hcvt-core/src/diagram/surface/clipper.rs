//! A surface triangle clipped by a cell's planes into a convex piece whose edges know
//! what they lie on (a triangle's edge or a bisector).

use crate::diagram::convex_cell::Face;
use crate::diagram::polygon_clip::clip_polygon;
use crate::geometry::{dot, HalfSpace};

/// What an edge of a clipped piece lies on: edge `k` of its triangle, or a plane of the cell.
#[derive(Debug, Clone, Copy)]
pub(super) enum Edge {
    Triangle(u8),
    Plane(Face),
}

/// A node of a clipped piece, relative to the site, with the edge leaving it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Node {
    pub(super) x: [f64; 3],
    pub(super) out: Edge,
}

/// Buffers of [`Clipper::triangle`].
#[derive(Debug, Default)]
pub(super) struct Clipper {
    polygon: Vec<Node>,
    spare: Vec<Node>,
    sides: Vec<(f64, bool)>,
    /// The planes cutting the triangle (by index) and its corners' sides of each.
    cutting: Vec<(usize, [f64; 3])>,
    /// The plane that last had a whole triangle outside, tried first.
    hint: usize,
}

impl Clipper {
    /// The triangle `rel` (relative to the site) whole, as a piece.
    pub(super) fn whole(&mut self, rel: [[f64; 3]; 3]) -> &[Node] {
        self.polygon.clear();
        self.polygon.extend((0..3).map(|k| Node {
            x: rel[k],
            out: Edge::Triangle(k as u8),
        }));
        &self.polygon
    }

    /// The triangle `rel` (relative to the site) clipped by every plane of a cell, or
    /// `None` when nothing is left. One pass over the planes finds the corners' sides of
    /// each: a plane with every corner outside leaves nothing, one with every corner
    /// inside leaves the triangle (and every piece of it, convex) whole; only the planes
    /// between cut, in their order.
    pub(super) fn triangle(
        &mut self,
        planes: &[(Face, HalfSpace<3>)],
        rel: [[f64; 3]; 3],
    ) -> Option<&[Node]> {
        let Self { cutting, hint, .. } = self;
        let outside = |h: &HalfSpace<3>| rel.iter().all(|&v| dot(h.normal, v) > h.offset);
        if planes.get(*hint).is_some_and(|(_, h)| outside(h)) {
            return None;
        }
        cutting.clear();
        for (p, (_, h)) in planes.iter().enumerate() {
            let d = rel.map(|v| dot(h.normal, v) - h.offset);
            let out = d.iter().filter(|&&x| x > 0.0).count();
            if out == 3 {
                *hint = p;
                return None;
            }
            if out > 0 {
                cutting.push((p, d));
            }
        }
        self.whole(rel);
        let Self {
            polygon,
            spare,
            sides,
            cutting,
            ..
        } = self;
        for (at, &(p, corners)) in cutting.iter().enumerate() {
            let (face, ref h) = planes[p];
            sides.clear();
            if at == 0 {
                sides.extend(corners.iter().map(|&d| (d, false)));
            } else {
                sides.extend(
                    polygon
                        .iter()
                        .map(|n| (dot(h.normal, n.x) - h.offset, false)),
                );
                if sides.iter().all(|&(d, _)| d <= 0.0) {
                    continue;
                }
            }
            clip_polygon(polygon, sides, spare, |u, w, (su, _), (sw, _)| {
                let r = su / (su - sw);
                Node {
                    x: std::array::from_fn(|c| u.x[c] + r * (w.x[c] - u.x[c])),
                    out: if su <= 0.0 { Edge::Plane(face) } else { u.out },
                }
            });
            std::mem::swap(polygon, spare);
            if polygon.len() < 3 {
                return None;
            }
        }
        Some(polygon)
    }
}
