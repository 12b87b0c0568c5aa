//! The buffers of a nearest-site stream, reused from cell to cell.

/// Buffers of a [`NearSites`](super::NearSites) stream, reused from cell to cell.
#[derive(Debug, Default)]
pub struct NearScratch {
    /// Gathered sites as (squared distance bits, index): returned before `next`; sorted
    /// from `next` to `sorted`; within the covered distance, unsorted but none nearer than
    /// the sorted ones, up to `covered`; farther after.
    pub(super) gathered: Vec<(u64, u32)>,
    pub(super) next: usize,
    pub(super) sorted: usize,
    pub(super) covered: usize,
    /// kd-tree answers and the sites returned at the last distance.
    pub(super) tree: Vec<(u32, f64)>,
    pub(super) at_last: Vec<u32>,
    /// The largest squared distance the stream has vouched for: of each site returned,
    /// and each limit it answered `None` for ([`NearSites::vouched2`](super::NearSites::vouched2)).
    pub(super) vouched2: f64,
}

impl NearScratch {
    /// The next of the sorted sites, if one is left: `Some(None)` when it lies beyond
    /// `limit2` (and stays next).
    pub(super) fn next_sorted(&mut self, limit2: f64) -> Option<Option<(u32, f64)>> {
        let &(bits, j) = self.gathered[..self.sorted].get(self.next)?;
        let dist2 = f64::from_bits(bits);
        if dist2 > limit2 {
            return Some(None);
        }
        self.next += 1;
        Some(Some((j, dist2)))
    }
    /// Ready for a new stream.
    pub(super) fn reset(&mut self) {
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
    ///
    /// [`IndexRef::near_warm`]: super::IndexRef::near_warm
    pub fn certified(&self) -> impl Iterator<Item = u32> + '_ {
        self.gathered[..self.sorted].iter().map(|&(_, j)| j)
    }
}
