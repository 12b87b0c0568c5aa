//! Nearest sites: a uniform grid of buckets, or a kiddo kd-tree when the grid would be
//! badly balanced.
//!
//! A Voronoi cell needs its site's neighbours in increasing distance until the security
//! radius; [`SiteIndex::near`] streams them. The grid answers from expanding rings of
//! buckets around the query, so the stream never re-queries; the kd-tree (clustered sites,
//! where some bucket would hold a large share of them) answers with doubled k-nearest
//! queries.

use std::num::NonZeroUsize;
use std::sync::OnceLock;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::error::CoreError;
use crate::geometry::{norm2, sub, Aabb, Lattice};

/// Sites per bucket the grid aims at. A cell's neighbours then mostly lie in the 3^D
/// buckets around its site; 1 and 3 cost 6% and 4% more instructions than 2 for a CVT of
/// 1,000 sites in a square, and 2% more for a 3D diagram of 4,000 random sites.
const SITES_PER_BUCKET: usize = 2;

/// The grid is used while `Σ (sites in bucket)²` stays below this multiple of the site
/// count: about 2 for uniform sites, and the work of a query grows with it.
const MAX_CROWDING: usize = 16;

/// Sites indexed for nearest-site queries in a deterministic order.
pub struct SiteIndex<const D: usize> {
    kind: Kind<D>,
}

enum Kind<const D: usize> {
    Grid(Grid<D>),
    Tree(ImmutableKdTree<f64, D>, usize),
}

/// Buffers of a [`NearSites`] stream, reused from cell to cell.
#[derive(Debug, Default)]
pub struct NearScratch {
    /// Gathered sites as (squared distance bits, index): returned before `next`; sorted
    /// from `next` to `sorted`; within the covered distance, unsorted but none nearer than
    /// the sorted ones, up to `covered`; farther after.
    gathered: Vec<(u64, u32)>,
    next: usize,
    sorted: usize,
    covered: usize,
    /// kd-tree answers and the sites returned at the last distance.
    tree: Vec<(u32, f64)>,
    at_last: Vec<u32>,
    /// The largest squared distance the stream has vouched for: of each site returned,
    /// and each limit it answered `None` for ([`NearSites::vouched2`]).
    vouched2: f64,
}

impl NearScratch {
    /// The next of the sorted sites, if one is left: `Some(None)` when it lies beyond
    /// `limit2` (and stays next).
    fn next_sorted(&mut self, limit2: f64) -> Option<Option<(u32, f64)>> {
        let &(bits, j) = self.gathered[..self.sorted].get(self.next)?;
        let dist2 = f64::from_bits(bits);
        if dist2 > limit2 {
            return Some(None);
        }
        self.next += 1;
        Some(Some((j, dist2)))
    }
    /// Ready for a new stream.
    fn reset(&mut self) {
        self.gathered.clear();
        self.next = 0;
        self.sorted = 0;
        self.covered = 0;
        self.tree.clear();
        self.at_last.clear();
        self.vouched2 = 0.0;
    }
    /// The candidates of the last warm stream ([`IndexRef::near_warm`]) within its
    /// certified distance, nearest first.
    pub fn certified(&self) -> impl Iterator<Item = u32> + '_ {
        self.gathered[..self.sorted].iter().map(|&(_, j)| j)
    }
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

