//! The surface as a domain that notes what each cell's measure met, for
//! [`super::delaunay`].

use std::collections::HashMap;
use std::sync::Mutex;

use crate::density::quadrature::Rule;
use crate::density::Cone;
use crate::diagram::clip::MeasureScratch;
use crate::diagram::convex_cell::ConvexCell;
use crate::diagram::domain_kind::DomainKind;
use crate::diagram::faces::FaceRow;
use crate::geometry::{add, Aabb};
use crate::moments::Moments;

use super::triangles::Surface;

/// The surface as a domain that also notes, per site (by its bits), the triangles of its
/// cell's pieces as the measure meets them ([`DomainKind::clip`], the cell's last
/// look): [`Surface::restricted_delaunay`] then clips those again for the meeting
/// points instead of walking the BVH a second time. Sites sharing bits note `None`
/// (their cells walk). Asked for `pieces`, it notes the pieces' nodes too
/// ([`Surface::pieces`]). Everything else is the surface's.
pub(super) struct Noting<'a> {
    surface: &'a Surface,
    /// Note each piece's nodes as well ([`Surface::pieces`]), not only its triangle.
    pieces: bool,
    met: Mutex<HashMap<[u64; 3], Option<Noted>>>,
}

/// What [`Noting`] noted of one cell: the triangles of its pieces in the measure's order
/// and, when asked, the pieces' nodes (absolute) and the end of each piece's in `nodes`.
#[derive(Debug, Default)]
pub(super) struct Noted {
    /// The triangle of each piece.
    pub(super) triangles: Vec<u32>,
    /// Where each piece's nodes end in `nodes`.
    pub(super) ends: Vec<usize>,
    /// The pieces' nodes, absolute, `L`.
    pub(super) nodes: Vec<[f64; 3]>,
}

impl<'a> Noting<'a> {
    pub(super) fn new(surface: &'a Surface, pieces: bool, n: usize) -> Self {
        Self {
            surface,
            pieces,
            met: Mutex::new(HashMap::with_capacity(n)),
        }
    }

    /// The notes, by the sites' bits.
    pub(super) fn into_notes(self) -> HashMap<[u64; 3], Option<Noted>> {
        self.met.into_inner().unwrap_or_else(|e| e.into_inner())
    }
}

impl DomainKind<3> for Noting<'_> {
    fn bounds(&self) -> Aabb<3> {
        self.surface.bounds()
    }
    fn volume(&self) -> f64 {
        self.surface.volume()
    }
    fn locate(&self, point: &[f64; 3]) -> Option<i32> {
        self.surface.locate(point)
    }
    fn density_checkpoints(&self) -> &[[f64; 3]] {
        self.surface.density_checkpoints()
    }
    fn is_convex(&self) -> bool {
        self.surface.is_convex()
    }
    fn cut_convex<C: ConvexCell<3>>(&self, cell: &mut C, site: [f64; 3], o: &mut Vec<u32>) -> bool {
        self.surface.cut_convex(cell, site, o)
    }
    fn local_radius2<C: ConvexCell<3>>(&self, cell: &C, site: [f64; 3]) -> f64 {
        self.surface.local_radius2(cell, site)
    }
    fn validate_part_after(&self) -> Option<usize> {
        self.surface.validate_part_after()
    }
    fn validation_points<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        first: bool,
        points: &mut Vec<[f64; 3]>,
    ) -> bool {
        self.surface.validation_points(cell, site, first, points)
    }
    fn clip<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        _: Option<i32>,
        row: Option<FaceRow<'_, 3>>,
        scratch: &mut MeasureScratch<3, C>,
    ) -> Moments<3> {
        let mut met = Noted::default();
        let total = self
            .surface
            .measure(cell, site, row, scratch, |t, polygon| {
                met.triangles.push(t);
                if self.pieces {
                    met.nodes
                        .extend(polygon.iter().map(|node| add(site, node.x)));
                    met.ends.push(met.nodes.len());
                }
            });
        let mut noted = self.met.lock().unwrap_or_else(|e| e.into_inner());
        noted
            .entry(site.map(f64::to_bits))
            .and_modify(|m| *m = None)
            .or_insert(Some(met));
        total
    }
    fn cell_dim(&self) -> usize {
        self.surface.cell_dim()
    }
    fn sampled_node(&self, site: [f64; 3], cone: &Cone<3>, lambda: &[f64]) -> [f64; 3] {
        self.surface.sampled_node(site, cone, lambda)
    }
    fn sampled_moments(
        &self,
        site: [f64; 3],
        cones: &[Cone<3>],
        rule: &Rule,
        values: &[f64],
        geometric: &Moments<3>,
    ) -> Moments<3> {
        self.surface
            .sampled_moments(site, cones, rule, values, geometric)
    }
    fn vertex_density_len(&self) -> Option<usize> {
        self.surface.vertex_density_len()
    }
    fn sums_weighted_hessian(&self) -> bool {
        self.surface.sums_weighted_hessian()
    }
    fn sums_hessian(&self) -> bool {
        self.surface.sums_hessian()
    }
}
