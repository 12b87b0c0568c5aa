//! The unit sphere about the origin as a kind of domain (DESIGN §13).
//!
//! Sites are unit vectors; the caller scales lengths by the radius `R` (areas by `R²`,
//! first moments by `R³`, energies by `R⁴`). The cell of site `z` is
//! `{x ∈ S² : x·z ≥ x·z_j for all j}`: bisector planes of sites on the sphere pass through
//! the centre, so the driver's convex cell of `z` is a cone from the centre (cut by its
//! start box), and the cell is the spherical polygon where that cone meets the sphere,
//! bounded by great circles.
//!
//! **Route.** The driver keeps doing what it does for every kind: the bisectors of the
//! nearest sites in order of distance, until the security radius certifies the 3D cell
//! (Euclidean distance between points of the sphere is monotone in arc length, so the kNN
//! order is the sphere's). This module then reads the cell's bisector planes
//! ([`ConvexCell::for_each_plane`]: their normals are `q = z_j − z` exactly as the driver
//! formed them) and clips a spherical polygon by their great circles itself, in an
//! orthonormal frame `(e1, e2, ẑ)` at the site: first the square cap of corners
//! `(±1, ±1, 1)` (45° around the site), which holds every cell of spread sites; a cell
//! that reaches the cap's edge is clipped again in each of the eight octants of the
//! frame and the pieces summed (every start polygon lies in an open hemisphere, so its
//! arcs are shorter than a half circle, which the clipper needs; a hemisphere cut by a
//! great circle would have two antipodal vertices). Two things decided this over taking
//! the polygon from the 3D cell's vertices or its section by the tangent plane (the
//! gnomonic image, where great circles are lines): (1) precision: in the frame a great
//! circle's normal is `(q·e1, q·e2, −|q|²/2)` (for unit sites `q·z = −|q|²/2`), every
//! component exact to relative round-off however small the cell, and each vertex is
//! recomputed as the cross product of its two circles' normals, so it is known relative
//! to the site as a 2D cell's vertex is, while the 3D cell's vertices near its apex (the
//! centre, where every bisector plane meets) are ill-conditioned; (2) generality: the
//! octants take any cell, also one reaching past its site's equator (few or clustered
//! sites), where a gnomonic section only sees the open hemisphere.
//!
//! **Stopping early.** The cone starts as the whole start box, whose corners would keep the
//! security radius at the size of the sphere. The sphere is therefore a "convex" kind
//! ([`DomainKind::is_convex`]): every `PRECLIP_K` neighbours (16),
//! [`DomainKind::cut_convex`] cuts the cone to the slab `1 − 2δ ≤ x·ẑ ≤ 1` around the
//! cap that holds the polygon so far (`δ = max_k (1 − v_k·ẑ)` over its vertices; the
//! polygon only shrinks later, and its lowest point is a vertex), which brings the radius
//! down to the cell's own scale; the cell is measured by [`DomainKind::clip`] as the
//! spherical polygon, not the slab. Measured on 20,000 random sites, every cell's reach
//! (the distance within which it read sites) is below 4 spacings, 2.3 on average
//! (reach² 15.3 and 5.2 spacings²): O(1) sites per cell.
//!
//! **Closed forms** for the polygon with unit vertices `v_k` (counter-clockwise seen from
//! outside), `y_k = v_k − ẑ`, edge arcs `θ_k`, edge normals `n_k = v_k × v_{k+1} / sin θ_k`:
//! - area by the fan of triangles `(ẑ, v_k, v_{k+1})`, each by Van Oosterom and Strackee,
//!   `tan(Ω/2) = [ẑ v_k v_{k+1}] / (1 + ẑ·v_k + v_k·v_{k+1} + v_{k+1}·ẑ)`;
//! - first moment `M = ∫x dA = ½ Σ θ_k n_k` (Stokes), computed as
//!   `½ Σ (y_k × y_{k+1} + (θ_k − sin θ_k) n_k)`: the same sum (`v_k × v_{k+1} =
//!   ẑ × (v_{k+1} − v_k) + y_k × y_{k+1}` and the first part telescopes), whose terms are
//!   of the cell's size and not of `θ_k`;
//! - energy `∫ |x − ẑ|² dA = 2A − 2 ẑ·M`, computed per fan triangle from the difference
//!   `Ω_k − ½ [ẑ v_k v_{k+1}]` in closed form (series for `atan x − x` and `θ − sin θ` when
//!   small), so that it keeps its relative precision when `A` and `ẑ·M` agree to many
//!   digits (a cell of size `h` has energy `~h⁴` from terms `~h²`).
//!
//! **A density** (`sphere_density.rs`): the measure keeps each fan triangle as a piece
//! ([`crate::density::Cone`]) when a density is on; a sampled field is evaluated at the
//! nodes of a triangle rule mapped onto the sphere ([`DomainKind::sampled_node`]) and summed
//! with the exact moments taking the cell's mean density ([`DomainKind::sampled_moments`]);
//! a polynomial is sampled the same way at the degree-5 rule's nodes here.
//!
//! Moments are reported about the site like every other kind's: mass `A`, first
//! `M − A ẑ`, second the energy; the neighbour face measures are the arc lengths. The cells
//! have dimension 2 ([`DomainKind::cell_dim`]); the CVT's centroid is `M / |M|` (Du,
//! Gunzburger and Ju 2003), where [`DomainKind::retract`] takes the Lloyd step, and the
//! optimisers step in the tangent plane ([`DomainKind::tangent`]).

use std::cell::RefCell;

use crate::density::quadrature::{Rule, SEGMENT_5, TRIANGLE_5};
use crate::density::Cone;
use crate::geometry::{add, cross, dot, norm2, scale, sub, Aabb, HalfSpace};
use crate::moments::{FaceMoments, Moments};

use super::clip::MeasureScratch;
use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::faces::{FaceRow, FaceSums};
use super::scratch::with_scratch;
use super::sphere_density;
use super::weighted_sums::{FaceNodes, FACE_NODES};

/// How far from the unit sphere a site may lie, `| |x|² − 1 | ≤ 2·ON_SPHERE_TOL` (so
/// `| |x| − 1 |` about `ON_SPHERE_TOL`): the sites are then taken as their directions. A
/// caller with radius `R` divides by `R` first; normalised vectors are within a few ulps.
pub const ON_SPHERE_TOL: f64 = 1e-10;

/// The unit sphere about the origin, as a domain of cells of dimension 2.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sphere;

impl Sphere {
    /// The unit sphere.
    pub fn new() -> Self {
        Self
    }

    /// The constrained centroid `M / |M|` of a cell of site `site` with moments `m` (about
    /// the site): where Lloyd moves the site; the site itself for an empty cell.
    pub fn centroid(&self, site: [f64; 3], m: &Moments<3>) -> [f64; 3] {
        match m.centroid() {
            Some(shift) => self.retract(add(site, shift)),
            None => site,
        }
    }
}

/// An orthonormal right-handed frame `(e1, e2, z)` with `z` the site's direction.
#[derive(Debug, Clone, Copy)]
pub(super) struct SiteFrame {
    pub(super) e1: [f64; 3],
    pub(super) e2: [f64; 3],
    pub(super) z: [f64; 3],
}

impl SiteFrame {
    /// Duff et al., "Building an orthonormal basis, revisited" (JCGT 2017): no branch
    /// but the sign, no loss of orthogonality near the poles.
    pub(super) fn at(site: [f64; 3]) -> Self {
        let z = scale(site, 1.0 / norm2(site).sqrt());
        let sign = 1.0_f64.copysign(z[2]);
        let a = -1.0 / (sign + z[2]);
        let b = z[0] * z[1] * a;
        Self {
            e1: [1.0 + sign * z[0] * z[0] * a, sign * b, -sign * z[0]],
            e2: [b, sign + z[1] * z[1] * a, -z[1]],
            z,
        }
    }

