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

mod density;

use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::Mutex;

use crate::density::quadrature::Rule;
use crate::density::{face_node, sum_sampled_on_faces, Cone};
use crate::domain::TriangleSet;
use crate::error::CoreError;
use crate::geometry::{add, cross, dot, norm2, scale, sub, Aabb, HalfSpace};
use crate::moments::{FaceMoments, Moments};

use super::clip::MeasureScratch;
use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::driver::clipped_diagram;
use super::faces::{FaceRow, FaceSums};
use super::output::Diagram;
use super::polygon_clip::clip_polygon;
use super::polyhedron_cell::PolyhedronCell;
use super::request::Request;
use super::scratch::with_scratch;

/// Neighbours a cell streams before its pieces are validated
/// ([`DomainKind::validate_part_after`]): a restricted cell has about six, as a planar one.
/// A diagram of 5,000 sites on the bunny (perf samples, six diagrams, one thread, under
/// load): streaming on to 64 neighbours, localising and validating took 4,886 (random
/// sites) and 5,064 (a CVT's); validating the pieces after 8 neighbours 11,807 and 3,321
/// (cells still open sideways have large pieces), after 12 4,815 and 3,020, after 16
/// 3,729 and 2,756, after 20 3,348 and 2,942, after 24 3,585 and 2,806, after 32 3,748
/// and 2,937.
const VALIDATE_PART_K: usize = 20;

/// A surface of triangles in 3D: closed or open, any number of components, checked
/// (finite, indices in range, no degenerate or repeated triangles, every edge in at most
/// two triangles, consistently oriented) and indexed by a BVH.
#[derive(Debug, Clone)]
pub struct Surface {
    /// The triangles, their vertices and BVH (which also finds nearest points).
    set: TriangleSet,
    /// Per triangle, whether its edge `k` (from vertex `k` to `k + 1`) lies in no other
    /// triangle: the surface's border.
    border: Vec<[bool; 3]>,
    area: f64,
    first: [f64; 3],
    /// Newton's Hessian with the flat weight on its arcs ([`HessianArcs`]), for a test.
    #[cfg(test)]
    flat_arcs: bool,
}

/// `count` offenders and the first, as an error.
fn refuse(what: &str, count: usize, first: String) -> CoreError {
    CoreError::InvalidSurface {
        reason: format!("{count} {what}, first {first}"),
    }
}

