//! The convex cell clipped by the domain (DESIGN §3, step 2, and step 4 for an apex on the
//! boundary): integrated through signed cones from an apex ([`clip_by_domain`], with
//! [`choose_apex`] and [`cone_sides`]), or, for a site strictly inside a convex domain or
//! far from the boundary, clipped by the boundary planes near it ([`clip_convex`],
//! [`clip_by_planes`]). Owns the measuring of a finished cell into its moments and its
//! `FaceSums`.

use crate::domain::{Boundary, WindingNumber};
use crate::geometry::{add, dot, norm2, scale, sub, Aabb, Euclid, HalfSpace, Space};
use crate::moments::Moments;

use super::convex_cell::{ConvexCell, Face};
use super::faces::{FaceRow, FaceSums};

/// Buffers of [`clip_by_domain`] (and of every [`super::DomainKind::clip`]), reused from
/// cell to cell; opaque outside the diagram.
pub struct MeasureScratch<const D: usize, C> {
    pub(super) faces: FaceSums<D>,
    pub(super) piece: Option<C>,
    candidates: Vec<u32>,
}

impl<const D: usize, C> Default for MeasureScratch<D, C> {
    fn default() -> Self {
        Self {
            faces: FaceSums::default(),
            piece: None,
            candidates: Vec::new(),
        }
    }
}

/// The boundary simplices whose boxes meet the cell's box (the cell relative to `site`).
pub(super) fn boundary_candidates<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    out: &mut Vec<u32>,
) where
    Euclid: Space<D>,
{
    let bounds = cell.bounds();
    let query = Aabb {
        lo: add(bounds.lo, site),
        hi: add(bounds.hi, site),
    };
    boundary.bvh().query(&query, out);
}

/// A cell whose signed pieces sum to at most this fraction of their absolute sum (or of
/// its bounding box) is empty.
const EMPTY_REL: f64 = 16.0 * f64::EPSILON;

/// Integrate `cell` (relative to `site`) restricted to the domain, through signed cones:
/// its moments (zero for an empty cell), its faces measured into `scratch.faces`.
pub(super) fn clip_by_domain<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    site_winding: Option<i32>,
    row: Option<FaceRow<'_, D>>,
    scratch: &mut MeasureScratch<D, C>,
) -> Moments<D>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let MeasureScratch {
        faces,
        piece,
        candidates,
    } = scratch;
    faces.clear();
    if cell.is_empty() {
        return Moments::zero();
    }
    candidates.clear();
    boundary_candidates(boundary, cell, site, candidates);
    if site_winding == Some(1) && (candidates.is_empty() || boundary.is_convex()) {
        // Strictly inside, and no boundary near (or a convex one): no cones to cut.
        return clip_convex(boundary, cell, site, candidates, row, faces, piece);
    }
    let (apex, winding) = choose_apex(boundary, cell, site, site_winding, candidates);
    // Σ |mass| of the signed terms: what their round-off scales with.
    let mut gross = 0.0;
    let mut total = Moments::zero();
    if winding != 0 {
        let m = faces.integrate(cell, winding as f64, row);
        total.add_scaled(&m, winding as f64);
        gross += (winding as f64 * m.mass).abs();
    }
    let apex_abs = add(apex, site);
    let piece = piece.get_or_insert_with(|| cell.clone()); // clone_from keeps its buffers
    for &t in candidates.iter() {
        let simplex = boundary.simplex(t);
        let side = Euclid::side(&simplex, &apex_abs);
        if side == 0.0 {
            continue; // the apex is on T's hyperplane: the cone is flat
        }
        let sigma = if side > 0.0 { 1.0 } else { -1.0 };
        let rel = simplex.map(|v| sub(v, site));
        // A segment from the apex to a point of C ∩ K(T) crosses T inside the convex C, so
        // a simplex that some face of C separates from C has an empty piece.
        if cell.excludes(&rel) {
            continue;
        }
        // Beyond T as seen from the apex: the inner side when the apex is outside T. Cut
        // there first: what is left beyond a small simplex is small, and the cone sides
        // then clip few vertices.
        let normal = Euclid::normal(&rel);
        let beyond = HalfSpace::through(
            rel[0],
            if sigma > 0.0 {
                normal
            } else {
                scale(normal, -1.0)
            },
        );
        piece.clone_from(cell);
        piece.clip(&beyond, Face::Boundary(t));
        for h in cone_sides(&rel, apex) {
            if piece.is_empty() {
                break;
            }
            piece.clip(&h, Face::Cone);
        }
        if piece.is_empty() {
            continue;
        }
        let m = faces.integrate(piece, sigma, row);
        total.add_scaled(&m, sigma);
        gross += m.mass.abs();
    }
    // Signed pieces that cancel to round-off leave a mass of either sign near 1e-18 and a
    // G of NaN or 1e15: the cell of a site outside the domain that only touches it, or
    // whose pieces are slivers of round-off. Their error scales with the pieces and with
    // the cell's coordinates, so measure against both: the cell is empty.
    let extent = cell.bounds();
    let box_measure: f64 = (0..D).map(|k| extent.hi[k] - extent.lo[k]).product();
    if total.mass.abs() <= EMPTY_REL * gross.max(box_measure) {
        faces.clear();
        return Moments::zero();
    }
    total
}

