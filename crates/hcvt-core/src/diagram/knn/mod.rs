//! Nearest sites: a uniform grid of buckets, or a kiddo kd-tree when the grid would be
//! badly balanced.
//!
//! A Voronoi cell needs its site's neighbours in increasing distance until the security
//! radius; [`SiteIndex::near`] streams them. The grid answers from expanding rings of
//! buckets around the query, so the stream never re-queries; the kd-tree (clustered sites,
//! where some bucket would hold a large share of them) answers with doubled k-nearest
//! queries.
//!
//! The files: this one holds the index and its streams; [`grid`] the buckets and their
//! rings, [`tree`] the kd-tree's doubling query, [`scratch`] the streams' buffers.

mod grid;
mod scratch;
mod tree;

pub use scratch::NearScratch;

use std::sync::OnceLock;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::error::CoreError;
use crate::geometry::{norm2, sub};

use grid::{sort_nearly_sorted, Grid, GridPlan, Rings};
use tree::tree_next;

/// Sites indexed for nearest-site queries in a deterministic order.
pub struct SiteIndex<const D: usize> {
    kind: Kind<D>,
}

enum Kind<const D: usize> {
    Grid(Grid<D>),
    Tree(ImmutableKdTree<f64, D>, usize),
}

impl<const D: usize> SiteIndex<D> {
    /// Index `sites` (must be finite).
    pub fn new(sites: &[[f64; D]]) -> Result<Self, CoreError> {
        if let Some(grid) = Grid::new(sites) {
            return Ok(Self {
                kind: Kind::Grid(grid),
            });
        }
        Self::tree(sites)
    }

    /// The kd-tree of `sites`.
    fn tree(sites: &[[f64; D]]) -> Result<Self, CoreError> {
        ImmutableKdTree::new_from_slice(sites)
            .map(|tree| Self {
                kind: Kind::Tree(tree, sites.len()),
            })
            .map_err(|e| CoreError::SiteIndex {
                reason: e.to_string(),
            })
    }

    /// The sites in increasing squared distance from `p`, ties by index on the grid.
    pub fn near<'a>(&'a self, p: [f64; D], scratch: &'a mut NearScratch) -> NearSites<'a, D> {
        scratch.reset();
        let state = match &self.kind {
            Kind::Grid(grid) => State::Grid(grid.ring_start(p)),
            Kind::Tree(..) => State::Tree {
                k: 0,
                position: 0,
                last_dist2: f64::NEG_INFINITY,
            },
        };
        NearSites {
            index: IndexRef::Built(self),
            p,
            scratch,
            state,
        }
    }

    /// The nearest site of `p` as `(index, squared distance)`.
    pub fn nearest_one(&self, p: [f64; D]) -> (u32, f64) {
        match &self.kind {
            Kind::Tree(tree, _) => {
                let r = tree
                    .query(&p)
                    .nearest_one::<SquaredEuclidean<f64>>()
                    .execute();
                (r.item, r.distance)
            }
            Kind::Grid(grid) => grid.nearest_one(p),
        }
    }

    /// The `k` nearest sites of `p` as `(index, squared distance)`, nearest first.
    pub fn nearest(&self, p: [f64; D], k: usize) -> Vec<(u32, f64)> {
        let mut scratch = NearScratch::default();
        let mut near = self.near(p, &mut scratch);
        std::iter::from_fn(|| near.next_within(f64::INFINITY))
            .take(k)
            .collect()
    }
}

/// A [`SiteIndex`] of some sites whose grid is filled on first use: a warm-started
/// diagram whose cells all stream from their lists ([`IndexRef::near_warm`]) never reads
/// it: its fill was 1.3% of such a 2D diagram's instructions (callgrind, square 20k),
/// besides writing a fresh array of 24 B/site. Whether the sites get a
/// grid or a kd-tree (which orders ties its own way, so a warm stream cannot stand for
/// it) is decided at once, and a kd-tree is built at once.
pub struct DeferredIndex<'a, const D: usize> {
    sites: &'a [[f64; D]],
    /// The grid to fill; `None` once `index` is built whole (a kd-tree, or at once).
    plan: Option<GridPlan<D>>,
    index: OnceLock<SiteIndex<D>>,
}

