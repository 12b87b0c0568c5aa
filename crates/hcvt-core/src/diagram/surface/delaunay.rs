//! The restricted Delaunay triangulation and the cells' pieces, read from a diagram whose
//! cells [`super::noting`] noted (module docs of [`super`], "The triangulation").

use std::collections::HashMap;

use crate::diagram::convex_cell::{ConvexCell, Face};
use crate::diagram::driver::clipped_diagram;
use crate::diagram::output::Diagram;
use crate::diagram::polyhedron_cell::PolyhedronCell;
use crate::diagram::request::Request;
use crate::error::CoreError;
use crate::geometry::{add, cross, dot, norm2, sub, HalfSpace};

use super::clipper::{Edge, Node};
use super::noting::Noting;
use super::triangles::Surface;
use super::walk::Triangles;

/// Points closer than this fraction of the surface's bounding-box diagonal are one
/// meeting point of three cells (rounding apart: found in two triangles, or as the
/// ends of two arcs on an edge).
pub(super) const SAME_POINT: f64 = 1e-10;

/// Where three cells meet: the sites (the cell's own first), the point, its surface triangle.
type Meeting = ([u32; 3], [f64; 3], u32);

/// The restricted Delaunay triangulation of sites on a surface ([`Surface::restricted_delaunay`]).
#[derive(Debug, Clone, Default)]
pub struct RestrictedDelaunay {
    /// One triangle of site indices per point where three cells meet on the surface,
    /// counter-clockwise seen from the side the surface's normal points to there, sorted.
    pub triangles: Vec<[u32; 3]>,
    /// Each triangle's meeting point, absolute, `L`.
    pub points: Vec<[f64; 3]>,
    /// The surface triangle each meeting point lies in.
    pub faces: Vec<u32>,
    /// Triples of cells that meet at more than one point (a cell that is not a disc, the
    /// closed-ball property of Edelsbrunner and Shah failing), sorted: each such triple
    /// gives one triangle above, and the triangulation may not be a manifold there.
    pub repeated: Vec<[u32; 3]>,
    /// The restricted Voronoi diagram of the sites, which the triangulation is read from
    /// (the one [`clipped_diagram`] gives): callers wanting both compute it once.
    pub diagram: Diagram<3>,
}

/// The restricted Voronoi cells of sites on a surface as convex planar pieces
/// ([`Surface::pieces`]): each the part of one input triangle in one cell, its nodes
/// counter-clockwise about the triangle's normal (as the triangle's corners run), in flat
/// arrays; the pieces by cell, within a cell in the measure's order (the BVH's, fixed).
#[derive(Debug, Clone, Default)]
pub struct SurfacePieces {
    /// Every piece's nodes, absolute, `L`.
    pub points: Vec<[f64; 3]>,
    /// Piece `p`'s nodes are `points[offsets[p]..offsets[p + 1]]` (at least three).
    pub offsets: Vec<usize>,
    /// The cell (site) of each piece, non-decreasing.
    pub cells: Vec<u32>,
    /// The input triangle of each piece.
    pub triangles: Vec<u32>,
    /// The diagram the pieces were noted by, bit for bit [`clipped_diagram`]'s.
    pub diagram: Diagram<3>,
}

