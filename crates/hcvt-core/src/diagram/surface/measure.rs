//! A cell's pieces measured in closed form: their moments about the site, the arcs'
//! lengths by neighbour and the border's length, and Newton's Hessian terms on the arcs.

use crate::diagram::clip::MeasureScratch;
use crate::diagram::convex_cell::{ConvexCell, Face};
use crate::diagram::faces::{FaceRow, FaceSums};
use crate::geometry::{add, cross, norm2, scale, sub};
use crate::moments::{FaceMoments, Moments};

use super::clipper::{Edge, Node};
use super::triangles::Surface;
use super::walk::Triangles;

/// Add the piece `polygon` (of triangle `t`, relative to the site) to `total`: the fan
/// triangles from its first node, each in closed form; its edges on bisectors to the
/// neighbours' measures (with `arcs`, and their Hessian terms) and on the border to the
/// boundary measure.
pub(super) fn add_piece(
    surface: &Surface,
    t: u32,
    polygon: &[Node],
    arcs: Option<&HessianArcs<'_>>,
    total: &mut Moments<3>,
    faces: &mut FaceSums<3>,
) {
    let a = polygon[0].x;
    for k in 1..polygon.len() - 1 {
        let (b, c) = (polygon[k].x, polygon[k + 1].x);
        let area = 0.5 * norm2(cross(sub(b, a), sub(c, a))).sqrt();
        let m = FaceMoments::simplex(&[a, b, c], area);
        total.mass += area;
        total.first = add(total.first, m.first);
        total.second += m.second[0][0] + m.second[1][1] + m.second[2][2];
    }
    let n = polygon.len();
    for k in 0..n {
        let length = norm2(sub(polygon[(k + 1) % n].x, polygon[k].x)).sqrt();
        match polygon[k].out {
            Edge::Plane(face @ Face::Neighbor(j)) => match arcs {
                Some(arcs) => {
                    let ends = [polygon[k].x, polygon[(k + 1) % n].x];
                    arcs.add(surface, t, j, ends, length, faces);
                }
                None => {
                    faces.add(face, length);
                }
            },
            Edge::Triangle(e) if surface.is_border(t, e as usize) => {
                faces.add(Face::Boundary(t), length);
            }
            _ => {}
        }
    }
}

/// The least sine of the angle between a bisector and a triangle that [`HessianArcs`]
/// weighs an arc by: a bisector more nearly parallel to the triangle has its arc there
/// weighted as if at this angle (1,000 times the flat weight at most).
const MIN_ARC_SINE: f64 = 1e-3;

/// Newton's Hessian on a surface (issue 33): the face moments its [`FaceRow`] sums over a
/// cell's arcs, each segment weighted by the slope of its bisector against its triangle.
///
/// The energy is `E(X) = Σ_i ∫_{Ω_i ∩ S} |x − x_i|² dA`, sites free in space (Yan et al.
/// 2009). The arc between cells `i` and `j` is a polyline: one segment `s` per triangle
/// `T` it crosses, the bisector plane `2 x·q = |x_j|² − |x_i|²` (`q = x_j − x_i`) cut by
/// `T`'s plane. When `x_j` moves by `δ` the segment moves *in `T`'s plane*, along its
/// unit normal there `u_s = P_T q / |P_T q|` (`P_T` the projection onto the plane), at
/// the speed that keeps the bisector's equation: `−(x − x_j)·δ / |P_T q|`, not the
/// flat `−(x − x_j)·δ / |q|` of a cell of full dimension (the border of an open surface
/// does not move, and a segment's ends sliding along `T`'s edges sweep no area to first
/// order). So `H_ij = Σ_s (2/|P_T q|) ∫_s (x − x_i)(x − x_j)ᵀ ds` and
/// `H_ii = 2 m_i I − Σ_j Σ_s (2/|P_T q|) ∫_s (x − x_i)(x − x_i)ᵀ ds`: the flat Hessian's
/// face terms (`optimise::hessian::HessianTerms`, weight `2/|q|`) serve unchanged when
/// each segment's moments come scaled by `|q| / |P_T q| = 1 / sin θ`, `θ` the angle
/// between the bisector's normal and `T`'s (the neighbours' measures stay the lengths).
///
/// Where the bisector is nearly parallel to `T` (`sin θ → 0`: two sites on either side of
/// a thin sheet, or a cell wrapping a sharp crease) the true weight grows without bound;
/// it is taken at `sin θ = MIN_ARC_SINE` there (a Hessian finite and inexact on that
/// segment alone, a model the trust region checks against the energy like any other).
/// At `sin θ = 0` exactly the triangle lies in the bisector and has no arc.
pub(super) struct HessianArcs<'a> {
    row: FaceRow<'a, 3>,
    /// The normal of each of the cell's bisectors (along `q`), by neighbour.
    bisectors: Vec<(u32, [f64; 3])>,
    /// The flat weight `2/|q|` instead (a test shows the finite differences tell).
    #[cfg(test)]
    flat: bool,
}

