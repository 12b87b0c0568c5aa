//! The diagram's output: cells measured in batches, in visiting order, and assembled into the
//! [`Diagram`], whose row `i` is site `i`.

use crate::density::Cone;
use crate::error::CoreError;
use crate::geometry::{add, scale};
use crate::moments::Moments;

use super::convex_cell::ConvexCell;
use super::faces::{FaceIntegrals, FaceSums, Matrix};
use super::power::MarginRows;
use super::warm::WarmStart;
use super::weighted_sums::FaceNodes;

/// The clipped diagram: row `i` of every array is site `i`.
#[derive(Debug, Clone, Default)]
pub struct Diagram<const D: usize> {
    /// Moments of each clipped cell about its own site.
    pub moments: Vec<Moments<D>>,
    /// Measure of each cell's share of the domain boundary (length in 2D, area in 3D).
    pub boundary_measure: Vec<f64>,
    /// Faces shared with other cells: those of site `i` are `neighbor_offsets[i]..[i + 1]`.
    pub neighbor_offsets: Vec<usize>,
    /// The other site of each shared face.
    pub neighbor_sites: Vec<u32>,
    /// Measure of each shared face inside the domain (length in 2D, area in 3D).
    pub neighbor_measures: Vec<f64>,
    /// In a periodic box ([`super::PeriodicBox`]): the image of each neighbour, `k` in
    /// `{−1, 0, 1}^d`: the face is shared with `z_j + k∘L` (`z` the sites wrapped into the
    /// box, `L` its periods), so site `j` may appear once per image, and a row is sorted
    /// by site, then image. Empty for the other kinds.
    pub neighbor_images: Vec<[i8; D]>,
    /// With a density ρ (DESIGN §8): each cell's `∫ρ`, `∫ρ (x − x_i)`, `∫ρ |x − x_i|²`
    /// about its site; empty without one (then the weighted moments are `moments`).
    pub weighted: Vec<Moments<D>>,
}

impl<const D: usize> Diagram<D> {
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.moments.len()
    }

    /// No cells.
    pub fn is_empty(&self) -> bool {
        self.moments.is_empty()
    }

    /// Cell volumes (areas in 2D), `L^d`.
    pub fn volumes(&self) -> Vec<f64> {
        self.moments.iter().map(|m| m.mass).collect()
    }

    /// The moments that the CVT weighs (DESIGN §8): the ρ-weighted ones with a density,
    /// else the geometric ones.
    pub fn mass_moments(&self) -> &[Moments<D>] {
        if self.weighted.is_empty() {
            &self.moments
        } else {
            &self.weighted
        }
    }

    /// Cell masses `∫ρ` (the volumes without a density), `ρ·L^d`.
    pub fn masses(&self) -> Vec<f64> {
        self.mass_moments().iter().map(|m| m.mass).collect()
    }

    /// Cell centroids in absolute coordinates, `L`, ρ-weighted with a density (where the
    /// CVT drives the sites); the site itself for an empty cell.
    pub fn centroids(&self, sites: &[[f64; D]]) -> Vec<[f64; D]> {
        self.mass_moments()
            .iter()
            .zip(sites)
            .map(|(m, &s)| m.centroid().map_or(s, |c| add(s, c)))
            .collect()
    }

    /// `∫ |x - c_i|²` over each cell, about its centroid, `L^(d+2)`.
    pub fn second_moments(&self) -> Vec<f64> {
        self.moments.iter().map(Moments::central_second).collect()
    }

    /// Dimensionless second moment of each cell (paper eq. 2); NaN for an empty cell,
    /// which only a site outside the domain can have.
    pub fn g_values(&self) -> Vec<f64> {
        self.moments
            .iter()
            .map(|m| m.dimensionless_second_moment().unwrap_or(f64::NAN))
            .collect()
    }

    /// Each cell's energy term `∫ ρ |x - x_i|²` about its site (ρ = 1 without a density),
    /// `ρ·L^(d+2)`.
    pub fn energy_terms(&self) -> Vec<f64> {
        self.mass_moments().iter().map(|m| m.second).collect()
    }

    /// CVT energy `E = Σ_i ∫ ρ |x - x_i|²`, summed in index order.
    pub fn energy(&self) -> f64 {
        self.mass_moments().iter().map(|m| m.second).sum()
    }

    /// Energy gradient `∂E/∂x_i = 2 m_i (x_i - c_i) = -2 ∫ρ (x - x_i)` (DESIGN §4, §8),
    /// `ρ·L^(d+1)`.
    pub fn gradient(&self) -> Vec<[f64; D]> {
        self.mass_moments()
            .iter()
            .map(|m| scale(m.first, -2.0))
            .collect()
    }
}