    pub(super) fn global(&self, l: [f64; 3]) -> [f64; 3] {
        add(
            add(scale(self.e1, l[0]), scale(self.e2, l[1])),
            scale(self.z, l[2]),
        )
    }

    /// Face moments in the frame turned into global axes: `F m`, `F S Fᵀ` with `F` the
    /// matrix of columns `(e1, e2, ẑ)`.
    fn global_moments(&self, m: &FaceMoments<3>) -> FaceMoments<3> {
        // `S` is symmetric: `F` times its row `r` is column `r` of `F S`, and `F` times row
        // `c` of `F S` is column `c` of `F S Fᵀ`.
        let columns = m.second.map(|row| self.global(row));
        let rows = [0, 1, 2].map(|c| self.global([columns[0][c], columns[1][c], columns[2][c]]));
        FaceMoments {
            measure: m.measure,
            first: self.global(m.first),
            second: std::array::from_fn(|r| std::array::from_fn(|c| rows[c][r])),
        }
    }
}

/// A convex spherical polygon in a [`SiteFrame`], inside an open hemisphere: unit
/// vertices counter-clockwise seen from outside; edge `k` (the short arc from vertex `k` to
/// `k + 1`) lies on the great circle `normals[k]·x = 0` (inside: `≤ 0`) and was made by
/// `faces[k]`; [`Face::Box`] marks an edge of the start polygon.
#[derive(Debug, Default)]
pub(super) struct SphericalPolygon {
    pub(super) vertices: Vec<[f64; 3]>,
    pub(super) normals: Vec<[f64; 3]>,
    pub(super) faces: Vec<Face>,
    spare_vertices: Vec<[f64; 3]>,
    spare_normals: Vec<[f64; 3]>,
    spare_faces: Vec<Face>,
}

/// The start polygon of the common cell: the square cap of corners `(±1, ±1, 1)` in the
/// site's frame (45° from the site along the axes), counter-clockwise from outside.
const CAP: [[f64; 3]; 4] = [
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
];

impl SphericalPolygon {
    /// The polygon with these corners (counter-clockwise from outside, within an open
    /// hemisphere), every edge [`Face::Box`].
    fn reset(&mut self, corners: &[[f64; 3]]) {
        let m = corners.len();
        self.vertices.clear();
        self.vertices.extend(corners.iter().map(|&c| unit(c)));
        self.normals.clear();
        self.normals
            .extend((0..m).map(|k| scale(cross(corners[k], corners[(k + 1) % m]), -1.0)));
        self.faces.clear();
        self.faces.extend(std::iter::repeat_n(Face::Box, m));
    }

    /// The octant `(sx e1, sy e2, sz ẑ)` of the site's frame, `s = ±1`.
    fn reset_to_octant(&mut self, sx: f64, sy: f64, sz: f64) {
        let (a, b, c) = ([sx, 0.0, 0.0], [0.0, sy, 0.0], [0.0, 0.0, sz]);
        if sx * sy * sz > 0.0 {
            self.reset(&[a, b, c]);
        } else {
            self.reset(&[b, a, c]);
        }
    }

    /// Keep the side `n·x ≤ 0` of a great circle, tagging its arc `face`
    /// (Sutherland–Hodgman on the sphere: every edge is shorter than a half circle, so a
    /// positive combination of its ends is on it). A vertex on the circle counts as inside.
    pub(super) fn clip(&mut self, n: [f64; 3], face: Face) {
        let count = self.vertices.len();
        if count == 0 {
            return;
        }
        if self.vertices.iter().all(|&v| dot(n, v) <= 0.0) {
            // Nothing cut; an edge with both ends on the circle lies on it (a circle
            // through the start polygon's edge: an antipodal site's bisector).
            for k in 0..count {
                let (a, b) = (self.vertices[k], self.vertices[(k + 1) % count]);
                if dot(n, a) == 0.0 && dot(n, b) == 0.0 {
                    (self.normals[k], self.faces[k]) = (n, face);
                }
            }
            return;
        }
        let mut vertices = std::mem::take(&mut self.spare_vertices);
        let mut normals = std::mem::take(&mut self.spare_normals);
        let mut faces = std::mem::take(&mut self.spare_faces);
        vertices.clear();
        normals.clear();
        faces.clear();
        let mut di = dot(n, self.vertices[0]);
        for k in 0..count {
            let (vi, ni, fi) = (self.vertices[k], self.normals[k], self.faces[k]);
            let vj = self.vertices[(k + 1) % count];
            let dj = dot(n, vj);
            let inside_i = di <= 0.0;
            if inside_i {
                vertices.push(vi);
                normals.push(ni);
                faces.push(fi);
            }
            if inside_i && dj > 0.0 {
                // Leaving: the next edge lies on the circle.
                if di < 0.0 {
                    vertices.push(crossing(vi, vj, di, dj));
                    normals.push(n);
                    faces.push(face);
                } else if let (Some(last_n), Some(last_f)) = (normals.last_mut(), faces.last_mut())
                {
                    (*last_n, *last_f) = (n, face); // vi is on the circle already
                }
            } else if !inside_i && dj < 0.0 {
                // Entering: the old edge goes on from the crossing.
                vertices.push(crossing(vi, vj, di, dj));
                normals.push(ni);
                faces.push(fi);
            }
            di = dj;
        }
        if vertices.len() < 3 {
            vertices.clear();
            normals.clear();
            faces.clear();
        }
        self.spare_vertices = std::mem::replace(&mut self.vertices, vertices);
        self.spare_normals = std::mem::replace(&mut self.normals, normals);
        self.spare_faces = std::mem::replace(&mut self.faces, faces);
    }

    /// Clip by the great circle of every bisector plane of `cell` (relative to its site,
    /// in `frame`), then [`SphericalPolygon::polish`].
    fn clip_by_cell<C: ConvexCell<3>>(&mut self, cell: &C, frame: &SiteFrame) {
        self.clip_by_bisectors(cell, frame);
        self.polish();
    }

    /// Clip by the great circle of every bisector plane of `cell` (relative to its site,
    /// in `frame`), as they come: also a polygon that is not convex (a region's,
    /// `sphere_region.rs`), whose pieces along a circle then run both ways.
    pub(super) fn clip_by_bisectors<C: ConvexCell<3>>(&mut self, cell: &C, frame: &SiteFrame) {
        cell.for_each_plane(|face, h| {
            if let Face::Neighbor(_) = face {
                // The plane `q·v ≤ |q|²/2` relative to the site is `q·x ≤ 0` on the sphere:
                // its normal in the frame, with `q·ẑ = −|q|²/2` exactly for unit sites.
                let q = h.normal;
                self.clip([dot(q, frame.e1), dot(q, frame.e2), -h.offset], face);
            }
        });
    }

    /// Recompute each vertex as the meeting point of its two circles, `n_{k−1} × n_k`
    /// normalised: in the frame their components are exact to relative round-off, so the
    /// vertex is too, where the clip's interpolation along an arc from a far start corner
    /// is only exact to round-off of the sphere's size. Circles meeting at less than about
    /// 1e-8 radians leave the vertex as clipped.
    fn polish(&mut self) {
        let m = self.vertices.len();
        for k in 0..m {
            let (a, b) = (self.normals[(k + m - 1) % m], self.normals[k]);
            let w = cross(a, b);
            let w2 = norm2(w);
            if w2 > 1e-16 * norm2(a) * norm2(b) {
                let w = scale(w, 1.0 / w2.sqrt());
                let v = self.vertices[k];
                self.vertices[k] = if dot(w, v) >= 0.0 { w } else { scale(w, -1.0) };
            }
        }
    }

    fn is_empty(&self) -> bool {
        self.vertices.len() < 3
    }

    /// An edge of the start polygon is left: the cell may go on beyond it.
    fn reaches_start(&self) -> bool {
        self.faces.contains(&Face::Box)
    }