impl Surface {
    /// The restricted Delaunay triangulation of `sites` (DESIGN §12): a triangle `(i, j, k)`
    /// for each point of the surface where the cells of `i`, `j` and `k` meet (a vertex of a
    /// cell's piece between its arcs on the bisectors with `j` and `k`), oriented by the
    /// normal of the surface triangle holding that point. Each meeting point is seen by
    /// its three cells; a triple is kept once, from the cell of its smallest site.
    ///
    /// Errors are [`clipped_diagram`]'s.
    pub fn restricted_delaunay(&self, sites: &[[f64; 3]]) -> Result<RestrictedDelaunay, CoreError> {
        use rayon::prelude::*;
        let request = Request {
            keep_cells: true,
            ..Default::default()
        };
        let noting = Noting::new(self, false, sites.len());
        let clipped = clipped_diagram::<3, PolyhedronCell, _>(&noting, sites, &request)?;
        let met = noting.into_notes();
        let same = SAME_POINT * self.set.bvh().bounds().diagonal();
        let found: Vec<Vec<Meeting>> = clipped
            .cells
            .par_iter()
            .enumerate()
            .map(|(i, cell)| {
                let noted = met
                    .get(&sites[i].map(f64::to_bits))
                    .and_then(Option::as_ref)
                    .map(|noted| noted.triangles.as_slice());
                self.meeting_points(i as u32, cell, sites[i], same, noted)
            })
            .collect();
        let mut out = RestrictedDelaunay::default();
        // Each triple's first point and how many distinct points it was seen at.
        let mut seen: HashMap<[u32; 3], ([f64; 3], usize)> = HashMap::new();
        for (tri, point, face) in found.into_iter().flatten() {
            let mut key = tri;
            key.sort_unstable();
            if let Some((first, count)) = seen.get_mut(&key) {
                // The same point seen from two triangles (on their edge) is one meeting.
                if norm2(sub(point, *first)) > same * same {
                    *count += 1;
                    if *count == 2 {
                        out.repeated.push(key);
                    }
                }
                continue;
            }
            seen.insert(key, (point, 1));
            // Counter-clockwise about the normal of the surface there.
            let normal = {
                let [a, b, c] = self.corners(face);
                cross(sub(b, a), sub(c, a))
            };
            let [i, j, k] = tri.map(|v| sites[v as usize]);
            let oriented = if dot(cross(sub(j, i), sub(k, i)), normal) >= 0.0 {
                tri
            } else {
                [tri[0], tri[2], tri[1]]
            };
            out.triangles.push(oriented);
            out.points.push(point);
            out.faces.push(face);
        }
        out.repeated.sort_unstable();
        out.diagram = clipped.diagram;
        Ok(out)
    }

    /// The restricted Voronoi cells of `sites` on the surface as their pieces
    /// ([`SurfacePieces`]): the convex polygons the diagram's measure clipped from the
    /// input triangles and summed the moments of, noted as it measured them (no second
    /// clip).
    ///
    /// Errors are [`clipped_diagram`]'s.
    pub fn pieces(&self, sites: &[[f64; 3]]) -> Result<SurfacePieces, CoreError> {
        let request = Request::default();
        let noting = Noting::new(self, true, sites.len());
        let clipped = clipped_diagram::<3, PolyhedronCell, _>(&noting, sites, &request)?;
        let mut met = noting.into_notes();
        let mut out = SurfacePieces {
            offsets: vec![0],
            ..Default::default()
        };
        for (i, site) in sites.iter().enumerate() {
            // A cell the driver did not measure has no pieces.
            let Some(noted) = met.remove(&site.map(f64::to_bits)) else {
                continue;
            };
            let noted = noted.ok_or_else(|| CoreError::InvalidSettings {
                reason: format!("site {i} shares its coordinates with another site"),
            })?;
            let start = out.points.len();
            out.points.extend_from_slice(&noted.nodes);
            out.offsets.extend(noted.ends.iter().map(|end| start + end));
            out.cells.extend(noted.triangles.iter().map(|_| i as u32));
            out.triangles.extend_from_slice(&noted.triangles);
        }
        out.diagram = clipped.diagram;
        Ok(out)
    }