/// [`clip_by_domain`] for a site strictly inside the domain when the domain is convex or
/// no boundary simplex's box meets the cell's box: the cell clipped by the inner
/// half-spaces of those simplices (`candidates`), measured into `faces`. `piece` holds
/// the clipped copy.
///
/// Exact: the domain `Ω` lies in every such half-space, so nothing of `C ∩ Ω` is cut. A
/// point `x` of the clipped cell outside `Ω` would see the segment from the site `y`
/// (strictly inside `Ω`, so strictly inside every simplex's hyperplane) leave `Ω` through
/// some simplex `T` at a point `z` of `C` before `x`: `T` meets the cell's box, so it was
/// clipped, and `x`, beyond `z` on a line from the inner side, is outside `T`'s half-space.
/// One clip per simplex instead of a cone piece (a copy of the cell and `D + 1` clips).
/// With no candidates the argument needs no convexity: the cell lies in `Ω`.
fn clip_convex<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    candidates: &[u32],
    row: Option<FaceRow<'_, D>>,
    faces: &mut FaceSums<D>,
    piece: &mut Option<C>,
) -> Moments<D>
where
    Euclid: Space<D>,
{
    if candidates.is_empty() {
        // An interior cell: nothing to cut, and no copy to make.
        return measure(cell, row, faces);
    }
    let clipped = piece.get_or_insert_with(|| cell.clone());
    clipped.clone_from(cell);
    clip_by_planes(boundary, clipped, site, candidates);
    measure(clipped, row, faces)
}

/// [`clip_convex`]'s cut inside [`voronoi_cell`](super::voronoi_cell::voronoi_cell): `cell` (relative to `site`, strictly
/// inside the convex domain) clipped by the inner half-spaces of the boundary simplices
/// whose boxes meet its box.
///
/// The cell then lies in the domain, and stays there as later bisectors cut it: any
/// simplex meeting a later cell's box met this larger box, so its half-space was clipped
/// by or already held the cell, [`clip_convex`]'s proof applies to every later cell, and
/// its own cuts would change nothing: the cell is measured as it is.
pub(super) fn cut_by_boundary<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &mut C,
    site: [f64; D],
    candidates: &mut Vec<u32>,
) where
    Euclid: Space<D>,
{
    candidates.clear();
    boundary_candidates(boundary, cell, site, candidates);
    clip_by_planes(boundary, cell, site, candidates);
}

/// Clip `cell` (relative to `site`, strictly inside the convex domain) by the inner
/// half-spaces of the simplices `candidates`, tagged `Face::Boundary`.
///
/// Nearest planes first: they cut away most of what lies outside, and the later clips
/// then have fewer vertices to remove. A plane farther from the site than the cell's
/// farthest vertex cannot cut it, and neither can any later one: stop there.
fn clip_by_planes<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &mut C,
    site: [f64; D],
    candidates: &[u32],
) where
    Euclid: Space<D>,
{
    let mut planes: Vec<(f64, u32, HalfSpace<D>)> = candidates
        .iter()
        .map(|&t| {
            let rel = boundary.simplex(t).map(|v| sub(v, site));
            let h = HalfSpace::through(rel[0], Euclid::normal(&rel));
            (h.offset / norm2(h.normal).sqrt(), t, h)
        })
        .collect();
    planes.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    for (distance, t, h) in planes {
        if distance * distance > cell.max_dist2() {
            break;
        }
        cell.clip(&h, Face::Boundary(t));
    }
}

