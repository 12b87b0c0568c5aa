//! A region of the unit sphere bounded by great-circle polygons, as a kind of domain
//! (DESIGN §13): a regional ocean, its islands as holes.
//!
//! The region is given by rings of unit vectors (the first the outline, the others holes);
//! the edge between consecutive vertices is the short great-circle arc. It must lie inside
//! an open hemisphere: every vertex within [`MAX_REACH_DEGREES`] of the vertices' mean
//! direction `c`. The gnomonic projection about `c` (`x ↦ (x·e1, x·e2) / x·c`) maps the
//! great circles to straight lines, so the rings are checked there as plane polygons: no
//! two edges meet but consecutive ones at their common vertex, holes inside the outline and
//! outside each other; the rings are oriented here (outline counter-clockwise seen from
//! outside, holes clockwise). The inside test is the plane one in the same projection.
//!
//! **Cells.** Cell `i` is the site's spherical Voronoi cell intersected with the region. The
//! driver computes the cone of the Voronoi cell as on the whole sphere (`sphere.rs`); this
//! module measures it:
//! - a cell whose polygon lies in the 45° cap of its site (the sphere's route) and whose
//!   bounding cap around the site meets no edge of the region is inside it: measured as on
//!   the whole sphere, bit for bit;
//! - any other cell: each ring of the region is clipped by the great circles of the cell's
//!   bisectors (Sutherland–Hodgman on the sphere, `SphericalPolygon::clip`, the sphere's
//!   own clipper), and the pieces measured by the sphere's closed forms (`measure_upper`,
//!   `measure_lower`). The region need not be convex: clipping a ring that is not
//!   convex leaves pieces of the bisector's circle that run both ways between the
//!   crossings, but as a chain the result is the boundary of `ring ∩ half-sphere` (the
//!   difference would be a closed chain on one circle, which is zero), so the moments,
//!   which are sums over the chain (the signed fan, Stokes' first moment), are exact. The
//!   arcs along a neighbour's circle are summed with their sign for the same reason
//!   (`signed_arcs`); a neighbour whose arcs cancel (its bisector meets the cell only
//!   outside the region) is no neighbour.
//!
//! **Stopping early.** A cell at the region's boundary has no sites beyond it and would
//! stream to the far side of the sphere: [`DomainKind::cut_convex`] cuts its cone to the
//! slab around the cap that holds its part in the region (the sphere's slab,
//! `cut_to_slab`), or, when that part reaches beyond the site's equator, to the region's
//! own cap.
//!
//! Not yet: a density (`sampled_moments` of the pieces of a non-convex part), the Hessian
//! (Newton is refused: the arcs of the region's boundary move with the cell).

use std::cell::RefCell;

use crate::error::CoreError;
use crate::geometry::{cross, dot, norm2, scale, sub, Aabb, HalfSpace};
use crate::moments::Moments;

use super::clip::MeasureScratch;
use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::faces::{FaceRow, FaceSums};
use super::scratch::with_scratch;
use super::sphere::{
    cap_polygon, cut_to_slab, measure_lower, measure_upper, radius2_within_depth, unit, SiteFrame,
    Sphere, SphericalPolygon, Sums, ON_SPHERE_TOL,
};

/// How far from its centre (the vertices' mean direction) a vertex of a region may lie, in
/// degrees: inside an open hemisphere, with a margin for the gnomonic projection that
/// checks the rings (a point at 89° is 57 radii from the centre there).
pub const MAX_REACH_DEGREES: f64 = 89.0;

/// A region of the unit sphere bounded by rings of great-circle arcs.
#[derive(Debug, Clone)]
pub struct SphereRegion {
    /// Unit vertices of each ring, the outline first (counter-clockwise seen from outside),
    /// then the holes (clockwise).
    rings: Vec<Vec<[f64; 3]>>,
    /// Unit normal `v_k × v_{k+1} / |…|` of each ring's edge `k`, parallel to `rings`.
    normals: Vec<Vec<[f64; 3]>>,
    /// The index of each ring's first edge among all edges (`Face::Boundary`).
    first_edge: Vec<u32>,
    /// Every vertex, ring after ring.
    vertices: Vec<[f64; 3]>,
    /// The gnomonic projection about the centre, and each ring's image there.
    centre: SiteFrame,
    plane: Vec<Vec<[f64; 2]>>,
    /// `min_k v_k·c`: the region lies in the cap `x·c ≥ cos_reach`.
    cos_reach: f64,
    area: f64,
}

