//! Stored margins: what a cell certified by its scan keeps so that later trials whose
//! weights moved little can skip the scan ([`Power::hinted_cell`](super::Power::hinted_cell)).

/// One cell's stored margin as a trial reads it ([`Power::hinted_cell`]): taken at the
/// weights `w_a`, with `dmax = max_j (w'_j − w_a,j)` of the trial's weights `w'`.
///
/// [`Power::hinted_cell`]: super::Power::hinted_cell
#[derive(Debug, Clone, Copy)]
pub(in crate::diagram) struct StoredMargin<'m, const D: usize> {
    /// The least `f_j` over the cell's vertices and its listed non-face sites, `L²`.
    pub s: f64,
    /// The largest distance of those sites from the cell's, `L`.
    pub q: f64,
    /// The cell's own weight `w_a,i`, `L²`.
    pub own: f64,
    /// `max_j (w'_j − w_a,j)`, `L²`.
    pub dmax: f64,
    /// The cell's vertices, relative to its site.
    pub vertices: &'m [[f64; D]],
    /// The sites of its faces.
    pub faces: &'m [u32],
}

/// A cell's margin being taken ([`Power::hinted_cell`] with `record`), and its buffers.
///
/// [`Power::hinted_cell`]: super::Power::hinted_cell
#[derive(Debug, Clone, Default)]
pub(in crate::diagram) struct MarginScratch<const D: usize> {
    /// A record was taken for the last cell.
    pub recorded: bool,
    /// The last cell was certified by its stored margin.
    pub skipped: bool,
    pub s: f64,
    pub q: f64,
    pub own: f64,
    pub vertices: Vec<[f64; D]>,
    pub faces: Vec<u32>,
    /// The listed sites, as indices into the grid's members, each with a lower bound of
    /// its `f_j` over the cell (`−∞` if none was computed).
    pub(super) list: Vec<(u32, f64)>,
}

/// Stored margins of some cells of a power diagram, in index order, for the trials of
/// later Newton steps of optimal transport (`Power::hinted_cell`, `optimise::transport`).
#[derive(Debug, Clone, Default)]
pub struct Margins<const D: usize> {
    /// Cells of the diagram that took these margins certified by a stored one instead.
    skipped: usize,
    /// Per cell, the iterate its margin was taken at (its caller's numbering), or
    /// `u32::MAX` for none.
    iterate: Vec<u32>,
    own: Vec<f64>,
    s: Vec<f64>,
    q: Vec<f64>,
    vertex_offsets: Vec<usize>,
    vertices: Vec<[f64; D]>,
    face_offsets: Vec<usize>,
    faces: Vec<u32>,
}

/// The margins one batch of cells took, in its visiting order.
#[derive(Debug, Clone, Default)]
pub(in crate::diagram) struct MarginRows<const D: usize> {
    /// Cells certified by their stored margin.
    skipped: usize,
    sites: Vec<u32>,
    values: Vec<[f64; 3]>,
    vertex_counts: Vec<u32>,
    vertices: Vec<[f64; D]>,
    face_counts: Vec<u32>,
    faces: Vec<u32>,
}

impl<const D: usize> MarginRows<D> {
    /// Append cell `i`'s record from `r`, if it took one.
    pub(in crate::diagram) fn push(&mut self, i: usize, r: &MarginScratch<D>) {
        self.skipped += usize::from(r.skipped);
        if !r.recorded {
            return;
        }
        self.sites.push(i as u32);
        self.values.push([r.s, r.q, r.own]);
        self.vertex_counts.push(r.vertices.len() as u32);
        self.vertices.extend_from_slice(&r.vertices);
        self.face_counts.push(r.faces.len() as u32);
        self.faces.extend_from_slice(&r.faces);
    }
}

impl<const D: usize> Margins<D> {
    /// No margins for `n` cells.
    pub fn none(n: usize) -> Self {
        Self {
            skipped: 0,
            iterate: vec![u32::MAX; n],
            own: vec![0.0; n],
            s: vec![0.0; n],
            q: vec![0.0; n],
            vertex_offsets: vec![0; n + 1],
            vertices: Vec::new(),
            face_offsets: vec![0; n + 1],
            faces: Vec::new(),
        }
    }