    /// `max_k (1 − v_k·ẑ)` over the vertices of a polygon above the equator: how deep the
    /// cap holding it is (`|x − ẑ|² = 2 (1 − x·ẑ)` on the polygon is largest at a vertex).
    pub(super) fn depth(&self) -> f64 {
        self.vertices
            .iter()
            .map(|&v| {
                let u = unit(v);
                (u[0] * u[0] + u[1] * u[1]) / (1.0 + u[2])
            })
            .fold(0.0, f64::max)
    }
}

/// The point where the arc from `a` (`n·a = da`) to `b` (`n·b = db`, of the other sign)
/// crosses the great circle, normalised: interpolated along the chord like a 2D cell's
/// crossing, so that it stays on the arc when `a` and `b` are close.
fn crossing(a: [f64; 3], b: [f64; 3], da: f64, db: f64) -> [f64; 3] {
    let t = da / (da - db);
    unit(add(a, scale(sub(b, a), t)))
}

pub(super) fn unit(v: [f64; 3]) -> [f64; 3] {
    scale(v, 1.0 / norm2(v).sqrt())
}

/// `θ − sin θ`, to relative round-off for small `θ` too (its Taylor series below 0.5).
fn theta_minus_sin(t: f64) -> f64 {
    if t >= 0.5 {
        return t - t.sin();
    }
    let u = t * t;
    // θ³/6 · (1 − θ²/20 (1 − θ²/42 (1 − θ²/72 (1 − …)))): term ratios θ²/((2k+2)(2k+3)).
    let mut s = 1.0;
    for den in [272.0, 210.0, 156.0, 110.0, 72.0, 42.0, 20.0] {
        s = 1.0 - u / den * s;
    }
    t * u / 6.0 * s
}

/// `atan x − x`, to relative round-off for small `x` too (its Taylor series below 0.1).
fn atan_minus_x(x: f64) -> f64 {
    if x.abs() >= 0.1 {
        return x.atan() - x;
    }
    let u = x * x;
    // Σ_{k≥1} (−1)^k x^(2k+1) / (2k+1), by Horner in u = x²; x² ≤ 0.01, nine terms.
    let mut s = 0.0;
    for k in (1..=9).rev() {
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        s = u * (sign / (2 * k + 1) as f64 + s);
    }
    x * s
}

/// What [`measure_polygons`] sums: area, the first moment's components along `e1`, `e2`
/// (`∫x·e = ∫(x − ẑ)·e`), and the energy `∫ |x − ẑ|²`.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Sums {
    pub(super) area: f64,
    pub(super) first: [f64; 2],
    pub(super) energy: f64,
}

impl Sums {
    /// The moments about the site of `frame`: mass `A`, first `M − A ẑ` (whose `ẑ` part is
    /// `−E/2` on the sphere), second the energy `E`.
    pub(super) fn moments(&self, frame: &SiteFrame) -> Moments<3> {
        Moments {
            mass: self.area,
            first: frame.global([self.first[0], self.first[1], -0.5 * self.energy]),
            second: self.energy,
        }
    }

    pub(super) fn add(&mut self, piece: Sums) {
        self.area += piece.area;
        self.first = [
            self.first[0] + piece.first[0],
            self.first[1] + piece.first[1],
        ];
        self.energy += piece.energy;
    }
}

/// A polygon above the site's equator holding the site (the cap's polygon, or a piece in
/// an upper octant, whose corner `ẑ` is the site), by the closed forms of the module
/// docs; its arcs are added to `faces`.
pub(super) fn measure_upper(
    poly: &SphericalPolygon,
    frame: &SiteFrame,
    faces: &mut FaceSums<3>,
    arcs: Option<ArcRow<'_>>,
) -> Sums {
    let keep_pieces = faces.weighted.is_on();
    let n = poly.vertices.len();
    let mut sums = Sums::default();
    if n < 3 {
        return sums;
    }
    // y = v − ẑ with 1 − v·ẑ = (v1² + v2²)/(1 + v·ẑ): no cancellation near the site.
    let y = |k: usize| {
        let u = unit(poly.vertices[k % n]);
        [u[0], u[1], -(u[0] * u[0] + u[1] * u[1]) / (1.0 + u[2])]
    };
    let mut ya = y(0);
    for k in 0..n {
        let yb = y(k + 1);
        let c = cross(ya, yb);
        let d = sub(yb, ya);
        let dd = norm2(d);
        // v_a × v_b = ẑ × d + y_a × y_b.
        let w = [c[0] - d[1], c[1] + d[0], c[2]];
        let sin_theta = norm2(w).sqrt();
        if sin_theta > 0.0 {
            let theta = 2.0 * (0.5 * dd.sqrt()).min(1.0).asin();
            let normal = scale(w, 1.0 / sin_theta);
            let tms = theta_minus_sin(theta);
            sums.first[0] += 0.5 * (c[0] + tms * normal[0]);
            sums.first[1] += 0.5 * (c[1] + tms * normal[1]);
            let (a, b) = (poly.vertices[k], poly.vertices[(k + 1) % n]);
            add_arc(faces, arcs, poly.faces[k], [unit(a), unit(b)], theta);
            // Fan triangle (ẑ, v_a, v_b): det = c[2], and 4 − den from the y's.
            let rest = 0.5 * dd - ya[2] - yb[2];
            let den = 4.0 - rest;
            let x = c[2] / den;
            sums.area += 2.0 * x.atan();
            sums.energy += 4.0 * atan_minus_x(x) + c[2] * rest / den - tms * normal[2];
            if keep_pieces {
                let y = [[0.0; 3], frame.global(ya), frame.global(yb)];
                (faces.weighted.cones).push(sphere_density::triangle(frame.z, y));
            }
        }
        ya = yb;
    }
    sums
}

/// A piece below the site's equator (a cell reaching past it: few or clustered sites),
/// plainly: fan from its first vertex, `½ Σ θ_k n_k`; its arcs are added to
/// `faces`. Its arcs along the octants' sides cancel those of the neighbouring pieces in
/// the first moment.
pub(super) fn measure_lower(
    poly: &SphericalPolygon,
    frame: &SiteFrame,
    faces: &mut FaceSums<3>,
    arcs: Option<ArcRow<'_>>,
) -> Sums {
    let n = poly.vertices.len();
    if n < 3 {
        return Sums::default();
    }
    let v = |k: usize| unit(poly.vertices[k % n]);
    let (mut area, mut first) = (0.0, [0.0; 3]);
    let v0 = v(0);
    for k in 1..n.saturating_sub(1) {
        let (a, b) = (v(k), v(k + 1));
        let det = dot(v0, cross(a, b));
        area += 2.0 * det.atan2(1.0 + dot(v0, a) + dot(a, b) + dot(b, v0));
        if faces.weighted.is_on() && det != 0.0 {
            let y = [v0, a, b].map(|v| sub(frame.global(v), frame.z));
            (faces.weighted.cones).push(sphere_density::triangle(frame.z, y));
        }
    }
    for k in 0..n {
        let (a, b) = (v(k), v(k + 1));
        let w = cross(a, b);
        let s = norm2(w).sqrt();
        if s > 0.0 {
            let theta = s.atan2(dot(a, b));
            first = add(first, scale(w, 0.5 * theta / s));
            add_arc(faces, arcs, poly.faces[k], [a, b], theta);
        }
    }
    Sums {
        area,
        first: [first[0], first[1]],
        energy: 2.0 * (area - first[2]),
    }
}

/// A row's face integrand (the optimiser's Hessian) and the frame of its site: what
/// [`add_arc`] needs to hand the integrand each arc's moments.
#[derive(Clone, Copy)]
pub(super) struct ArcRow<'a> {
    row: FaceRow<'a, 3>,
    frame: &'a SiteFrame,
}

