//! The kd-tree's stream: the `k` nearest sites, `k` doubled while the stream goes on.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::scratch::NearScratch;

/// The next site of a kd-tree stream, without consuming it: the next of the `k` nearest
/// not returned yet, doubling `k` when they run out. A re-query returns the nearer sites
/// again (all returned already), and ties at the last distance in any order.
pub(super) fn tree_next<const D: usize>(
    tree: &ImmutableKdTree<f64, D>,
    n: usize,
    p: [f64; D],
    scratch: &mut NearScratch,
    k: &mut usize,
    position: &mut usize,
    last_dist2: f64,
) -> Option<(u32, f64)> {
    loop {
        while let Some(&(j, dist2)) = scratch.tree.get(*position) {
            if dist2 < last_dist2 || (dist2 == last_dist2 && scratch.at_last.contains(&j)) {
                *position += 1;
                continue;
            }
            return Some((j, dist2));
        }
        if *k >= n || scratch.tree.len() < *k {
            return None;
        }
        *k = (2 * *k).max(FIRST_K.get(D).copied().unwrap_or(64)).min(n);
        scratch.tree.clear();
        scratch.tree.extend(
            tree.query(&p)
                .nearest_n::<SquaredEuclidean<f64>>(NonZeroUsize::new(*k).expect("k > 0"))
                .execute()
                .into_iter()
                .map(|r| (r.item, r.distance)),
        );
        *position = 0;
    }
}

/// Number of nearest sites a kd-tree stream fetches first; doubled while the stream goes
/// on. A cell has about 6 neighbours in 2D and 15.5 in 3D, and the security radius usually
/// needs about twice that.
const FIRST_K: [usize; 4] = [2, 4, 16, 64];