impl Surface {
    /// Check and index a surface of `triangles` (vertex indices) over `vertices`.
    ///
    /// Refuses an empty surface, non-finite coordinates, indices out of range, degenerate
    /// triangles (a repeated vertex or zero area), triangles repeated on the same three
    /// vertices, non-manifold edges (in three or more triangles) and edges two triangles
    /// run the same way (inconsistent orientation): each with the count and the first.
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Result<Self, CoreError> {
        crate::domain::check_indexed(&vertices, &triangles)?;
        let corners = |t: &[u32; 3]| t.map(|v| vertices[v as usize]);
        let degenerate: Vec<usize> = (0..triangles.len())
            .filter(|&f| {
                let [a, b, c] = triangles[f];
                let p = corners(&triangles[f]);
                a == b || b == c || c == a || norm2(cross(sub(p[1], p[0]), sub(p[2], p[0]))) == 0.0
            })
            .collect();
        if let Some(&f) = degenerate.first() {
            return Err(refuse(
                "degenerate triangle(s) (a repeated vertex or zero area)",
                degenerate.len(),
                format!("face {f} {:?}", triangles[f]),
            ));
        }
        let mut seen: HashMap<[u32; 3], usize> = HashMap::with_capacity(triangles.len());
        let mut repeated = Vec::new();
        for (f, t) in triangles.iter().enumerate() {
            let mut key = *t;
            key.sort_unstable();
            if let Some(&g) = seen.get(&key) {
                repeated.push((g, f));
            } else {
                seen.insert(key, f);
            }
        }
        if let Some(&(g, f)) = repeated.first() {
            return Err(refuse(
                "repeated triangle(s) on the same vertices",
                repeated.len(),
                format!("faces {g} and {f}"),
            ));
        }
        // Directed edges: each at most once (else two triangles run it the same way), and
        // each undirected edge in at most two triangles.
        let mut directed: HashMap<(u32, u32), usize> = HashMap::with_capacity(3 * triangles.len());
        let mut undirected: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
        let (mut flipped, mut nonmanifold) = (Vec::new(), Vec::new());
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if let Some(&g) = directed.get(&(a, b)) {
                    flipped.push((a, b, g, f));
                }
                directed.insert((a, b), f);
                let count = undirected.entry((a.min(b), a.max(b))).or_insert(0);
                *count += 1;
                if *count == 3 {
                    nonmanifold.push((a.min(b), a.max(b)));
                }
            }
        }
        if let Some(&(a, b)) = nonmanifold.first() {
            return Err(refuse(
                "non-manifold edge(s) (in three or more triangles)",
                nonmanifold.len(),
                format!("edge ({a}, {b})"),
            ));
        }
        if let Some(&(a, b, g, f)) = flipped.first() {
            return Err(refuse(
                "edge(s) run the same way by two triangles (inconsistent orientation; \
                 flip one side)",
                flipped.len(),
                format!("edge ({a}, {b}) in faces {g} and {f}"),
            ));
        }
        let border = triangles
            .iter()
            .map(|t| std::array::from_fn(|k| !directed.contains_key(&(t[(k + 1) % 3], t[k]))))
            .collect();
        let (mut area, mut first) = (0.0, [0.0; 3]);
        for t in &triangles {
            let p = corners(t);
            let a = 0.5 * norm2(cross(sub(p[1], p[0]), sub(p[2], p[0]))).sqrt();
            area += a;
            first = add(first, scale(add(add(p[0], p[1]), p[2]), a / 3.0));
        }
        Ok(Self {
            set: TriangleSet::new(vertices, triangles)?,
            border,
            area,
            first,
            #[cfg(test)]
            flat_arcs: false,
        })
    }

    /// The surface whose Hessian weighs its arcs as if flat (`2/|q|`, [`HessianArcs`]):
    /// what the tests show the finite differences reject.
    #[cfg(test)]
    pub(crate) fn with_flat_arcs(mut self) -> Self {
        self.flat_arcs = true;
        self
    }

    /// The vertices, as given.
    pub fn vertices(&self) -> &[[f64; 3]] {
        self.set.vertices()
    }

    /// The triangles (vertex indices), as given.
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.set.triangles()
    }

    /// The triangles as a [`TriangleSet`]: nearest points on the surface.
    pub fn triangle_set(&self) -> &TriangleSet {
        &self.set
    }

    /// The total area, `L²`: the sum of the triangles' areas in index order.
    pub fn area(&self) -> f64 {
        self.area
    }

    /// `∫ x dA` over the surface (3,), `L³`.
    pub fn first_moment(&self) -> [f64; 3] {
        self.first
    }

    /// Whether edge `k` of triangle `t` lies on the surface's border.
    pub fn is_border(&self, t: u32, k: usize) -> bool {
        self.border[t as usize][k]
    }

    fn corners(&self, t: u32) -> [[f64; 3]; 3] {
        self.set.corners(t)
    }

    /// Call `f(t, piece)` for every triangle `t` that meets `cell` (relative to `site`),
    /// with `piece` the triangle clipped by the cell's planes (relative to the site,
    /// counter-clockwise as the triangle), in the BVH's fixed order.
    ///
    /// `triangles` says where the triangles come from ([`Triangles`]): a walk of the
    /// BVH, or those an earlier walk for the same site and a larger cell met (in the
    /// walk's order). The pieces of a recording walk, or of the recorded triangles, are
    /// kept with the planes they were clipped by: a later call for the same site whose
    /// cell has the same planes (bit for bit; the measure after a validation that cut
    /// nothing) replays them instead of clipping again.
    fn for_each_piece<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        triangles: Triangles,
        mut f: impl FnMut(u32, &[Node]),
    ) {
        if cell.is_empty() {
            return;
        }
        let reach = {
            let b = cell.bounds();
            Aabb {
                lo: add(b.lo, site),
                hi: add(b.hi, site),
            }
        };
        let key = site.map(f64::to_bits);
        with_scratch(&BUFFERS, |buffers| {
            let Buffers {
                clip,
                planes,
                met,
                met_by,
                kept,
                box_hint,
                box_planes,
                leaf_planes,
            } = &mut **buffers;
            planes.clear();
            cell.for_each_plane(|face, h| planes.push((face, *h)));
            let mine = *met_by == Some(key);
            if matches!(triangles, Triangles::Met | Triangles::LastMet) && mine {
                if kept.planes == *planes {
                    for (k, &(t, end)) in kept.pieces.iter().enumerate() {
                        let start = if k == 0 { 0 } else { kept.pieces[k - 1].1 };
                        f(t, &kept.nodes[start as usize..end as usize]);
                    }
                } else {
                    kept.restart(planes);
                    for &t in met.iter() {
                        if let Some(polygon) = clip.triangle(planes, self.relative(t, site)) {
                            kept.push(t, polygon);
                            f(t, polygon);
                        }
                    }
                }
            } else {
                let record = triangles == Triangles::Record;
                if record {
                    met.clear();
                    kept.restart(planes);
                }
                let bvh = self.set.bvh();
                // The site in its own cell (no side of the domain's box between them):
                // inner boxes holding it need no test ([`holds_site`]).
                let site_in_cell = planes.iter().all(|(_, h)| h.offset >= 0.0);
                box_planes.set(planes);
                bvh.walk(|node, is_leaf| {
                    let bounds = bvh.node_bounds(node);
                    if !bounds.overlaps(&reach) {
                        return false;
                    }
                    if !is_leaf && site_in_cell && holds_site(&bounds, site) {
                        return true;
                    }
                    // A leaf's triangles are clipped by the planes its box is not inside
                    // (`leaf_planes`), the others leave them as they are.
                    let across = is_leaf.then_some(&mut *leaf_planes);
                    let side = box_side(planes, box_planes, &bounds, site, box_hint, across);
                    let inside = match side {
                        BoxSide::Outside => return false,
                        BoxSide::Inside => true,
                        BoxSide::Across if !is_leaf => return true,
                        BoxSide::Across => false,
                    };
                    bvh.for_each_leaf_under(node, |leaf| {
                        for &t in bvh.node_items(leaf) {
                            let rel = self.relative(t, site);
                            let piece = if inside {
                                Some(clip.whole(rel))
                            } else {
                                clip.triangle(leaf_planes, rel)
                            };
                            if let Some(polygon) = piece {
                                if record {
                                    met.push(t);
                                    kept.push(t, polygon);
                                }
                                f(t, polygon);
                            }
                        }
                    });
                    false
                });
            }
            match triangles {
                Triangles::Record => *met_by = Some(key),
                Triangles::LastMet => *met_by = None,
                Triangles::Walk | Triangles::Met => {}
            }
        });
    }

    /// Call `f(t, piece)` for each of `triangles` that meets `cell` (relative to `site`),
    /// in their order, with `piece` as [`Surface::for_each_piece`] gives it: the same
    /// pieces as its walk when `triangles` holds every triangle the walk would meet, in
    /// the walk's order (a triangle whose box the walk finds inside every plane is left
    /// whole by the clipper too).
    fn for_each_piece_of<C: ConvexCell<3>>(
        &self,
        cell: &C,
        site: [f64; 3],
        triangles: &[u32],
        mut f: impl FnMut(u32, &[Node]),
    ) {
        if cell.is_empty() {
            return;
        }
        with_scratch(&BUFFERS, |buffers| {
            let Buffers { clip, planes, .. } = &mut **buffers;
            planes.clear();
            cell.for_each_plane(|face, h| planes.push((face, *h)));
            for &t in triangles {
                if let Some(polygon) = clip.triangle(planes, self.relative(t, site)) {
                    f(t, polygon);
                }
            }
        });
    }

    /// Triangle `t`'s corners relative to `site`.
    fn relative(&self, t: u32, site: [f64; 3]) -> [[f64; 3]; 3] {
        self.corners(t).map(|v| sub(v, site))
    }
}

/// Where [`Surface::for_each_piece`] finds the triangles of a cell. The driver validates
/// a cell (or asks its radius, [`DomainKind::local_radius2`], then localises and
/// validates it), which only shrinks it, and measures it last: the first validation (the
/// radius) walks the BVH and records the triangles the cell met, the later validations
/// and the measure clip only those (a triangle that missed the larger cell misses the
/// smaller one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Triangles {
    /// Walk the BVH.
    Walk,
    /// Walk the BVH and record the triangles met, for this site.
    Record,
    /// The recorded triangles if they are this site's, else walk.
    Met,
    /// As `Met`, then forget them: the cell is done.
    LastMet,
}

/// Where a box of the BVH lies against a cell ([`box_side`]).
enum BoxSide {
    /// Strictly outside some plane: none of its triangles meets the cell.
    Outside,
    /// Inside every plane with a margin for round-off: its triangles are whole pieces.
    Inside,
    /// Neither.
    Across,
}