impl<'a, const D: usize> DeferredIndex<'a, D> {
    /// The index of `sites` (must be finite), its grid not filled yet.
    pub fn new(sites: &'a [[f64; D]]) -> Result<Self, CoreError> {
        let plan = GridPlan::new(sites);
        let index = OnceLock::new();
        if plan.is_none() {
            // Set on a fresh cell: it cannot be taken.
            let _ = index.set(SiteIndex::tree(sites)?);
        }
        Ok(Self { sites, plan, index })
    }

    /// The index of `sites` built whole at once (nothing deferred), for a diagram whose
    /// cells all read it.
    pub fn built(sites: &'a [[f64; D]]) -> Result<Self, CoreError> {
        let index = OnceLock::new();
        // Set on a fresh cell: it cannot be taken.
        let _ = index.set(SiteIndex::new(sites)?);
        Ok(Self {
            sites,
            plan: None,
            index,
        })
    }

    /// The index, filled now if it was not.
    pub fn get(&self) -> &SiteIndex<D> {
        self.index.get_or_init(|| {
            let plan = self
                .plan
                .as_ref()
                .expect("a grid is planned when no tree is built");
            SiteIndex {
                kind: Kind::Grid(plan.fill(self.sites)),
            }
        })
    }

    /// The filled index, for keeping.
    pub fn into_built(self) -> SiteIndex<D> {
        self.get();
        self.index.into_inner().expect("filled just above")
    }
}

/// A built [`SiteIndex`] or a [`DeferredIndex`], as the cells read them.
#[derive(Clone, Copy)]
pub enum IndexRef<'a, const D: usize> {
    /// An index built whole.
    Built(&'a SiteIndex<D>),
    /// An index filled on first use.
    Deferred(&'a DeferredIndex<'a, D>),
}

impl<'a, const D: usize> From<&'a SiteIndex<D>> for IndexRef<'a, D> {
    fn from(index: &'a SiteIndex<D>) -> Self {
        Self::Built(index)
    }
}

impl<'a, const D: usize> From<&'a DeferredIndex<'a, D>> for IndexRef<'a, D> {
    fn from(index: &'a DeferredIndex<'a, D>) -> Self {
        Self::Deferred(index)
    }
}

impl<'a, const D: usize> IndexRef<'a, D> {
    /// The index, filled now if it was deferred.
    pub fn get(self) -> &'a SiteIndex<D> {
        match self {
            Self::Built(index) => index,
            Self::Deferred(deferred) => deferred.get(),
        }
    }

    /// Whether the index is a grid (without filling it).
    fn is_grid(self) -> bool {
        match self {
            Self::Built(index) => matches!(index.kind, Kind::Grid(_)),
            Self::Deferred(deferred) => match deferred.index.get() {
                Some(index) => matches!(index.kind, Kind::Grid(_)),
                None => deferred.plan.is_some(),
            },
        }
    }

    /// [`SiteIndex::near`] from a warm start: `candidates` are sites known to include
    /// every site within `certified2` of `p` (`p` is `sites[i]`, itself a candidate). They
    /// are streamed in the grid's order, squared distance then index, as long as they are
    /// certified; a request beyond `certified2` switches to the grid's own stream (filling
    /// a deferred grid), which returns the same sites in the same order. So the stream is
    /// the cold one bit for bit, however far the sites moved. A kd-tree orders ties its
    /// own way: it streams cold.
    pub fn near_warm(
        self,
        p: [f64; D],
        sites: &[[f64; D]],
        candidates: &[u32],
        certified2: f64,
        scratch: &'a mut NearScratch,
    ) -> NearSites<'a, D> {
        // A NaN or empty certificate streams cold.
        let certified = certified2.partial_cmp(&0.0) == Some(std::cmp::Ordering::Greater);
        if !self.is_grid() || !certified {
            return self.get().near(p, scratch);
        }
        scratch.reset();
        let gathered = &mut scratch.gathered;
        for &j in candidates {
            let dist2 = norm2(sub(sites[j as usize], p));
            if dist2 <= certified2 {
                gathered.push((dist2.to_bits(), j));
            }
        }
        sort_nearly_sorted(gathered);
        scratch.sorted = gathered.len();
        NearSites {
            index: self,
            p,
            scratch,
            state: State::Warm { certified2 },
        }
    }
}