impl<'a> HessianArcs<'a> {
    fn new<C: ConvexCell<3>>(_surface: &Surface, cell: &C, row: FaceRow<'a, 3>) -> Self {
        let mut bisectors = Vec::new();
        cell.for_each_plane(|face, h| {
            if let Face::Neighbor(j) = face {
                bisectors.push((j, h.normal));
            }
        });
        Self {
            row,
            bisectors,
            #[cfg(test)]
            flat: _surface.flat_arcs,
        }
    }

    /// `1 / max(sin θ, MIN_ARC_SINE)` for the bisector with `j` in triangle `t`.
    fn weight(&self, surface: &Surface, t: u32, j: u32) -> f64 {
        #[cfg(test)]
        if self.flat {
            return 1.0;
        }
        let Some(&(_, normal)) = self.bisectors.iter().find(|(k, _)| *k == j) else {
            return 1.0; // not reached: the arc lies on one of the cell's bisectors
        };
        let [a, b, c] = surface.corners(t);
        let across = cross(sub(b, a), sub(c, a));
        let along = norm2(normal).sqrt();
        // |P_T n| = |n × t̂| = |n| sin θ.
        let tilt = norm2(cross(normal, across)).sqrt() / norm2(across).sqrt();
        along / tilt.max(MIN_ARC_SINE * along)
    }

    /// Add the arc segment `ends` (relative to the site, `length` long) on the bisector
    /// with `j` in triangle `t`: its length to the neighbour's measure, its moments
    /// weighted by [`HessianArcs::weight`] to the row's integrand.
    fn add(
        &self,
        surface: &Surface,
        t: u32,
        j: u32,
        ends: [[f64; 3]; 2],
        length: f64,
        faces: &mut FaceSums<3>,
    ) {
        let [a, b] = ends;
        let s = add(a, b);
        let w = self.weight(surface, t, j) * length;
        // ∫ y ds = L (a + b)/2 and ∫ y yᵀ ds = L (a aᵀ + b bᵀ + s sᵀ)/6 over the segment.
        let m = FaceMoments {
            measure: w,
            first: scale(s, 0.5 * w),
            second: std::array::from_fn(|r| {
                std::array::from_fn(|c| w / 6.0 * (a[r] * a[c] + b[r] * b[c] + s[r] * s[c]))
            }),
        };
        faces.add_weighted_moments(Face::Neighbor(j), 1.0, length, &m, self.row);
    }
}

impl Surface {
    /// [`DomainKind::clip`]: the moments of the cell's pieces, each piece (its triangle
    /// and nodes, relative to the site) told to `met` in order; with a `row`, the
    /// Hessian's terms of its arcs.
    ///
    /// [`DomainKind::clip`]: crate::diagram::domain_kind::DomainKind::clip
    pub(super) fn measure<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        row: Option<FaceRow<'_, 3>>,
        scratch: &mut MeasureScratch<3, C>,
        mut met: impl FnMut(u32, &[Node]),
    ) -> Moments<3> {
        let faces = &mut scratch.faces;
        faces.clear();
        let arcs = row.map(|row| HessianArcs::new(self, cell, row));
        let mut total = Moments::zero();
        self.for_each_piece(cell, site, Triangles::LastMet, |t, polygon| {
            met(t, polygon);
            add_piece(self, t, polygon, arcs.as_ref(), &mut total, faces);
            if faces.weighted.is_on() {
                self.add_weighted_piece(t, site, polygon, &mut faces.weighted);
            }
        });
        total
    }
}