/// A cell's planes as [`box_side`] reads them: per plane, its normal's positive part,
/// its negative part (each component in one of the two, 0 in the other) and its
/// offset. The least value of `n·x` over a box `[lo, hi]` is then `pos·lo + neg·hi`,
/// its greatest `pos·hi + neg·lo`, each the same number as choosing the corner component
/// by component (a product with 0 adds nothing), without a branch: a box costs a few
/// products and sums per plane, two planes at a time. The walk tests about 50 boxes a
/// cell against every plane (fandisk, 5,000 sites, callgrind: the test was 0.97 G of the
/// diagrams' 2.84 G instructions, 0.49 G of 2.24 G now, with the leaves' planes).
#[derive(Debug, Default)]
struct BoxPlanes {
    rows: Vec<[f64; 8]>,
    /// The same rows two planes at a time, component by component (the two lanes of a
    /// vector register): planes `2i` and `2i + 1` in `pairs[i][c]`, `c` as in a row. An
    /// odd last plane is paired with one no box is outside (no normal, offset +∞).
    pairs: Vec<[[f64; 2]; 7]>,
}

impl BoxPlanes {
    /// The rows of `planes`, in their order.
    fn set(&mut self, planes: &[(Face, HalfSpace<3>)]) {
        self.rows.clear();
        self.rows.extend(planes.iter().map(|(_, h)| {
            let n = h.normal;
            let pos = n.map(|c| if c > 0.0 { c } else { 0.0 });
            let neg = n.map(|c| if c > 0.0 { 0.0 } else { c });
            [
                pos[0], pos[1], pos[2], neg[0], neg[1], neg[2], h.offset, 0.0,
            ]
        }));
        let never = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::INFINITY, 0.0];
        self.pairs.clear();
        self.pairs.extend(self.rows.chunks(2).map(|two| {
            let second = two.get(1).unwrap_or(&never);
            std::array::from_fn(|c| [two[0][c], second[c]])
        }));
    }

    /// Whether the box `[lo, hi]` is strictly outside plane `p`: its least value there
    /// exceeds the offset.
    fn outside(&self, p: usize, lo: [f64; 3], hi: [f64; 3]) -> bool {
        self.pairs
            .get(p / 2)
            .is_some_and(|pr| least_of_pair(pr, lo, hi)[p % 2] > pr[6][p % 2])
    }

    /// The first plane (by index) with the box `[lo, hi]` strictly outside it, two planes
    /// at a time.
    fn first_outside(&self, lo: [f64; 3], hi: [f64; 3]) -> Option<usize> {
        for (i, pr) in self.pairs.iter().enumerate() {
            let least = least_of_pair(pr, lo, hi);
            let out = [least[0] > pr[6][0], least[1] > pr[6][1]];
            if out[0] | out[1] {
                return Some(2 * i + usize::from(!out[0]));
            }
        }
        None
    }
}

/// The least values of two planes' `n·x` over the box `[lo, hi]` ([`BoxPlanes`]).
fn least_of_pair(pr: &[[f64; 2]; 7], lo: [f64; 3], hi: [f64; 3]) -> [f64; 2] {
    std::array::from_fn(|j| {
        (pr[0][j] * lo[0] + pr[3][j] * hi[0])
            + (pr[1][j] * lo[1] + pr[4][j] * hi[1])
            + (pr[2][j] * lo[2] + pr[5][j] * hi[2])
    })
}

/// Whether the box `[lo, hi]` (`reach`: its components' greatest magnitudes) is inside
/// plane `r` with a margin for the round-off of either ([`box_side`]).
fn inside_with_margin(r: &[f64; 8], lo: [f64; 3], hi: [f64; 3], reach: [f64; 3]) -> bool {
    let greatest = (r[0] * hi[0] + r[3] * lo[0])
        + (r[1] * hi[1] + r[4] * lo[1])
        + (r[2] * hi[2] + r[5] * lo[2]);
    // |n_k| max(|lo_k|, |hi_k|): pos - neg is |n_k| exactly (one of them is 0).
    let size =
        r[6].abs() + (r[0] - r[3]) * reach[0] + (r[1] - r[4]) * reach[1] + (r[2] - r[5]) * reach[2];
    greatest <= r[6] - 1e-12 * size
}

/// Where the box `b` (absolute) lies against the cell of `planes` (relative to `site`;
/// `box_planes` the same planes): strictly outside a plane when its least value
/// over the box, at the corner the normal points away from, exceeds the offset; inside
/// every plane when the greatest is below it by more than the round-off of either (the
/// triangles' corners, in the box, are then inside as [`Clipper::triangle`] computes
/// them, and it would leave them whole).
///
/// With `across` (a leaf's box), every plane is tried and those the box is not inside
/// are put there, in order (empty when `Inside`): the box's triangles are inside the
/// others, which would neither cut them nor leave them out, so they are clipped by
/// those alone, bit for bit the same pieces. The plane that last put a box outside
/// (`hint`) is tried first: neighbouring boxes tend to lie outside the same one.
fn box_side(
    planes: &[(Face, HalfSpace<3>)],
    box_planes: &BoxPlanes,
    b: &Aabb<3>,
    site: [f64; 3],
    hint: &mut usize,
    across: Option<&mut Vec<(Face, HalfSpace<3>)>>,
) -> BoxSide {
    let rows = &box_planes.rows;
    let (lo, hi) = (sub(b.lo, site), sub(b.hi, site));
    if box_planes.outside(*hint, lo, hi) {
        return BoxSide::Outside;
    }
    if let Some(p) = box_planes.first_outside(lo, hi) {
        *hint = p;
        return BoxSide::Outside;
    }
    let reach: [f64; 3] = std::array::from_fn(|k| lo[k].abs().max(hi[k].abs()));
    let inside = match across {
        None => rows.iter().all(|r| inside_with_margin(r, lo, hi, reach)),
        Some(across) => {
            across.clear();
            for (plane, r) in planes.iter().zip(rows) {
                if !inside_with_margin(r, lo, hi, reach) {
                    across.push(*plane);
                }
            }
            across.is_empty()
        }
    };
    if inside {
        BoxSide::Inside
    } else {
        BoxSide::Across
    }
}

/// Whether the box `b` (absolute) holds `site`, as [`box_side`] computes the box's corners
/// relative to it. Then no plane whose offset is `>= 0` has the box outside (its least
/// value over the box is a sum of terms `<= 0`): with the site in its own cell the box is
/// walked into untested: its leaves are the same, in the same order (an inner box inside
/// every plane, whose leaves the walk would have taken whole, has them inside every plane
/// too). The boxes near the root hold the site: fandisk, 5,000 sites, two CVT iterates'
/// diagrams and a triangulation tested 0.81 M boxes instead of 1.04 M (callgrind: 5%
/// fewer instructions in the diagrams).
fn holds_site(b: &Aabb<3>, site: [f64; 3]) -> bool {
    let (lo, hi) = (sub(b.lo, site), sub(b.hi, site));
    (0..3).all(|k| lo[k] <= 0.0 && hi[k] >= 0.0)
}

/// What an edge of a clipped piece lies on: edge `k` of its triangle, or a plane of the cell.
#[derive(Debug, Clone, Copy)]
enum Edge {
    Triangle(u8),
    Plane(Face),
}

