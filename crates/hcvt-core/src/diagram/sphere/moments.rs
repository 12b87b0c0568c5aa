//! A spherical polygon's area, first moment and energy in closed form, and its arcs'
//! face moments (module docs of [`super`], "Closed forms").

use crate::density::quadrature::SEGMENT_5;
use crate::geometry::{add, cross, dot, norm2, scale, sub};
use crate::moments::{FaceMoments, Moments};

use crate::diagram::convex_cell::Face;
use crate::diagram::faces::{FaceRow, FaceSums};
use crate::diagram::sphere_density;
use crate::diagram::weighted_sums::{FaceNodes, FACE_NODES};

use super::polygon::{unit, SiteFrame, SphericalPolygon};

/// `θ − sin θ`, to relative round-off for small `θ` too (its Taylor series below 0.5).
pub(super) fn theta_minus_sin(t: f64) -> f64 {
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
pub(super) fn atan_minus_x(x: f64) -> f64 {
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

/// What [`measure_polygons`](super::measure_polygons) sums: area, the first moment's components along `e1`, `e2`
/// (`∫x·e = ∫(x − ẑ)·e`), and the energy `∫ |x − ẑ|²`.
#[derive(Debug, Clone, Copy, Default)]
pub(in crate::diagram) struct Sums {
    pub(in crate::diagram) area: f64,
    pub(in crate::diagram) first: [f64; 2],
    pub(in crate::diagram) energy: f64,
}

impl Sums {
    /// The moments about the site of `frame`: mass `A`, first `M − A ẑ` (whose `ẑ` part is
    /// `−E/2` on the sphere), second the energy `E`.
    pub(in crate::diagram) fn moments(&self, frame: &SiteFrame) -> Moments<3> {
        Moments {
            mass: self.area,
            first: frame.global([self.first[0], self.first[1], -0.5 * self.energy]),
            second: self.energy,
        }
    }

    pub(in crate::diagram) fn add(&mut self, piece: Sums) {
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
pub(in crate::diagram) fn measure_upper(
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
pub(in crate::diagram) fn measure_lower(
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
pub(in crate::diagram) struct ArcRow<'a> {
    /// The cell's row of face integrals.
    pub(super) row: FaceRow<'a, 3>,
    /// The site's frame, in which the arcs' ends are given.
    pub(super) frame: &'a SiteFrame,
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
pub(super) fn arc_moments(a: [f64; 3], b: [f64; 3], theta: f64) -> FaceMoments<3> {
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
