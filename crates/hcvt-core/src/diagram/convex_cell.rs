//! What a convex Voronoi cell must offer the dimension-generic clipping (DESIGN §3).

use crate::geometry::{Aabb, HalfSpace};
use crate::moments::{FaceMoments, Moments};

/// Whether `pred` holds for some item, tested four at a time without branches between
/// them (`|`, not `||`), then the rest one by one: the clips' test of whether any vertex
/// lies beyond the half-space, which most clips of a Voronoi cell answer "no" after
/// reading every vertex. A running maximum of the distances instead made that pass wait
/// on its chain of comparisons (3D: 44% fewer samples in the test, `perf`, ball 1k).
#[inline]
pub(super) fn any_by_fours<T>(items: &[T], pred: impl Fn(&T) -> bool) -> bool {
    let mut fours = items.chunks_exact(4);
    (fours.by_ref()).any(|c| pred(&c[0]) | pred(&c[1]) | pred(&c[2]) | pred(&c[3]))
        || fours.remainder().iter().any(pred)
}

/// The order of the faces of a canonical cell ([`ConvexCell::canonicalise`]): by their
/// normals' coordinates, x first. It does not depend on what the neighbours are called, so
/// a partition, which numbers its sites its own way, orders them as the whole diagram does.
pub(super) fn normal_order<const D: usize>(a: &[f64; D], b: &[f64; D]) -> std::cmp::Ordering {
    (0..D)
        .map(|k| a[k].total_cmp(&b[k]))
        .find(|o| o.is_ne())
        .unwrap_or(std::cmp::Ordering::Equal)
}

/// What made a face of a convex cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Face {
    /// A side of the domain's bounding box, where every cell starts.
    Box,
    /// The bisector with site `j`: a dual (Delaunay) edge.
    Neighbor(u32),
    /// The hyperplane of boundary simplex `t`.
    Boundary(u32),
    /// A side of a cone from the apex through a boundary simplex.
    Cone,
}

/// A convex polytope in coordinates relative to its site, clipped one half-space at a time.
pub trait ConvexCell<const D: usize>: Clone + Send + Sync {
    /// The box `b` (relative to the site); all its faces are [`Face::Box`].
    fn from_box(b: &Aabb<D>) -> Self;

    /// Become [`ConvexCell::from_box`] of `b`, reusing this cell's buffers where it can.
    fn reset_to_box(&mut self, b: &Aabb<D>) {
        *self = Self::from_box(b);
    }

    /// Keep the part in `h`, tagging the new face with `face`; `false` when `h` held the
    /// whole cell already and nothing changed.
    fn clip(&mut self, h: &HalfSpace<D>, face: Face) -> bool;

    /// Recompute every vertex from the half-spaces of the faces it joins, and put the faces
    /// in [`normal_order`] (2D: start at the least), so that the cell's bits depend only on
    /// which half-spaces bound it, not on the order they cut it: a warm diagram can then
    /// build the cell from its previous neighbours ([`ConvexCell::rebuild_from_ring`]) bit
    /// for bit as the clips made it. `plane(j)`: the half-space of neighbour `j`'s face,
    /// as clipped by.
    /// `false`, the cell unchanged, when some face is not a neighbour's, a vertex does not
    /// come out finite, or the kind has no canonical form (the default: 3D).
    fn canonicalise(&mut self, plane: impl Fn(u32) -> HalfSpace<D>) -> bool {
        let _ = plane;
        false
    }

    /// Become the canonical cell ([`ConvexCell::canonicalise`]) whose faces are those of
    /// the neighbours `ring` in order (3D: with the vertices where the faces `triangles`
    /// meet), `plane(j)` the half-space of neighbour `j`'s face, if those half-spaces bound
    /// such a cell with every vertex farther than `separation` (relative to each plane's
    /// `|normal|²`) inside every half-space but its own faces'. `false` (the cell left in
    /// any state) otherwise, or when the kind has no canonical form (the default).
    fn rebuild_from_ring(
        &mut self,
        ring: &[u32],
        triangles: &[[u8; 3]],
        plane: impl Fn(u32) -> HalfSpace<D>,
        separation: f64,
    ) -> bool {
        let _ = (ring, triangles, plane, separation);
        false
    }

