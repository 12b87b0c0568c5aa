//! The seam between the diagram driver and the kinds of domain (DESIGN §11).
//!
//! The driver ([`super::clipped_diagram`], [`super::clipped_cells`]) and the optimisers
//! above it know a domain only through [`DomainKind`]: where a site's convex cell starts,
//! which points are inside, and the exact moments of a convex cell restricted to the
//! domain. The kNN, the convex clipping, the moments, the optimisers, the hierarchy, the
//! densities and the partitions are shared by every kind; a kind is one implementation of
//! this trait, not a copy of the driver.
//!
//! The kinds: the region bounded by simplices ([`Boundary`]: a polygon with holes in 2D, a
//! solid bounded by triangles in 3D), measured through signed cones (`clip.rs`); an
//! axis-aligned box ([`super::BoxDomain`]); and a periodic box ([`super::PeriodicBox`]: no
//! boundary along its periodic axes, the cell itself, its neighbours' images through the
//! [`Torus`] of [`DomainKind::periodic`]). The sphere and a triangle surface (great-circle
//! and triangle pieces, cells of dimension 2) will implement the same methods. The
//! conforming mesh (`mesh`) still reads a [`Boundary`]'s simplices: the boundary pieces a
//! mesh needs join this trait with the first kind that meshes otherwise.

use crate::density::quadrature::Rule;
use crate::density::{cone_node, sum_sampled, Cone};
use crate::domain::{Boundary, WindingNumber};
use crate::geometry::{Aabb, Euclid, Space};
use crate::moments::Moments;

use super::clip::{clip_by_domain, cut_by_boundary, domain_radius2, MeasureScratch};
use super::convex_cell::ConvexCell;
use super::faces::FaceRow;
use super::torus::Torus;

/// Margin of the starting box around the domain, relative to the domain's diagonal
/// ([`DomainKind::start`]).
pub(super) const BOX_MARGIN: f64 = 1e-3;

/// What the diagram driver asks of a domain. Lengths in the input's unit `L`; a cell is
/// given relative to its site (absolute coordinates `site + v`).
pub trait DomainKind<const D: usize>: Sync {
    /// (a) A box holding the domain: every convex cell starts as this box (a little
    /// larger), before the bisectors cut it.
    fn bounds(&self) -> Aabb<D>;

    /// (a) The box, relative to `site`, that the site's convex cell starts from: by
    /// default [`DomainKind::bounds`] grown by a thousandth of its diagonal (a cell face
    /// on the domain boundary would otherwise be a box face, and the boundary pieces that
    /// measure it flat).
    fn start(&self, site: [f64; D]) -> Aabb<D> {
        let bounds = self.bounds();
        bounds
            .expanded(BOX_MARGIN * bounds.diagonal())
            .relative_to(site)
    }

    /// (e) The torus whose images of the sites the cells are computed among, for a
    /// periodic kind; `None` (the default) for the others.
    fn periodic(&self) -> Option<&Torus<D>> {
        None
    }

    /// The domain's measure (area in 2D, volume in 3D), `L^d`: what the mean spacing of the
    /// sites is taken from.
    fn volume(&self) -> f64;

    /// (c) The inside test: the winding number of `point` (0 outside, 1 inside a simple
    /// domain), `None` on the boundary itself.
    fn locate(&self, point: &[f64; D]) -> Option<i32>;

    /// Points besides the sites where a polynomial density must be finite and positive
    /// (where its extremes over the domain can lie: the boundary's vertices).
    fn density_checkpoints(&self) -> &[[f64; D]];

    /// The domain is convex: a cell of a site strictly inside may be cut to the domain
    /// early ([`DomainKind::cut_convex`]) and then measured as it is.
    fn is_convex(&self) -> bool;