/// The moments of a cell that lies in the domain, its face measures (and, for the
/// integrand of a `row`, face integrals) into `faces`.
pub(super) fn measure<const D: usize, C: ConvexCell<D>>(
    cell: &C,
    row: Option<FaceRow<'_, D>>,
    faces: &mut FaceSums<D>,
) -> Moments<D> {
    faces.clear();
    faces.integrate(cell, 1.0, row)
}

/// The `D` side half-spaces of the cone from `apex` through the simplex `rel` (both
/// relative to the site): the hyperplane through the apex and each facet of the simplex,
/// keeping the side of the remaining vertex.
fn cone_sides<const D: usize>(
    rel: &[[f64; D]; D],
    apex: [f64; D],
) -> impl Iterator<Item = HalfSpace<D>> + '_
where
    Euclid: Space<D>,
{
    (0..D).map(move |k| {
        // Replace vertex k by the apex: the facet opposite vertex k, coned to the apex.
        let mut points = *rel;
        points[k] = apex;
        let mut normal = Euclid::normal(&points);
        if dot(normal, sub(rel[k], apex)) > 0.0 {
            normal = scale(normal, -1.0);
        }
        HalfSpace::through(apex, normal)
    })
}

/// Fractional part of the golden ratio: successive multiples spread evenly over [0, 1).
const GOLDEN: f64 = 0.618_033_988_749_895;

/// Least distance of the apex from the hyperplane of a boundary simplex near the cell,
/// relative to the cell's radius.
const APEX_CLEARANCE: f64 = 1e-9;

/// A point of the cell to cone from, relative to the site, and its winding number.
///
/// The site itself when it lies strictly inside or outside the domain, inside its
/// (box-limited) cell and clear of the hyperplanes of the boundary simplices near the cell;
/// otherwise the vertex mean of the cell, nudged towards successive vertices until it is
/// off the boundary (a site on the boundary has no winding number) and clear of them.
/// Only for a cell of no measure can every candidate stay on the boundary.
fn choose_apex<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    site_winding: Option<i32>,
    candidates: &[u32],
) -> ([f64; D], i32)
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let site_in_box = {
        let b = boundary.bounds();
        (0..D).all(|k| b.lo[k] <= site[k] && site[k] <= b.hi[k])
    };
    // An apex within round-off of a simplex's hyperplane (a site 1e-17 off a face, as a
    // face centroid computed in floats is) makes the cone's sides nearly coincide with
    // that hyperplane, and which side of them to keep is decided by round-off: a sphere
    // with one such site got the volume -3.6 instead of 4.15. Such an apex is refused.
    let size = cell.max_dist2().sqrt();
    let clear = |apex: [f64; D]| {
        candidates.iter().all(|&t| {
            let rel = boundary.simplex(t).map(|v| sub(v, site));
            let normal = Euclid::normal(&rel);
            let dist = dot(normal, sub(apex, rel[0])).abs();
            dist > APEX_CLEARANCE * size * norm2(normal).sqrt()
        })
    };
    if let (Some(w), true) = (site_winding, site_in_box) {
        if clear([0.0; D]) {
            return ([0.0; D], w);
        }
    }
    let mean = cell.vertex_mean();
    let vertices = cell.vertices();
    let mut candidate = mean;
    let mut fallback = None;
    for step in 0..64 {
        if let Some(w) = Euclid::winding_number(boundary, &add(candidate, site)) {
            if clear(candidate) {
                return (candidate, w);
            }
            fallback = fallback.or(Some((candidate, w)));
        }
        // Deterministic nudge: a convex combination of the vertices with irregular positive
        // weights (golden-ratio sequence), so strictly inside the cell and on no line
        // through the mean. Nudges along fixed directions stayed on the boundary: a
        // square cell of a site on a slope-1 edge counted twice its area, and the box
        // cell of a pinched bow-tie had every vertex direction along an edge.
        if vertices.is_empty() {
            break;
        }
        let mut sum = [0.0; D];
        let mut total = 0.0;
        for (j, v) in vertices.iter().enumerate() {
            let w = 0.25 + ((j as f64 + 1.0) * GOLDEN * (step as f64 + 1.0)).fract();
            total += w;
            for k in 0..D {
                sum[k] += w * v[k];
            }
        }
        candidate = sum.map(|x| x / total);
    }
    fallback.unwrap_or((mean, 0))
}