/// A node of a clipped piece, relative to the site, with the edge leaving it.
#[derive(Debug, Clone, Copy)]
struct Node {
    x: [f64; 3],
    out: Edge,
}

/// Buffers of [`Clipper::triangle`].
#[derive(Debug, Default)]
struct Clipper {
    polygon: Vec<Node>,
    spare: Vec<Node>,
    sides: Vec<(f64, bool)>,
    /// The planes cutting the triangle (by index) and its corners' sides of each.
    cutting: Vec<(usize, [f64; 3])>,
    /// The plane that last had a whole triangle outside, tried first.
    hint: usize,
}

impl Clipper {
    /// The triangle `rel` (relative to the site) whole, as a piece.
    fn whole(&mut self, rel: [[f64; 3]; 3]) -> &[Node] {
        self.polygon.clear();
        self.polygon.extend((0..3).map(|k| Node {
            x: rel[k],
            out: Edge::Triangle(k as u8),
        }));
        &self.polygon
    }

    /// The triangle `rel` (relative to the site) clipped by every plane of a cell, or
    /// `None` when nothing is left. One pass over the planes finds the corners' sides of
    /// each: a plane with every corner outside leaves nothing, one with every corner
    /// inside leaves the triangle (and every piece of it, convex) whole; only the planes
    /// between cut, in their order.
    fn triangle(&mut self, planes: &[(Face, HalfSpace<3>)], rel: [[f64; 3]; 3]) -> Option<&[Node]> {
        let Self { cutting, hint, .. } = self;
        let outside = |h: &HalfSpace<3>| rel.iter().all(|&v| dot(h.normal, v) > h.offset);
        if planes.get(*hint).is_some_and(|(_, h)| outside(h)) {
            return None;
        }
        cutting.clear();
        for (p, (_, h)) in planes.iter().enumerate() {
            let d = rel.map(|v| dot(h.normal, v) - h.offset);
            let out = d.iter().filter(|&&x| x > 0.0).count();
            if out == 3 {
                *hint = p;
                return None;
            }
            if out > 0 {
                cutting.push((p, d));
            }
        }
        self.whole(rel);
        let Self {
            polygon,
            spare,
            sides,
            cutting,
            ..
        } = self;
        for (at, &(p, corners)) in cutting.iter().enumerate() {
            let (face, ref h) = planes[p];
            sides.clear();
            if at == 0 {
                sides.extend(corners.iter().map(|&d| (d, false)));
            } else {
                sides.extend(
                    polygon
                        .iter()
                        .map(|n| (dot(h.normal, n.x) - h.offset, false)),
                );
                if sides.iter().all(|&(d, _)| d <= 0.0) {
                    continue;
                }
            }
            clip_polygon(polygon, sides, spare, |u, w, (su, _), (sw, _)| {
                let r = su / (su - sw);
                Node {
                    x: std::array::from_fn(|c| u.x[c] + r * (w.x[c] - u.x[c])),
                    out: if su <= 0.0 { Edge::Plane(face) } else { u.out },
                }
            });
            std::mem::swap(polygon, spare);
            if polygon.len() < 3 {
                return None;
            }
        }
        Some(polygon)
    }
}

/// The pieces one cell's planes clipped ([`Surface::for_each_piece`]), for replay.
#[derive(Debug, Default)]
struct Kept {
    /// The planes they were clipped by.
    planes: Vec<(Face, HalfSpace<3>)>,
    /// Each piece's triangle and the end of its nodes in `nodes`.
    pieces: Vec<(u32, u32)>,
    nodes: Vec<Node>,
}

impl Kept {
    /// Forget the pieces: those of `planes` follow.
    fn restart(&mut self, planes: &[(Face, HalfSpace<3>)]) {
        self.planes.clear();
        self.planes.extend_from_slice(planes);
        self.pieces.clear();
        self.nodes.clear();
    }

    fn push(&mut self, t: u32, polygon: &[Node]) {
        self.nodes.extend_from_slice(polygon);
        self.pieces.push((t, self.nodes.len() as u32));
    }
}

/// One thread's buffers, reused from cell to cell.
#[derive(Debug, Default)]
struct Buffers {
    clip: Clipper,
    /// The cell's planes, relative to its site.
    planes: Vec<(Face, HalfSpace<3>)>,
    /// The triangles a walk met for the site of bits `met_by` ([`Triangles`]).
    met: Vec<u32>,
    met_by: Option<[u64; 3]>,
    /// The last pieces clipped from `met`, for the same site.
    kept: Kept,
    /// The plane that last put a box of the BVH outside the cell ([`box_side`]).
    box_hint: usize,
    /// The cell's planes as [`box_side`] reads them.
    box_planes: BoxPlanes,
    /// The planes of the cell a leaf's box is not inside ([`box_side`]), in order.
    leaf_planes: Vec<(Face, HalfSpace<3>)>,
}

// This thread's buffers, reused from cell to cell ([`with_scratch`]). Boxed: the static
// TLS block a module loaded at run time may take is small (glibc's surplus, shared with
// every library loaded before), and these buffers inline made `import hcvt` fail there
// ("cannot allocate memory in static TLS block") once they grew by two vectors.
thread_local! {
    static BUFFERS: RefCell<Box<Buffers>> = RefCell::new(Box::default());
}