    /// Append the neighbours of a canonical cell ([`ConvexCell::canonicalise`]) to
    /// `neighbours`, face after face, and (3D) its vertices as triples of their faces'
    /// positions there to `triangles`: what [`ConvexCell::rebuild_from_ring`] rebuilds it
    /// from.
    fn ring(&self, neighbours: &mut Vec<u32>, triangles: &mut Vec<[u8; 3]>) {
        let _ = (neighbours, triangles);
    }

    /// Call `f(face, h)` for the half-space `h` (relative to the site) of every face. The
    /// 3D cell gives every plane that has cut it, in the order they did, exactly as given
    /// to [`ConvexCell::clip`] (one may since have been cut away); the 2D cell each edge's
    /// line through its ends. The sphere (`sphere.rs`) reads its great circles here.
    fn for_each_plane(&self, f: impl FnMut(Face, &HalfSpace<D>));

    /// Nothing (of positive measure) is left.
    fn is_empty(&self) -> bool;

    /// Largest squared distance of a vertex from the site (the security radius², Ray et al.
    /// 2018): a site farther than twice that distance cannot cut the cell.
    fn max_dist2(&self) -> f64;

    /// Bounding box relative to the site.
    fn bounds(&self) -> Aabb<D>;

    /// The vertices, relative to the site.
    fn vertices(&self) -> &[[f64; D]];

    /// Some face's half-space has every one of `points` (relative to the site) strictly
    /// outside, so their convex hull misses the cell.
    fn excludes(&self, points: &[[f64; D]]) -> bool;

    /// An upper bound on `|x|²` over the points `x` of the simplex (relative to the site)
    /// inside the cell, `None` when the simplex misses the cell. This default bounds by
    /// the simplex's farthest vertex.
    fn farthest_on(&self, simplex: &[[f64; D]; D]) -> Option<f64> {
        if self.excludes(simplex) {
            return None;
        }
        Some(
            simplex
                .iter()
                .map(|&v| crate::geometry::norm2(v))
                .fold(0.0, f64::max),
        )
    }

    /// Mean of the vertices: a point strictly inside a non-empty cell.
    fn vertex_mean(&self) -> [f64; D];

    /// Mass, first and second moments about the site.
    fn moments(&self) -> Moments<D>;

    /// Call `f(simplex, measure)` for every simplex of the cell's cone decomposition from
    /// the site: the `D` vertices besides the site (relative to it) and the signed measure
    /// (area in 2D, volume in 3D) that the moments sum. What a density is integrated over
    /// (`density`).
    fn for_each_cone(&self, f: impl FnMut(&[[f64; D]; D], f64));

    /// Call `f(face, simplex, measure)` for every `(D − 1)`-simplex of the faces (edges in
    /// 2D; the fan triangles of [`ConvexCell::for_each_cone`] in 3D), relative to the site,
    /// with its measure: what a density weighs the Hessian's face terms over. One simplex per
    /// cone of [`ConvexCell::for_each_cone`], in the same order (the transport's face masses
    /// take each simplex's `∫ρ` from its cone's nodes: `FaceSums::integrate_face_masses`).
    fn for_each_face_simplex(&self, f: impl FnMut(Face, &[[f64; D]; D], f64));

    /// Call `f(face, measure)` for every face (length in 2D, area in 3D).
    fn for_each_face(&self, f: impl FnMut(Face, f64));

    /// [`ConvexCell::for_each_face`] and [`ConvexCell::moments`] together, for cells that
    /// can do both in one pass over their faces.
    fn moments_and_faces(&self, f: impl FnMut(Face, f64)) -> Moments<D> {
        self.for_each_face(f);
        self.moments()
    }

    /// Call `f(face, moments)` for every face, with the face's moments about the site: the
    /// integrals behind the optimiser's Hessian (`optimise::hessian`).
    fn for_each_face_moments(&self, f: impl FnMut(Face, FaceMoments<D>));

    /// [`ConvexCell::for_each_face_moments`] and [`ConvexCell::moments`] together.
    fn moments_and_face_moments(&self, f: impl FnMut(Face, FaceMoments<D>)) -> Moments<D> {
        self.for_each_face_moments(f);
        self.moments()
    }
}
