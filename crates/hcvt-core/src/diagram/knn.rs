//! Nearest sites, through a kiddo kd-tree.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::error::CoreError;

/// kd-tree over the sites, answering k-nearest queries in a deterministic order.
pub struct SiteIndex<const D: usize> {
    tree: ImmutableKdTree<f64, D>,
}

impl<const D: usize> SiteIndex<D> {
    /// Index `sites` (must be finite).
    pub fn new(sites: &[[f64; D]]) -> Result<Self, CoreError> {
        ImmutableKdTree::new_from_slice(sites)
            .map(|tree| Self { tree })
            .map_err(|e| CoreError::SiteIndex {
                reason: e.to_string(),
            })
    }

    /// The `k` nearest sites of `p` as `(index, squared distance)`, nearest first.
    pub fn nearest(&self, p: &[f64; D], k: usize) -> Vec<(u32, f64)> {
        let Some(k) = NonZeroUsize::new(k) else {
            return Vec::new();
        };
        self.tree
            .query(p)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute()
            .into_iter()
            .map(|r| (r.item, r.distance))
            .collect()
    }

    /// The nearest site of `p` as `(index, squared distance)`.
    pub fn nearest_one(&self, p: &[f64; D]) -> (u32, f64) {
        let r = self
            .tree
            .query(p)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        (r.item, r.distance)
    }
}
