//! A triangle surface as a kind of domain: restricted Voronoi diagrams (DESIGN §12).
//!
//! Cell `i` of a surface `S` is `Vor(z_i) ∩ S`, the part of the surface nearer its site than
//! any other, sites anywhere in space. The driver computes the convex 3D cell of each site
//! as for every kind; this module clips every surface triangle that meets it by the
//! cell's planes ([`clip_polygon`], the clipper the conforming mesh cuts a solid's boundary
//! triangles with) and measures the convex planar pieces in closed form: area, `∫(x − z)`
//! and `∫|x − z|²` of the fan triangles of each piece ([`FaceMoments::simplex`]), about the
//! site. The neighbour face measures are the lengths of the pieces' edges on each bisector
//! (the arcs two cells share), the boundary measure the length of the surface's border
//! (edges of one triangle only) in the cell. The cells have dimension 2
//! ([`DomainKind::cell_dim`]); their centroids lie off the surface (inside its curvature),
//! and the CVT moves the sites freely in space (Yan, Lévy, Liu, Sun, Wang 2009).
//!
//! **Finding the triangles.** The triangles meeting a cell are found by walking their BVH
//! ([`crate::domain::Bvh::walk`]) and pruning every node whose box lies outside one of the
//! cell's planes (its corner least along the plane's normal beyond the plane). The cell of
//! a site on a surface is a needle along the normal until sites across the model cut it:
//! its bounding box would take in much of the model, the pruned walk does not. The test
//! takes the planes two at a time with no branch ([`BoxPlanes`]), and inner boxes that
//! hold the site (in its own cell) are walked into untested ([`holds_site`]).
//!
//! **Stopping early.** Only the cell's pieces of the surface matter. After
//! `VALIDATE_PART_K` neighbours the driver checks their vertices' nearest sites
//! ([`DomainKind::validation_points`]) and cuts the cell by any nearer site until each
//! vertex has the cell's site as a nearest one: each piece is convex, so it then lies in
//! the Voronoi cell, and the cell's part on the surface is exact while the rest of the
//! 3D cell (a needle along the normal, open until sites across the model cut it) need not
//! be. Before that check, the security radius of the pieces: when the last of those
//! neighbours lies beyond twice the farthest piece node, no other site can be nearer
//! any point of the pieces, and the cell is exact without a nearest-site query (most
//! cells: the nearest-site queries went from 16% of a kitten diagram's samples to 3%).
//! The triangles the first look's walk met are recorded per thread ([`Triangles`]),
//! with their pieces: the later checks clip only those, and the measure replays the
//! pieces when the cell was not cut since.
//!
//! **Whole triangles.** A box of the BVH inside every plane of the cell (with a margin
//! for round-off) gives its triangles whole, without testing them plane by plane; the
//! other triangles are tested once against the planes their leaf's box is not inside
//! ([`box_side`]; the others leave them as they are) ([`Clipper::triangle`]) and clipped
//! only by the planes that cut them.
//!
//! **The cells' pieces.** [`Surface::pieces`] hands over the pieces themselves: its
//! diagram notes each piece's nodes as the measure sums its moments ([`Noting`]).
//!
//! **The triangulation.** [`Surface::restricted_delaunay`] reads the meeting points of
//! three cells from each cell's pieces. Its diagram notes, per site, the triangles its
//! measure met ([`Noting`]), and the meeting points clip those again instead of walking
//! the BVH a second time (the same pieces, in the same order): its triangulation took
//! 0.37-0.39 s of CPU against 0.27-0.28 s (armadillo, 5,000 CVT sites) and 1.19 s
//! against 0.82-0.89 s (20,000), one thread under load ~3.5.
//!
//! The files: [`triangles`] holds the surface itself (checked, with its BVH); [`walk`]
//! finds a cell's triangles and clips them into pieces (the boxes of the BVH tested in
//! [`prune`], the triangles clipped in [`clipper`]); [`measure`] sums the pieces' moments,
//! arc measures and Newton's Hessian terms ([`density`] with a density); [`delaunay`] reads
//! the restricted Delaunay triangulation and the pieces from a diagram that [`noting`]
//! notes; this file makes the surface a [`DomainKind`].
//!
//! [`clip_polygon`]: super::polygon_clip::clip_polygon
//! [`FaceMoments::simplex`]: crate::moments::FaceMoments::simplex
//! [`BoxPlanes`]: prune::BoxPlanes
//! [`holds_site`]: prune::holds_site
//! [`box_side`]: prune::box_side
//! [`Clipper::triangle`]: clipper::Clipper::triangle
//! [`Noting`]: noting::Noting

mod clipper;
mod delaunay;
mod density;
mod measure;
mod noting;
mod prune;
mod triangles;
mod walk;

pub use delaunay::{RestrictedDelaunay, SurfacePieces};
pub use triangles::Surface;
use walk::Triangles;

use crate::density::quadrature::Rule;
use crate::density::{face_node, sum_sampled_on_faces, Cone};
use crate::geometry::{norm2, Aabb};
use crate::moments::Moments;

use super::clip::MeasureScratch;
use super::convex_cell::ConvexCell;
use super::domain_kind::DomainKind;
use super::faces::FaceRow;