/// An upper bound on `|x|²` over the part of `cell` (relative to `site`) inside the domain.
///
/// The farthest point of that part is one of its vertices: a vertex of the cell inside
/// the domain, or a point where the boundary meets the cell, which lies on a boundary
/// simplex that the cell does not exclude. Exact winding numbers decide the first kind;
/// the farthest vertex of each simplex bounds the second.
pub(super) fn domain_radius2<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
) -> f64
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let r2 = boundary_radius2(boundary, cell, site);
    // Only vertices beyond the simplices' bound can raise it: test them farthest first
    // and stop at the first inside the domain (each test is a ray cast).
    let mut far: Vec<(f64, [f64; D])> = cell
        .vertices()
        .iter()
        .map(|&v| (norm2(v), v))
        .filter(|&(d2, _)| d2 > r2)
        .collect();
    far.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    for (d2, v) in far {
        if Euclid::winding_number(boundary, &add(v, site)) != Some(0) {
            return d2;
        }
    }
    r2
}

/// The largest [`ConvexCell::farthest_on`] over the boundary simplices whose boxes meet
/// the cell's box ([`boundary_candidates`]), `0` when the cell misses them all.
///
/// A boundary cell not yet localised is open to the far side of the domain's box, and its
/// box holds much of the boundary (on Armadillo, 86,482 triangles and 20k sites, 621
/// simplices a cell, of which the cell excludes all but 107, each exclusion a test against
/// some 23 planes). In 3D the maximum is read a subtree at a time instead, skipping a BVH
/// node when its box lies
/// - within the largest distance found so far: no vertex in it is farther;
/// - or outside one of the cell's planes: [`ConvexCell::for_each_plane`] gives the 3D
///   cell's planes, the very ones that [`ConvexCell::excludes`] tests, so `excludes` and
///   the default `farthest_on` refuse every simplex in it.
///
/// Each with a margin far above the round-off of the tests it stands for: the simplices
/// skipped could not have changed the maximum, which keeps its bits. (The 2D cell's
/// `excludes` skips its shortest edges and its `farthest_on` bounds the clipped segment
/// with a margin: the bounds would not be exact there; polygons take the plain query.)
fn boundary_radius2<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
) -> f64
where
    Euclid: Space<D>,
{
    let farthest_on = |t: u32| cell.farthest_on(&boundary.simplex(t).map(|v| sub(v, site)));
    if D != 3 {
        let mut candidates = Vec::new();
        boundary_candidates(boundary, cell, site, &mut candidates);
        return candidates
            .into_iter()
            .filter_map(farthest_on)
            .fold(0.0, f64::max);
    }
    let bounds = cell.bounds();
    let query = Aabb {
        lo: add(bounds.lo, site),
        hi: add(bounds.hi, site),
    };
    // Each plane that still bears a face (a vertex on it, to round-off: the others were
    // cut away and bound less), with the l1 norm of its normal, which scales its dot
    // products' round-off.
    let vertices = cell.vertices();
    let tolerance = 1e-9 * cell.max_dist2().sqrt();
    let mut planes: Vec<(HalfSpace<D>, f64)> = Vec::new();
    cell.for_each_plane(|_, h| {
        let l1: f64 = h.normal.iter().map(|x| x.abs()).sum();
        let limit = h.offset - tolerance * l1;
        if vertices.iter().any(|&v| dot(h.normal, v) >= limit) {
            planes.push((*h, l1));
        }
    });
    let r2 = std::cell::Cell::new(0.0_f64);
    let skip = |b: &Aabb<D>| {
        // A simplex vertex `v` in `b` has `v - site` in `b - site` (the subtraction
        // rounds monotonically), so each coordinate within `far` of the site.
        let rel = b.relative_to(site);
        let far: [f64; D] = std::array::from_fn(|k| rel.lo[k].abs().max(rel.hi[k].abs()));
        if norm2(far) * (1.0 + ROUNDING_MARGIN) < r2.get() {
            return true;
        }
        let reach = far.iter().fold(0.0, |a: f64, &x| a.max(x));
        planes.iter().any(|(h, l1)| {
            let nearest: [f64; D] = std::array::from_fn(|k| {
                if h.normal[k] >= 0.0 {
                    rel.lo[k]
                } else {
                    rel.hi[k]
                }
            });
            dot(h.normal, nearest) > h.offset + ROUNDING_MARGIN * l1 * reach
        })
    };
    boundary.bvh().visit_overlapping(&query, skip, |t| {
        let rel = boundary.simplex(t).map(|v| sub(v, site));
        // The default `farthest_on`'s bound, without its plane tests when it cannot raise
        // the maximum.
        if rel.iter().any(|&v| norm2(v) > r2.get()) {
            if let Some(d2) = cell.farthest_on(&rel) {
                r2.set(r2.get().max(d2));
            }
        }
    });
    r2.get()
}

