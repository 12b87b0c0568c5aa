//! A box of the BVH against a cell's planes, without a branch per corner (module docs of
//! [`super`], "Finding the triangles" and "Whole triangles").

use crate::diagram::convex_cell::Face;
use crate::geometry::{sub, Aabb, HalfSpace};

/// Where a box of the BVH lies against a cell ([`box_side`]).
pub(super) enum BoxSide {
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
pub(super) struct BoxPlanes {
    rows: Vec<[f64; 8]>,
    /// The same rows two planes at a time, component by component (the two lanes of a
    /// vector register): planes `2i` and `2i + 1` in `pairs[i][c]`, `c` as in a row. An
    /// odd last plane is paired with one no box is outside (no normal, offset +∞).
    pairs: Vec<[[f64; 2]; 7]>,
}

impl BoxPlanes {
    /// The rows of `planes`, in their order.
    pub(super) fn set(&mut self, planes: &[(Face, HalfSpace<3>)]) {
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
///
/// [`Clipper::triangle`]: super::clipper::Clipper::triangle
pub(super) fn box_side(
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
pub(super) fn holds_site(b: &Aabb<3>, site: [f64; 3]) -> bool {
    let (lo, hi) = (sub(b.lo, site), sub(b.hi, site));
    (0..3).all(|k| lo[k] <= 0.0 && hi[k] >= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