/// What [`super::clipped_diagram`] returns.
#[derive(Debug, Clone, Default)]
pub struct Clipped<const D: usize, C> {
    /// The clipped diagram, row `i` the cell of site `i`.
    pub diagram: Diagram<D>,
    /// With [`super::Request::keep_cells`], each site's convex cell from [`super::voronoi_cell::voronoi_cell`]
    /// (relative to its site): the Voronoi cell in the domain's box, cut to a box around
    /// the domain's part for some cells of sites near the boundary, and in a convex domain
    /// already cut to the domain for cells that needed more than `PRECLIP_K` neighbours
    /// (most cells at its boundary). Empty otherwise. In a periodic box each is the cell
    /// of the wrapped site (the torus' cell, unwrapped around it), and its
    /// [`super::Face::Neighbor`] tags number the sites and images it was computed among: read the
    /// neighbours off the diagram.
    pub cells: Vec<C>,
    /// With [`super::Request::integrand`], its sums over the faces between cells; empty otherwise.
    pub face_integrals: FaceIntegrals<D>,
    /// With [`super::Request::warm`], this diagram's near-site lists for the next one.
    pub warm: Option<WarmStart<D>>,
}

/// Cells visited one after the other, measured into flat arrays in visiting order: one
/// allocation per array and batch instead of several per cell.
pub(super) struct Batch<const D: usize, C> {
    pub(super) sites: Vec<u32>,
    pub(super) moments: Vec<Moments<D>>,
    pub(super) boundary_measure: Vec<f64>,
    /// Faces of each cell, its entries of `neighbor_sites` and `neighbor_measures` (and
    /// of `face_integrals`) in turn: two arrays rather than one of `(u32, f64)` pairs,
    /// whose padding cost 4 bytes a face.
    pub(super) face_counts: Vec<u32>,
    pub(super) neighbor_sites: Vec<u32>,
    pub(super) neighbor_measures: Vec<f64>,
    /// With a [`super::FaceIntegrand`]: its sum per cell, and per face.
    pub(super) cell_integrals: Vec<Matrix<D>>,
    pub(super) face_integrals: Vec<Matrix<D>>,
    /// Each cell's convex cell, when kept.
    pub(super) cells: Vec<C>,
    /// Each cell's reach ([`super::PartCells::reach2`]), when [`super::visit::Visit::reach`] asks for it.
    pub(super) reach2: Vec<f64>,
    /// With a polynomial density: each cell's weighted moments.
    pub(super) weighted: Vec<Moments<D>>,
    /// With a sampled density: each cell's number of cone simplices, and the simplices,
    /// cell after cell.
    pub(super) cone_counts: Vec<u32>,
    pub(super) cones: Vec<Cone<D>>,
    /// With a sampled density and a face integrand on the sphere: each cell's number of
    /// deferred faces, and the faces, cell after cell.
    pub(super) face_node_counts: Vec<u32>,
    pub(super) face_nodes: Vec<FaceNodes<D>>,
    /// With [`super::Request::warm`]: each cell's near sites for the next diagram, their number
    /// per cell and the squared distance within which they are complete.
    pub(super) near_counts: Vec<u32>,
    pub(super) near: Vec<u32>,
    pub(super) near_complete2: Vec<f64>,
    /// Per cell, how many sites at the head of its list are its ring ([`super::ring`]),
    /// and (3D) how many vertex triangles the ring has, the triangles cell after cell.
    pub(super) near_rings: Vec<u8>,
    pub(super) near_triangle_counts: Vec<u32>,
    pub(super) near_triangles: Vec<[u8; 3]>,
    /// Cells whose nearest sites came from the warm start alone, and of those the cells
    /// rebuilt from their ring.
    pub(super) warm_cells: usize,
    pub(super) ring_cells: usize,
    /// The stored margins the power cells took ([`super::MarginRequest::record`]).
    pub(super) margins: MarginRows<D>,
    /// The error of the batch's first offending site in index order.
    pub(super) error: Option<(usize, CoreError)>,
}