/// Add the piece `polygon` (of triangle `t`, relative to the site) to `total`: the fan
/// triangles from its first node, each in closed form; its edges on bisectors to the
/// neighbours' measures (with `arcs`, and their Hessian terms) and on the border to the
/// boundary measure.
fn add_piece(
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
struct HessianArcs<'a> {
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

/// Points closer than this fraction of the surface's bounding-box diagonal are one
/// meeting point of three cells (rounding apart: found in two triangles, or as the
/// ends of two arcs on an edge).
const SAME_POINT: f64 = 1e-10;

/// Where three cells meet: the sites (the cell's own first), the point, its surface triangle.
type Meeting = ([u32; 3], [f64; 3], u32);

/// The restricted Delaunay triangulation of sites on a surface ([`Surface::restricted_delaunay`]).
#[derive(Debug, Clone, Default)]
pub struct RestrictedDelaunay {
    /// One triangle of site indices per point where three cells meet on the surface,
    /// counter-clockwise seen from the side the surface's normal points to there, sorted.
    pub triangles: Vec<[u32; 3]>,
    /// Each triangle's meeting point, absolute, `L`.
    pub points: Vec<[f64; 3]>,
    /// The surface triangle each meeting point lies in.
    pub faces: Vec<u32>,
    /// Triples of cells that meet at more than one point (a cell that is not a disc, the
    /// closed-ball property of Edelsbrunner and Shah failing), sorted: each such triple
    /// gives one triangle above, and the triangulation may not be a manifold there.
    pub repeated: Vec<[u32; 3]>,
    /// The restricted Voronoi diagram of the sites, which the triangulation is read from
    /// (the one [`super::clipped_diagram`] gives): callers wanting both compute it once.
    pub diagram: Diagram<3>,
}

/// The restricted Voronoi cells of sites on a surface as convex planar pieces
/// ([`Surface::pieces`]): each the part of one input triangle in one cell, its nodes
/// counter-clockwise about the triangle's normal (as the triangle's corners run), in flat
/// arrays; the pieces by cell, within a cell in the measure's order (the BVH's, fixed).
#[derive(Debug, Clone, Default)]
pub struct SurfacePieces {
    /// Every piece's nodes, absolute, `L`.
    pub points: Vec<[f64; 3]>,
    /// Piece `p`'s nodes are `points[offsets[p]..offsets[p + 1]]` (at least three).
    pub offsets: Vec<usize>,
    /// The cell (site) of each piece, non-decreasing.
    pub cells: Vec<u32>,
    /// The input triangle of each piece.
    pub triangles: Vec<u32>,
    /// The diagram the pieces were noted by, bit for bit [`super::clipped_diagram`]'s.
    pub diagram: Diagram<3>,
}

impl Surface {
    /// The restricted Delaunay triangulation of `sites` (DESIGN §12): a triangle `(i, j, k)`
    /// for each point of the surface where the cells of `i`, `j` and `k` meet (a vertex of a
    /// cell's piece between its arcs on the bisectors with `j` and `k`), oriented by the
    /// normal of the surface triangle holding that point. Each meeting point is seen by
    /// its three cells; a triple is kept once, from the cell of its smallest site.
    ///
    /// Errors are [`super::clipped_diagram`]'s.
    pub fn restricted_delaunay(&self, sites: &[[f64; 3]]) -> Result<RestrictedDelaunay, CoreError> {
        use rayon::prelude::*;
        let request = Request {
            keep_cells: true,
            ..Default::default()
        };
        let noting = Noting::new(self, false, sites.len());
        let clipped = clipped_diagram::<3, PolyhedronCell, _>(&noting, sites, &request)?;
        let met = noting.into_notes();
        let same = SAME_POINT * self.set.bvh().bounds().diagonal();
        let found: Vec<Vec<Meeting>> = clipped
            .cells
            .par_iter()
            .enumerate()
            .map(|(i, cell)| {
                let noted = met
                    .get(&sites[i].map(f64::to_bits))
                    .and_then(Option::as_ref)
                    .map(|noted| noted.triangles.as_slice());
                self.meeting_points(i as u32, cell, sites[i], same, noted)
            })
            .collect();
        let mut out = RestrictedDelaunay::default();
        // Each triple's first point and how many distinct points it was seen at.
        let mut seen: HashMap<[u32; 3], ([f64; 3], usize)> = HashMap::new();
        for (tri, point, face) in found.into_iter().flatten() {
            let mut key = tri;
            key.sort_unstable();
            if let Some((first, count)) = seen.get_mut(&key) {
                // The same point seen from two triangles (on their edge) is one meeting.
                if norm2(sub(point, *first)) > same * same {
                    *count += 1;
                    if *count == 2 {
                        out.repeated.push(key);
                    }
                }
                continue;
            }
            seen.insert(key, (point, 1));
            // Counter-clockwise about the normal of the surface there.
            let normal = {
                let [a, b, c] = self.corners(face);
                cross(sub(b, a), sub(c, a))
            };
            let [i, j, k] = tri.map(|v| sites[v as usize]);
            let oriented = if dot(cross(sub(j, i), sub(k, i)), normal) >= 0.0 {
                tri
            } else {
                [tri[0], tri[2], tri[1]]
            };
            out.triangles.push(oriented);
            out.points.push(point);
            out.faces.push(face);
        }
        out.repeated.sort_unstable();
        out.diagram = clipped.diagram;
        Ok(out)
    }

    /// The restricted Voronoi cells of `sites` on the surface as their pieces
    /// ([`SurfacePieces`]): the convex polygons the diagram's measure clipped from the
    /// input triangles and summed the moments of, noted as it measured them (no second
    /// clip).
    ///
    /// Errors are [`super::clipped_diagram`]'s.
    pub fn pieces(&self, sites: &[[f64; 3]]) -> Result<SurfacePieces, CoreError> {
        let request = Request::default();
        let noting = Noting::new(self, true, sites.len());
        let clipped = clipped_diagram::<3, PolyhedronCell, _>(&noting, sites, &request)?;
        let mut met = noting.into_notes();
        let mut out = SurfacePieces {
            offsets: vec![0],
            ..Default::default()
        };
        for (i, site) in sites.iter().enumerate() {
            // A cell the driver did not measure has no pieces.
            let Some(noted) = met.remove(&site.map(f64::to_bits)) else {
                continue;
            };
            let noted = noted.ok_or_else(|| CoreError::InvalidSettings {
                reason: format!("site {i} shares its coordinates with another site"),
            })?;
            let start = out.points.len();
            out.points.extend_from_slice(&noted.nodes);
            out.offsets.extend(noted.ends.iter().map(|end| start + end));
            out.cells.extend(noted.triangles.iter().map(|_| i as u32));
            out.triangles.extend_from_slice(&noted.triangles);
        }
        out.diagram = clipped.diagram;
        Ok(out)
    }

    /// The points where cell `i` (its convex cell `cell`, relative to `site`) meets two
    /// other cells `j < k` on the surface, with `i < j`: `([i, j, k], point, face)`;
    /// points closer than `same` are one.
    ///
    /// Inside a triangle such a point is a vertex of the cell's piece between its arcs on
    /// the bisectors with `j` and `k`. On an input edge or vertex it may be no such
    /// vertex: the piece on one side ends its arc on the bisector with `j` there, the
    /// piece on the other side its arc on the one with `k` ([`ArcEnd`]). An edge of a
    /// piece on an inner input edge that lies on one of the cell's bisectors (to `same`)
    /// is an arc on it: the clipping left it labelled by the triangle.
    ///
    /// `noted`: the triangles of the cell's pieces as its measure met them
    /// ([`Noting`]), clipped again instead of a walk of the BVH (the same pieces).
    fn meeting_points<C: ConvexCell<3>>(
        &self,
        i: u32,
        cell: &C,
        site: [f64; 3],
        same: f64,
        noted: Option<&[u32]>,
    ) -> Vec<Meeting> {
        let mut bisectors: Vec<(u32, HalfSpace<3>)> = Vec::new();
        cell.for_each_plane(|face, h| {
            if let Face::Neighbor(j) = face {
                bisectors.push((j, *h));
            }
        });
        let on_bisector = |u: [f64; 3], w: [f64; 3]| {
            bisectors.iter().find_map(|&(j, ref h)| {
                let tol = same * norm2(h.normal).sqrt();
                let off = |x| (dot(h.normal, x) - h.offset).abs();
                (off(u) <= tol && off(w) <= tol).then_some(j)
            })
        };
        let mut out = Vec::new();
        let mut ends: Vec<ArcEnd> = Vec::new();
        let mut each = |t: u32, polygon: &[Node]| {
            let n = polygon.len();
            // Each edge of the piece: on a bisector (`Arc`), on an inner input edge
            // (`Inner`), or on the border.
            let side = |k: usize| match polygon[k].out {
                Edge::Plane(Face::Neighbor(j)) => Side::Arc(j),
                Edge::Triangle(e) if !self.is_border(t, e as usize) => {
                    match on_bisector(polygon[k].x, polygon[(k + 1) % n].x) {
                        Some(j) => Side::Arc(j),
                        None => Side::Inner,
                    }
                }
                _ => Side::Other,
            };
            let sides: Vec<Side> = (0..n).map(side).collect();
            for k in 0..n {
                let point = add(site, polygon[k].x);
                match (sides[(k + n - 1) % n], sides[k]) {
                    (Side::Arc(a), Side::Arc(b)) if a != b && i < a.min(b) => {
                        out.push(([i, a.min(b), a.max(b)], point, t));
                    }
                    (Side::Arc(label), Side::Inner) | (Side::Inner, Side::Arc(label)) => {
                        ends.push(ArcEnd {
                            point,
                            label,
                            face: t,
                        });
                    }
                    _ => {}
                }
            }
        };
        match noted {
            Some(triangles) => self.for_each_piece_of(cell, site, triangles, &mut each),
            None => self.for_each_piece(cell, site, Triangles::Walk, &mut each),
        }
        arc_ends_meetings(i, same, &mut ends, &mut out);
        out
    }
}

/// The meeting points of cell `i` on the input's edges and vertices from the ends `ends`
/// of its arcs there: two ends at one point (to `same`) in different triangles, on the
/// bisectors with `j` and `k`, are a point of all three cells (it lies on both
/// bisectors).
fn arc_ends_meetings(i: u32, same: f64, ends: &mut [ArcEnd], out: &mut Vec<Meeting>) {
    ends.sort_unstable_by(|x, y| {
        (x.point[0].total_cmp(&y.point[0]))
            .then(x.face.cmp(&y.face))
            .then(x.label.cmp(&y.label))
    });
    for (k, x) in ends.iter().enumerate() {
        for y in &ends[k + 1..] {
            if y.point[0] - x.point[0] > same {
                break;
            }
            let (a, b) = (x.label.min(y.label), x.label.max(y.label));
            if x.face != y.face && a != b && i < a && norm2(sub(x.point, y.point)) <= same * same {
                out.push(([i, a, b], x.point, x.face));
            }
        }
    }
}

/// What an edge of a cell's piece lies on ([`Surface::meeting_points`]).
#[derive(Debug, Clone, Copy)]
enum Side {
    /// The bisector with a site.
    Arc(u32),
    /// An edge of the triangle shared with another.
    Inner,
    /// The border, or a plane of no neighbour.
    Other,
}

/// Where an arc of a cell (on the bisector with site `label`) ends on an inner edge of
/// surface triangle `face`: the point, absolute.
#[derive(Debug, Clone, Copy)]
struct ArcEnd {
    point: [f64; 3],
    label: u32,
    face: u32,
}

/// The surface as a domain that also notes, per site (by its bits), the triangles of its
/// cell's pieces as the measure meets them ([`DomainKind::clip`], the cell's last
/// look): [`Surface::restricted_delaunay`] then clips those again for the meeting
/// points instead of walking the BVH a second time. Sites sharing bits note `None`
/// (their cells walk). Asked for `pieces`, it notes the pieces' nodes too
/// ([`Surface::pieces`]). Everything else is the surface's.
struct Noting<'a> {
    surface: &'a Surface,
    /// Note each piece's nodes as well ([`Surface::pieces`]), not only its triangle.
    pieces: bool,
    met: Mutex<HashMap<[u64; 3], Option<Noted>>>,
}

