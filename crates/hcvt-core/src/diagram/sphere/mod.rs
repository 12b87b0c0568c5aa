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
//!
//! The files: this one makes the sphere a [`DomainKind`] and measures a cell's polygons;
//! [`polygon`] holds the site's frame and the polygon clipped by great circles,
//! [`moments`] the closed forms and the arcs' face moments.

mod moments;
mod polygon;

use moments::ArcRow;
pub(super) use moments::{measure_lower, measure_upper, Sums};
use polygon::CAP;
pub(super) use polygon::{unit, SiteFrame, SphericalPolygon};

use std::cell::RefCell;

use crate::density::quadrature::{Rule, TRIANGLE_5};
use crate::density::Cone;
use crate::geometry::{add, dot, norm2, scale, sub, Aabb, HalfSpace};
use crate::moments::Moments;

use super::clip::MeasureScratch;
use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::faces::{FaceRow, FaceSums};
use super::scratch::with_scratch;
use super::sphere_density;

// This thread's polygon, reused from cell to cell ([`with_scratch`]).
thread_local! {
    static POLYGON: RefCell<SphericalPolygon> = RefCell::new(SphericalPolygon::default());
}

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
pub(super) mod tests;