/// A stream of the sites in increasing distance from a point.
pub struct NearSites<'a, const D: usize> {
    index: IndexRef<'a, D>,
    p: [f64; D],
    scratch: &'a mut NearScratch,
    state: State<D>,
}

enum State<const D: usize> {
    Grid(Rings<D>),
    /// Certified candidates sorted in `gathered[..sorted]` ([`IndexRef::near_warm`]).
    Warm {
        certified2: f64,
    },
    Tree {
        k: usize,
        position: usize,
        last_dist2: f64,
    },
}

impl<const D: usize> NearSites<'_, D> {
    /// The next site as `(index, squared distance)` if its squared distance is at most
    /// `limit2`, else `None` (and that site stays next). On the grid, `limit2` must not
    /// grow from call to call: farther sites are dropped as they are gathered.
    pub fn next_within(&mut self, limit2: f64) -> Option<(u32, f64)> {
        let next = self.next_unvouched(limit2);
        let vouched = next.map_or(limit2, |(_, dist2)| dist2);
        self.scratch.vouched2 = self.scratch.vouched2.max(vouched);
        next
    }

    /// The largest squared distance within which the stream has told every site so far:
    /// that of each site returned, and each limit it answered `None` for. Another stream
    /// that holds every site within it answers the same calls the same way.
    pub fn vouched2(&self) -> f64 {
        self.scratch.vouched2
    }

    /// Whether the stream still answers from a warm start's candidates.
    pub fn is_warm(&self) -> bool {
        matches!(self.state, State::Warm { .. })
    }

    fn next_unvouched(&mut self, limit2: f64) -> Option<(u32, f64)> {
        if let State::Warm { certified2 } = self.state {
            if let Some(next) = self.scratch.next_sorted(limit2) {
                return next;
            }
            if limit2 <= certified2 {
                // Every site not among the candidates lies beyond `certified2`.
                return None;
            }
            self.go_cold(limit2);
        }
        match &mut self.state {
            State::Grid(rings) => {
                let Kind::Grid(grid) = &self.index.get().kind else {
                    unreachable!("a grid stream comes from a grid")
                };
                grid.next_within(rings, self.p, self.scratch, limit2)
            }
            State::Tree {
                k,
                position,
                last_dist2,
            } => {
                let Kind::Tree(tree, n) = &self.index.get().kind else {
                    unreachable!("a tree stream comes from a tree")
                };
                let next = tree_next(tree, *n, self.p, self.scratch, k, position, *last_dist2)?;
                if next.1 > limit2 {
                    return None;
                }
                *position += 1;
                if next.1 > *last_dist2 {
                    *last_dist2 = next.1;
                    self.scratch.at_last.clear();
                }
                self.scratch.at_last.push(next.0);
                Some(next)
            }
            State::Warm { .. } => unreachable!("a warm stream answers above"),
        }
    }

    /// Leave the warm candidates for the grid's stream, skipping the sites already
    /// returned: they are the grid's first ones, in its order.
    fn go_cold(&mut self, limit2: f64) {
        let Kind::Grid(grid) = &self.index.get().kind else {
            unreachable!("a warm stream comes from a grid")
        };
        // Resolved once: the grid stream reads it at every step.
        self.index = IndexRef::Built(self.index.get());
        let returned = self.scratch.next;
        let scratch = &mut *self.scratch;
        scratch.gathered.clear();
        scratch.next = 0;
        scratch.sorted = 0;
        scratch.covered = 0;
        let mut rings = grid.ring_start(self.p);
        for _ in 0..returned {
            let skipped = grid.next_within(&mut rings, self.p, scratch, limit2);
            debug_assert!(skipped.is_some(), "the certified sites come first");
        }
        self.state = State::Grid(rings);
    }
}

#[cfg(test)]
mod tests;