    /// Cut `cell` (of a site strictly inside a convex domain) to the domain, tagging the
    /// new faces `Face::Boundary`; `candidates` is a buffer. `true`: the cell now lies in
    /// the domain and is measured as it is. `false`: the cell is to be measured by
    /// [`DomainKind::clip`], and the driver streams on and asks again `PRECLIP_K`
    /// neighbours later (the sphere, whose cut only bounds the cap holding the cell so far,
    /// and tightens as the cell shrinks).
    fn cut_convex<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        site: [f64; D],
        candidates: &mut Vec<u32>,
    ) -> bool;

    /// An upper bound on `|x|²` over the part of `cell` inside the domain, `L²`: how far a
    /// localised cell must be validated.
    fn local_radius2<C: ConvexCell<D>>(&self, cell: &C, site: [f64; D]) -> f64;

    /// For a kind whose cells matter only where they meet the domain through the points
    /// of [`DomainKind::validation_points`] (a surface): after this many neighbours the
    /// driver validates those points at once (each must have the site as a nearest site,
    /// else the cell is cut by the nearer site), instead of streaming on to the security
    /// radius or localising the cell. `None` (the default): stream on.
    fn validate_part_after(&self) -> Option<usize> {
        None
    }

    /// The points (relative to `site`) whose nearest site must be `site` for a validated
    /// `cell` to be exact where it meets the domain, into `points`; `false` (the default):
    /// the cell's own vertices. A kind whose cells are pieces of lower dimension (a
    /// surface) gives the vertices of the pieces: each piece is convex, so it lies in the
    /// Voronoi cell once its vertices do. `first`: the first call for this cell; the
    /// later calls see the same cell cut further.
    fn validation_points<C: ConvexCell<D>>(
        &self,
        _cell: &C,
        _site: [f64; D],
        _first: bool,
        _points: &mut Vec<[f64; D]>,
    ) -> bool {
        false
    }

    /// (b) The exact moments of `cell ∩ Ω` about the site, its faces measured into
    /// `scratch` (and the integrand of `row` summed over them). `winding` is the site's
    /// [`DomainKind::locate`].
    fn clip<C: ConvexCell<D>>(
        &self,
        cell: &C,
        site: [f64; D],
        winding: Option<i32>,
        row: Option<FaceRow<'_, D>>,
        scratch: &mut MeasureScratch<D, C>,
    ) -> Moments<D>;

    /// The dimension `d` of the cells: `D` for a region of space, 2 for a surface (the
    /// sphere). The `d` of `G` and of the gap's `V_i^{1/d}` (DESIGN §7, §11).
    fn cell_dim(&self) -> usize {
        D
    }

    /// `∫ |x − c|²` over a cell with moments `m` (about its site) about its centroid `c`:
    /// the parallel-axis rule in a flat domain; on a curved one, about the centroid that
    /// the CVT drives the site to (the sphere's `∫x / |∫x|`).
    fn central_second(&self, m: &Moments<D>) -> f64 {
        m.central_second()
    }

    /// `G = ∫|x − c|² / (d · V^((d+2)/d))` of a cell with moments `m`, `d` the
    /// [`DomainKind::cell_dim`], [`DomainKind::central_second`] about `c`; `None` for an
    /// empty cell.
    fn g_value(&self, m: &Moments<D>) -> Option<f64> {
        if m.mass <= 0.0 {
            return None;
        }
        // The exponent a constant in a flat domain, as `Moments` has it: LLVM folds
        // `powf` with constant exponents, and the bits must not change with this seam.
        let d = self.cell_dim();
        let size = if d == D {
            let d = D as f64;
            d * m.mass.powf((d + 2.0) / d)
        } else {
            let d = d as f64;
            d * m.mass.powf((d + 2.0) / d)
        };
        Some(self.central_second(m) / size)
    }

    /// The part of a move `v` of the site `site` along the domain: `v` itself in a flat
    /// domain, its component in the tangent plane on the sphere. The optimisers' gradients
    /// and steps are projected by it.
    fn tangent(&self, _site: [f64; D], v: [f64; D]) -> [f64; D] {
        v
    }

    /// The curvature term of the Riemannian Hessian of an energy at `site` whose ambient
    /// gradient there is `gradient`: the Hessian along the domain is `P ∇²f P − c P` with
    /// `c` this and `P` the projection of [`DomainKind::tangent`] (Absil, Mahony and
    /// Sepulchre 2008, §5.5, for a surface whose shape operator is the identity, as the
    /// unit sphere's). 0 in a flat domain, where the Hessian is used as it is.
    fn curvature_term(&self, _site: [f64; D], _gradient: [f64; D]) -> f64 {
        0.0
    }

    /// The core sums Newton's Hessian for this kind: the flat kinds (cells of dimension
    /// `D`), the sphere (its Riemannian Hessian) and a triangle surface (its arcs weighted
    /// by their slope, `surface/measure.rs`); not yet a region of the sphere, whose Newton is
    /// refused with a message instead of reading faces it has not measured.
    fn sums_hessian(&self) -> bool {
        self.cell_dim() == D
    }

    /// Newton's first trust region may be as large as the model's own step (its
    /// `TrustRegion::open`, in `optimise/newton.rs`): a domain without boundary (no site
    /// can be moved out of it) whose runs often start near a CVT. `false` by default.
    fn trusts_newton(&self) -> bool {
        false
    }

    /// With a sampled density (DESIGN §8): the node of the rule's point `lambda` in the
    /// piece `cone` of the cell of `site`, relative to the site. The cone simplex's own
    /// point by default; the sphere maps a flat triangle onto the sphere
    /// (`sphere_density.rs`). The rule has dimension [`DomainKind::cell_dim`].
    fn sampled_node(&self, _site: [f64; D], cone: &Cone<D>, lambda: &[f64]) -> [f64; D] {
        cone_node(&cone.0, lambda)
    }

    /// With a sampled density: the weighted moments about `site` of its cell (of
    /// geometric moments `geometric`) from its pieces `cones` and the density's `values`
    /// at their nodes (cone after cone, node after node). The rule's sums by default.
    fn sampled_moments(
        &self,
        _site: [f64; D],
        cones: &[Cone<D>],
        rule: &Rule,
        values: &[f64],
        _geometric: &Moments<D>,
    ) -> Moments<D> {
        sum_sampled(cones, rule, values)
    }

    /// The number of values a per-vertex density takes ([`crate::Density::PerVertex`]): a
    /// triangle surface's vertex count; `None` (the default): the kind takes none.
    fn vertex_density_len(&self) -> Option<usize> {
        None
    }

    /// Newton's Hessian is weighted by a density here (the default, where it is summed at
    /// all): a triangle surface's is not, and Newton with a density is refused there.
    fn sums_weighted_hessian(&self) -> bool {
        self.sums_hessian()
    }

    /// The point of the domain that stands for `x` after a step: `x` itself in a flat
    /// domain (no arithmetic, so no bit changes), `x / |x|` on the unit sphere (the
    /// retraction of DESIGN §13).
    fn retract(&self, x: [f64; D]) -> [f64; D] {
        x
    }
}

