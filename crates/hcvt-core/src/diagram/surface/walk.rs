//! Finding the triangles that meet a cell and clipping them into its pieces, in the BVH's
//! fixed order, with the triangles and pieces a site's earlier looks met kept for replay
//! (module docs of [`super`], "Finding the triangles" and "Stopping early").

use std::cell::RefCell;

use crate::diagram::convex_cell::{ConvexCell, Face};
use crate::diagram::scratch::with_scratch;
use crate::geometry::{add, sub, Aabb, HalfSpace};

use super::clipper::{Clipper, Node};
use super::prune::{box_side, holds_site, BoxPlanes, BoxSide};
use super::triangles::Surface;

impl Surface {
    pub(super) fn corners(&self, t: u32) -> [[f64; 3]; 3] {
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
    pub(super) fn for_each_piece<C: ConvexCell<3>>(
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
    pub(super) fn for_each_piece_of<C: ConvexCell<3>>(
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
    pub(super) fn relative(&self, t: u32, site: [f64; 3]) -> [[f64; 3]; 3] {
        self.corners(t).map(|v| sub(v, site))
    }
}

/// Where [`Surface::for_each_piece`] finds the triangles of a cell. The driver validates
/// a cell (or asks its radius, [`DomainKind::local_radius2`], then localises and
/// validates it), which only shrinks it, and measures it last: the first validation (the
/// radius) walks the BVH and records the triangles the cell met, the later validations
/// and the measure clip only those (a triangle that missed the larger cell misses the
/// smaller one).
///
/// [`DomainKind::local_radius2`]: crate::diagram::domain_kind::DomainKind::local_radius2
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Triangles {
    /// Walk the BVH.
    Walk,
    /// Walk the BVH and record the triangles met, for this site.
    Record,
    /// The recorded triangles if they are this site's, else walk.
    Met,
    /// As `Met`, then forget them: the cell is done.
    LastMet,
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