/// Cells per [`Batch`]: enough to make its allocations rare, few enough to balance the
/// threads.
pub(super) const BATCH: usize = 256;

impl<const D: usize, C: ConvexCell<D>> Batch<D, C> {
    pub(super) fn new(cells: usize, integrals: bool) -> Self {
        let faces = if integrals { 8 * cells } else { 0 };
        Self {
            sites: Vec::with_capacity(cells),
            moments: Vec::with_capacity(cells),
            boundary_measure: Vec::with_capacity(cells),
            face_counts: Vec::with_capacity(cells),
            neighbor_sites: Vec::with_capacity(8 * cells),
            neighbor_measures: Vec::with_capacity(8 * cells),
            cell_integrals: Vec::with_capacity(if integrals { cells } else { 0 }),
            face_integrals: Vec::with_capacity(faces),
            cells: Vec::new(),
            reach2: Vec::new(),
            weighted: Vec::new(),
            cone_counts: Vec::new(),
            cones: Vec::new(),
            face_node_counts: Vec::new(),
            face_nodes: Vec::new(),
            near_counts: Vec::new(),
            near: Vec::new(),
            near_complete2: Vec::new(),
            near_rings: Vec::new(),
            near_triangle_counts: Vec::new(),
            near_triangles: Vec::new(),
            warm_cells: 0,
            ring_cells: 0,
            margins: MarginRows::default(),
            error: None,
        }
    }

    /// Room for the near-site lists of `cells` cells of about `per_cell` sites each:
    /// grown from nothing they were reallocated a dozen times a batch.
    pub(super) fn reserve_lists(&mut self, cells: usize, per_cell: usize) {
        self.near_counts.reserve(cells);
        self.near_complete2.reserve(cells);
        self.near_rings.reserve(cells);
        self.near.reserve(cells * per_cell);
    }

    /// Append site `i`'s cell: its `moments` and the faces measured into `faces`.
    pub(super) fn push(
        &mut self,
        i: usize,
        moments: Moments<D>,
        faces: &mut FaceSums<D>,
        integrals: bool,
    ) {
        faces.sort_neighbors();
        self.sites.push(i as u32);
        self.moments.push(moments);
        self.boundary_measure.push(faces.boundary);
        self.face_counts.push(faces.neighbors.len() as u32);
        (self.neighbor_sites).extend(faces.neighbors.iter().map(|&(j, _)| j));
        (self.neighbor_measures).extend(faces.neighbors.iter().map(|&(_, measure)| measure));
        if integrals {
            self.cell_integrals.push(faces.cell_integral);
            self.face_integrals.extend_from_slice(&faces.integrals);
        }
        let w = &faces.weighted;
        if w.is_sampled() {
            self.cone_counts.push(w.cones.len() as u32);
            self.cones.extend_from_slice(&w.cones);
            if integrals {
                self.face_node_counts.push(w.faces.len() as u32);
                self.face_nodes.extend_from_slice(&w.faces);
            }
        } else if w.is_on() {
            self.weighted.push(w.moments);
        }
    }