/// Add the arc from `ends[0]` to `ends[1]` (unit, in the site's frame, `theta` long, made by
/// `face`) to `faces`: its length, and with `arcs` its moments about the site
/// ([`arc_moments`]) for the row's integrand. With a density the moments are ρ-weighted
/// ([`arc_nodes`]): a polynomial's at once, a field's once it is sampled (the arc waits in
/// the cell's weighted sums, its entry in the row zero until then).
fn add_arc(
    faces: &mut FaceSums<3>,
    arcs: Option<ArcRow<'_>>,
    face: Face,
    ends: [[f64; 3]; 2],
    theta: f64,
) {
    let (Some(arcs), Face::Neighbor(j)) = (arcs, face) else {
        faces.add(face, theta);
        return;
    };
    let local = arc_moments(ends[0], ends[1], theta);
    let geometric = arcs.frame.global_moments(&local);
    if !faces.weighted.is_on() {
        faces.add_moments(face, 1.0, &geometric, arcs.row);
        return;
    }
    let arc = FaceNodes {
        neighbor: j,
        nodes: arc_nodes(ends, theta).map(|(y, w)| (arcs.frame.global(y), w)),
        geometric,
    };
    match faces.weighted.polynomial_about_site() {
        Some(rho) => {
            let values = arc.nodes.map(|(y, _)| rho.value(y));
            let weighted = arc.weighted(&values);
            faces.add_weighted_moments(face, 1.0, theta, &weighted, arcs.row);
        }
        None => {
            let zero = FaceMoments::zero();
            faces.add_weighted_moments(face, 1.0, theta, &zero, arcs.row);
            faces.weighted.faces.push(arc);
        }
    }
}

/// The nodes `y = x − ẑ` of the 3-point Gauss–Legendre rule ([`SEGMENT_5`]) on the arc
/// from `ends[0]` to `ends[1]` (unit, in the site's frame, `theta < π` long), with their
/// weights (arc length): along the arc as [`arc_moments`] writes it, no cancellation. The
/// rule is of degree 5 in the arc's angle: a polynomial ρ of degree 2 makes `ρ y yᵀ` a
/// trigonometric polynomial of degree 4 in it, integrated to a relative `O(θ⁶)`.
fn arc_nodes(ends: [[f64; 3]; 2], theta: f64) -> [([f64; 3], f64); FACE_NODES] {
    let [a, b] = ends;
    let n = cross(a, b);
    let u = cross(scale(n, 1.0 / norm2(n).sqrt()), a);
    let ya = [a[0], a[1], -(a[0] * a[0] + a[1] * a[1]) / (1.0 + a[2])];
    std::array::from_fn(|k| {
        let t = theta * SEGMENT_5.points[k];
        let (s, c) = t.sin_cos();
        let w = 2.0 * (0.5 * t).sin().powi(2);
        let y = [
            ya[0] * c + u[0] * s,
            ya[1] * c + u[1] * s,
            ya[2] * c + u[2] * s - w,
        ];
        (y, theta * SEGMENT_5.weights[k])
    })
}

/// The length, `∫ y ds` and `∫ y yᵀ ds` (`y = x − ẑ`) of the great-circle arc from `a` to
/// `b` (unit, in the site's frame, `theta < π` long).
///
/// Along the arc `x(t) = a cos t + u sin t` (`u = n × a`, `n` the unit normal of `a × b`),
/// so `y(t) = y_a c + u s − ẑ w` with `c = cos t`, `s = sin t`, `w = 1 − cos t` and
/// `y_a = a − ẑ`: every term of the cell's size, no cancellation. The products' integrals
/// over `[0, θ]` are written through `τ(θ) = θ − sin θ` ([`theta_minus_sin`]) and powers of
/// `sin(θ/2)`, which keep their relative precision for short arcs (`∫w² = 2τ(θ) − τ(2θ)/4
/// ~ θ⁵/20` cancels, but only below `1e-16 θ³` absolute, the scale of `∫ y yᵀ`).
fn arc_moments(a: [f64; 3], b: [f64; 3], theta: f64) -> FaceMoments<3> {
    let n = cross(a, b);
    let u = cross(scale(n, 1.0 / norm2(n).sqrt()), a);
    let ya = [a[0], a[1], -(a[0] * a[0] + a[1] * a[1]) / (1.0 + a[2])];
    let z = [0.0, 0.0, 1.0];
    let (sin, half) = (theta.sin(), (0.5 * theta).sin());
    let (tau, tau2) = (theta_minus_sin(theta), theta_minus_sin(2.0 * theta));
    let int_c = sin;
    let int_s = 2.0 * half * half;
    let int_w = tau;
    let int_ss = 0.25 * tau2;
    let int_cc = theta - int_ss;
    let int_cs = 0.5 * sin * sin;
    let int_ww = 2.0 * tau - 0.25 * tau2;
    let int_cw = 0.25 * tau2 - tau;
    let int_sw = 2.0 * half.powi(4);
    let first = std::array::from_fn(|r| ya[r] * int_c + u[r] * int_s - z[r] * int_w);
    let second = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            ya[r] * ya[c] * int_cc
                + u[r] * u[c] * int_ss
                + z[r] * z[c] * int_ww
                + (ya[r] * u[c] + u[r] * ya[c]) * int_cs
                - (ya[r] * z[c] + z[r] * ya[c]) * int_cw
                - (u[r] * z[c] + z[r] * u[c]) * int_sw
        })
    });
    FaceMoments {
        measure: theta,
        first,
        second,
    }
}

// This thread's polygon, reused from cell to cell ([`with_scratch`]).
thread_local! {
    static POLYGON: RefCell<SphericalPolygon> = RefCell::new(SphericalPolygon::default());
}

/// The cell's polygon in the cap around its site (`poly`), and whether it lies there:
/// no edge of the cap is left.
pub(super) fn cap_polygon<C: ConvexCell<3>>(
    poly: &mut SphericalPolygon,
    cell: &C,
    frame: &SiteFrame,
) -> bool {
    poly.reset(&CAP);
    poly.clip_by_cell(cell, frame);
    !poly.is_empty() && !poly.reaches_start()
}

/// The moments about the site's direction of the spherical polygon cut out by `cell`'s
/// bisectors, its arcs measured into `faces`: the cap's polygon for a cell within 45° of
/// its site, else the cell's pieces in the eight octants of the site's frame (each inside
/// an open hemisphere, as the clipper needs), summed.
fn measure_polygons<C: ConvexCell<3>>(
    cell: &C,
    site: [f64; 3],
    faces: &mut FaceSums<3>,
    row: Option<FaceRow<'_, 3>>,
) -> Moments<3> {
    faces.clear();
    let frame = SiteFrame::at(site);
    let arcs = row.map(|row| ArcRow { row, frame: &frame });
    let sums = with_scratch(&POLYGON, |poly| {
        if cap_polygon(poly, cell, &frame) {
            return measure_upper(poly, &frame, faces, arcs);
        }
        let mut sums = Sums::default();
        for sz in [1.0, -1.0] {
            for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
                poly.reset_to_octant(sx, sy, sz);
                poly.clip_by_cell(cell, &frame);
                let piece = if sz > 0.0 {
                    measure_upper(poly, &frame, faces, arcs)
                } else {
                    measure_lower(poly, &frame, faces, arcs)
                };
                sums.add(piece);
            }
        }
        sums
    });
    let moments = sums.moments(&frame);
    if let Some(local) = faces.weighted.polynomial_about_site() {
        // A polynomial is sampled here, at the sampled rule's nodes of degree 5.
        let rule = TRIANGLE_5;
        let w = &faces.weighted;
        let values: Vec<f64> = (w.cones.iter())
            .flat_map(|cone| {
                rule.nodes()
                    .map(move |(l, _)| local.value(node_at(site, cone, l)))
            })
            .collect();
        let weighted = sphere_density::weighted_moments(site, &w.cones, &rule, &values, &moments);
        faces.weighted.moments = weighted;
    }
    moments
}

/// `max |x − site|²` over the points of the sphere in the cap of depth `depth` around the
/// site (`|x − ẑ|² = 2δ` at its rim), a little more; 4 (the whole sphere) without one.
pub(super) fn radius2_within_depth(site: [f64; 3], depth: Option<f64>) -> f64 {
    let chord = depth.map_or(2.0, |d| (2.0 * d).sqrt());
    let off = (norm2(site).sqrt() - 1.0).abs();
    (chord + off).powi(2) * (1.0 + 1e-12)
}

