//! An axis-aligned box as a kind of domain (DESIGN §11): the first kind besides the
//! simplicial boundary, and the start of the periodic box of DESIGN §14 (which adds the
//! images of the neighbours). A convex cell restricted to a box is the cell clipped by the
//! box's `2D` sides: no cones, no boundary simplices, no winding numbers.

use crate::error::CoreError;
use crate::geometry::{sub, Aabb, HalfSpace};
use crate::moments::Moments;

use super::clip::{measure, MeasureScratch};
use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::faces::FaceRow;

/// The box `[lo, hi]` (every side of positive length), `L`. Its sides are boundary
/// elements `0..2D`: side `2k` is `x_k = lo_k`, side `2k + 1` is `x_k = hi_k`.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxDomain<const D: usize> {
    bounds: Aabb<D>,
    /// The `2^D` corners: where a polynomial density takes its extremes on the boundary.
    corners: Vec<[f64; D]>,
}

impl<const D: usize> BoxDomain<D> {
    /// The box between the corners `lo` and `hi`.
    ///
    /// Errors: a non-finite coordinate (vertex 0 is `lo`, 1 is `hi`), or a side of zero or
    /// negative length (no positive volume).
    pub fn new(lo: [f64; D], hi: [f64; D]) -> Result<Self, CoreError> {
        for (index, corner) in [lo, hi].iter().enumerate() {
            if let Some(&value) = corner.iter().find(|x| !x.is_finite()) {
                return Err(CoreError::NonFiniteVertex { index, value });
            }
        }
        if (0..D).any(|k| lo[k] >= hi[k]) {
            let volume = (0..D).map(|k| hi[k] - lo[k]).product();
            return Err(CoreError::NonPositiveVolume { volume });
        }
        Ok(Self::of_checked(Aabb { lo, hi }))
    }

    /// The box `bounds`, checked already (finite, sides of positive length).
    pub(super) fn of_checked(bounds: Aabb<D>) -> Self {
        let Aabb { lo, hi } = bounds;
        let corners = (0..1usize << D)
            .map(|bits| std::array::from_fn(|k| if bits >> k & 1 == 0 { lo[k] } else { hi[k] }))
            .collect();
        Self { bounds, corners }
    }

    /// The sides along the axes `along` marks, relative to `site`, each with its boundary
    /// element number.
    fn sides(
        &self,
        site: [f64; D],
        along: [bool; D],
    ) -> impl Iterator<Item = (u32, HalfSpace<D>)> + '_ {
        let (lo, hi) = (sub(self.bounds.lo, site), sub(self.bounds.hi, site));
        (0..D).filter(move |&k| along[k]).flat_map(move |k| {
            let axis: [f64; D] = std::array::from_fn(|j| if j == k { 1.0 } else { 0.0 });
            let below = HalfSpace {
                normal: axis.map(|a| -a),
                offset: -lo[k],
            };
            let above = HalfSpace {
                normal: axis,
                offset: hi[k],
            };
            [(2 * k as u32, below), (2 * k as u32 + 1, above)]
        })
    }

    /// `cell` (relative to `site`) clipped by the sides along the axes `along` marks (all of
    /// them for this box; the non-periodic ones for a [`super::PeriodicBox`]).
    pub(super) fn cut_along<C: ConvexCell<D>>(
        &self,
        cell: &mut C,
        site: [f64; D],
        along: [bool; D],
    ) {
        for (t, h) in self.sides(site, along) {
            if cell.is_empty() {
                return;
            }
            cell.clip(&h, Face::Boundary(t));
        }
    }

    /// [`DomainKind::clip`] of a cell by the sides along the axes `along` marks (all of them
    /// for this box; the non-periodic ones for a [`super::PeriodicBox`]): the moments of
    /// `cell` (relative to `site`) cut by those sides, in a copy kept in `scratch`, or of
    /// `cell` itself when no axis is marked (a box periodic along every axis).
    pub(super) fn clip_along<C: ConvexCell<D>>(
        &self,
        cell: &C,
        site: [f64; D],
        along: [bool; D],
        row: Option<FaceRow<'_, D>>,
        scratch: &mut MeasureScratch<D, C>,
    ) -> Moments<D> {
        if !along.contains(&true) {
            return measure(cell, row, &mut scratch.faces);
        }
        let piece = scratch.piece.get_or_insert_with(|| cell.clone());
        piece.clone_from(cell);
        self.cut_along(piece, site, along);
        measure(piece, row, &mut scratch.faces)
    }

    /// The inside test along the axes `along` marks (every coordinate counts as inside along
    /// the others): 0 outside, `None` on a side, 1 inside.
    pub(super) fn locate_along(&self, point: &[f64; D], along: [bool; D]) -> Option<i32> {
        let (lo, hi) = (self.bounds.lo, self.bounds.hi);
        let axes = (0..D).filter(|&k| along[k]);
        if axes.clone().any(|k| point[k] < lo[k] || point[k] > hi[k]) {
            Some(0)
        } else if axes.clone().any(|k| point[k] == lo[k] || point[k] == hi[k]) {
            None
        } else {
            Some(1)
        }
    }
}

impl<const D: usize> DomainKind<D> for BoxDomain<D> {
    fn bounds(&self) -> Aabb<D> {
        self.bounds
    }

    fn volume(&self) -> f64 {
        (0..D)
            .map(|k| self.bounds.hi[k] - self.bounds.lo[k])
            .product()
    }

    fn locate(&self, point: &[f64; D]) -> Option<i32> {
        self.locate_along(point, [true; D])
    }

    fn density_checkpoints(&self) -> &[[f64; D]] {
        &self.corners
    }

    fn is_convex(&self) -> bool {
        true
    }

