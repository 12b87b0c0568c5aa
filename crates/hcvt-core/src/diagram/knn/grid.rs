//! The uniform grid of buckets: its plan (the bucket size, or `None` when the sites are
//! too crowded for it) and its stream of sites from expanding rings of buckets.

use crate::geometry::{norm2, sub, Aabb, Lattice};

use super::scratch::NearScratch;

/// Sites per bucket the grid aims at. A cell's neighbours then mostly lie in the 3^D
/// buckets around its site; 1 and 3 cost 6% and 4% more instructions than 2 for a CVT of
/// 1,000 sites in a square, and 2% more for a 3D diagram of 4,000 random sites.
const SITES_PER_BUCKET: usize = 2;

/// The grid is used while `Σ (sites in bucket)²` stays below this multiple of the site
/// count: about 2 for uniform sites, and the work of a query grows with it.
const MAX_CROWDING: usize = 16;

/// Buckets of sites over the sites' bounding box, in compressed rows: bucket `b` holds
/// `points[starts[b]..starts[b + 1]]`.
pub(super) struct Grid<const D: usize> {
    pub(super) buckets: Lattice<D>,
    starts: Vec<u32>,
    /// Sites in bucket order (by index within a bucket), with their indices.
    points: Vec<([f64; D], u32)>,
    /// Slack on the distance to a bucket's face, for the rounding of bucket coordinates.
    slack: f64,
}

/// A grid decided on but not filled: its buckets, each site's bucket and their counts.
pub(super) struct GridPlan<const D: usize> {
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
    pub(super) fn new(sites: &[[f64; D]]) -> Option<Self> {
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
    pub(super) fn fill(&self, sites: &[[f64; D]]) -> Grid<D> {
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
pub(super) struct Rings<const D: usize> {
    center: [usize; D],
    ring: usize,
    /// Every site within this squared distance has been gathered.
    covered2: f64,
}

impl<const D: usize> Grid<D> {
    /// The grid of `sites`, or `None` when they are too crowded for one (or too far apart
    /// for the floating-point box).
    pub(super) fn new(sites: &[[f64; D]]) -> Option<Self> {
        Some(GridPlan::new(sites)?.fill(sites))
    }

    pub(super) fn ring_start(&self, p: [f64; D]) -> Rings<D> {
        Rings {
            center: self.buckets.coordinates(&p),
            ring: 0,
            covered2: f64::NEG_INFINITY,
        }
    }

    /// See [`NearSites::next_within`](super::NearSites::next_within).
    pub(super) fn next_within(
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
    /// rings until the covered distance passes the best, keeping only that. Inlined into
    /// [`SiteIndex::nearest_one`](super::SiteIndex::nearest_one), its one caller, as it was
    /// before the grid had a file of its own (0.3% of a surface CVT's instructions).
    #[inline]
    pub(super) fn nearest_one(&self, p: [f64; D]) -> (u32, f64) {
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
pub(super) fn sort_nearly_sorted(gathered: &mut [(u64, u32)]) {
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
