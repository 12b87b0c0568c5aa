//! A density on a triangle surface (DESIGN §8, §12): each restricted cell's `∫ρ`,
//! `∫ρ (x − z)` and `∫ρ |x − z|²` about its site `z`, as the flat kinds report them, so that
//! Lloyd's ρ-weighted centroid, the gradient `−2 ∫ρ (x − z)` and the energy
//! `Σ ∫ρ |x − z_i|²` carry over unchanged.
//!
//! **Pieces.** A cell's part of the surface is a set of convex planar pieces (input
//! triangles clipped by the cell's planes), each cut into the fan triangles from its first
//! node that the geometric measure sums in closed form (`add_piece` in `measure.rs`). Each
//! fan triangle is flat, so the flat kinds' face rules apply to it as they stand
//! ([`WeightedSums::add_face_piece`]; the sphere needs a Jacobian, `sphere_density.rs`,
//! the surface does not):
//!
//! - a polynomial of degree ≤ 2: `ρ |y|²` has degree 4 on the triangle, integrated exactly
//!   by the degree-4 triangle rule of the flat kinds' face averages
//!   ([`crate::density::polynomial_face_moments`]);
//! - a sampled field: the fan triangle is kept and the field asked at the triangle rule's
//!   nodes of the requested degree with the rest of the diagram
//!   ([`crate::density::sum_sampled_on_faces`]);
//! - a per-vertex field (linear on each input triangle): its values at the fan triangle's
//!   corners, interpolated in the input triangle, and the degree-4 rule on the linear
//!   interpolant (`ρ |y|²` cubic): exact ([`crate::density::linear_face_moments`]).

use crate::geometry::{cross, dot, norm2, sub};

use super::clipper::Node;
use super::triangles::Surface;
use crate::diagram::weighted_sums::WeightedSums;

impl Surface {
    /// Add the piece `polygon` of triangle `t` (relative to `site`) to the cell's weighted
    /// sums: the same fan triangles from its first node as the geometric measure.
    pub(super) fn add_weighted_piece(
        &self,
        t: u32,
        site: [f64; 3],
        polygon: &[Node],
        weighted: &mut WeightedSums<3>,
    ) {
        let a = polygon[0].x;
        for k in 1..polygon.len() - 1 {
            let (b, c) = (polygon[k].x, polygon[k + 1].x);
            let area = 0.5 * norm2(cross(sub(b, a), sub(c, a))).sqrt();
            weighted.add_face_piece(&[a, b, c], area, |values| {
                self.interpolate(t, site, [a, b, c], values)
            });
        }
    }

    /// The field of `values` (one per vertex of the surface, linear on each triangle) at
    /// `points` of triangle `t` (relative to `site`), by their barycentric coordinates.
    /// A value missing (the caller checks the count) is NaN, which the mass check names.
    fn interpolate(
        &self,
        t: u32,
        site: [f64; 3],
        points: [[f64; 3]; 3],
        values: &[f64],
    ) -> [f64; 3] {
        let r = self.relative(t, site);
        let rho = self.triangles()[t as usize].map(|v| values.get(v as usize).copied());
        let [Some(r0), Some(r1), Some(r2)] = rho else {
            return [f64::NAN; 3];
        };
        let n = cross(sub(r[1], r[0]), sub(r[2], r[0]));
        let nn = norm2(n);
        points.map(|p| {
            let l0 = dot(n, cross(sub(r[1], p), sub(r[2], p))) / nn;
            let l1 = dot(n, cross(sub(r[2], p), sub(r[0], p))) / nn;
            l0 * r0 + l1 * r1 + (1.0 - l0 - l1) * r2
        })
    }
}