/// What [`Noting`] noted of one cell: the triangles of its pieces in the measure's order
/// and, when asked, the pieces' nodes (absolute) and the end of each piece's in `nodes`.
#[derive(Debug, Default)]
struct Noted {
    triangles: Vec<u32>,
    ends: Vec<usize>,
    nodes: Vec<[f64; 3]>,
}

impl<'a> Noting<'a> {
    fn new(surface: &'a Surface, pieces: bool, n: usize) -> Self {
        Self {
            surface,
            pieces,
            met: Mutex::new(HashMap::with_capacity(n)),
        }
    }

    /// The notes, by the sites' bits.
    fn into_notes(self) -> HashMap<[u64; 3], Option<Noted>> {
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

impl Surface {
    /// [`DomainKind::clip`]: the moments of the cell's pieces, each piece (its triangle
    /// and nodes, relative to the site) told to `met` in order; with a `row`, the
    /// Hessian's terms of its arcs.
    fn measure<C: ConvexCell<3>>(
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
    /// by the slope of its bisector against its triangle ([`HessianArcs`]).
    fn sums_hessian(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An open grid of `k × k` squares in the plane `z = 0`, each split into two triangles,
    /// bent up along x by `bend` (a roof) so that it is not flat.
    fn roof(k: usize, bend: f64) -> Surface {
        let mut v = Vec::new();
        for j in 0..=k {
            for i in 0..=k {
                let x = i as f64 / k as f64;
                v.push([x, j as f64 / k as f64, bend * (0.5 - (x - 0.5).abs())]);
            }
        }
        let id = |i: usize, j: usize| (j * (k + 1) + i) as u32;
        let mut t = Vec::new();
        for j in 0..k {
            for i in 0..k {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Surface::new(v, t).unwrap()
    }

    fn sites(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = crate::sample::Lcg::new(seed);
        (0..n)
            .map(|_| [rng.unit(), rng.unit(), 0.3 * rng.unit() - 0.1])
            .collect()
    }

    /// [`BoxPlanes`] decides as the corner chosen component by component (the least and
    /// greatest of `n·x` over the box, the margin's size), plane by plane: normals with
    /// zero components, odd and even counts, boxes across, inside and outside.
    #[test]
    fn box_planes_decide_as_the_corners_do() {
        let mut rng = crate::sample::Lcg::new(7);
        let mut value = |zero: bool| if zero { 0.0 } else { 2.0 * rng.unit() - 1.0 };
        for count in [1usize, 2, 5, 8] {
            let planes: Vec<(Face, HalfSpace<3>)> = (0..count)
                .map(|p| {
                    let normal = [value(p % 3 == 0), value(p % 4 == 1), value(false)];
                    let offset = 0.5 * value(false).abs();
                    (Face::Neighbor(p as u32), HalfSpace { normal, offset })
                })
                .collect();
            let mut box_planes = BoxPlanes::default();
            box_planes.set(&planes);
            for _ in 0..500 {
                let (a, b) = (
                    [value(false), value(false), value(false)],
                    value(false).abs(),
                );
                let (lo, hi) = (a, a.map(|c| c + b));
                let corner = |h: &HalfSpace<3>, least: bool| -> f64 {
                    (0..3)
                        .map(|k| {
                            let low = (h.normal[k] > 0.0) == least;
                            h.normal[k] * if low { lo[k] } else { hi[k] }
                        })
                        .sum()
                };
                let outside: Vec<bool> = planes
                    .iter()
                    .map(|(_, h)| corner(h, true) > h.offset)
                    .collect();
                let reach = std::array::from_fn(|k| lo[k].abs().max(hi[k].abs()));
                for (p, (_, h)) in planes.iter().enumerate() {
                    assert_eq!(box_planes.outside(p, lo, hi), outside[p]);
                    // The margin's size summed as the test did before: from |offset| on.
                    let size = (0..3)
                        .map(|k| (h.normal[k] * lo[k]).abs().max((h.normal[k] * hi[k]).abs()))
                        .fold(h.offset.abs(), |s, x| s + x);
                    let inside = corner(h, false) <= h.offset - 1e-12 * size;
                    assert_eq!(
                        inside_with_margin(&box_planes.rows[p], lo, hi, reach),
                        inside
                    );
                }
                assert_eq!(
                    box_planes.first_outside(lo, hi),
                    outside.iter().position(|&o| o)
                );
            }
        }
    }

    #[test]
    fn cells_tile_an_open_surface() {
        let s = roof(8, 0.6);
        let sites = sites(300, 5);
        let d = clipped_diagram::<3, PolyhedronCell, _>(&s, &sites, &Request::default())
            .unwrap()
            .diagram;
        let total: f64 = d.moments.iter().map(|m| m.mass).sum();
        assert!(
            (total - s.area()).abs() <= 1e-13 * s.area(),
            "{total} vs {}",
            s.area()
        );
        let first = d.moments.iter().zip(&sites).fold([0.0; 3], |acc, (m, z)| {
            add(acc, add(m.first, scale(*z, m.mass)))
        });
        for (got, want) in first.iter().zip(s.first_moment()) {
            assert!((got - want).abs() <= 1e-13);
        }
        // The border: four sides, the two across the roof's slopes longer.
        let border: f64 = d.boundary_measure.iter().sum();
        let want = 2.0 + 2.0 * 2.0 * (0.25f64 + 0.09).sqrt();
        assert!((border - want).abs() <= 1e-12, "{border} vs {want}");
        // Shared arcs are seen alike from both sides.
        for i in 0..sites.len() {
            for at in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                let j = d.neighbor_sites[at] as usize;
                let back = (d.neighbor_offsets[j]..d.neighbor_offsets[j + 1])
                    .find(|&b| d.neighbor_sites[b] as usize == i)
                    .map(|b| d.neighbor_measures[b]);
                let m = d.neighbor_measures[at];
                assert!(back.is_some_and(|b| (b - m).abs() <= 1e-12), "{i} {j}");
            }
        }
    }

    /// The pieces are the measure's: the diagram is the plain one bit for bit, each
    /// cell's pieces sum (fanned) to its area and first moment, every piece lies in its
    /// triangle's plane and runs counter-clockwise about its normal, and the pieces of
    /// all cells cover each triangle's area; a site given twice is refused, not a panic.
    #[test]
    fn pieces_are_the_measures_and_tile_the_triangles() {
        let s = roof(8, 0.6);
        let sites = sites(300, 5);
        let plain = clipped_diagram::<3, PolyhedronCell, _>(&s, &sites, &Request::default());
        let p = s.pieces(&sites).unwrap();
        assert_eq!(plain.unwrap().diagram.moments, p.diagram.moments);
        let m = p.cells.len();
        assert!(m > 300 && p.offsets.len() == m + 1 && p.triangles.len() == m);
        assert!(p.cells.windows(2).all(|w| w[0] <= w[1]));
        let mut area = vec![0.0; sites.len()];
        let mut first = vec![[0.0; 3]; sites.len()];
        let mut covered = vec![0.0; s.triangles().len()];
        for k in 0..m {
            let nodes = &p.points[p.offsets[k]..p.offsets[k + 1]];
            let [a, b, c] = s.corners(p.triangles[k]);
            let normal = cross(sub(b, a), sub(c, a));
            let unit = scale(normal, 1.0 / norm2(normal).sqrt());
            assert!(nodes.len() >= 3);
            for x in nodes {
                assert!(
                    dot(unit, sub(*x, a)).abs() < 1e-14,
                    "piece {k} off its plane"
                );
            }
            for j in 1..nodes.len() - 1 {
                let twice = cross(sub(nodes[j], nodes[0]), sub(nodes[j + 1], nodes[0]));
                assert!(dot(twice, unit) >= -1e-15, "piece {k} turns clockwise");
                let (i, da) = (p.cells[k] as usize, 0.5 * dot(twice, unit));
                area[i] += da;
                covered[p.triangles[k] as usize] += da;
                let mid = scale(add(add(nodes[0], nodes[j]), nodes[j + 1]), da / 3.0);
                first[i] = add(first[i], mid);
            }
        }
        for (i, moments) in p.diagram.moments.iter().enumerate() {
            assert!((area[i] - moments.mass).abs() <= 1e-14, "cell {i}");
            // The moments are about the site.
            let about = sub(first[i], scale(sites[i], area[i]));
            assert!(norm2(sub(about, moments.first)) <= 1e-28, "cell {i}");
        }
        for (t, got) in covered.iter().enumerate() {
            let [a, b, c] = s.corners(t as u32);
            let whole = 0.5 * norm2(cross(sub(b, a), sub(c, a))).sqrt();
            assert!(
                (got - whole).abs() <= 1e-14,
                "triangle {t}: {got} of {whole}"
            );
        }
        let mut twice = sites.clone();
        twice[7] = twice[3];
        assert!(matches!(
            s.pieces(&twice),
            Err(CoreError::DuplicateSites { .. })
        ));
    }

    /// [`Noting`] is the surface as a domain, plus the triangles each cell's measure met:
    /// its diagram equals the surface's bit for bit (every method `Surface` overrides is
    /// forwarded: one left out would show here), and the meeting points from the noted
    /// triangles equal those of a fresh walk of the BVH, for every cell.
    #[test]
    fn noted_triangles_give_the_walks_diagram_and_meeting_points() {
        let s = roof(8, 0.6);
        let sites = sites(300, 5);
        let request = Request {
            keep_cells: true,
            ..Default::default()
        };
        let plain = clipped_diagram::<3, PolyhedronCell, _>(&s, &sites, &request).unwrap();
        let noting = Noting::new(&s, false, sites.len());
        let noted = clipped_diagram::<3, PolyhedronCell, _>(&noting, &sites, &request).unwrap();
        let (a, b) = (&plain.diagram, &noted.diagram);
        assert_eq!(a.moments, b.moments);
        assert_eq!(a.neighbor_offsets, b.neighbor_offsets);
        assert_eq!(a.neighbor_sites, b.neighbor_sites);
        assert_eq!(a.neighbor_measures, b.neighbor_measures);
        assert_eq!(a.boundary_measure, b.boundary_measure);
        let met = noting.into_notes();
        let same = SAME_POINT * s.set.bvh().bounds().diagonal();
        let mut replays = 0;
        for (i, cell) in noted.cells.iter().enumerate() {
            // Some sites off the roof have cells that miss it: nothing noted, nothing met.
            let noted = met[&sites[i].map(f64::to_bits)].as_ref();
            let triangles = noted.map(|n| n.triangles.as_slice());
            assert!(triangles.is_some(), "cell {i} not noted");
            replays += usize::from(triangles.is_some_and(|t| !t.is_empty()));
            let walked = s.meeting_points(i as u32, cell, sites[i], same, None);
            let replayed = s.meeting_points(i as u32, cell, sites[i], same, triangles);
            assert_eq!(walked, replayed, "cell {i}");
        }
        // Every cell with an area replayed its noted triangles (here 135 of the 300).
        let with_area = b.moments.iter().filter(|m| m.mass > 0.0).count();
        assert!(
            replays == with_area && replays > 100,
            "{replays} of {with_area}"
        );
    }

    /// Three sites whose cells meet at `(0.5, 0.5, 0)` in the flat square `roof(k, 0.0)`
    /// (split on the diagonal `y = x`, so the point is on an input edge for `k = 1` and an
    /// input vertex for `k = 2`), in every order, and mirrored (the other diagonal): one
    /// triangle, counter-clockwise about `+z`, no triple repeated. The first set has the
    /// bisector of two sites along the diagonal (exactly); the second has the meeting
    /// point on it up to rounding (sites on a circle about it).
    #[test]
    fn three_cells_meeting_on_an_input_edge_or_vertex_give_one_triangle() {
        let on_circle = |deg: f64| {
            let a = deg.to_radians();
            [0.5 + 0.3 * a.cos(), 0.5 + 0.3 * a.sin(), 0.0]
        };
        let sets = [
            [[0.2, 0.5, 0.0], [0.8, 0.5, 0.0], [0.5, 0.8, 0.0]],
            [on_circle(10.0), on_circle(130.0), on_circle(250.0)],
            [on_circle(45.0), on_circle(165.0), on_circle(285.0)],
        ];
        let orders = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        for k in [1, 2] {
            let s = roof(k, 0.0);
            for set in &sets {
                for mirror in [false, true] {
                    for order in orders {
                        let sites: Vec<[f64; 3]> = order
                            .iter()
                            .map(|&o| {
                                let [x, y, z] = set[o];
                                [if mirror { 1.0 - x } else { x }, y, z]
                            })
                            .collect();
                        let rdt = s.restricted_delaunay(&sites).unwrap();
                        let case = format!("k {k} {set:?} mirror {mirror} order {order:?}");
                        assert_eq!(rdt.triangles.len(), 1, "{case}: {:?}", rdt.triangles);
                        assert!(rdt.repeated.is_empty(), "{case}");
                        let [a, b, c] = rdt.triangles[0].map(|v| sites[v as usize]);
                        assert!(cross(sub(b, a), sub(c, a))[2] > 0.0, "{case}");
                        let p = rdt.points[0];
                        assert!(norm2(sub(p, [0.5, 0.5, 0.0])) < 1e-24, "{case}: {p:?}");
                    }
                }
            }
        }
    }

    /// Sites on a triangular lattice whose cells all meet on the vertical edges of a flat
    /// grid (x multiples of 1/12): the triangles are the Delaunay triangles with their
    /// circumcentre in the square, found by brute force (empty circumcircles), each once.
    #[test]
    fn lattice_cells_meeting_on_grid_edges_give_the_delaunay_triangles() {
        let s = roof(12, 0.0);
        let mut sites = Vec::new();
        for j in 0..6 {
            let (shift, count) = if j % 2 == 0 { (0.5, 6) } else { (1.0, 5) };
            for i in 0..count {
                sites.push([(i as f64 + shift) / 6.0, (j as f64 + 0.5) / 6.0, 0.0]);
            }
        }
        let mut want = Vec::new();
        let n = sites.len();
        for a in 0..n {
            for b in a + 1..n {
                for c in b + 1..n {
                    let [p, q, r] = [sites[a], sites[b], sites[c]];
                    let (bx, by, cx, cy) = (q[0] - p[0], q[1] - p[1], r[0] - p[0], r[1] - p[1]);
                    let d = 2.0 * (bx * cy - by * cx);
                    if d.abs() < 1e-12 {
                        continue;
                    }
                    let (b2, c2) = (bx * bx + by * by, cx * cx + cy * cy);
                    let centre = [
                        p[0] + (cy * b2 - by * c2) / d,
                        p[1] + (bx * c2 - cx * b2) / d,
                        0.0,
                    ];
                    let r2 = norm2(sub(centre, p));
                    let inside = centre[..2].iter().all(|&x| (0.0..=1.0).contains(&x));
                    if inside && sites.iter().all(|&z| norm2(sub(z, centre)) > r2 - 1e-12) {
                        want.push([a as u32, b as u32, c as u32]);
                    }
                }
            }
        }
        assert!(want.len() > 40);
        let rdt = s.restricted_delaunay(&sites).unwrap();
        assert!(rdt.repeated.is_empty());
        let mut got: Vec<[u32; 3]> = rdt
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| sites[v as usize]);
                assert!(cross(sub(b, a), sub(c, a))[2] > 0.0, "{t:?}");
                let mut k = *t;
                k.sort_unstable();
                k
            })
            .collect();
        got.sort_unstable();
        assert_eq!(got, want);
    }

    #[test]
    fn bad_surfaces_are_refused_by_name() {
        let v = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
        ];
        let err = Surface::new(v.clone(), vec![[0, 1, 3]]).unwrap_err();
        assert!(err.to_string().contains("degenerate"), "{err}");
        let err = Surface::new(v.clone(), vec![[0, 1, 2], [0, 1, 2]]).unwrap_err();
        assert!(err.to_string().contains("repeated"), "{err}");
        let err = Surface::new(v.clone(), vec![[0, 1, 2], [1, 0, 2]]).unwrap_err();
        assert!(err.to_string().contains("repeated"), "{err}");
        let w = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let err = Surface::new(w.clone(), vec![[0, 1, 2], [0, 1, 3]]).unwrap_err();
        assert!(err.to_string().contains("orientation"), "{err}");
        let err = Surface::new(w, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap_err();
        assert!(err.to_string().contains("non-manifold"), "{err}");
    }
}