/// The next site of a kd-tree stream, without consuming it: the next of the `k` nearest
/// not returned yet, doubling `k` when they run out. A re-query returns the nearer sites
/// again (all returned already), and ties at the last distance in any order.
fn tree_next<const D: usize>(
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

/// Buckets of sites over the sites' bounding box, in compressed rows: bucket `b` holds
/// `points[starts[b]..starts[b + 1]]`.
struct Grid<const D: usize> {
    buckets: Lattice<D>,
    starts: Vec<u32>,
    /// Sites in bucket order (by index within a bucket), with their indices.
    points: Vec<([f64; D], u32)>,
    /// Slack on the distance to a bucket's face, for the rounding of bucket coordinates.
    slack: f64,
}

/// A grid decided on but not filled: its buckets, each site's bucket and their counts.
struct GridPlan<const D: usize> {
    buckets: Lattice<D>,
    /// Sites per bucket, `starts[b + 1]` for bucket `b` (`starts[0]` is 0).
    starts: Vec<u32>,
    /// Each site's bucket.
    site_buckets: Vec<u32>,
    slack: f64,
}

impl<const D: usize> GridPlan<D> {
    /// The buckets of `sites` and their counts, or `None` when they are too crowded for a
    /// grid (or too far apart for the floating-point box).
    fn new(sites: &[[f64; D]]) -> Option<Self> {
        let n = sites.len();
        if n == 0 || n >= u32::MAX as usize {
            return None;
        }
        let bounds = Aabb::of_points(sites);
        let extent = sub(bounds.hi, bounds.lo);
        if !extent.iter().all(|e| e.is_finite()) {
            return None;
        }
        let buckets = Lattice::new(bounds.lo, extent, n.div_ceil(SITES_PER_BUCKET));
        let (mut site_buckets, mut starts) = counted(sites, &buckets)?;
        // Sites filling a fraction of their box (a star, a ball) would crowd the buckets
        // they occupy: aim at SITES_PER_BUCKET in the occupied buckets instead.
        let occupied = starts.iter().filter(|&&c| c > 0).count();
        let mut buckets = buckets;
        if occupied > 0 && 4 * occupied < 3 * buckets.len() {
            let target = n.div_ceil(SITES_PER_BUCKET) * buckets.len() / occupied;
            buckets = Lattice::new(bounds.lo, extent, target.min(MAX_BUCKETS_PER_SITE * n));
            (site_buckets, starts) = counted(sites, &buckets)?;
        }
        let crowding: usize = starts.iter().map(|&c| (c as usize).pow(2)).sum();
        if crowding > MAX_CROWDING * n {
            return None;
        }
        let largest_side = buckets.side.iter().fold(0.0, |m: f64, &s| m.max(s));
        Some(Self {
            buckets,
            starts,
            site_buckets,
            slack: rounding_slack(&bounds, extent, largest_side),
        })
    }

    /// The grid: the sites sorted into their buckets (by index within a bucket).
    fn fill(&self, sites: &[[f64; D]]) -> Grid<D> {
        let mut starts = self.starts.clone();
        for b in 1..starts.len() {
            starts[b] += starts[b - 1];
        }
        let mut next = starts.clone();
        let mut points = vec![([0.0; D], 0); sites.len()];
        for (i, &b) in self.site_buckets.iter().enumerate() {
            points[next[b as usize] as usize] = (sites[i], i as u32);
            next[b as usize] += 1;
        }
        Grid {
            buckets: self.buckets.clone(),
            starts,
            points,
            slack: self.slack,
        }
    }
}

/// Each site's bucket of `lattice`, and the sites per bucket shifted by one (`counts[b +
/// 1]` for bucket `b`), or `None` when the buckets do not fit a `u32`.
fn counted<const D: usize>(
    sites: &[[f64; D]],
    lattice: &Lattice<D>,
) -> Option<(Vec<u32>, Vec<u32>)> {
    let count = lattice.len();
    if count >= u32::MAX as usize {
        return None;
    }
    let mut counts = vec![0u32; count + 1];
    let site_buckets = sites
        .iter()
        .map(|s| {
            let b = lattice.index(lattice.coordinates(s));
            counts[b + 1] += 1;
            b as u32
        })
        .collect();
    Some((site_buckets, counts))
}

/// Where a grid stream stands: the bucket of the query and the next ring to gather.
struct Rings<const D: usize> {
    center: [usize; D],
    ring: usize,
    /// Every site within this squared distance has been gathered.
    covered2: f64,
}

impl<const D: usize> Grid<D> {
    /// The grid of `sites`, or `None` when they are too crowded for one (or too far apart
    /// for the floating-point box).
    fn new(sites: &[[f64; D]]) -> Option<Self> {
        Some(GridPlan::new(sites)?.fill(sites))
    }

    fn ring_start(&self, p: [f64; D]) -> Rings<D> {
        Rings {
            center: self.buckets.coordinates(&p),
            ring: 0,
            covered2: f64::NEG_INFINITY,
        }
    }

    /// See [`NearSites::next_within`].
    fn next_within(
        &self,
        rings: &mut Rings<D>,
        p: [f64; D],
        scratch: &mut NearScratch,
        limit2: f64,
    ) -> Option<(u32, f64)> {
        loop {
            if let Some(next) = scratch.next_sorted(limit2) {
                return next;
            }
            if scratch.sorted < scratch.covered {
                let pending = &mut scratch.gathered[scratch.sorted..scratch.covered];
                scratch.sorted += sort_nearest(pending);
                continue;
            }
            if rings.covered2 > limit2 || rings.covered2 == f64::INFINITY {
                return None;
            }
            self.gather_ring(rings, p, &mut scratch.gathered, limit2);
            let pending = &mut scratch.gathered[scratch.covered..];
            scratch.covered += move_covered(pending, rings.covered2);
        }
    }

    /// Push the sites of the next ring of buckets within `limit2` of `p`, and raise the
    /// covered distance.
    fn gather_ring(
        &self,
        rings: &mut Rings<D>,
        p: [f64; D],
        gathered: &mut Vec<(u64, u32)>,
        limit2: f64,
    ) {
        self.next_ring(rings, p, |q, j| {
            let dist2 = norm2(sub(q, p));
            if dist2 <= limit2 {
                gathered.push((dist2.to_bits(), j));
            }
        });
    }

    /// Call `f(site, index)` for the sites of the next ring and raise the covered distance.
    /// The first call takes rings 0 and 1 together: ring 0 alone covers too little to
    /// return anything but its own sites, and the 3^D block is fewer, longer rows.
    fn next_ring(&self, rings: &mut Rings<D>, p: [f64; D], f: impl FnMut([f64; D], u32)) {
        let whole = rings.ring == 0;
        let r = rings.ring.max(1);
        self.for_each_in_ring(rings.center, r, whole, f);
        rings.ring = r + 1;
        rings.covered2 = self.covered2(p, rings.center, rings.ring);
    }

    /// The nearest site of `p` as `(index, squared distance)`, the least index among equals:
    /// rings until the covered distance passes the best, keeping only that.
    fn nearest_one(&self, p: [f64; D]) -> (u32, f64) {
        let mut rings = self.ring_start(p);
        let mut best = (u32::MAX, f64::INFINITY);
        while !(best.1 < rings.covered2 || rings.covered2 == f64::INFINITY) {
            self.next_ring(&mut rings, p, |q, j| {
                let dist2 = norm2(sub(q, p));
                if dist2 < best.1 || (dist2 == best.1 && j < best.0) {
                    best = (j, dist2);
                }
            });
        }
        best
    }

    /// Call `f(site, index)` for the sites of the buckets at Chebyshev distance `r` from
    /// bucket `c`, or up to `r` if `whole`.
    fn for_each_in_ring(
        &self,
        c: [usize; D],
        r: usize,
        whole: bool,
        mut f: impl FnMut([f64; D], u32),
    ) {
        // Buckets `from..=to` of a row along axis 0 (contiguous in `points`).
        let mut push_row = |row: [usize; D], from: usize, to: usize| {
            let base = self.buckets.index(row) - row[0];
            let sites = self.starts[base + from] as usize..self.starts[base + to + 1] as usize;
            for &(q, j) in &self.points[sites] {
                f(q, j);
            }
        };
        // Rows along axis 0: a row on the ring's shell in some other axis is a full segment
        // of the ring; an inner row only meets the shell at its two ends.
        let range = |k: usize| {
            (
                c[k].saturating_sub(r),
                (c[k] + r).min(self.buckets.cells[k] - 1),
            )
        };
        let (from, to) = range(0);
        let first: [usize; D] = std::array::from_fn(|k| if k == 0 { c[0] } else { range(k).0 });
        let mut row = first;
        loop {
            let on_shell = whole || r == 0 || (1..D).any(|k| row[k].abs_diff(c[k]) == r);
            if on_shell {
                push_row(row, from, to);
            } else {
                if c[0] >= r {
                    push_row(row, c[0] - r, c[0] - r);
                }
                if c[0] + r < self.buckets.cells[0] {
                    push_row(row, c[0] + r, c[0] + r);
                }
            }
            // Next row: odometer over axes 1..D.
            let Some(k) = (1..D).find(|&k| row[k] < range(k).1) else {
                break;
            };
            row[k] += 1;
            row[1..k].copy_from_slice(&first[1..k]);
        }
    }

    /// A lower bound on the squared distance from `p` (in bucket `c`) to the sites outside
    /// the rings `0..ring` around `c`: the nearest face of their block that has buckets
    /// beyond it, less a slack for rounding. Infinite once the block holds the whole grid.
    fn covered2(&self, p: [f64; D], c: [usize; D], ring: usize) -> f64 {
        let mut nearest = f64::INFINITY;
        for k in 0..D {
            if c[k] + 1 > ring {
                let face = self.buckets.lo[k] + (c[k] + 1 - ring) as f64 * self.buckets.side[k];
                nearest = nearest.min(p[k] - face);
            }
            if c[k] + ring < self.buckets.cells[k] {
                let face = self.buckets.lo[k] + (c[k] + ring) as f64 * self.buckets.side[k];
                nearest = nearest.min(face - p[k]);
            }
        }
        if nearest == f64::INFINITY {
            // The block holds the whole grid (tested first: an infinite slack would make
            // the bound NaN, and the rings would grow for ever).
            return f64::INFINITY;
        }
        let bound = nearest - self.slack;
        if bound == f64::INFINITY {
            f64::INFINITY
        } else if bound >= 0.0 {
            bound * bound * (1.0 - 1e-12)
        } else {
            f64::NEG_INFINITY
        }
    }
}

/// The grid's slack for rounding in [`Grid::covered2`], L: a billionth of a bucket plus 16
/// ulps of the coordinates' size. Where squaring the coordinates overflows (sites near
/// 1e155 and beyond) the size is bounded by the largest coordinate instead, so that the
/// slack stays finite.
fn rounding_slack<const D: usize>(bounds: &Aabb<D>, extent: [f64; D], largest_side: f64) -> f64 {
    let size = norm2(bounds.lo).max(norm2(bounds.hi)).sqrt() + norm2(extent).sqrt();
    let size = if size.is_finite() {
        size
    } else {
        let largest = |v: [f64; D]| v.iter().fold(0.0, |m: f64, &x| m.max(x.abs()));
        (D as f64).sqrt() * (largest(bounds.lo).max(largest(bounds.hi)) + largest(extent))
    };
    1e-9 * largest_side + 16.0 * f64::EPSILON * size
}

/// Move the sites of `pending` within `covered2` to its front and return their number:
/// only those can be returned before the next ring.
fn move_covered(pending: &mut [(u64, u32)], covered2: f64) -> usize {
    let mut front = 0;
    for k in 0..pending.len() {
        if f64::from_bits(pending[k].0) <= covered2 {
            pending.swap(front, k);
            front += 1;
        }
    }
    front
}

/// Sites sorted at a time: a cell near a non-convex boundary gathers a hundred sites within
/// the covered distance and takes 16 before it is localised, so sorting them all cost more
/// than selecting the nearest few.
const SORT_CHUNK: usize = 8;

/// Sort the nearest [`SORT_CHUNK`] of `pending` to its front and return how many.
fn sort_nearest(pending: &mut [(u64, u32)]) -> usize {
    if pending.len() > SORT_CHUNK {
        pending.select_nth_unstable(SORT_CHUNK - 1);
    }
    let sorted = pending.len().min(SORT_CHUNK);
    pending[..sorted].sort_unstable();
    sorted
}

/// Longest warm list sorted by insertion ([`sort_nearly_sorted`]); a 3D cell's holds about
/// 30 sites.
const INSERTION_SORTED: usize = 64;

/// Sort `gathered` by squared distance then index. A warm start's candidates come in the
/// order of their distances in the previous diagram (a stream's order, kept by
/// [`NearScratch::certified`] and `voronoi_cell`'s record), which small moves of the
/// sites barely change: an insertion sort passes over them in about one comparison each,
/// where `sort_unstable` partitioned them (2.6% of a warm 3D diagram, `perf`, ball 20k).
/// Longer lists, which a far move may have shuffled, are sorted the general way.
fn sort_nearly_sorted(gathered: &mut [(u64, u32)]) {
    if gathered.len() > INSERTION_SORTED {
        gathered.sort_unstable();
        return;
    }
    for k in 1..gathered.len() {
        let entry = gathered[k];
        let mut at = k;
        while at > 0 && gathered[at - 1] > entry {
            gathered[at] = gathered[at - 1];
            at -= 1;
        }
        gathered[at] = entry;
    }
}

/// At most this many buckets per site, however little of their box the sites fill.
const MAX_BUCKETS_PER_SITE: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    fn random_points<const D: usize>(n: usize, seed: u64) -> Vec<[f64; D]> {
        let mut rng = crate::sample::Lcg::new(seed);
        (0..n)
            .map(|_| std::array::from_fn(|_| rng.unit()))
            .collect()
    }

    /// Every site, by squared distance then index, as the grid streams them.
    fn brute_force<const D: usize>(sites: &[[f64; D]], p: [f64; D]) -> Vec<(u32, f64)> {
        let mut all: Vec<(u32, f64)> = (0..sites.len())
            .map(|j| (j as u32, norm2(sub(sites[j], p))))
            .collect();
        all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        all
    }

    fn streamed<const D: usize>(index: &SiteIndex<D>, p: [f64; D]) -> Vec<(u32, f64)> {
        index.nearest(p, usize::MAX)
    }

    /// Sites so far apart that their squared coordinates overflow (hypothesis found it:
    /// the slack became infinite, the bound NaN, and the rings grew for ever).
    #[test]
    fn sites_whose_squares_overflow_stream_to_the_end() {
        let sites = [
            [2.8794063704950784e18, 0.0],
            [5.549490502643398e-160, -1.7478835447777867e185],
            [5e-324, 0.0],
            [0.0, 0.0],
            [5e-324, -4.802692022558717e-206],
        ];
        let index = SiteIndex::new(&sites).unwrap();
        for &p in &sites {
            // The stream ends; a site at an infinite squared distance is beyond any limit.
            let finite: Vec<_> = brute_force(&sites, p)
                .into_iter()
                .filter(|s| s.1.is_finite())
                .collect();
            assert_eq!(streamed(&index, p), finite, "query {p:?}");
            assert_eq!(index.nearest_one(p), finite[0], "query {p:?}");
        }
    }

    fn assert_streams_in_order<const D: usize>(sites: &[[f64; D]], queries: &[[f64; D]]) {
        let index = SiteIndex::new(sites).unwrap();
        assert!(matches!(index.kind, Kind::Grid(_)));
        for &p in queries {
            let expected = brute_force(sites, p);
            assert_eq!(streamed(&index, p), expected, "query {p:?}");
            assert_eq!(index.nearest_one(p), expected[0], "query {p:?}");
        }
    }

    #[test]
    fn the_grid_streams_every_site_in_order_of_distance() {
        let sites = random_points::<2>(500, 1);
        let mut queries = random_points::<2>(20, 2);
        // Far outside the sites' box, and on sites (as the diagram asks).
        queries.extend([[-3.0, 0.5], [7.0, 9.0], [0.5, -1e3], sites[3], sites[77]]);
        assert_streams_in_order(&sites, &queries);
        let sites3 = random_points::<3>(400, 3);
        assert_streams_in_order(&sites3, &[sites3[0], [2.0, -1.0, 0.5], [0.5; 3]]);
    }

    #[test]
    fn sites_filling_part_of_their_box_get_finer_buckets_and_stream_in_order() {
        // Sites in the lower-left triangle of the unit square (and one corner site that
        // spans the box): half of the coarse buckets would be empty.
        let mut sites: Vec<[f64; 2]> = random_points::<2>(2000, 9)
            .into_iter()
            .filter(|p| p[0] + p[1] < 0.8)
            .collect();
        sites.push([1.0, 1.0]);
        let index = SiteIndex::new(&sites).unwrap();
        let Kind::Grid(grid) = &index.kind else {
            panic!("a grid")
        };
        let buckets = grid.buckets.len();
        assert!(
            buckets > sites.len(),
            "{buckets} buckets for {} sites",
            sites.len()
        );
        assert_streams_in_order(&sites, &[sites[0], sites[100], [0.9, 0.9], [0.1, 0.7]]);
    }

    #[test]
    fn flat_and_single_site_grids_stream_in_order() {
        let line: Vec<[f64; 2]> = (0..50).map(|k| [k as f64 * 0.37, 2.0]).collect();
        assert_streams_in_order(&line, &[[3.0, 2.0], [-1.0, 5.0], [100.0, 2.0]]);
        assert_streams_in_order(&[[1.0, 1.0]], &[[1.0, 1.0], [5.0, -3.0]]);
        // Ties: a square lattice seen from its centres.
        let lattice: Vec<[f64; 2]> = (0..100)
            .map(|k| [(k % 10) as f64, (k / 10) as f64])
            .collect();
        assert_streams_in_order(&lattice, &[[4.5, 4.5], [0.0, 0.0], [3.0, 7.5]]);
    }

    #[test]
    fn a_limit_stops_the_stream_before_farther_sites() {
        let sites = random_points::<2>(300, 5);
        let index = SiteIndex::new(&sites).unwrap();
        let mut scratch = NearScratch::default();
        let mut near = index.near(sites[0], &mut scratch);
        let expected = brute_force(&sites, sites[0]);
        let limit2 = expected[9].1;
        let got: Vec<_> = std::iter::from_fn(|| near.next_within(limit2)).collect();
        assert_eq!(got, expected[..10]);
        assert_eq!(near.next_within(limit2), None);
    }

    /// A deferred grid is not filled while a warm stream answers from its candidates;
    /// asked beyond them, the stream fills it and goes on as the cold stream does.
    #[test]
    fn a_warm_stream_fills_a_deferred_grid_only_when_it_goes_cold() {
        let sites = random_points::<2>(2000, 13);
        let deferred = DeferredIndex::new(&sites).unwrap();
        let i = 77;
        let p = sites[i];
        let cold = brute_force(&sites, p);
        // Candidates: the 12 nearest sites (shuffled), complete within the 12th distance.
        let mut candidates: Vec<u32> = cold[..12].iter().map(|&(j, _)| j).rev().collect();
        candidates.swap(3, 8);
        let certified2 = cold[11].1;
        let mut scratch = NearScratch::default();
        let index = IndexRef::from(&deferred);
        let mut near = index.near_warm(p, &sites, &candidates, certified2, &mut scratch);
        let mut got = Vec::new();
        while let Some(next) = near.next_within(certified2) {
            got.push(next);
        }
        assert_eq!(got, cold[..12]);
        assert!(deferred.index.get().is_none(), "filled by a warm stream");
        while let Some(next) = near.next_within(f64::INFINITY) {
            got.push(next);
        }
        assert!(deferred.index.get().is_some());
        assert_eq!(got, cold);
    }

    #[test]
    fn warm_lists_sort_as_sort_unstable_does_however_shuffled() {
        let mut rng = crate::sample::Lcg::new(11);
        for len in [0, 1, 2, 7, 30, 64, 65, 200] {
            let sorted: Vec<(u64, u32)> = (0..len)
                .map(|j| ((rng.unit() * 100.0).floor().to_bits(), j as u32))
                .collect();
            let mut sorted = sorted;
            sorted.sort_unstable();
            // Nearly sorted (neighbours swapped), reversed, and shuffled.
            let mut nearly = sorted.clone();
            for k in (1..len).step_by(3) {
                nearly.swap(k - 1, k);
            }
            let reversed: Vec<_> = sorted.iter().rev().copied().collect();
            let mut shuffled = sorted.clone();
            for k in (1..len).rev() {
                shuffled.swap(k, (rng.unit() * (k + 1) as f64) as usize);
            }
            for mut list in [nearly, reversed, shuffled] {
                sort_nearly_sorted(&mut list);
                assert_eq!(list, sorted, "length {len}");
            }
        }
    }

    #[test]
    fn clustered_sites_fall_back_to_the_kd_tree() {
        // All sites but one in a tiny region: one bucket would hold nearly all of them.
        let mut sites: Vec<[f64; 2]> = random_points::<2>(400, 7)
            .into_iter()
            .map(|p| [p[0] * 1e-6, p[1] * 1e-6])
            .collect();
        sites.push([1e3, 1e3]);
        let index = SiteIndex::new(&sites).unwrap();
        assert!(matches!(index.kind, Kind::Tree(..)));
        for p in [sites[5], sites[400], [0.5, 0.5]] {
            let got = streamed(&index, p);
            let expected = brute_force(&sites, p);
            assert_eq!(got.len(), expected.len());
            let dists = |v: &[(u32, f64)]| v.iter().map(|x| x.1).collect::<Vec<_>>();
            assert_eq!(dists(&got), dists(&expected));
        }
    }
}