/// Relative margin of [`boundary_radius2`]'s bounds: some 1,500 times the round-off of a
/// 3-term dot product, twice over.
const ROUNDING_MARGIN: f64 = 1e-12;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagram::voronoi_cell::{voronoi_cell, CellScratch};
    use crate::diagram::{DomainKind, PolyhedronCell, SiteIndex};
    use crate::domain::Solid;
    use crate::sample::interior_sites;

    /// A closed, non-convex solid of `2 * rows * (cols - 1)` triangles: a latitude-longitude
    /// sphere with its radius rippled by ±35%, outward.
    fn bumpy_sphere(rows: usize, cols: usize) -> Solid {
        let ring = |r: usize, c: usize| (1 + (r - 1) * cols + c % cols) as u32;
        let mut vertices = vec![[0.0, 0.0, 1.0]];
        for r in 1..rows {
            let theta = std::f64::consts::PI * r as f64 / rows as f64;
            for c in 0..cols {
                let phi = std::f64::consts::TAU * c as f64 / cols as f64;
                let radius = 1.0 + 0.35 * (3.0 * theta).sin() * (4.0 * phi).sin();
                vertices.push([
                    radius * theta.sin() * phi.cos(),
                    radius * theta.sin() * phi.sin(),
                    radius * theta.cos(),
                ]);
            }
        }
        let south = vertices.len() as u32;
        vertices.push([0.0, 0.0, -1.0]);
        let mut faces = Vec::new();
        for c in 0..cols {
            faces.push([0, ring(1, c), ring(1, c + 1)]);
            faces.push([south, ring(rows - 1, c + 1), ring(rows - 1, c)]);
            for r in 1..rows - 1 {
                let (a, b) = (ring(r, c), ring(r, c + 1));
                let (d, e) = (ring(r + 1, c), ring(r + 1, c + 1));
                faces.push([a, d, e]);
                faces.push([a, e, b]);
            }
        }
        Solid::new(vertices, faces).unwrap()
    }

    /// `boundary_radius2`'s pruned walk gives the maximum of `farthest_on` over every
    /// candidate bit for bit, on cells open to the outside (the box clipped by a few
    /// neighbours, as before a boundary cell is localised) and on closed ones.
    #[test]
    fn pruned_boundary_radius_keeps_its_bits() {
        let solid = bumpy_sphere(40, 80);
        assert!(!solid.is_convex());
        let sites = interior_sites(&solid, 2_000, 3);
        let (mut open, mut far) = (0, 0);
        for (i, &site) in sites.iter().enumerate().step_by(7) {
            let mut cell = PolyhedronCell::from_box(&DomainKind::start(&solid, site));
            let mut near: Vec<usize> = (0..sites.len()).filter(|&j| j != i).collect();
            near.sort_by(|&a, &b| {
                norm2(sub(sites[a], site)).total_cmp(&norm2(sub(sites[b], site)))
            });
            for (k, &j) in near.iter().take(40).enumerate() {
                cell.clip(
                    &HalfSpace::bisector(sub(sites[j], site)),
                    Face::Neighbor(j as u32),
                );
                if k != 7 && k != 39 {
                    continue;
                }
                let mut candidates = Vec::new();
                boundary_candidates(&solid, &cell, site, &mut candidates);
                let want = candidates
                    .iter()
                    .filter_map(|&t| cell.farthest_on(&solid.simplex(t).map(|v| sub(v, site))))
                    .fold(0.0, f64::max);
                let got = boundary_radius2(&solid, &cell, site);
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "site {i} after {k} neighbours"
                );
                open += (candidates.len() > 100) as usize;
                far += (want > 1.0) as usize;
            }
        }
        // The check saw cells meeting many simplices, and reaching across the solid.
        assert!(open > 50 && far > 20, "{open} open cells, {far} far");
    }

    /// Cutting boundary cells by the domain's planes inside `voronoi_cell` gives the cells
    /// that `clip_convex` gives after it, to round-off, faces and their tags included.
    #[test]
    fn early_boundary_cut_matches_the_late_one() {
        let cuboid = Solid::cuboid([0.0; 3], [1.0, 0.6, 0.8]).unwrap();
        for solid in [cuboid, Solid::octahedron([1.3, 0.7, 1.1]).unwrap()] {
            assert!(solid.is_convex());
            let sites = interior_sites(&solid, 400, 7);
            let index = SiteIndex::new(&sites).unwrap();
            let (mut late, mut early) = (CellScratch::default(), CellScratch::default());
            let (mut a, mut b) = (MeasureScratch::default(), MeasureScratch::default());
            let h = (solid.volume() / sites.len() as f64).cbrt();
            let mut cut_early = 0;
            for (i, &site) in sites.iter().enumerate() {
                let (cell, inside) = voronoi_cell::<3, PolyhedronCell, Solid>(
                    &solid,
                    &index,
                    &sites,
                    None,
                    sites.len(),
                    i,
                    false,
                    None,
                    false,
                    &mut late,
                )
                .unwrap();
                assert!(!inside);
                let ma = clip_by_domain(&solid, cell, site, Some(1), None, &mut a);
                let (cell, inside) = voronoi_cell::<3, PolyhedronCell, Solid>(
                    &solid,
                    &index,
                    &sites,
                    None,
                    sites.len(),
                    i,
                    true,
                    None,
                    false,
                    &mut early,
                )
                .unwrap();
                let mb = if inside {
                    measure(cell, None, &mut b.faces)
                } else {
                    clip_by_domain(&solid, cell, site, Some(1), None, &mut b)
                };
                cut_early += inside as usize;
                assert!((ma.mass - mb.mass).abs() <= 1e-12 * ma.mass, "cell {i}");
                assert!(
                    (ma.second - mb.second).abs() <= 1e-12 * ma.second,
                    "cell {i}"
                );
                for k in 0..3 {
                    assert!(
                        (ma.first[k] - mb.first[k]).abs() <= 1e-12 * ma.mass * h,
                        "cell {i}"
                    );
                }
                let db = a.faces.boundary - b.faces.boundary;
                assert!(db.abs() <= 1e-12 * h * h, "cell {i}: boundary {db:e}");
                // Faces of more than round-off, with their measures.
                let faces = |o: &mut MeasureScratch<3, PolyhedronCell>| -> Vec<(u32, f64)> {
                    o.faces.sort_neighbors();
                    o.faces
                        .neighbors
                        .iter()
                        .copied()
                        .filter(|&(_, m)| m > 1e-12 * h * h)
                        .collect()
                };
                let (fa, fb) = (faces(&mut a), faces(&mut b));
                assert_eq!(fa.len(), fb.len(), "cell {i}");
                for ((ja, ma), (jb, mb)) in fa.into_iter().zip(fb) {
                    assert!(ja == jb && (ma - mb).abs() <= 1e-12 * h * h, "cell {i}");
                }
            }
            assert!(
                cut_early > 0 && cut_early < sites.len(),
                "{cut_early} cells cut early"
            );
        }
    }
}
