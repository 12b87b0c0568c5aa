//! A warm cell rebuilt from its ring (issue 32): the neighbours its canonical cell had in
//! the previous diagram, face after face ([`ConvexCell::canonicalise`]).
//!
//! Between two late iterates of a CVT most cells keep their neighbours. Such a cell is the
//! canonical cell of the same half-spaces, whose vertices come from their faces' planes
//! alone ([`ConvexCell::rebuild_from_ring`]), so it can be built without clipping: when the
//! half-spaces bound a cell with every vertex clear of every other face, and no site of
//! the warm list within the security radius comes near a vertex, the clips would have made
//! the same faces, and canonicalised them into the same bits. Anything closer to a tie
//! than [`SEPARATION`] falls back to the clipped cell. Only for the kinds with a canonical
//! form (2D).

use crate::geometry::{dot, norm2, sub, Aabb, HalfSpace};

use super::convex_cell::ConvexCell;
use super::warm::WarmList;

/// How far, relative to a plane's `|normal|²` (the squared distance to the neighbour), a
/// vertex must lie inside every half-space but its own faces' for the ring's cell to be
/// taken: 1e-9 of the spacing, far above the round-off of a clip (1e-16) yet a tie to
/// any sampled geometry.
pub(super) const SEPARATION: f64 = 1e-9;

/// What the ring's cell read, when it stood.
pub(super) struct RingCell {
    /// The squared distance of the farthest site of the warm list the cell read, or the
    /// stopping distance `4 r²` if farther: the cold cell's reach.
    pub reach2: f64,
    /// How many sites the cold cell would have taken from its stream, its own included.
    pub taken: usize,
}

/// Site `i`'s cell from `warm`'s ring into `cell` (relative to the site), its near sites
/// for the next diagram (the ring first) into `record`; `None` when the ring does not
/// certify the cell and it must be clipped (`cell` and `record` then hold anything).
///
/// The cold cell starts from the box `start` (relative to the site) and streams every
/// site within twice its radius ([`RingCell::taken`] of them): cells that reach near the
/// box (whose cold cell has the box's faces) or beyond what the list certifies fall back.
pub(super) fn ring_cell<const D: usize, C: ConvexCell<D>>(
    sites: &[[f64; D]],
    i: usize,
    start: &Aabb<D>,
    warm: WarmList<'_>,
    cell: &mut C,
    record: &mut Vec<u32>,
) -> Option<RingCell> {
    let (ring, rest) = warm.near.split_at(warm.ring.min(warm.near.len()));
    let site = sites[i];
    let mut last2: f64 = 0.0;
    for &j in ring {
        let dist2 = norm2(sub(sites[j as usize], site));
        if dist2 == 0.0 {
            return None; // two sites at one point: the clipped cell says so
        }
        last2 = last2.max(dist2);
    }
    // The half-spaces exactly as the clips take them (`voronoi_cell`).
    let plane = |j: u32| HalfSpace::bisector(sub(sites[j as usize], site));
    if !cell.rebuild_from_ring(ring, warm.triangles, plane, SEPARATION)
        || !well_inside(cell.vertices(), start)
    {
        return None;
    }
    let stop2 = 4.0 * cell.max_dist2();
    if stop2 > warm.certified2 || stop2.is_nan() {
        return None;
    }
    record.clear();
    record.extend_from_slice(ring);
    let mut taken = 1 + ring.len();
    for &j in rest {
        let q = sub(sites[j as usize], site);
        let dist2 = norm2(q);
        if dist2 > warm.certified2 {
            continue;
        }
        record.push(j);
        if dist2 > stop2 || j as usize == i {
            continue;
        }
        let plane = HalfSpace::bisector(q);
        let clear = -SEPARATION * dist2;
        if dist2 == 0.0
            || !(cell.vertices().iter()).all(|&v| dot(plane.normal, v) - plane.offset < clear)
        {
            return None;
        }
        taken += 1;
        last2 = last2.max(dist2);
    }
    Some(RingCell {
        reach2: last2.max(stop2),
        taken,
    })
}

/// Every vertex inside the box by [`SEPARATION`] of its extent on each axis.
fn well_inside<const D: usize>(vertices: &[[f64; D]], b: &Aabb<D>) -> bool {
    let margin: [f64; D] = std::array::from_fn(|k| SEPARATION * (b.hi[k] - b.lo[k]));
    vertices
        .iter()
        .all(|v| (0..D).all(|k| v[k] > b.lo[k] + margin[k] && v[k] < b.hi[k] - margin[k]))
}