    /// The cells' number.
    pub fn len(&self) -> usize {
        self.iterate.len()
    }

    /// Cell `i`'s margin, taken at iterate `iterate[i]`, when it has one.
    pub fn iterate(&self, i: usize) -> Option<u32> {
        self.iterate.get(i).copied().filter(|&k| k != u32::MAX)
    }

    /// Cells of the diagram that took these margins certified by a stored one instead of
    /// their scan.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// The records of `rows` (one diagram's batches) for `n` cells, taken at `iterate`
    /// (`u32::MAX`: none were taken, the cells certified by margins are counted).
    pub(in crate::diagram) fn gather<'r>(
        n: usize,
        iterate: u32,
        rows: impl Iterator<Item = &'r MarginRows<D>> + Clone,
    ) -> Self {
        let mut m = Self::none(n);
        for r in rows.clone() {
            m.skipped += r.skipped;
            for (k, &i) in r.sites.iter().enumerate() {
                let i = i as usize;
                m.iterate[i] = iterate;
                [m.s[i], m.q[i], m.own[i]] = r.values[k];
                m.vertex_offsets[i + 1] = r.vertex_counts[k] as usize;
                m.face_offsets[i + 1] = r.face_counts[k] as usize;
            }
        }
        for i in 0..n {
            m.vertex_offsets[i + 1] += m.vertex_offsets[i];
            m.face_offsets[i + 1] += m.face_offsets[i];
        }
        m.vertices = vec![[0.0; D]; m.vertex_offsets[n]];
        m.faces = vec![0; m.face_offsets[n]];
        for r in rows {
            let (mut at_v, mut at_f) = (0, 0);
            for (k, &i) in r.sites.iter().enumerate() {
                let i = i as usize;
                let (v, f) = (r.vertex_counts[k] as usize, r.face_counts[k] as usize);
                let (to_v, to_f) = (m.vertex_offsets[i], m.face_offsets[i]);
                m.vertices[to_v..to_v + v].copy_from_slice(&r.vertices[at_v..at_v + v]);
                m.faces[to_f..to_f + f].copy_from_slice(&r.faces[at_f..at_f + f]);
                at_v += v;
                at_f += f;
            }
        }
        m
    }

    /// Each cell's margin from `fresh` where it has one, else from `self`.
    pub fn merged(&self, fresh: &Self) -> Self {
        let n = fresh.len();
        let pick = |i: usize| {
            if fresh.iterate(i).is_some() || self.len() != n {
                fresh
            } else {
                self
            }
        };
        let mut m = Self::none(n);
        for i in 0..n {
            let from = pick(i);
            m.iterate[i] = from.iterate[i];
            m.s[i] = from.s[i];
            m.q[i] = from.q[i];
            m.own[i] = from.own[i];
            let v = from.vertex_offsets[i]..from.vertex_offsets[i + 1];
            m.vertices.extend_from_slice(&from.vertices[v]);
            m.vertex_offsets[i + 1] = m.vertices.len();
            let f = from.face_offsets[i]..from.face_offsets[i + 1];
            m.faces.extend_from_slice(&from.faces[f]);
            m.face_offsets[i + 1] = m.faces.len();
        }
        m
    }

    /// Cell `i`'s margin for a trial whose weights exceed iterate `k`'s by at most
    /// `dmax[k]` (`max_j (w'_j − w_k,j)`).
    pub(in crate::diagram) fn get(&self, i: usize, dmax: &[f64]) -> Option<StoredMargin<'_, D>> {
        let k = self.iterate(i)? as usize;
        Some(StoredMargin {
            s: self.s[i],
            q: self.q[i],
            own: self.own[i],
            dmax: *dmax.get(k)?,
            vertices: &self.vertices[self.vertex_offsets[i]..self.vertex_offsets[i + 1]],
            faces: &self.faces[self.face_offsets[i]..self.face_offsets[i + 1]],
        })
    }
}