/// Cut the cone `cell` of `site` to the slab `1 − 2δ ≤ x·ẑ ≤ 1` (`δ` = `depth`) around
/// the cap that holds its part on the sphere (module docs, "Stopping early").
pub(super) fn cut_to_slab<C: ConvexCell<3>>(
    cell: &mut C,
    site: [f64; 3],
    frame: &SiteFrame,
    depth: f64,
) {
    // Absolute `x·ẑ ≤ 1` and `x·ẑ ≥ 1 − 2δ`, relative to the site at `x·ẑ = |site|`.
    let r = norm2(site).sqrt();
    let top = HalfSpace {
        normal: frame.z,
        offset: 1.0 - r,
    };
    let bottom = HalfSpace {
        normal: scale(frame.z, -1.0),
        offset: r - (1.0 - 2.0 * depth),
    };
    cell.clip(&top, Face::Boundary(0));
    cell.clip(&bottom, Face::Boundary(1));
}

/// The node of `lambda` in the piece `cone` of the cell of `site`, relative to the site.
fn node_at(site: [f64; 3], cone: &Cone<3>, lambda: &[f64]) -> [f64; 3] {
    sphere_density::node(sphere_density::direction(site), cone, lambda).0
}

impl DomainKind<3> for Sphere {
    fn bounds(&self) -> Aabb<3> {
        Aabb {
            lo: [-1.0; 3],
            hi: [1.0; 3],
        }
    }

    /// The area `4π`: the mean spacing is `(4π/n)^{1/2}`.
    fn volume(&self) -> f64 {
        4.0 * std::f64::consts::PI
    }

    /// 1 on the sphere (within [`ON_SPHERE_TOL`]), 0 elsewhere: the driver refuses other
    /// sites by row. There is no boundary.
    fn locate(&self, point: &[f64; 3]) -> Option<i32> {
        Some(i32::from(
            (norm2(*point) - 1.0).abs() <= 2.0 * ON_SPHERE_TOL,
        ))
    }

    fn density_checkpoints(&self) -> &[[f64; 3]] {
        &[]
    }

    /// Not convex, but a cell may be cut early all the same ([`DomainKind::cut_convex`]).
    fn is_convex(&self) -> bool {
        true
    }

    /// Cut the cone to the slab around the cap holding its polygon (module docs), when the
    /// polygon lies within 45° of the site; otherwise (a cell still open to a large part
    /// of the sphere: its nearest sites all on one side) leave it to stream on. Always
    /// `false`: the slab was fitted to the polygon as it is now, and the next neighbours
    /// often cut off a long spike of it, so the driver asks again `PRECLIP_K` neighbours
    /// later and the slab shrinks with the cell (a slab cut once at 16 neighbours kept
    /// the radius of 0.15% of 20,000 random cells at the size of the sphere). The cell
    /// is measured by [`DomainKind::clip`].
    fn cut_convex<C: ConvexCell<3>>(&self, cell: &mut C, site: [f64; 3], _: &mut Vec<u32>) -> bool {
        let frame = SiteFrame::at(site);
        let depth = with_scratch(&POLYGON, |poly| {
            cap_polygon(poly, cell, &frame).then(|| poly.depth())
        });
        if let Some(depth) = depth {
            cut_to_slab(cell, site, &frame, depth);
        }
        false
    }

    /// `max |x − site|²` over the polygon, from its deepest vertex; 4 (the whole sphere)
    /// for a cell reaching beyond 45° of its site.
    fn local_radius2<C: ConvexCell<3>>(&self, cell: &C, site: [f64; 3]) -> f64 {
        let frame = SiteFrame::at(site);
        let depth = with_scratch(&POLYGON, |poly| {
            cap_polygon(poly, cell, &frame).then(|| poly.depth())
        });
        radius2_within_depth(site, depth)
    }