/// A polygon with holes (2D) or a solid bounded by triangles (3D): cells clipped through
/// signed cones from an apex (`clip.rs`), the inside test a winding number.
impl<const D: usize> DomainKind<D> for Boundary<D>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    fn bounds(&self) -> Aabb<D> {
        Boundary::bounds(self)
    }

    fn volume(&self) -> f64 {
        Boundary::volume(self)
    }

    fn locate(&self, point: &[f64; D]) -> Option<i32> {
        Euclid::winding_number(self, point)
    }

    fn density_checkpoints(&self) -> &[[f64; D]] {
        self.vertices()
    }

    fn is_convex(&self) -> bool {
        Boundary::is_convex(self)
    }

    fn cut_convex<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        site: [f64; D],
        candidates: &mut Vec<u32>,
    ) -> bool {
        cut_by_boundary(self, cell, site, candidates);
        true
    }

    fn local_radius2<C: ConvexCell<D>>(&self, cell: &C, site: [f64; D]) -> f64 {
        domain_radius2(self, cell, site)
    }

    fn clip<C: ConvexCell<D>>(
        &self,
        cell: &C,
        site: [f64; D],
        winding: Option<i32>,
        row: Option<FaceRow<'_, D>>,
        scratch: &mut MeasureScratch<D, C>,
    ) -> Moments<D> {
        clip_by_domain(self, cell, site, winding, row, scratch)
    }
}