fn invalid(reason: String) -> CoreError {
    CoreError::InvalidRegion { reason }
}

/// Twice the signed area of a plane ring (counter-clockwise positive).
fn plane_area2(ring: &[[f64; 2]]) -> f64 {
    let m = ring.len();
    (0..m)
        .map(|k| {
            let (a, b) = (ring[k], ring[(k + 1) % m]);
            a[0] * b[1] - a[1] * b[0]
        })
        .sum()
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether the closed segments `ab` and `cd` meet.
fn segments_meet(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let within = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        r[0] >= p[0].min(q[0])
            && r[0] <= p[0].max(q[0])
            && r[1] >= p[1].min(q[1])
            && r[1] <= p[1].max(q[1])
    };
    let (d1, d2) = (orient(c, d, a), orient(c, d, b));
    let (d3, d4) = (orient(a, b, c), orient(a, b, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && within(c, d, a))
        || (d2 == 0.0 && within(c, d, b))
        || (d3 == 0.0 && within(a, b, c))
        || (d4 == 0.0 && within(a, b, d))
}

/// Winding number of the plane ring about `p` (non-zero inside), `None` on an edge.
fn plane_winding(ring: &[[f64; 2]], p: [f64; 2]) -> Option<i32> {
    let m = ring.len();
    let mut w = 0;
    for k in 0..m {
        let (a, b) = (ring[k], ring[(k + 1) % m]);
        let o = orient(a, b, p);
        if o == 0.0 && segments_meet(a, b, p, p) {
            return None;
        }
        if a[1] <= p[1] {
            if b[1] > p[1] && o > 0.0 {
                w += 1;
            }
        } else if b[1] <= p[1] && o < 0.0 {
            w -= 1;
        }
    }
    Some(w)
}

/// The signed area of the spherical polygon `ring` (unit vertices), by the fan from `c`
/// of triangles each measured by Van Oosterom and Strackee (a ring inside the open
/// hemisphere about `c`).
fn spherical_area(ring: &[[f64; 3]], c: [f64; 3]) -> f64 {
    let m = ring.len();
    (0..m)
        .map(|k| {
            let (a, b) = (ring[k], ring[(k + 1) % m]);
            let det = dot(c, cross(a, b));
            2.0 * det.atan2(1.0 + dot(c, a) + dot(a, b) + dot(b, c))
        })
        .sum()
}

impl SphereRegion {
    /// The region bounded by `rings` of points on (or near: they are normalised) the unit
    /// sphere, the first the outline and the others holes (islands), in either orientation;
    /// consecutive vertices joined by the short great-circle arc, each ring closed from its
    /// last vertex back to its first (not repeated).
    ///
    /// Errors ([`CoreError::InvalidRegion`]): a ring of fewer than 3 vertices, a
    /// non-finite or zero vertex, consecutive vertices that coincide (or are antipodal), a
    /// region not within [`MAX_REACH_DEGREES`] of its vertices' mean direction, edges that
    /// cross or touch (also between rings), a hole outside the outline or inside another
    /// hole; each naming the ring and vertex or edge.
    pub fn new(rings: Vec<Vec<[f64; 3]>>) -> Result<Self, CoreError> {
        if rings.is_empty() {
            return Err(invalid("no rings".into()));
        }
        let mut unit_rings = Vec::with_capacity(rings.len());
        let mut sum = [0.0; 3];
        for (r, ring) in rings.iter().enumerate() {
            if ring.len() < 3 {
                return Err(invalid(format!(
                    "ring {r} has {} vertices, at least 3 are needed",
                    ring.len()
                )));
            }
            let mut out = Vec::with_capacity(ring.len());
            for (k, v) in ring.iter().enumerate() {
                let n2 = norm2(*v);
                if !v.iter().all(|x| x.is_finite()) || n2 <= 0.0 || !n2.is_finite() {
                    return Err(invalid(format!(
                        "ring {r}, vertex {k}: {v:?} is no direction"
                    )));
                }
                let u = unit(*v);
                sum = [sum[0] + u[0], sum[1] + u[1], sum[2] + u[2]];
                out.push(u);
            }
            let m = out.len();
            for k in 0..m {
                let (a, b) = (out[k], out[(k + 1) % m]);
                let s = norm2(cross(a, b)).sqrt();
                if s < 1e-14 {
                    let what = if dot(a, b) > 0.0 {
                        "coincide"
                    } else {
                        "are antipodal"
                    };
                    return Err(invalid(format!(
                        "ring {r}: vertices {k} and {} {what} (no edge between them)",
                        (k + 1) % m
                    )));
                }
            }
            unit_rings.push(out);
        }
        if norm2(sum) <= 0.0 {
            return Err(invalid("the vertices have no mean direction".into()));
        }
        let c = unit(sum);
        let centre = SiteFrame::at(c);
        let cos_max = MAX_REACH_DEGREES.to_radians().cos();
        let mut cos_reach = 1.0_f64;
        for (r, ring) in unit_rings.iter().enumerate() {
            for (k, v) in ring.iter().enumerate() {
                let cos = dot(*v, c);
                if cos < cos_max {
                    return Err(invalid(format!(
                        "ring {r}, vertex {k} lies {:.3}° from the vertices' mean direction: \
                         a region must lie within {MAX_REACH_DEGREES}° of it (inside an open \
                         hemisphere); split it",
                        cos.clamp(-1.0, 1.0).acos().to_degrees()
                    )));
                }
                cos_reach = cos_reach.min(cos);
            }
        }
        let project = |v: [f64; 3]| {
            let h = dot(v, centre.z);
            [dot(v, centre.e1) / h, dot(v, centre.e2) / h]
        };
        let mut plane: Vec<Vec<[f64; 2]>> = unit_rings
            .iter()
            .map(|ring| ring.iter().map(|&v| project(v)).collect())
            .collect();
        check_simple(&plane)?;
        // Orient: the outline counter-clockwise, the holes clockwise (seen from outside,
        // as in the projection, whose frame is right-handed about `c`).
        for (r, (ring, image)) in unit_rings.iter_mut().zip(plane.iter_mut()).enumerate() {
            let area2 = plane_area2(image);
            if (r == 0) != (area2 > 0.0) {
                ring.reverse();
                image.reverse();
            }
        }
        for r in 1..plane.len() {
            let p = plane[r][0];
            if plane_winding(&plane[0], p) == Some(0) {
                return Err(invalid(format!(
                    "hole {r} (ring {r}) lies outside the outline"
                )));
            }
            for (h, other) in plane.iter().enumerate().skip(1) {
                if h != r && plane_winding(other, p) != Some(0) {
                    return Err(invalid(format!("hole {r} lies inside hole {h}")));
                }
            }
        }
        let normals: Vec<Vec<[f64; 3]>> = unit_rings
            .iter()
            .map(|ring| {
                let m = ring.len();
                (0..m)
                    .map(|k| unit(cross(ring[k], ring[(k + 1) % m])))
                    .collect()
            })
            .collect();
        let mut first_edge = Vec::with_capacity(unit_rings.len());
        let mut count = 0u32;
        for ring in &unit_rings {
            first_edge.push(count);
            count += ring.len() as u32;
        }
        let area: f64 = unit_rings.iter().map(|ring| spherical_area(ring, c)).sum();
        if area.is_nan() || area <= 0.0 {
            return Err(invalid(format!("the region has no area ({area:e})")));
        }
        Ok(Self {
            vertices: unit_rings.iter().flatten().copied().collect(),
            rings: unit_rings,
            normals,
            first_edge,
            centre,
            plane,
            cos_reach,
            area,
        })
    }

    /// The rings as oriented here: the outline counter-clockwise seen from outside, the
    /// holes clockwise; unit vectors.
    pub fn rings(&self) -> &[Vec<[f64; 3]>] {
        &self.rings
    }

    /// The unit vector about which the region lies (its vertices' mean direction).
    pub fn centre(&self) -> [f64; 3] {
        self.centre.z
    }

    /// The region's area on the unit sphere.
    pub fn area(&self) -> f64 {
        self.area
    }

    /// The region's length of boundary on the unit sphere (sum of its arcs).
    pub fn perimeter(&self) -> f64 {
        (self.rings.iter())
            .map(|ring| {
                let m = ring.len();
                (0..m)
                    .map(|k| arc_length(ring[k], ring[(k + 1) % m]))
                    .sum::<f64>()
            })
            .sum()
    }

    /// Whether the arc of some edge of the region comes within the cap `x·z ≥ 1 − 2δ` of
    /// unit `z` (`δ` = `depth`): conservatively, true also a little outside.
    fn meets_cap(&self, z: [f64; 3], depth: f64) -> bool {
        let h = 1.0 - 2.0 * depth - 1e-12;
        for (ring, normals) in self.rings.iter().zip(&self.normals) {
            let m = ring.len();
            for k in 0..m {
                let (a, b, n) = (ring[k], ring[(k + 1) % m], normals[k]);
                if dot(a, z) >= h || dot(b, z) >= h {
                    return true;
                }
                // The arc's highest point along z is inside it when the point of its
                // circle nearest z lies between a and b.
                let p = sub(z, scale(n, dot(n, z)));
                if dot(cross(a, p), n) >= 0.0
                    && dot(cross(p, b), n) >= 0.0
                    && (1.0 - dot(n, z).powi(2)).max(0.0).sqrt() >= h
                {
                    return true;
                }
            }
        }
        false
    }

    /// Each ring of the region clipped by the bisectors of `cell`, in the site's `frame`,
    /// handed to `piece` (rings clipped away are skipped); `poly` is the buffer.
    fn for_each_piece<C: ConvexCell<3>>(
        &self,
        cell: &C,
        frame: &SiteFrame,
        poly: &mut SphericalPolygon,
        mut piece: impl FnMut(&SphericalPolygon),
    ) {
        let local = |v: [f64; 3]| [dot(v, frame.e1), dot(v, frame.e2), dot(v, frame.z)];
        for (r, (ring, normals)) in self.rings.iter().zip(&self.normals).enumerate() {
            poly.vertices.clear();
            poly.normals.clear();
            poly.faces.clear();
            poly.vertices.extend(ring.iter().map(|&v| local(v)));
            // The clipper keeps `n·x ≤ 0`: the region lies left of its edges.
            poly.normals
                .extend(normals.iter().map(|&n| scale(local(n), -1.0)));
            let first = self.first_edge[r];
            poly.faces
                .extend((0..ring.len() as u32).map(|k| Face::Boundary(first + k)));
            poly.clip_by_bisectors(cell, frame);
            if poly.vertices.len() >= 3 {
                piece(poly);
            }
        }
    }

    /// How deep (`max (1 − v·ẑ)`) the cap around the site holding the cell's part in the
    /// region is; `None` if that part reaches to the site's equator.
    fn part_depth<C: ConvexCell<3>>(
        &self,
        cell: &C,
        frame: &SiteFrame,
        scratch: &mut RegionScratch,
    ) -> Option<f64> {
        if cap_polygon(&mut scratch.poly, cell, frame) {
            let depth = scratch.poly.depth();
            if !self.meets_cap(frame.z, depth) {
                return Some(depth);
            }
        }
        let mut depth = Some(0.0_f64);
        let mut poly = std::mem::take(&mut scratch.poly);
        self.for_each_piece(cell, frame, &mut poly, |piece| {
            for &v in &piece.vertices {
                let u = unit(v);
                depth = match depth {
                    Some(d) if u[2] > 0.0 => {
                        Some(d.max((u[0] * u[0] + u[1] * u[1]) / (1.0 + u[2])))
                    }
                    _ => None,
                };
            }
        });
        scratch.poly = poly;
        depth
    }

    /// The moments of the cell of `cell` (of the site of `frame`) in the region, its arcs
    /// into `faces` (module docs).
    fn measure<C: ConvexCell<3>>(
        &self,
        cell: &C,
        frame: &SiteFrame,
        faces: &mut FaceSums<3>,
        scratch: &mut RegionScratch,
    ) -> Moments<3> {
        faces.clear();
        if cap_polygon(&mut scratch.poly, cell, frame)
            && !self.meets_cap(frame.z, scratch.poly.depth())
        {
            return measure_upper(&scratch.poly, frame, faces, None).moments(frame);
        }
        let mut sums = Sums::default();
        let mut poly = std::mem::take(&mut scratch.poly);
        scratch.ignored.clear();
        let (ignored, arcs) = (&mut scratch.ignored, &mut scratch.arcs);
        arcs.clear();
        self.for_each_piece(cell, frame, &mut poly, |piece| {
            let upper = piece.vertices.iter().all(|v| v[2] > 0.0);
            sums.add(if upper {
                measure_upper(piece, frame, ignored, None)
            } else {
                measure_lower(piece, frame, ignored, None)
            });
            signed_arcs(piece, arcs);
        });
        scratch.poly = poly;
        for &(face, net, total) in arcs.iter() {
            match face {
                // Arcs that cancel to round-off: the bisector meets the cell only
                // outside the region.
                Face::Neighbor(_) if net <= 1e-9 * total => {}
                _ => {
                    faces.add(face, net);
                }
            }
        }
        sums.moments(frame)
    }
}

/// The length of the short arc between unit `a` and `b`, from their chord.
fn arc_length(a: [f64; 3], b: [f64; 3]) -> f64 {
    2.0 * (0.5 * norm2(sub(b, a)).sqrt()).min(1.0).asin()
}

/// Add the arcs of `piece` to `arcs` (face, signed length, length): along a neighbour's
/// circle with the sign of its direction (the region's side on the left: `+`), each edge
/// of the region with its length.
fn signed_arcs(piece: &SphericalPolygon, arcs: &mut Vec<(Face, f64, f64)>) {
    let m = piece.vertices.len();
    for k in 0..m {
        let (a, b) = (unit(piece.vertices[k]), unit(piece.vertices[(k + 1) % m]));
        let theta = arc_length(a, b);
        if theta == 0.0 {
            continue;
        }
        let face = piece.faces[k];
        let sign = match face {
            // Kept side `n·x ≤ 0` on the left of a→b: `(a × b)·n < 0`.
            Face::Neighbor(_) if dot(cross(a, b), piece.normals[k]) > 0.0 => -1.0,
            _ => 1.0,
        };
        match arcs.iter_mut().find(|(f, _, _)| *f == face) {
            Some(entry) => {
                entry.1 += sign * theta;
                entry.2 += theta;
            }
            None => arcs.push((face, sign * theta, theta)),
        }
    }
}

/// A thread's buffers for measuring cells of a region.
#[derive(Debug, Default)]
struct RegionScratch {
    poly: SphericalPolygon,
    /// What the sphere's measures add to faces, not read (the arcs are summed signed).
    ignored: FaceSums<3>,
    arcs: Vec<(Face, f64, f64)>,
}

// This thread's buffers, reused from cell to cell ([`with_scratch`]).
thread_local! {
    static SCRATCH: RefCell<RegionScratch> = RefCell::new(RegionScratch::default());
}

/// No two edges of the plane rings meet but consecutive edges of a ring, at their vertex
/// (and there only: no edge folds back along the last).
fn check_simple(rings: &[Vec<[f64; 2]>]) -> Result<(), CoreError> {
    // Every edge with its ring, index and bounding box, sorted by the box's low x.
    let mut edges: Vec<(usize, usize, [f64; 2], [f64; 2])> = Vec::new();
    for (r, ring) in rings.iter().enumerate() {
        let m = ring.len();
        for k in 0..m {
            edges.push((r, k, ring[k], ring[(k + 1) % m]));
        }
    }
    edges.sort_by(|p, q| p.2[0].min(p.3[0]).total_cmp(&q.2[0].min(q.3[0])));
    for (x, &(r, k, a, b)) in edges.iter().enumerate() {
        let hi_x = a[0].max(b[0]);
        for &(s, l, c, d) in &edges[x + 1..] {
            if c[0].min(d[0]) > hi_x {
                break;
            }
            let m = rings[r].len();
            let (first, second) = if (r, k) < (s, l) {
                ((r, k), (s, l))
            } else {
                ((s, l), (r, k))
            };
            let adjacent =
                r == s && (second.1 == first.1 + 1 || (first.1 == 0 && second.1 == m - 1));
            let meet = if adjacent {
                // Consecutive edges share a vertex: they must not overlap beyond it.
                let (p, q, t) = if second.1 == first.1 + 1 {
                    (
                        rings[r][first.1],
                        rings[r][second.1],
                        rings[r][(second.1 + 1) % m],
                    )
                } else {
                    (rings[r][m - 1], rings[r][0], rings[r][1])
                };
                orient(p, q, t) == 0.0 && dot(sub(q, p), sub(t, q)) < 0.0
            } else {
                segments_meet(a, b, c, d)
            };
            if meet {
                let what = if r == s {
                    format!("ring {r}: edges {} and {} cross", first.1, second.1)
                } else {
                    format!(
                        "edge {} of ring {} and edge {} of ring {} meet",
                        first.1, first.0, second.1, second.0
                    )
                };
                return Err(invalid(format!("{what} (the region must be simple)")));
            }
        }
    }
    Ok(())
}

impl DomainKind<3> for SphereRegion {
    fn bounds(&self) -> Aabb<3> {
        Sphere.bounds()
    }

    /// The region's area: the mean spacing is `(A/n)^{1/2}`.
    fn volume(&self) -> f64 {
        self.area
    }

    /// 1 for a point on the sphere (within [`ON_SPHERE_TOL`]) inside the region, 0 for one
    /// outside or off the sphere, `None` on the region's boundary.
    fn locate(&self, point: &[f64; 3]) -> Option<i32> {
        if (norm2(*point) - 1.0).abs() > 2.0 * ON_SPHERE_TOL {
            return Some(0);
        }
        let h = dot(*point, self.centre.z);
        if h <= 0.0 {
            return Some(0);
        }
        let p = [
            dot(*point, self.centre.e1) / h,
            dot(*point, self.centre.e2) / h,
        ];
        let mut inside = false;
        for (r, ring) in self.plane.iter().enumerate() {
            let w = plane_winding(ring, p)?;
            if r == 0 {
                inside = w != 0;
            } else if w != 0 {
                inside = false;
            }
        }
        Some(i32::from(inside))
    }

    fn density_checkpoints(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    /// Not convex, but a cell may be cut early all the same ([`DomainKind::cut_convex`]).
    fn is_convex(&self) -> bool {
        true
    }

    /// Cut the cone to the slab around the cap holding the cell's part in the region
    /// (module docs), or to the region's cap when that part reaches to the site's
    /// equator. Always `false`, as on the sphere: the slab tightens as the cell shrinks.
    fn cut_convex<C: ConvexCell<3>>(&self, cell: &mut C, site: [f64; 3], _: &mut Vec<u32>) -> bool {
        let frame = SiteFrame::at(site);
        match with_scratch(&SCRATCH, |s| self.part_depth(cell, &frame, s)) {
            Some(depth) => cut_to_slab(cell, site, &frame, depth),
            None => {
                // `cos_reach ≤ x·c ≤ 1` relative to the site, a little wider.
                let c = self.centre.z;
                let at = dot(c, site);
                let low = self.cos_reach - 1e-9;
                cell.clip(
                    &HalfSpace {
                        normal: c,
                        offset: 1.0 - at,
                    },
                    Face::Boundary(0),
                );
                cell.clip(
                    &HalfSpace {
                        normal: scale(c, -1.0),
                        offset: at - low,
                    },
                    Face::Boundary(1),
                );
            }
        }
        false
    }

    /// `max |x − site|²` over the cell's part in the region, from its deepest vertex; 4
    /// for a part reaching to the site's equator.
    fn local_radius2<C: ConvexCell<3>>(&self, cell: &C, site: [f64; 3]) -> f64 {
        let frame = SiteFrame::at(site);
        radius2_within_depth(
            site,
            with_scratch(&SCRATCH, |s| self.part_depth(cell, &frame, s)),
        )
    }

    fn clip<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        _: Option<i32>,
        _: Option<FaceRow<'_, 3>>,
        scratch: &mut MeasureScratch<3, C>,
    ) -> Moments<3> {
        let frame = SiteFrame::at(site);
        with_scratch(&SCRATCH, |s| {
            self.measure(cell, &frame, &mut scratch.faces, s)
        })
    }

    fn cell_dim(&self) -> usize {
        2
    }

    fn central_second(&self, m: &Moments<3>) -> f64 {
        Sphere.central_second(m)
    }

    fn tangent(&self, site: [f64; 3], v: [f64; 3]) -> [f64; 3] {
        Sphere.tangent(site, v)
    }

    fn curvature_term(&self, site: [f64; 3], gradient: [f64; 3]) -> f64 {
        Sphere.curvature_term(site, gradient)
    }

    /// Not yet: the region's boundary arcs move with the cell (module docs).
    fn sums_hessian(&self) -> bool {
        false
    }

    fn retract(&self, x: [f64; 3]) -> [f64; 3] {
        Sphere.retract(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagram::sphere::tests::random_sites;
    use crate::diagram::{clipped_diagram, PolyhedronCell, Request};
    use std::f64::consts::PI;

    /// The octant `x, y, z > 0` has area `π/2` (an eighth of `4π`), cut into a
    /// non-convex region by a notch from the corner `(1, 1, 1)/√3`: the region of a
    /// triangle minus a triangle.
    fn notched_octant() -> Vec<[f64; 3]> {
        vec![
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 3.0],
            [3.0, 1.0, 1.0],
        ]
    }

    #[test]
    fn the_octant_has_an_eighth_of_the_area() {
        let octant = SphereRegion::new(vec![vec![
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]]);
        let octant = octant.unwrap();
        assert!((octant.area() - PI / 2.0).abs() < 1e-15);
        assert!((octant.perimeter() - 1.5 * PI).abs() < 1e-14);
        // Clockwise given, oriented here.
        let reversed = SphereRegion::new(vec![vec![
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
        ]]);
        assert_eq!(reversed.unwrap().area(), octant.area());
    }

    /// Random sites in the notched octant: the cells tile it, every neighbour's arc is
    /// positive, and the boundary measures sum to its perimeter.
    #[test]
    fn cells_tile_a_non_convex_region() {
        let region = SphereRegion::new(vec![notched_octant()]).unwrap();
        let sites: Vec<[f64; 3]> = random_sites(20_000, 11)
            .into_iter()
            .filter(|s| region.locate(s) == Some(1))
            .take(300)
            .collect();
        assert_eq!(sites.len(), 300);
        let d = clipped_diagram::<3, PolyhedronCell, _>(&region, &sites, &Request::default())
            .unwrap()
            .diagram;
        let total: f64 = d.moments.iter().map(|m| m.mass).sum();
        assert!((total - region.area()).abs() < 1e-13 * region.area());
        let boundary: f64 = d.boundary_measure.iter().sum();
        assert!((boundary - region.perimeter()).abs() < 1e-13 * region.perimeter());
        assert!(d.neighbor_measures.iter().all(|&m| m > 0.0));
    }

    #[test]
    fn bad_regions_are_named() {
        let reason = |rings: Vec<Vec<[f64; 3]>>| match SphereRegion::new(rings) {
            Err(CoreError::InvalidRegion { reason }) => reason,
            other => panic!("{other:?}"),
        };
        let diamond = [
            [1.0, 0.0, 0.1],
            [1.0, 0.1, 0.0],
            [1.0, 0.0, -0.1],
            [1.0, -0.1, 0.0],
        ];
        let swapped = vec![diamond[0], diamond[2], diamond[1], diamond[3]]; // a bow tie
        assert!(reason(vec![swapped]).contains("cross"));
        let wide = vec![[1.0, 0.0, 0.0], [-0.5, 0.8, 0.0], [-0.5, -0.8, 0.1]];
        assert!(reason(vec![wide]).contains("within"));
        let repeated = vec![[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(reason(vec![repeated]).contains("coincide"));
        let nan = vec![[1.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(reason(vec![nan]).contains("no direction"));
        let outside_hole = vec![[1.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.0, 0.0, 0.1]];
        let far_hole = vec![[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.1, 1.0]];
        assert!(reason(vec![outside_hole, far_hole]).contains("outside the outline"));
    }
}