    /// Fit the face arrays to their length: after their last doubling up to half of
    /// them is unused, and a 2D cell has ~6 of the 8 faces reserved, while all the
    /// batches are alive when the result is assembled. A copy, not `shrink_to_fit`: an
    /// allocator may shrink a block in place and keep it whole (mimalloc, the binding's,
    /// does when it shrinks by less than half; issue 32, 2D 1M: 24 B/site).
    pub(super) fn shrink(&mut self) {
        fit(&mut self.neighbor_sites);
        fit(&mut self.neighbor_measures);
        fit(&mut self.face_integrals);
    }

    pub(super) fn fail(&mut self, i: usize, error: CoreError) {
        if self.error.as_ref().is_none_or(|(first, _)| i < *first) {
            self.error = Some((i, error));
        }
    }
}

/// `v` in a block of its length (see [`Batch::shrink`]).
fn fit<T: Copy>(v: &mut Vec<T>) {
    if v.capacity() > v.len() {
        *v = v.to_vec();
    }
}

/// The diagram in index order from the batches (visiting order), the kept cells and the
/// face integrals.
///
/// Each kind of value is copied in turn, and each batch's copy freed as soon as it is
/// copied, before the next kind is allocated: the per-cell values first, then the faces'
/// sites, their measures and integrals. The batches' values (and the diagram's) are thus
/// never all alive at once (issue 32: memory per site, docs/results/memory.txt).
pub(super) fn assemble<const D: usize, C: ConvexCell<D>>(
    sites: &[[f64; D]],
    order: Vec<u32>,
    mut batches: Vec<Batch<D, C>>,
    integrals: bool,
    keep_cells: bool,
) -> Clipped<D, C> {
    let n = sites.len();
    let warm = warm_lists(sites, order, &batches);
    let mut diagram = Diagram {
        moments: vec![Moments::zero(); n],
        boundary_measure: vec![0.0; n],
        neighbor_offsets: face_offsets(n, &batches),
        ..Diagram::default()
    };
    let mut sums = FaceIntegrals::default();
    if integrals {
        sums.cells = vec![[[0.0; D]; D]; n];
    }
    let weighted = batches.iter().any(|b| !b.weighted.is_empty());
    if weighted {
        diagram.weighted = vec![Moments::zero(); n];
    }
    let mut cells: Vec<Option<C>> = Vec::new();
    if keep_cells {
        cells.resize_with(n, || None);
    }
    for b in &mut batches {
        for (k, &i) in b.sites.iter().enumerate() {
            let i = i as usize;
            diagram.moments[i] = b.moments[k];
            if weighted {
                diagram.weighted[i] = b.weighted[k];
            }
            diagram.boundary_measure[i] = b.boundary_measure[k];
            if integrals {
                sums.cells[i] = b.cell_integrals[k];
            }
        }
        for (&i, cell) in b.sites.iter().zip(std::mem::take(&mut b.cells)) {
            cells[i as usize] = Some(cell);
        }
        b.moments = Vec::new();
        b.weighted = Vec::new();
        b.boundary_measure = Vec::new();
        b.cell_integrals = Vec::new();
    }
    let offsets = &diagram.neighbor_offsets;
    diagram.neighbor_sites = scatter_faces(offsets, &mut batches, 0, |b| &mut b.neighbor_sites);
    diagram.neighbor_measures =
        scatter_faces(offsets, &mut batches, 0.0, |b| &mut b.neighbor_measures);
    if integrals {
        sums.faces = scatter_faces(offsets, &mut batches, [[0.0; D]; D], |b| {
            &mut b.face_integrals
        });
    }
    Clipped {
        diagram,
        cells: cells.into_iter().flatten().collect(),
        face_integrals: sums,
        warm,
    }
}