    fn cut_convex<C: ConvexCell<D>>(&self, cell: &mut C, site: [f64; D], _: &mut Vec<u32>) -> bool {
        self.cut_along(cell, site, [true; D]);
        true
    }

    /// The cell's own bound: its part in the box lies within it.
    fn local_radius2<C: ConvexCell<D>>(&self, cell: &C, _: [f64; D]) -> f64 {
        cell.max_dist2()
    }

    fn clip<C: ConvexCell<D>>(
        &self,
        cell: &C,
        site: [f64; D],
        _: Option<i32>,
        row: Option<FaceRow<'_, D>>,
        scratch: &mut MeasureScratch<D, C>,
    ) -> Moments<D> {
        self.clip_along(cell, site, [true; D], row, scratch)
    }
}

#[cfg(test)]
mod tests {
    use std::ops::ControlFlow;

    use super::*;
    use crate::diagram::{clipped_diagram, Diagram, PolygonCell, PolyhedronCell, Request};
    use crate::domain::{Polygon, Solid};
    use crate::optimise::{cvt, Method, Rule, Settings};
    use crate::sample::interior_sites;

    /// Moments, boundary shares and shared faces agree to `rel` of the cells' scale.
    fn assert_same<const D: usize>(a: &Diagram<D>, b: &Diagram<D>, rel: f64) {
        assert_eq!(a.neighbor_offsets, b.neighbor_offsets);
        assert_eq!(a.neighbor_sites, b.neighbor_sites);
        let close = |x: f64, y: f64, scale: f64| (x - y).abs() <= rel * scale;
        for (i, (m, n)) in a.moments.iter().zip(&b.moments).enumerate() {
            let h = m.mass.powf(1.0 / D as f64);
            assert!(close(m.mass, n.mass, m.mass), "cell {i}: {m:?} {n:?}");
            assert!(
                (0..D).all(|k| close(m.first[k], n.first[k], m.mass * h)),
                "cell {i}"
            );
            assert!(close(m.second, n.second, m.mass * h * h), "cell {i}");
            let (s, t) = (a.boundary_measure[i], b.boundary_measure[i]);
            assert!(close(s, t, h.powi(D as i32 - 1)), "cell {i}: {s} {t}");
        }
        for (x, y) in a.neighbor_measures.iter().zip(&b.neighbor_measures) {
            assert!(close(*x, *y, x.abs().max(1e-300)), "{x} {y}");
        }
    }

    /// The same cells as the cuboid bounded by twelve triangles, measured through cones.
    #[test]
    fn a_box_gives_the_cells_of_the_same_solid() {
        let (lo, hi) = ([0.2, -0.1, 0.0], [1.2, 0.5, 0.8]);
        let cuboid = Solid::cuboid(lo, hi).unwrap();
        let boxed = BoxDomain::new(lo, hi).unwrap();
        let sites = interior_sites(&cuboid, 400, 11);
        let request = Request::default();
        let a = clipped_diagram::<3, PolyhedronCell, _>(&cuboid, &sites, &request).unwrap();
        let b = clipped_diagram::<3, PolyhedronCell, _>(&boxed, &sites, &request).unwrap();
        assert_same(&a.diagram, &b.diagram, 1e-12);
        let total: f64 = b.diagram.volumes().iter().sum();
        assert!((total - boxed.volume()).abs() < 1e-14 * boxed.volume());
    }

    /// In 2D, against the square polygon; sites outside the box are allowed too.
    #[test]
    fn a_box_gives_the_cells_of_the_same_polygon() {
        let square = Polygon::new(
            vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]],
            vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        )
        .unwrap();
        let boxed = BoxDomain::new([0.0, 0.0], [2.0, 1.0]).unwrap();
        let mut sites = interior_sites(&square, 300, 4);
        sites.push([2.5, 0.5]);
        let request = Request {
            options: crate::diagram::Options {
                allow_outside: true,
            },
            ..Request::default()
        };
        let a = clipped_diagram::<2, PolygonCell, _>(&square, &sites, &request).unwrap();
        let b = clipped_diagram::<2, PolygonCell, _>(&boxed, &sites, &request).unwrap();
        assert_same(&a.diagram, &b.diagram, 1e-12);
    }

    /// The optimisers run on the seam alone: ten Lloyd steps in the box and in the cuboid
    /// reach the same sites.
    #[test]
    fn lloyd_in_a_box_follows_lloyd_in_the_cuboid() {
        let cuboid = Solid::cuboid([0.0; 3], [1.0; 3]).unwrap();
        let boxed = BoxDomain::new([0.0; 3], [1.0; 3]).unwrap();
        let sites = interior_sites(&cuboid, 200, 2);
        let settings = Settings {
            method: Method::Lloyd,
            rule: Rule::Gap,
            tol: 0.0,
            max_iter: 10,
            ..Settings::default()
        };
        let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
        let a = cvt::<3, PolyhedronCell, _>(&cuboid, sites.clone(), &settings, go).unwrap();
        let b = cvt::<3, PolyhedronCell, _>(&boxed, sites, &settings, go).unwrap();
        assert_eq!(a.iterations(), 10);
        for (p, q) in a.sites.iter().zip(&b.sites) {
            assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-12), "{p:?} {q:?}");
        }
    }

    #[test]
    fn a_flat_box_is_refused() {
        assert!(matches!(
            BoxDomain::new([0.0, 0.0], [1.0, 0.0]),
            Err(CoreError::NonPositiveVolume { .. })
        ));
        assert!(matches!(
            BoxDomain::new([0.0, f64::NAN], [1.0, 1.0]),
            Err(CoreError::NonFiniteVertex { index: 0, .. })
        ));
    }
}