    /// The points where cell `i` (its convex cell `cell`, relative to `site`) meets two
    /// other cells `j < k` on the surface, with `i < j`: `([i, j, k], point, face)`;
    /// points closer than `same` are one.
    ///
    /// Inside a triangle such a point is a vertex of the cell's piece between its arcs on
    /// the bisectors with `j` and `k`. On an input edge or vertex it may be no such
    /// vertex: the piece on one side ends its arc on the bisector with `j` there, the
    /// piece on the other side its arc on the one with `k` ([`ArcEnd`]). An edge of a
    /// piece on an inner input edge that lies on one of the cell's bisectors (to `same`)
    /// is an arc on it: the clipping left it labelled by the triangle.
    ///
    /// `noted`: the triangles of the cell's pieces as its measure met them
    /// ([`Noting`]), clipped again instead of a walk of the BVH (the same pieces).
    pub(super) fn meeting_points<C: ConvexCell<3>>(
        &self,
        i: u32,
        cell: &C,
        site: [f64; 3],
        same: f64,
        noted: Option<&[u32]>,
    ) -> Vec<Meeting> {
        let mut bisectors: Vec<(u32, HalfSpace<3>)> = Vec::new();
        cell.for_each_plane(|face, h| {
            if let Face::Neighbor(j) = face {
                bisectors.push((j, *h));
            }
        });
        let on_bisector = |u: [f64; 3], w: [f64; 3]| {
            bisectors.iter().find_map(|&(j, ref h)| {
                let tol = same * norm2(h.normal).sqrt();
                let off = |x| (dot(h.normal, x) - h.offset).abs();
                (off(u) <= tol && off(w) <= tol).then_some(j)
            })
        };
        let mut out = Vec::new();
        let mut ends: Vec<ArcEnd> = Vec::new();
        let mut each = |t: u32, polygon: &[Node]| {
            let n = polygon.len();
            // Each edge of the piece: on a bisector (`Arc`), on an inner input edge
            // (`Inner`), or on the border.
            let side = |k: usize| match polygon[k].out {
                Edge::Plane(Face::Neighbor(j)) => Side::Arc(j),
                Edge::Triangle(e) if !self.is_border(t, e as usize) => {
                    match on_bisector(polygon[k].x, polygon[(k + 1) % n].x) {
                        Some(j) => Side::Arc(j),
                        None => Side::Inner,
                    }
                }
                _ => Side::Other,
            };
            let sides: Vec<Side> = (0..n).map(side).collect();
            for k in 0..n {
                let point = add(site, polygon[k].x);
                match (sides[(k + n - 1) % n], sides[k]) {
                    (Side::Arc(a), Side::Arc(b)) if a != b && i < a.min(b) => {
                        out.push(([i, a.min(b), a.max(b)], point, t));
                    }
                    (Side::Arc(label), Side::Inner) | (Side::Inner, Side::Arc(label)) => {
                        ends.push(ArcEnd {
                            point,
                            label,
                            face: t,
                        });
                    }
                    _ => {}
                }
            }
        };
        match noted {
            Some(triangles) => self.for_each_piece_of(cell, site, triangles, &mut each),
            None => self.for_each_piece(cell, site, Triangles::Walk, &mut each),
        }
        arc_ends_meetings(i, same, &mut ends, &mut out);
        out
    }
}

/// The meeting points of cell `i` on the input's edges and vertices from the ends `ends`
/// of its arcs there: two ends at one point (to `same`) in different triangles, on the
/// bisectors with `j` and `k`, are a point of all three cells (it lies on both
/// bisectors).
fn arc_ends_meetings(i: u32, same: f64, ends: &mut [ArcEnd], out: &mut Vec<Meeting>) {
    ends.sort_unstable_by(|x, y| {
        (x.point[0].total_cmp(&y.point[0]))
            .then(x.face.cmp(&y.face))
            .then(x.label.cmp(&y.label))
    });
    for (k, x) in ends.iter().enumerate() {
        for y in &ends[k + 1..] {
            if y.point[0] - x.point[0] > same {
                break;
            }
            let (a, b) = (x.label.min(y.label), x.label.max(y.label));
            if x.face != y.face && a != b && i < a && norm2(sub(x.point, y.point)) <= same * same {
                out.push(([i, a, b], x.point, x.face));
            }
        }
    }
}

/// What an edge of a cell's piece lies on ([`Surface::meeting_points`]).
#[derive(Debug, Clone, Copy)]
enum Side {
    /// The bisector with a site.
    Arc(u32),
    /// An edge of the triangle shared with another.
    Inner,
    /// The border, or a plane of no neighbour.
    Other,
}

/// Where an arc of a cell (on the bisector with site `label`) ends on an inner edge of
/// surface triangle `face`: the point, absolute.
#[derive(Debug, Clone, Copy)]
struct ArcEnd {
    point: [f64; 3],
    label: u32,
    face: u32,
}