/// One per-face value of every batch (`values` of it) in index order, in rows of
/// `offsets`; each batch's values are freed once copied.
pub(super) fn scatter_faces<const D: usize, C, T: Copy>(
    offsets: &[usize],
    batches: &mut [Batch<D, C>],
    zero: T,
    values: impl Fn(&mut Batch<D, C>) -> &mut Vec<T>,
) -> Vec<T> {
    let mut to = vec![zero; offsets.last().copied().unwrap_or(0)];
    for b in batches {
        let from = std::mem::take(values(b));
        copy_faces(offsets, b, &from, &mut to);
    }
    to
}

/// The face offsets of the diagram in index order: cell `i`'s faces are entries
/// `offsets[i]..offsets[i + 1]`.
pub(super) fn face_offsets<const D: usize, C>(n: usize, batches: &[Batch<D, C>]) -> Vec<usize> {
    let mut offsets = vec![0; n + 1];
    for b in batches {
        for (&i, &count) in b.sites.iter().zip(&b.face_counts) {
            offsets[i as usize + 1] = count as usize;
        }
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    offsets
}

/// Copy batch `b`'s per-face values `from` (its cells' faces in turn) to the rows of its
/// cells in `to` (indexed by `offsets`).
pub(super) fn copy_faces<const D: usize, C, T: Copy>(
    offsets: &[usize],
    b: &Batch<D, C>,
    from: &[T],
    to: &mut [T],
) {
    let mut at = 0;
    for (&i, &count) in b.sites.iter().zip(&b.face_counts) {
        let (start, count) = (offsets[i as usize], count as usize);
        to[start..start + count].copy_from_slice(&from[at..at + count]);
        at += count;
    }
}

/// The batches' near-site lists in visiting order `order` (the batches' own, one after
/// the other), when they recorded them.
pub(super) fn warm_lists<const D: usize, C>(
    sites: &[[f64; D]],
    order: Vec<u32>,
    batches: &[Batch<D, C>],
) -> Option<WarmStart<D>> {
    if batches.iter().all(|b| b.near_counts.is_empty()) {
        return None;
    }
    let n = sites.len();
    let mut offsets = Vec::with_capacity(n + 1);
    offsets.push(0);
    let mut complete2 = Vec::with_capacity(n);
    let mut rings = Vec::with_capacity(n);
    let mut triangle_offsets = Vec::with_capacity(n + 1);
    triangle_offsets.push(0u32);
    let mut triangles = Vec::with_capacity(batches.iter().map(|b| b.near_triangles.len()).sum());
    let mut near = Vec::with_capacity(batches.iter().map(|b| b.near.len()).sum());
    for b in batches {
        for &count in &b.near_counts {
            offsets.push(offsets.last().copied().unwrap_or(0) + count as usize);
        }
        complete2.extend_from_slice(&b.near_complete2);
        rings.extend_from_slice(&b.near_rings);
        for &count in &b.near_triangle_counts {
            triangle_offsets.push(triangle_offsets.last().copied().unwrap_or(0) + count);
        }
        triangles.extend_from_slice(&b.near_triangles);
        near.extend_from_slice(&b.near);
    }
    let warm_cells = batches.iter().map(|b| b.warm_cells).sum();
    let ring_cells = batches.iter().map(|b| b.ring_cells).sum();
    let rings = (rings, triangles, triangle_offsets);
    Some(
        WarmStart::from_lists(sites, offsets, near, complete2, rings, order)
            .with_counts(warm_cells, ring_cells),
    )
}

/// The cells of some of the sites, computed among the others: a partition's own sites
/// among its own and its halo (DESIGN §10).
#[derive(Debug, Clone, Default)]
pub struct PartCells<const D: usize> {
    /// Row `k` is the cell of site `own[k]`; neighbours are indices into the `sites` given.
    pub diagram: Diagram<D>,
    /// Per row, the squared distance from its site within which the cell depends on the
    /// sites present: the cell is the one a run over all the problem's sites would compute,
    /// bit for bit, whenever `sites` holds every site of the problem within this distance
    /// (see [`super::clipped_cells`]), `L²`.
    pub reach2: Vec<f64>,
}