/// Neighbours a cell streams before its pieces are validated
/// ([`DomainKind::validate_part_after`]): a restricted cell has about six, as a planar one.
/// A diagram of 5,000 sites on the bunny (perf samples, six diagrams, one thread, under
/// load): streaming on to 64 neighbours, localising and validating took 4,886 (random
/// sites) and 5,064 (a CVT's); validating the pieces after 8 neighbours 11,807 and 3,321
/// (cells still open sideways have large pieces), after 12 4,815 and 3,020, after 16
/// 3,729 and 2,756, after 20 3,348 and 2,942, after 24 3,585 and 2,806, after 32 3,748
/// and 2,937.
const VALIDATE_PART_K: usize = 20;

impl DomainKind<3> for Surface {
    fn bounds(&self) -> Aabb<3> {
        self.set.bvh().bounds()
    }

    /// The area: the mean spacing of the sites is `(A/n)^{1/2}`.
    fn volume(&self) -> f64 {
        self.area
    }

    /// 1 everywhere: sites may lie anywhere in space (a site far from the surface has an
    /// empty cell).
    fn locate(&self, _: &[f64; 3]) -> Option<i32> {
        Some(1)
    }

    fn density_checkpoints(&self) -> &[[f64; 3]] {
        self.set.vertices()
    }

    /// Not convex: a cell is localised by the driver to the box holding its part on the
    /// surface ([`DomainKind::local_radius2`]) and validated by its vertices' nearest sites.
    /// Cutting it to that box every `PRECLIP_K` neighbours as well (the sphere's way) cost
    /// more than it saved: the cell of a site on a surface is a needle along the normal
    /// that meets the surface again across the model, so the box stays the model's
    /// thickness until the sites over there cut it. Without the cuts a diagram took 0.24 s
    /// instead of 0.33 s (kitten, 2,000 sites), 0.46 s instead of 0.83 s (fandisk, 5,000)
    /// and 2.3 s instead of 11.8 s (armadillo, 20,000), two threads under load ~7.
    fn is_convex(&self) -> bool {
        false
    }

    /// Never called (not convex): leaves the cell as it is.
    fn cut_convex<C: ConvexCell<3>>(&self, _: &mut C, _: [f64; 3], _: &mut Vec<u32>) -> bool {
        false
    }

    /// `max |x|²` over the clipped pieces' nodes (the pieces are convex), with a margin
    /// for their round-off; 0 when no triangle meets the cell.
    fn local_radius2<C: ConvexCell<3>>(&self, cell: &C, site: [f64; 3]) -> f64 {
        let mut r2: f64 = 0.0;
        self.for_each_piece(cell, site, Triangles::Record, |_, polygon| {
            for node in polygon {
                r2 = r2.max(norm2(node.x));
            }
        });
        r2 * (1.0 + 1e-10)
    }

    /// Its cells matter only on the surface: after `VALIDATE_PART_K` neighbours a
    /// cell's pieces are validated ([`DomainKind::validation_points`]) rather than the
    /// stream going on (the 3D cell is a needle along the normal, open until sites
    /// across the model cut it) to be localised and its vertices validated.
    fn validate_part_after(&self) -> Option<usize> {
        Some(VALIDATE_PART_K)
    }

    /// The vertices of the cell's pieces of the surface: the cell's part on the surface
    /// lies in the Voronoi cell once they do (each piece is convex), and the rest of the
    /// 3D cell (the needle along the normal) need not be exact.
    fn validation_points<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        first: bool,
        points: &mut Vec<[f64; 3]>,
    ) -> bool {
        points.clear();
        let triangles = if first {
            Triangles::Record
        } else {
            Triangles::Met
        };
        self.for_each_piece(cell, site, triangles, |_, polygon| {
            points.extend(polygon.iter().map(|node| node.x));
        });
        true
    }

    /// The moments of the cell's part of the surface about the site (mass the area), its
    /// arcs on bisectors into the neighbours' measures, with a `row` (Newton's Hessian)
    /// their face moments weighted by the slope of the bisector against each triangle
    /// ([`HessianArcs`]), and with a density its weighted sums (`surface/density.rs`).
    ///
    /// [`HessianArcs`]: measure::HessianArcs
    fn clip<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        _: Option<i32>,
        row: Option<FaceRow<'_, 3>>,
        scratch: &mut MeasureScratch<3, C>,
    ) -> Moments<3> {
        self.measure(cell, site, row, scratch, |_, _| {})
    }

    fn cell_dim(&self) -> usize {
        2
    }

    /// The rule's point in the fan triangle `cone` (its three corners relative to the
    /// site): the cells are pieces of flat triangles (`surface/density.rs`).
    fn sampled_node(&self, _site: [f64; 3], cone: &Cone<3>, lambda: &[f64]) -> [f64; 3] {
        face_node(&cone.0, lambda)
    }

    /// The triangle rule's sums over the fan triangles (`surface/density.rs`).
    fn sampled_moments(
        &self,
        _site: [f64; 3],
        cones: &[Cone<3>],
        rule: &Rule,
        values: &[f64],
        _geometric: &Moments<3>,
    ) -> Moments<3> {
        sum_sampled_on_faces(cones, rule, values)
    }

    /// One value per vertex of the surface.
    fn vertex_density_len(&self) -> Option<usize> {
        Some(self.set.vertices().len())
    }

    /// Newton's Hessian is not weighted by a density on a surface.
    fn sums_weighted_hessian(&self) -> bool {
        false
    }

    /// Newton's Hessian: the flat one's face terms over the arcs, each segment weighted
    /// by the slope of its bisector against its triangle ([`HessianArcs`](measure::HessianArcs)).
    fn sums_hessian(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests;