    fn clip<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        _: Option<i32>,
        row: Option<FaceRow<'_, 3>>,
        scratch: &mut MeasureScratch<3, C>,
    ) -> Moments<3> {
        measure_polygons(cell, site, &mut scratch.faces, row)
    }

    fn cell_dim(&self) -> usize {
        2
    }

    /// `∫ |x − c|²` about `c = M/|M|` on the sphere: `2 (A − |M|)`, with
    /// `A² − |M|² = A E − |m1|²` (`m1 = M − A ẑ`, `m1·ẑ = −E/2`) so that it keeps its
    /// digits: `2 (A E − |m1|²) / (A + |M|)`.
    fn central_second(&self, m: &Moments<3>) -> f64 {
        if m.mass <= 0.0 {
            return 0.0;
        }
        let s = (m.mass * m.second - norm2(m.first)).max(0.0);
        let big_m = (m.mass * m.mass - s).max(0.0).sqrt();
        2.0 * s / (m.mass + big_m)
    }

    fn tangent(&self, site: [f64; 3], v: [f64; 3]) -> [f64; 3] {
        let z = scale(site, 1.0 / norm2(site).sqrt());
        sub(v, scale(z, dot(v, z)))
    }

    /// `x·g` at the unit vector `x` (the sphere's outward normal at `x`): for the CVT
    /// energy, whose ambient gradient is `g_i = 2 (A_i x_i − ∫x)`, the cell's energy
    /// `∫|x − x_i|²`.
    fn curvature_term(&self, site: [f64; 3], gradient: [f64; 3]) -> f64 {
        dot(site, gradient) / norm2(site).sqrt()
    }

    /// No boundary, and icosahedral starts lie near a CVT.
    fn trusts_newton(&self) -> bool {
        true
    }

    /// The Riemannian Hessian (arc face moments, [`DomainKind::curvature_term`]).
    fn sums_hessian(&self) -> bool {
        true
    }

    /// The rule's point on the sphere (`sphere_density.rs`).
    fn sampled_node(&self, site: [f64; 3], cone: &Cone<3>, lambda: &[f64]) -> [f64; 3] {
        node_at(site, cone, lambda)
    }

    /// The rule's sums with the constant part exact (`sphere_density.rs`).
    fn sampled_moments(
        &self,
        site: [f64; 3],
        cones: &[Cone<3>],
        rule: &Rule,
        values: &[f64],
        geometric: &Moments<3>,
    ) -> Moments<3> {
        sphere_density::weighted_moments(site, cones, rule, values, geometric)
    }

    fn retract(&self, x: [f64; 3]) -> [f64; 3] {
        let r2 = norm2(x);
        if r2 > 0.0 {
            scale(x, 1.0 / r2.sqrt())
        } else {
            x
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::diagram::{clipped_cells, clipped_diagram, PolyhedronCell, Request};
    use crate::error::CoreError;
    use std::f64::consts::PI;

    /// Uniform random unit vectors from a fixed generator (Marsaglia's normals).
    pub(crate) fn random_sites(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let v = [
                2.0 * uniform() - 1.0,
                2.0 * uniform() - 1.0,
                2.0 * uniform() - 1.0,
            ];
            let r2 = norm2(v);
            if r2 > 1e-6 && r2 <= 1.0 {
                out.push(scale(v, 1.0 / r2.sqrt()));
            }
        }
        out
    }

    /// The 12 vertices of the icosahedron, unit.
    fn icosahedron() -> Vec<[f64; 3]> {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut v = Vec::new();
        for a in [-1.0, 1.0] {
            for b in [-t, t] {
                v.push([0.0, a, b]);
                v.push([a, b, 0.0]);
                v.push([b, 0.0, a]);
            }
        }
        v.into_iter().map(unit).collect()
    }

    fn diagram(sites: &[[f64; 3]]) -> crate::diagram::Diagram<3> {
        clipped_diagram::<3, PolyhedronCell, _>(&Sphere, sites, &Request::default())
            .unwrap()
            .diagram
    }

    #[test]
    fn the_frame_is_orthonormal_and_right_handed() {
        for site in random_sites(50, 3).into_iter().chain([[0.0, 0.0, -1.0]]) {
            let f = SiteFrame::at(site);
            let m = [f.e1, f.e2, f.z];
            for (a, u) in m.iter().enumerate() {
                for (b, v) in m.iter().enumerate() {
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!((dot(*u, *v) - want).abs() < 1e-15);
                }
            }
            assert!((dot(cross(f.e1, f.e2), f.z) - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn the_series_agree_with_the_plain_forms() {
        for t in [1e-3, 0.01, 0.1, 0.3, 0.4999] {
            let (a, b) = (theta_minus_sin(t), t - t.sin());
            assert!(
                (a - b).abs() <= 1e-15 * t.powi(3).max(1e-300) + 1e-16 * t,
                "{t}"
            );
        }
        for x in [1e-3, 0.01, 0.05, 0.0999, -0.07] {
            let (a, b) = (atan_minus_x(x), x.atan() - x);
            assert!((a - b).abs() <= 1e-15 * x.abs().powi(3) + 1e-17, "{x}");
        }
        // Where the plain forms have lost every digit, the series keep them.
        let t: f64 = 1e-6;
        let want = t.powi(3) / 6.0 * (1.0 - t * t / 20.0);
        assert!((theta_minus_sin(t) / want - 1.0).abs() < 1e-15);
        let want = -t.powi(3) / 3.0 * (1.0 - 0.6 * t * t);
        assert!((atan_minus_x(t) / want - 1.0).abs() < 1e-15);
    }

    /// The icosahedron's 12 cells are regular pentagons of area 4π/12; each has 5
    /// neighbours, its arcs are all the same, and Σ areas = 4π.
    #[test]
    fn the_icosahedron_has_twelve_regular_pentagons() {
        let sites = icosahedron();
        let d = diagram(&sites);
        // Pentagon edge: the dodecahedron's, arc between adjacent face centres' duals.
        let arcs = &d.neighbor_measures;
        for (i, m) in d.moments.iter().enumerate() {
            assert!((m.mass - PI / 3.0).abs() < 1e-14, "cell {i}: {}", m.mass);
            let deg = d.neighbor_offsets[i + 1] - d.neighbor_offsets[i];
            assert_eq!(deg, 5, "cell {i}");
            // Centroid on the site's ray: no tangential first moment.
            let t = Sphere.tangent(sites[i], m.first);
            assert!(norm2(t).sqrt() < 1e-15, "cell {i}: {t:?}");
        }
        // The dodecahedron's edge seen from the centre: cos θ = √5/3.
        let theta = (5f64.sqrt() / 3.0).acos();
        for a in arcs {
            assert!((a - theta).abs() < 1e-14, "{a} {theta}");
        }
        let total: f64 = d.volumes().iter().sum();
        assert!((total - 4.0 * PI).abs() < 1e-14);
    }

    /// Random sites: Σ areas = 4π to 1e-13, Σ (M − A z) + A z = Σ M = 0 (the sphere's
    /// first moment), and every arc is listed by both its cells with the same length.
    #[test]
    fn random_cells_tile_the_sphere() {
        for (n, seed) in [(5, 1), (17, 2), (100, 3), (2000, 4)] {
            let sites = random_sites(n, seed);
            let d = diagram(&sites);
            let total: f64 = d.volumes().iter().sum();
            assert!((total - 4.0 * PI).abs() < 1e-13 * 4.0 * PI, "{n}: {total}");
            let m = (d.moments.iter().zip(&sites)).fold([0.0; 3], |s, (m, &z)| {
                add(s, add(m.first, scale(z, m.mass)))
            });
            assert!(norm2(m).sqrt() < 1e-13, "{n}: {m:?}");
            for i in 0..n {
                for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                    let j = d.neighbor_sites[e] as usize;
                    let back = (d.neighbor_offsets[j]..d.neighbor_offsets[j + 1])
                        .find(|&f| d.neighbor_sites[f] as usize == i)
                        .unwrap_or_else(|| panic!("{n}: {i}–{j} one-sided"));
                    let (a, b) = (d.neighbor_measures[e], d.neighbor_measures[back]);
                    assert!((a - b).abs() < 1e-13, "{n}: {i}–{j}: {a} {b}");
                }
            }
            // Euler on the sphere: V − E + F = 2 with trivalent vertices, so E = 3F − 6.
            assert_eq!(d.neighbor_sites.len(), 2 * (3 * n - 6), "{n}");
        }
    }

    /// Two antipodal sites split the sphere into hemispheres; three on the equator into
    /// lunes of 4π/3; a cell reaching past its site's equator (one site against a cluster)
    /// is measured through the octants, against a quadrature.
    #[test]
    fn cells_past_their_sites_equator_are_measured() {
        let d = diagram(&[[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]);
        for m in &d.moments {
            assert!((m.mass - 2.0 * PI).abs() < 1e-14);
            // ∫(x − z) over a hemisphere: −π z (the centroid at height 1/2): energy 2π.
            assert!((m.second - 2.0 * PI).abs() < 1e-14);
        }
        assert!((d.moments[0].first[2] + PI).abs() < 1e-14);
        assert!((d.neighbor_measures[0] - 2.0 * PI).abs() < 1e-14);
        let third = 2.0 * PI / 3.0;
        let sites: Vec<[f64; 3]> = (0..3)
            .map(|k| [(k as f64 * third).cos(), (k as f64 * third).sin(), 0.0])
            .collect();
        let d = diagram(&sites);
        for m in &d.moments {
            assert!((m.mass - 4.0 * PI / 3.0).abs() < 1e-14);
        }
        // A site on the equator against a cluster at the north pole: its cell reaches
        // far below its own equator (measured through the octants of its frame).
        let mut sites: Vec<[f64; 3]> = (0..5)
            .map(|k| {
                let a = k as f64 * 2.0 * PI / 5.0;
                unit([0.2 * a.cos(), 0.2 * a.sin(), 1.0])
            })
            .collect();
        sites.push([1.0, 0.0, 0.0]);
        let d = diagram(&sites);
        let total: f64 = d.volumes().iter().sum();
        assert!((total - 4.0 * PI).abs() < 1e-13);
        let (area, first, energy) = lat_lon_quadrature(&sites, 5, 2000);
        let m = &d.moments[5];
        assert!(m.mass > 5.0, "{}", m.mass);
        assert!((area - m.mass).abs() < 1e-4 * m.mass, "{area} {}", m.mass);
        for c in 0..3 {
            assert!(
                (first[c] - m.first[c]).abs() < 1e-4 * m.mass,
                "{first:?} {:?}",
                m.first
            );
        }
        assert!(
            (energy - m.second).abs() < 1e-4 * m.second,
            "{energy} {}",
            m.second
        );
    }

    /// Area, `∫(x − z)` and `∫|x − z|²` over cell `i`, by the midpoint rule on a
    /// latitude-longitude grid of `k × 2k` over the whole sphere.
    fn lat_lon_quadrature(sites: &[[f64; 3]], i: usize, k: usize) -> (f64, [f64; 3], f64) {
        let z = sites[i];
        let (dt, dp) = (PI / k as f64, PI / k as f64);
        let (mut area, mut first, mut energy) = (0.0, [0.0; 3], 0.0);
        for a in 0..k {
            let t = (a as f64 + 0.5) * dt;
            for b in 0..2 * k {
                let p = (b as f64 + 0.5) * dp;
                let x = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
                if sites.iter().any(|&s| dot(x, s) > dot(x, z)) {
                    continue;
                }
                let da = t.sin() * dt * dp;
                area += da;
                first = add(first, scale(sub(x, z), da));
                energy += norm2(sub(x, z)) * da;
            }
        }
        (area, first, energy)
    }

    /// The first moment and the energy of one cell against a fine quadrature: the cell
    /// mapped from the gnomonic plane (`x = (w + ẑ)/√(1 + |w|²)`, `dA = (1 + |w|²)^{-3/2}
    /// dw`), midpoint rule on a fine grid over the cell's gnomonic image.
    #[test]
    fn moments_match_a_quadrature() {
        let sites = random_sites(40, 9);
        let d = diagram(&sites);
        let i = 7;
        let z = sites[i];
        let frame = SiteFrame::at(z);
        // The cell: points closer to z than to every other site.
        let inside = |x: [f64; 3]| sites.iter().all(|&s| dot(x, s) <= dot(x, z) + 1e-300);
        let (k, half) = (1600, 1.5);
        let step = 2.0 * half / k as f64;
        let (mut area, mut first, mut energy) = (0.0, [0.0; 3], 0.0);
        for a in 0..k {
            for b in 0..k {
                let w = [
                    -half + (a as f64 + 0.5) * step,
                    -half + (b as f64 + 0.5) * step,
                ];
                let r2 = w[0] * w[0] + w[1] * w[1];
                let x = frame.global(scale([w[0], w[1], 1.0], 1.0 / (1.0 + r2).sqrt()));
                if !inside(x) {
                    continue;
                }
                let da = step * step / (1.0 + r2).powf(1.5);
                area += da;
                first = add(first, scale(sub(x, z), da));
                energy += norm2(sub(x, z)) * da;
            }
        }
        let m = &d.moments[i];
        // The midpoint rule's error on a cell's staircase edge: ~1e-3 relative at 1600².
        assert!((area - m.mass).abs() < 2e-3 * m.mass, "{area} {}", m.mass);
        let size = m.mass * m.mass.sqrt();
        for c in 0..3 {
            assert!(
                (first[c] - m.first[c]).abs() < 5e-3 * size,
                "{first:?} {:?}",
                m.first
            );
        }
        assert!((energy - m.second).abs() < 5e-3 * m.second);
    }

    /// A cell's neighbours are found among O(1) sites: every cell of 20,000 random sites
    /// and of a tiny cluster depends on the sites within a few spacings only.
    #[test]
    fn cells_read_sites_within_a_few_spacings() {
        let n = 20_000;
        let sites = random_sites(n, 5);
        let own: Vec<u32> = (0..n as u32).collect();
        let part = clipped_cells::<3, PolyhedronCell, _>(
            &Sphere,
            &sites,
            &own,
            n,
            &Request::default(),
            None,
        )
        .unwrap();
        let h2 = 4.0 * PI / n as f64;
        let worst = part.reach2.iter().fold(0.0_f64, |m, &r| m.max(r)) / h2;
        let mean = part.reach2.iter().sum::<f64>() / n as f64 / h2;
        // Reach² in spacings²: πr² of them hold about that many sites times π.
        assert!(worst < 25.0, "worst reach² {worst} spacings²");
        assert!(mean < 7.0, "mean reach² {mean} spacings²");
    }

    /// The icosahedron's vertices subdivided `k` times: `10·4^k + 2` unit vectors.
    fn icosahedral(k: usize) -> Vec<[f64; 3]> {
        let mut v = icosahedron();
        // The 20 faces: triples of vertices pairwise at the edge length.
        let edge2 = (0..12).map(|j| norm2(sub(v[0], v[j]))).filter(|&d| d > 0.0);
        let edge2 = edge2.fold(f64::INFINITY, f64::min) * (1.0 + 1e-9);
        let near = |a: [f64; 3], b: [f64; 3]| norm2(sub(a, b)) <= edge2;
        let mut faces = Vec::new();
        for a in 0..12 {
            for b in a + 1..12 {
                for c in b + 1..12 {
                    if near(v[a], v[b]) && near(v[b], v[c]) && near(v[a], v[c]) {
                        faces.push([a, b, c]);
                    }
                }
            }
        }
        assert_eq!(faces.len(), 20);
        for _ in 0..k {
            let mut mids = std::collections::HashMap::new();
            let mut mid = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| {
                *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push(unit(add(v[a], v[b])));
                    v.len() - 1
                })
            };
            let mut next = Vec::new();
            for [a, b, c] in faces {
                let (ab, bc, ca) = (mid(a, b, &mut v), mid(b, c, &mut v), mid(c, a, &mut v));
                next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
            }
            faces = next;
        }
        v
    }

    /// Cells by number of sides, from the diagram's neighbour lists.
    fn sides(d: &crate::diagram::Diagram<3>) -> std::collections::BTreeMap<usize, usize> {
        let mut count = std::collections::BTreeMap::new();
        for i in 0..d.len() {
            *count
                .entry(d.neighbor_offsets[i + 1] - d.neighbor_offsets[i])
                .or_insert(0) += 1;
        }
        count
    }

    /// Icosahedral sites (k = 1, 2), jittered, go to a spherical CVT by Newton, L-BFGS and
    /// Lloyd, to the default rule, with exactly 12 pentagons and the rest hexagons; every
    /// site stays on the sphere and the energy goes down.
    #[test]
    fn icosahedral_sites_converge_to_twelve_pentagons() {
        use crate::optimise::{cvt, Method, Rule, Settings, StopReason};
        use std::ops::ControlFlow;
        for k in [1, 2] {
            let exact = icosahedral(k);
            let n = exact.len();
            assert_eq!(n, 10 * 4usize.pow(k as u32) + 2);
            // Jittered by a tenth of a spacing: the CVT must find the pattern again (k = 1
            // unjittered is a CVT already, by symmetry: every site on an axis of a rotation
            // of the icosahedron).
            let h = (4.0 * PI / n as f64).sqrt();
            let jitter = random_sites(n, 77 + k as u64);
            let sites: Vec<[f64; 3]> = (exact.iter().zip(&jitter))
                .map(|(&x, &r)| unit(add(x, scale(Sphere.tangent(x, r), 0.1 * h))))
                .collect();
            for method in [Method::Newton, Method::Lbfgs, Method::Lloyd] {
                let settings = Settings {
                    method,
                    max_iter: 2000,
                    ..Settings::default()
                };
                let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
                let out =
                    cvt::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &settings, go).unwrap();
                assert_eq!(out.stop_reason, StopReason::Converged, "{k} {method:?}");
                let last = out.history.last().unwrap();
                assert!(Rule::Gap.value(&last.measures) < 1e-7);
                assert!(last.energy < out.history[0].energy, "{k} {method:?}");
                let want = std::collections::BTreeMap::from([(5, 12), (6, n - 12)]);
                assert_eq!(sides(&out.diagram), want, "{k} {method:?}");
                for x in &out.sites {
                    assert!((norm2(*x) - 1.0).abs() < 1e-15);
                }
                // At the CVT every site is its cell's constrained centroid.
                for (m, &x) in out.diagram.moments.iter().zip(&out.sites) {
                    let c = Sphere.centroid(x, m);
                    assert!(norm2(sub(c, x)).sqrt() < 1e-5 * m.mass.sqrt());
                }
            }
        }
    }

    /// Random sites converge to the default rule by L-BFGS, and to the paper's rule too;
    /// every cell ends with 5 to 7 sides mostly, and Σ(6 − sides) = 12 (Euler).
    #[test]
    fn random_sites_converge() {
        use crate::optimise::{cvt, Method, Rule, Settings, StopReason};
        use std::ops::ControlFlow;
        let sites = random_sites(500, 8);
        for rule in [Rule::Gap, Rule::Paper] {
            let settings = Settings {
                method: Method::Lbfgs,
                rule,
                tol: rule.default_tol(),
                max_iter: 3000,
                ..Settings::default()
            };
            let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
            let out = cvt::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &settings, go).unwrap();
            assert_eq!(out.stop_reason, StopReason::Converged, "{rule:?}");
            let defect: i64 = sides(&out.diagram)
                .iter()
                .map(|(&s, &c)| (6 - s as i64) * c as i64)
                .sum();
            assert_eq!(defect, 12);
            // Mean G of a near-hexagonal spherical CVT: just above the flat hexagon's.
            let last = out.history.last().unwrap();
            assert!(
                last.mean_g > 0.0801 && last.mean_g < 0.0812,
                "{}",
                last.mean_g
            );
        }
        // Newton from random sites: to the same rule in fewer diagrams than L-BFGS.
        let mut diagrams = Vec::new();
        for method in [Method::Newton, Method::Lbfgs] {
            let settings = Settings {
                method,
                max_iter: 3000,
                ..Settings::default()
            };
            let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
            let out = cvt::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &settings, go).unwrap();
            assert_eq!(out.stop_reason, StopReason::Converged, "{method:?}");
            diagrams.push(out.evaluations());
        }
        assert!(
            diagrams[0] < diagrams[1],
            "Newton, L-BFGS diagrams: {diagrams:?}"
        );
    }

    /// The Riemannian Hessian (arc face terms, projected, with the curvature term) against
    /// central differences of the tangent gradient along the retraction
    /// `x(t) = (x + t v)/|x + t v|`: `P_x (g(t) − g(−t)) / 2t → Hess[v]`, per site.
    #[test]
    fn the_hessian_matches_differences_of_the_gradient() {
        use crate::optimise::{evaluate, PointRequest};
        // A cluster at the north pole and a site on the equator, whose cell reaches far
        // below its own equator (measured through the octants), then random sites.
        let mut cluster: Vec<[f64; 3]> = (0..5)
            .map(|k| {
                let a = k as f64 * 2.0 * PI / 5.0 + 0.1;
                unit([0.2 * a.cos(), 0.2 * a.sin(), 1.0])
            })
            .collect();
        cluster.push([1.0, 0.0, 0.0]);
        let cases = [
            (cluster, 5),
            (random_sites(60, 3), 3),
            (random_sites(400, 4), 4),
        ];
        for (sites, seed) in cases {
            let n = sites.len();
            let h = (4.0 * PI / n as f64).sqrt();
            let request = PointRequest {
                hessian: true,
                density: None,
            };
            let point = evaluate::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &request).unwrap();
            let v: Vec<[f64; 3]> = (random_sites(n, seed + 100).iter().zip(&sites))
                .map(|(&r, &x)| Sphere.tangent(x, r))
                .collect();
            let hv = point.hessian_product(&v).unwrap();
            let t = 1e-6 * h;
            let moved = |s: f64| {
                let x: Vec<[f64; 3]> = (sites.iter().zip(&v))
                    .map(|(&x, &d)| Sphere.retract(add(x, scale(d, s * t))))
                    .collect();
                evaluate::<3, PolyhedronCell, _>(&Sphere, x, &PointRequest::default())
                    .unwrap()
                    .gradient
            };
            let (plus, minus) = (moved(1.0), moved(-1.0));
            let scale_hv = hv.iter().map(|&r| norm2(r)).fold(0.0, f64::max).sqrt();
            let mut worst: f64 = 0.0;
            for i in 0..n {
                let fd = Sphere.tangent(sites[i], scale(sub(plus[i], minus[i]), 0.5 / t));
                worst = worst.max(norm2(sub(fd, hv[i])).sqrt() / scale_hv);
                // The Hessian maps into the tangent plane.
                assert!(dot(hv[i], sites[i]).abs() < 1e-13 * scale_hv);
            }
            let tol = 1e-7;
            assert!(worst < tol, "{n}: worst relative miss {worst:e}");
            // Without the curvature term the miss is of the cells' energy: far above that.
            let curvature: f64 =
                point.diagram.moments.iter().map(|m| m.second).sum::<f64>() / n as f64;
            let v_norm = v.iter().map(|&r| norm2(r)).fold(0.0, f64::max).sqrt();
            assert!(
                curvature * v_norm > 100.0 * tol * scale_hv,
                "{curvature} {v_norm} {scale_hv}"
            );
        }
    }

    /// The Riemannian Hessian (its arc terms and its projection in parallel) is the same
    /// bit for bit on 1 and 3 threads.
    #[test]
    fn the_hessian_does_not_depend_on_the_thread_count() {
        use crate::optimise::{evaluate, PointRequest};
        let sites = random_sites(3000, 6);
        let request = PointRequest {
            hessian: true,
            density: None,
        };
        let hessian = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                evaluate::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &request)
                    .unwrap()
                    .hessian
                    .unwrap()
            })
        };
        let (one, three) = (hessian(1), hessian(3));
        assert_eq!(one.diagonal, three.diagonal);
        assert_eq!(one.off_diagonal, three.off_diagonal);
    }

    /// An arc's moments about the site against a Gauss–Legendre rule along it.
    #[test]
    fn arc_moments_match_a_quadrature() {
        for (a, b) in [
            ([0.01, 0.02, 1.0], [-0.015, 0.012, 1.0]),
            ([0.3, -0.2, 0.9], [0.5, 0.4, 0.7]),
            ([1.0, 0.0, 0.0], [0.0, 0.7, -0.7]),
        ] {
            let (a, b) = (unit(a), unit(b));
            let theta = dot(a, b).clamp(-1.0, 1.0).acos();
            let m = arc_moments(a, b, theta);
            let n = unit(cross(a, b));
            let u = cross(n, a);
            // 20 Gauss–Legendre nodes on [0, θ].
            let (mut first, mut second) = ([0.0; 3], [[0.0; 3]; 3]);
            for (x, w) in gauss_legendre(20) {
                let w = w * 0.5 * theta;
                let tt = 0.5 * theta * (x + 1.0);
                let y = sub(add(scale(a, tt.cos()), scale(u, tt.sin())), [0.0, 0.0, 1.0]);
                for p in 0..3 {
                    first[p] += w * y[p];
                    for q in 0..3 {
                        second[p][q] += w * y[p] * y[q];
                    }
                }
            }
            let size = norm2(sub(a, [0.0, 0.0, 1.0])).max(norm2(sub(b, [0.0, 0.0, 1.0])));
            for p in 0..3 {
                assert!(
                    (first[p] - m.first[p]).abs() < 1e-14 * theta,
                    "{first:?} {:?}",
                    m.first
                );
                for (q, (s, t)) in second[p].iter().zip(&m.second[p]).enumerate() {
                    let e = (s - t).abs();
                    assert!(e < 1e-14 * theta * size, "{p}{q}: {e:e}");
                }
            }
        }
    }

    /// The `k` Gauss–Legendre nodes and weights on [−1, 1], by Newton on `P_k`.
    pub(crate) fn gauss_legendre(k: usize) -> Vec<(f64, f64)> {
        (1..=k)
            .map(|r| {
                let mut x = (PI * (r as f64 - 0.25) / (k as f64 + 0.5)).cos();
                let mut dp = 0.0;
                for _ in 0..100 {
                    let (mut p0, mut p1) = (1.0, x);
                    for l in 2..=k {
                        let l = l as f64;
                        (p0, p1) = (p1, ((2.0 * l - 1.0) * x * p1 - (l - 1.0) * p0) / l);
                    }
                    dp = k as f64 * (x * p1 - p0) / (x * x - 1.0);
                    x -= p1 / dp;
                }
                (x, 2.0 / ((1.0 - x * x) * dp * dp))
            })
            .collect()
    }

    #[test]
    fn sites_off_the_sphere_are_refused_by_row() {
        let mut sites = random_sites(30, 2);
        sites[11] = scale(sites[11], 1.0 + 1e-6);
        let err = clipped_diagram::<3, PolyhedronCell, _>(&Sphere, &sites, &Request::default())
            .unwrap_err();
        assert!(
            matches!(err, CoreError::SiteOutsideDomain { index: 11, .. }),
            "{err:?}"
        );
        // Normalised vectors are accepted; duplicates are named.
        sites[11] = unit(sites[11]);
        sites[20] = sites[3];
        let err = clipped_diagram::<3, PolyhedronCell, _>(&Sphere, &sites, &Request::default())
            .unwrap_err();
        assert!(matches!(
            err,
            CoreError::DuplicateSites {
                first: 3,
                second: 20,
                ..
            }
        ));
    }
}
