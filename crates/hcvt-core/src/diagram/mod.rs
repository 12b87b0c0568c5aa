//! The clipped Voronoi diagram, exact to round-off (DESIGN §3).
//!
//! Per site, independently and in parallel:
//! 1. the convex Voronoi cell: the domain's bounding box clipped by the bisectors of the
//!    nearest sites in order of distance, until the next site is farther than twice the
//!    cell's radius (security radius); in a convex domain a cell still open after a few
//!    neighbours is cut by the boundary planes near it, and is then finished in step 1;
//! 2. its intersection with the domain, integrated exactly through the identity
//!    `1_Ω(x) = w(q) + Σ_T σ_T 1_K(q,T)(x)` for every `x` in the cell, where `q` is a point
//!    of the cell (the site when possible), `K(q, T)` the part of the cone from `q`
//!    through boundary simplex `T` beyond `T`, and `σ_T = ±1` the side of `T` that `q` is
//!    on. Each `C ∩ K(q, T)` is the cell clipped by `d + 1` more half-spaces.

pub mod convex_cell;
mod knn;
pub mod polygon_cell;
pub mod polyhedron_cell;

use rayon::prelude::*;

use crate::domain::{Boundary, WindingNumber};
use crate::error::CoreError;
use crate::geometry::{dot, norm2, scale, sub, Aabb, Euclid, HalfSpace, Space};
use crate::moments::{FaceMoments, Moments};
pub use convex_cell::{ConvexCell, Face};
pub use knn::{NearScratch, NearSites, SiteIndex};
pub use polygon_cell::PolygonCell;
pub use polyhedron_cell::PolyhedronCell;

/// How to treat unusual input.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Accept sites outside the domain. The cell of such a site is the part of its Voronoi
    /// cell that lies inside the domain: possibly empty, and not containing its site.
    pub allow_outside: bool,
    /// Also compute the Hessian of the CVT energy ([`Hessian`]).
    pub hessian: bool,
}

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
    /// The Hessian of the energy, when [`Options::hessian`] asked for it.
    pub hessian: Option<Hessian<D>>,
}

/// The Hessian of the CVT energy `E(X) = Σ_i ∫_{Ω_i} |x − x_i|²`, exact, in `D × D` blocks.
///
/// With `F_ij` the face shared by cells `i` and `j` inside the domain, `d_ij = |x_j − x_i|`
/// and `y = x − x_i` (Liu et al. 2009, §3; the domain boundary does not move, so only the
/// faces between cells contribute):
/// `H_ij = (2/d_ij) ∫_{F_ij} (x − x_i)(x − x_j)ᵀ` and
/// `H_ii = 2 m_i I − Σ_j (2/d_ij) ∫_{F_ij} (x − x_i)(x − x_i)ᵀ`.
/// Row `i` is computed by cell `i` alone, so `H_ij` and `H_jiᵀ` agree to round-off.
#[derive(Debug, Clone, Default)]
pub struct Hessian<const D: usize> {
    /// `H_ii`, `L^d`.
    pub diagonal: Vec<Block<D>>,
    /// `H_ij` for each entry of [`Diagram::neighbor_sites`], `L^d`.
    pub off_diagonal: Vec<Block<D>>,
}

/// A `D × D` block of the [`Hessian`], row-major.
pub type Block<const D: usize> = [[f64; D]; D];

/// Cells visited one after the other, measured into flat arrays in visiting order: one
/// allocation per array and batch instead of several per cell.
struct Batch<const D: usize, C> {
    sites: Vec<u32>,
    moments: Vec<Moments<D>>,
    boundary_measure: Vec<f64>,
    /// Faces of each cell, its entries of `neighbors` (and of `blocks`) in turn.
    face_counts: Vec<u32>,
    neighbors: Vec<(u32, f64)>,
    /// With the Hessian: `H_ii` per cell, `H_ij` per entry of `neighbors`.
    diagonal: Vec<Block<D>>,
    blocks: Vec<Block<D>>,
    /// Each cell's convex cell, when kept.
    cells: Vec<C>,
    /// The error of the batch's first offending site in index order.
    error: Option<(usize, CoreError)>,
}

/// Cells per [`Batch`]: enough to make its allocations rare, few enough to balance the
/// threads.
const BATCH: usize = 256;

impl<const D: usize, C: ConvexCell<D>> Batch<D, C> {
    fn new(cells: usize, hessian: bool) -> Self {
        let faces = if hessian { 8 * cells } else { 0 };
        Self {
            sites: Vec::with_capacity(cells),
            moments: Vec::with_capacity(cells),
            boundary_measure: Vec::with_capacity(cells),
            face_counts: Vec::with_capacity(cells),
            neighbors: Vec::with_capacity(8 * cells),
            diagonal: Vec::with_capacity(if hessian { cells } else { 0 }),
            blocks: Vec::with_capacity(faces),
            cells: Vec::new(),
            error: None,
        }
    }

    /// Append site `i`'s cell: its `moments` and the faces measured into `faces`.
    fn push(&mut self, i: usize, moments: Moments<D>, faces: &mut FaceSums<D>, hessian: bool) {
        faces.sort_neighbors();
        self.sites.push(i as u32);
        self.moments.push(moments);
        self.boundary_measure.push(faces.boundary);
        self.face_counts.push(faces.neighbors.len() as u32);
        self.neighbors.extend_from_slice(&faces.neighbors);
        if hessian {
            self.diagonal.push(faces.hessian_diagonal(moments.mass));
            self.blocks.extend_from_slice(&faces.blocks);
        }
    }

    fn fail(&mut self, i: usize, error: CoreError) {
        if self.error.as_ref().is_none_or(|(first, _)| i < *first) {
            self.error = Some((i, error));
        }
    }
}

/// Buffers of [`clip_by_domain`], reused from cell to cell.
struct MeasureScratch<const D: usize, C> {
    faces: FaceSums<D>,
    piece: Option<C>,
    candidates: Vec<u32>,
}

impl<const D: usize, C> Default for MeasureScratch<D, C> {
    fn default() -> Self {
        Self {
            faces: FaceSums::default(),
            piece: None,
            candidates: Vec::new(),
        }
    }
}

/// What a cell's row of the [`Hessian`] needs besides its faces: every site, and which one
/// is the cell's.
#[derive(Debug, Clone, Copy)]
struct HessianRow<'a, const D: usize> {
    sites: &'a [[f64; D]],
    site: usize,
}

/// The clipped Voronoi diagram of `sites` in `boundary`, and, if `keep_cells`, each site's
/// convex cell from [`voronoi_cell`] (relative to its site) for pictures and export: the
/// Voronoi cell in the domain's box, cut to a box around the domain's part for some cells
/// of sites near the boundary, and in a convex domain already cut to the domain for
/// cells that needed more than `PRECLIP_K` neighbours (most cells at its boundary).
///
/// Errors name the first offending site in index order: non-finite coordinates, a site
/// outside the domain (unless allowed), two coinciding sites.
pub fn clipped_diagram<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    sites: &[[f64; D]],
    options: Options,
    keep_cells: bool,
) -> Result<(Diagram<D>, Vec<C>), CoreError>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    if sites.is_empty() {
        return Err(CoreError::NoSites);
    }
    for (index, s) in sites.iter().enumerate() {
        if let Some(&value) = s.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::NonFiniteSite { index, value });
        }
    }
    if options.allow_outside {
        let b = boundary.bounds();
        let size = (0..D).fold(f64::INFINITY, |m, k| m.min(b.hi[k] - b.lo[k]));
        for (index, s) in sites.iter().enumerate() {
            let distance = norm2::<D>(std::array::from_fn(|k| {
                (b.lo[k] - s[k]).max(s[k] - b.hi[k]).max(0.0)
            }))
            .sqrt();
            if distance > FAR_OUTSIDE * size {
                return Err(CoreError::SiteFarOutside {
                    index,
                    point: s.to_vec(),
                    distance,
                    limit: FAR_OUTSIDE,
                });
            }
        }
    }
    let windings: Vec<Option<i32>> = sites
        .par_iter()
        .map(|s| Euclid::winding_number(boundary, s))
        .collect();
    if !options.allow_outside {
        if let Some(index) = windings.iter().position(|w| *w == Some(0)) {
            return Err(CoreError::SiteOutsideDomain {
                index,
                point: sites[index].to_vec(),
            });
        }
    }
    let index = SiteIndex::new(sites)?;
    // Visit the sites along a Morton curve: neighbouring cells then share index buckets
    // and boundary elements in cache. Results go back to index order afterwards.
    let order = morton_order(sites);
    let convex = boundary.is_convex();
    let batches: Vec<Batch<D, C>> = order
        .par_chunks(BATCH)
        .map_init(
            || (CellScratch::default(), MeasureScratch::default()),
            |(scratch, measuring), chunk| {
                let mut batch = Batch::new(chunk.len(), options.hessian);
                for &i in chunk {
                    let i = i as usize;
                    let convex_inside = convex && windings[i] == Some(1);
                    let (cell, inside) = match voronoi_cell::<D, C>(
                        boundary,
                        &index,
                        sites,
                        i,
                        convex_inside,
                        scratch,
                    ) {
                        Ok(found) => found,
                        Err(e) => {
                            batch.fail(i, e);
                            continue;
                        }
                    };
                    let hessian = options.hessian.then_some(HessianRow { sites, site: i });
                    let moments = if inside {
                        measure(cell, hessian, &mut measuring.faces)
                    } else {
                        clip_by_domain(boundary, cell, sites[i], windings[i], hessian, measuring)
                    };
                    batch.push(i, moments, &mut measuring.faces, options.hessian);
                    if keep_cells {
                        batch.cells.push(cell.clone());
                    }
                }
                batch
            },
        )
        .collect();
    let first_error = batches
        .iter()
        .filter_map(|b| b.error.as_ref().map(|(i, _)| *i))
        .min();
    if let Some(first) = first_error {
        let mut batches = batches;
        let batch = batches
            .iter_mut()
            .find(|b| b.error.as_ref().is_some_and(|(i, _)| *i == first))
            .expect("the batch of the first error");
        return Err(batch.error.take().expect("its error").1);
    }
    Ok(assemble(sites.len(), batches, options.hessian, keep_cells))
}

/// The diagram in index order from the batches (visiting order), and the kept cells.
fn assemble<const D: usize, C: ConvexCell<D>>(
    n: usize,
    batches: Vec<Batch<D, C>>,
    hessian: bool,
    keep_cells: bool,
) -> (Diagram<D>, Vec<C>) {
    let mut diagram = Diagram {
        moments: vec![Moments::zero(); n],
        boundary_measure: vec![0.0; n],
        neighbor_offsets: vec![0; n + 1],
        ..Diagram::default()
    };
    for b in &batches {
        for (&i, &count) in b.sites.iter().zip(&b.face_counts) {
            diagram.neighbor_offsets[i as usize + 1] = count as usize;
        }
    }
    for i in 0..n {
        diagram.neighbor_offsets[i + 1] += diagram.neighbor_offsets[i];
    }
    let faces = diagram.neighbor_offsets[n];
    diagram.neighbor_sites = vec![0; faces];
    diagram.neighbor_measures = vec![0.0; faces];
    let mut h = hessian.then(|| Hessian {
        diagonal: vec![[[0.0; D]; D]; n],
        off_diagonal: vec![[[0.0; D]; D]; faces],
    });
    let mut cells: Vec<Option<C>> = Vec::new();
    if keep_cells {
        cells.resize_with(n, || None);
    }
    for b in batches {
        let mut at = 0;
        for (k, &i) in b.sites.iter().enumerate() {
            let i = i as usize;
            diagram.moments[i] = b.moments[k];
            diagram.boundary_measure[i] = b.boundary_measure[k];
            let from = diagram.neighbor_offsets[i];
            let count = b.face_counts[k] as usize;
            for (e, &(j, measure)) in b.neighbors[at..at + count].iter().enumerate() {
                diagram.neighbor_sites[from + e] = j;
                diagram.neighbor_measures[from + e] = measure;
            }
            if let Some(h) = h.as_mut() {
                h.diagonal[i] = b.diagonal[k];
                h.off_diagonal[from..from + count].copy_from_slice(&b.blocks[at..at + count]);
            }
            at += count;
        }
        for (&i, cell) in b.sites.iter().zip(b.cells) {
            cells[i as usize] = Some(cell);
        }
    }
    diagram.hessian = h;
    (diagram, cells.into_iter().flatten().collect())
}

/// How far outside the domain's box an allowed outside site may lie, in units of the
/// box's smallest side. Its cell is cut in coordinates relative to the site, and the
/// moments of pieces at distance `R` carry an error of about `eps·R²`: measured on the
/// unit square, 7e-15 of the area at R = 10, 9e-13 at 100, 6e-11 at 1000, and garbage
/// (volume 8193) at 1e10. The smallest side, not the diagonal: a needle 1 wide and 1.4e14
/// long seen from 9e15 away lost its width to the rounding of the relative coordinates.
pub const FAR_OUTSIDE: f64 = 64.0;

/// Site indices sorted along a Z-order (Morton) curve over the sites' bounding box, ties
/// broken by index so that the order is deterministic.
///
/// The curve is only as fine as locality needs, about 4^D cells per site: interleaving all
/// 63 bits cost 5% of a CVT's instructions at 1,000 sites.
pub fn morton_order<const D: usize>(sites: &[[f64; D]]) -> Vec<u32> {
    let bounds = Aabb::of_points(sites);
    let bits = (sites.len().max(1).ilog2() / D as u32 + 3).min(63 / D as u32);
    let cells = (1u64 << bits) as f64;
    let key = |p: &[f64; D]| -> u64 {
        let mut key = 0u64;
        for (k, &x) in p.iter().enumerate() {
            let extent = (bounds.hi[k] - bounds.lo[k]).max(f64::MIN_POSITIVE);
            let q = (((x - bounds.lo[k]) / extent) * (cells - 1.0)) as u64;
            for b in 0..bits {
                key |= ((q >> b) & 1) << (b * D as u32 + k as u32);
            }
        }
        key
    };
    let mut keyed: Vec<(u64, u32)> = sites
        .par_iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Margin of the starting box around the domain, relative to the domain's diagonal.
const BOX_MARGIN: f64 = 1e-3;

/// Neighbour count, per dimension, after which a cell that has not reached its security
/// radius is localised to the domain (see [`domain_radius2`]). 16 in 2D: a CVT of the star
/// spends 23% less per diagram than with 64 (2.36 against 3.05 ms at 2,000 sites), the unit
/// square the same, and with the bucket grid 8 and 32 cost 1% and 3% more instructions per
/// diagram than 16; 3D cells need about 31 neighbours, so 64 there.
const LOCALISE_K: [usize; 4] = [16, 16, 16, 64];

/// Neighbour count, per dimension, after which the cell of a site inside a convex domain
/// that has not reached its security radius is cut by the domain's boundary planes near it
/// ([`cut_by_boundary`]). A cell at the boundary otherwise reaches out to the corners of
/// the starting box and never meets its security radius: in a ball of 5,000 sites it
/// streamed 64 neighbours, then [`localise`] and [`validate_vertices`].
const PRECLIP_K: [usize; 4] = [usize::MAX, usize::MAX, usize::MAX, 16];

/// The convex Voronoi cell of site `i` inside the domain's bounding box, relative to the
/// site, exact wherever it meets the domain, and whether it already lies in the domain.
///
/// A site near the boundary of a non-convex domain has a Voronoi cell reaching far into
/// the empty part of the bounding box, and the security radius would pull in most sites.
/// Only the cell's part inside the domain matters, so once `LOCALISE_K` neighbours did not
/// suffice the cell is cut to a box that holds that part ([`localise`]) and finished by
/// checking its vertices' nearest sites ([`validate_vertices`]).
///
/// With `convex_inside` (the domain is convex and the site strictly inside it), a cell
/// still open after `PRECLIP_K` neighbours is instead cut by the nearby boundary planes:
/// it then lies in the domain, its radius shrinks to the domain's scale there, and the
/// security radius stays valid (a site beyond twice the radius of any region holding the
/// cell cannot cut it). The cell returned is then the clipped cell itself, `true`.
pub fn voronoi_cell<'a, const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    index: &SiteIndex<D>,
    sites: &[[f64; D]],
    i: usize,
    convex_inside: bool,
    scratch: &'a mut CellScratch<C>,
) -> Result<(&'a C, bool), CoreError>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let site = sites[i];
    // Start a little outside the domain's box: a cell face lying on the domain boundary
    // would otherwise be a box face, and the boundary pieces that measure it would be flat.
    let bounds = boundary.bounds();
    let start = bounds
        .expanded(BOX_MARGIN * bounds.diagonal())
        .relative_to(site);
    let cell = scratch.cell.get_or_insert_with(|| C::from_box(&start));
    cell.reset_to_box(&start);
    let mut radius2 = cell.max_dist2();
    let localise_after = LOCALISE_K.get(D).copied().unwrap_or(64);
    let preclip_after = if convex_inside {
        PRECLIP_K.get(D).copied().unwrap_or(usize::MAX)
    } else {
        usize::MAX
    };
    let mut inside = false;
    let mut near = index.near(site, &mut scratch.near);
    let mut clipped = 0; // sites taken from the stream, the site itself included
    while let Some((j, _)) = near.next_within(4.0 * radius2) {
        if j as usize != i {
            let q = offset_to(sites, i, j)?;
            if cell.clip(&HalfSpace::bisector(q), Face::Neighbor(j)) {
                radius2 = cell.max_dist2();
            }
        }
        clipped += 1;
        if clipped == preclip_after && clipped < sites.len() {
            cut_by_boundary(boundary, cell, site, &mut scratch.candidates);
            radius2 = cell.max_dist2();
            inside = true;
        }
        if clipped == localise_after && clipped < sites.len() && !inside && !cell.is_empty() {
            localise(boundary, cell, site);
            validate_vertices(cell, index, sites, i)?;
            return Ok((cell, false));
        }
    }
    Ok((cell, inside))
}

/// Buffers of [`voronoi_cell`], reused from cell to cell so that the common cell allocates
/// nothing.
#[derive(Debug)]
pub struct CellScratch<C> {
    near: NearScratch,
    cell: Option<C>,
    candidates: Vec<u32>,
}

impl<C> Default for CellScratch<C> {
    fn default() -> Self {
        Self {
            near: NearScratch::default(),
            cell: None,
            candidates: Vec::new(),
        }
    }
}

/// Site `j` relative to site `i`; two sites at one point have no bisector.
fn offset_to<const D: usize>(sites: &[[f64; D]], i: usize, j: u32) -> Result<[f64; D], CoreError> {
    let q = sub(sites[j as usize], sites[i]);
    if norm2(q) == 0.0 {
        let (first, second) = (i.min(j as usize), i.max(j as usize));
        return Err(CoreError::DuplicateSites {
            first,
            second,
            point: sites[i].to_vec(),
        });
    }
    Ok(q)
}

/// Cut `cell` (relative to `site`) to the box of half-width `R` around the site, `R` a
/// bound on the distance of its part inside the domain: nothing of the domain is lost, and
/// the far reaches of the cell outside it stop costing neighbours and boundary pieces.
fn localise<const D: usize, C: ConvexCell<D>>(boundary: &Boundary<D>, cell: &mut C, site: [f64; D])
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let r = domain_radius2(boundary, cell, site).sqrt();
    for axis in 0..D {
        let unit: [f64; D] = std::array::from_fn(|j| if j == axis { 1.0 } else { 0.0 });
        cell.clip(&HalfSpace::through(scale(unit, r), unit), Face::Box);
        cell.clip(
            &HalfSpace::through(scale(unit, -r), scale(unit, -1.0)),
            Face::Box,
        );
    }
}

/// Most vertex checks one cell may need before it is accepted as it is.
const MAX_VALIDATIONS: usize = 100_000;

/// Clip `cell` until each of its vertices has site `i` as a nearest site, so that the cell
/// (the convex hull of its vertices) lies in the Voronoi cell; as it already contains the
/// Voronoi cell's part in the box it started from, the two are then equal there.
///
/// Used instead of the security radius for cells localised by [`localise`]: each vertex
/// asks the index for its own nearest site, so the work follows where the cell is, not
/// a ball around the site. A vertex within round-off of a bisector already clipped counts
/// as valid; vertices that survive a clip keep their bits and are not checked again.
fn validate_vertices<const D: usize, C: ConvexCell<D>>(
    cell: &mut C,
    index: &SiteIndex<D>,
    sites: &[[f64; D]],
    i: usize,
) -> Result<(), CoreError> {
    let site = sites[i];
    let mut valid: Vec<[u64; D]> = Vec::new();
    let mut used: Vec<u32> = Vec::new();
    for _ in 0..MAX_VALIDATIONS {
        let mut cut = None;
        for &v in cell.vertices() {
            let key = v.map(f64::to_bits);
            if valid.contains(&key) {
                continue;
            }
            let (j, dist2) = index.nearest_one(add_point(v, site));
            let closer = dist2 < norm2(v) * (1.0 - 1e-12);
            if j as usize != i && closer && !used.contains(&j) {
                cut = Some(j);
                break;
            }
            valid.push(key);
        }
        let Some(j) = cut else {
            return Ok(());
        };
        let q = offset_to(sites, i, j)?;
        cell.clip(&HalfSpace::bisector(q), Face::Neighbor(j));
        used.push(j);
        if cell.is_empty() {
            return Ok(());
        }
    }
    Ok(())
}

/// An upper bound on `|x|²` over the part of `cell` (relative to `site`) inside the domain.
///
/// The farthest point of that part is one of its vertices: a vertex of the cell inside
/// the domain, or a point where the boundary meets the cell, which lies on a boundary
/// simplex that the cell does not exclude. Exact winding numbers decide the first kind;
/// the farthest vertex of each simplex bounds the second.
fn domain_radius2<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
) -> f64
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let mut r2: f64 = 0.0;
    let mut candidates = Vec::new();
    boundary_candidates(boundary, cell, site, &mut candidates);
    for t in candidates {
        let rel = boundary.simplex(t).map(|v| sub(v, site));
        if let Some(d2) = cell.farthest_on(&rel) {
            r2 = r2.max(d2);
        }
    }
    // Only vertices beyond the simplices' bound can raise it: test them farthest first
    // and stop at the first inside the domain (each test is a ray cast).
    let mut far: Vec<(f64, [f64; D])> = cell
        .vertices()
        .iter()
        .map(|&v| (norm2(v), v))
        .filter(|&(d2, _)| d2 > r2)
        .collect();
    far.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    for (d2, v) in far {
        if Euclid::winding_number(boundary, &add_point(v, site)) != Some(0) {
            return d2;
        }
    }
    r2
}

/// The boundary simplices whose boxes meet the cell's box (the cell relative to `site`).
fn boundary_candidates<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    out: &mut Vec<u32>,
) where
    Euclid: Space<D>,
{
    let bounds = cell.bounds();
    let query = Aabb {
        lo: add_point(bounds.lo, site),
        hi: add_point(bounds.hi, site),
    };
    boundary.bvh().query(&query, out);
}

/// A cell whose signed pieces sum to at most this fraction of their absolute sum (or of
/// its bounding box) is empty.
const EMPTY_REL: f64 = 16.0 * f64::EPSILON;

/// Integrate `cell` (relative to `site`) restricted to the domain, through signed cones:
/// its moments (zero for an empty cell), its faces measured into `scratch.faces`.
fn clip_by_domain<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    site_winding: Option<i32>,
    hessian: Option<HessianRow<'_, D>>,
    scratch: &mut MeasureScratch<D, C>,
) -> Moments<D>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let MeasureScratch {
        faces,
        piece,
        candidates,
    } = scratch;
    faces.clear();
    if cell.is_empty() {
        return Moments::zero();
    }
    candidates.clear();
    boundary_candidates(boundary, cell, site, candidates);
    if site_winding == Some(1) && (candidates.is_empty() || boundary.is_convex()) {
        // Strictly inside, and no boundary near (or a convex one): no cones to cut.
        return clip_convex(boundary, cell, site, candidates, hessian, faces, piece);
    }
    let (apex, winding) = choose_apex(boundary, cell, site, site_winding, candidates);
    // Σ |mass| of the signed terms: what their round-off scales with.
    let mut gross = 0.0;
    let mut total = Moments::zero();
    if winding != 0 {
        let m = faces.integrate(cell, winding as f64, hessian);
        total.add_scaled(&m, winding as f64);
        gross += (winding as f64 * m.mass).abs();
    }
    let apex_abs = add_point(apex, site);
    let piece = piece.get_or_insert_with(|| cell.clone()); // clone_from keeps its buffers
    for &t in candidates.iter() {
        let simplex = boundary.simplex(t);
        let side = Euclid::side(&simplex, &apex_abs);
        if side == 0.0 {
            continue; // the apex is on T's hyperplane: the cone is flat
        }
        let sigma = if side > 0.0 { 1.0 } else { -1.0 };
        let rel = simplex.map(|v| sub(v, site));
        // A segment from the apex to a point of C ∩ K(T) crosses T inside the convex C, so
        // a simplex that some face of C separates from C has an empty piece.
        if cell.excludes(&rel) {
            continue;
        }
        // Beyond T as seen from the apex: the inner side when the apex is outside T. Cut
        // there first: what is left beyond a small simplex is small, and the cone sides
        // then clip few vertices.
        let normal = Euclid::normal(&rel);
        let beyond = HalfSpace::through(
            rel[0],
            if sigma > 0.0 {
                normal
            } else {
                scale(normal, -1.0)
            },
        );
        piece.clone_from(cell);
        piece.clip(&beyond, Face::Boundary(t));
        for h in cone_sides(&rel, apex) {
            if piece.is_empty() {
                break;
            }
            piece.clip(&h, Face::Cone);
        }
        if piece.is_empty() {
            continue;
        }
        let m = faces.integrate(piece, sigma, hessian);
        total.add_scaled(&m, sigma);
        gross += m.mass.abs();
    }
    // Signed pieces that cancel to round-off leave a mass of either sign near 1e-18 and a
    // G of NaN or 1e15: the cell of a site outside the domain that only touches it, or
    // whose pieces are slivers of round-off. Their error scales with the pieces and with
    // the cell's coordinates, so measure against both: the cell is empty.
    let extent = cell.bounds();
    let box_measure: f64 = (0..D).map(|k| extent.hi[k] - extent.lo[k]).product();
    if total.mass.abs() <= EMPTY_REL * gross.max(box_measure) {
        faces.clear();
        return Moments::zero();
    }
    total
}

/// [`clip_by_domain`] for a site strictly inside the domain when the domain is convex or
/// no boundary simplex's box meets the cell's box: the cell clipped by the inner
/// half-spaces of those simplices (`candidates`), measured into `faces`. `piece` holds
/// the clipped copy.
///
/// Exact: the domain `Ω` lies in every such half-space, so nothing of `C ∩ Ω` is cut. A
/// point `x` of the clipped cell outside `Ω` would see the segment from the site `y`
/// (strictly inside `Ω`, so strictly inside every simplex's hyperplane) leave `Ω` through
/// some simplex `T` at a point `z` of `C` before `x`: `T` meets the cell's box, so it was
/// clipped, and `x`, beyond `z` on a line from the inner side, is outside `T`'s half-space.
/// One clip per simplex instead of a cone piece (a copy of the cell and `D + 1` clips).
/// With no candidates the argument needs no convexity: the cell lies in `Ω`.
fn clip_convex<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    candidates: &[u32],
    hessian: Option<HessianRow<'_, D>>,
    faces: &mut FaceSums<D>,
    piece: &mut Option<C>,
) -> Moments<D>
where
    Euclid: Space<D>,
{
    if candidates.is_empty() {
        // An interior cell: nothing to cut, and no copy to make.
        return measure(cell, hessian, faces);
    }
    let clipped = piece.get_or_insert_with(|| cell.clone());
    clipped.clone_from(cell);
    clip_by_planes(boundary, clipped, site, candidates);
    measure(clipped, hessian, faces)
}

/// [`clip_convex`]'s cut inside [`voronoi_cell`]: `cell` (relative to `site`, strictly
/// inside the convex domain) clipped by the inner half-spaces of the boundary simplices
/// whose boxes meet its box.
///
/// The cell then lies in the domain, and stays there as later bisectors cut it: any
/// simplex meeting a later cell's box met this larger box, so its half-space was clipped
/// by or already held the cell, [`clip_convex`]'s proof applies to every later cell, and
/// its own cuts would change nothing: the cell is measured as it is.
fn cut_by_boundary<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &mut C,
    site: [f64; D],
    candidates: &mut Vec<u32>,
) where
    Euclid: Space<D>,
{
    candidates.clear();
    boundary_candidates(boundary, cell, site, candidates);
    clip_by_planes(boundary, cell, site, candidates);
}

/// Clip `cell` (relative to `site`, strictly inside the convex domain) by the inner
/// half-spaces of the simplices `candidates`, tagged `Face::Boundary`.
///
/// Nearest planes first: they cut away most of what lies outside, and the later clips
/// then have fewer vertices to remove. A plane farther from the site than the cell's
/// farthest vertex cannot cut it, and neither can any later one: stop there.
fn clip_by_planes<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &mut C,
    site: [f64; D],
    candidates: &[u32],
) where
    Euclid: Space<D>,
{
    let mut planes: Vec<(f64, u32, HalfSpace<D>)> = candidates
        .iter()
        .map(|&t| {
            let rel = boundary.simplex(t).map(|v| sub(v, site));
            let h = HalfSpace::through(rel[0], Euclid::normal(&rel));
            (h.offset / norm2(h.normal).sqrt(), t, h)
        })
        .collect();
    planes.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    for (distance, t, h) in planes {
        if distance * distance > cell.max_dist2() {
            break;
        }
        cell.clip(&h, Face::Boundary(t));
    }
}

/// The moments of a cell that lies in the domain, its face measures (and, for the
/// Hessian, face moments) into `faces`.
fn measure<const D: usize, C: ConvexCell<D>>(
    cell: &C,
    hessian: Option<HessianRow<'_, D>>,
    faces: &mut FaceSums<D>,
) -> Moments<D> {
    faces.clear();
    faces.integrate(cell, 1.0, hessian)
}

/// The `D` side half-spaces of the cone from `apex` through the simplex `rel` (both
/// relative to the site): the hyperplane through the apex and each facet of the simplex,
/// keeping the side of the remaining vertex.
fn cone_sides<const D: usize>(
    rel: &[[f64; D]; D],
    apex: [f64; D],
) -> impl Iterator<Item = HalfSpace<D>> + '_
where
    Euclid: Space<D>,
{
    (0..D).map(move |k| {
        // Replace vertex k by the apex: the facet opposite vertex k, coned to the apex.
        let mut points = *rel;
        points[k] = apex;
        let mut normal = Euclid::normal(&points);
        if dot(normal, sub(rel[k], apex)) > 0.0 {
            normal = scale(normal, -1.0);
        }
        HalfSpace::through(apex, normal)
    })
}

/// Fractional part of the golden ratio: successive multiples spread evenly over [0, 1).
const GOLDEN: f64 = 0.618_033_988_749_895;

/// Least distance of the apex from the hyperplane of a boundary simplex near the cell,
/// relative to the cell's radius.
const APEX_CLEARANCE: f64 = 1e-9;

/// A point of the cell to cone from, relative to the site, and its winding number.
///
/// The site itself when it lies strictly inside or outside the domain, inside its
/// (box-limited) cell and clear of the hyperplanes of the boundary simplices near the cell;
/// otherwise the vertex mean of the cell, nudged towards successive vertices until it is
/// off the boundary (a site on the boundary has no winding number) and clear of them.
/// Only for a cell of no measure can every candidate stay on the boundary.
fn choose_apex<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    site_winding: Option<i32>,
    candidates: &[u32],
) -> ([f64; D], i32)
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let site_in_box = {
        let b = boundary.bounds();
        (0..D).all(|k| b.lo[k] <= site[k] && site[k] <= b.hi[k])
    };
    // An apex within round-off of a simplex's hyperplane (a site 1e-17 off a face, as a
    // face centroid computed in floats is) makes the cone's sides nearly coincide with
    // that hyperplane, and which side of them to keep is decided by round-off: a sphere
    // with one such site got the volume -3.6 instead of 4.15. Such an apex is refused.
    let size = cell.max_dist2().sqrt();
    let clear = |apex: [f64; D]| {
        candidates.iter().all(|&t| {
            let rel = boundary.simplex(t).map(|v| sub(v, site));
            let normal = Euclid::normal(&rel);
            let dist = dot(normal, sub(apex, rel[0])).abs();
            dist > APEX_CLEARANCE * size * norm2(normal).sqrt()
        })
    };
    if let (Some(w), true) = (site_winding, site_in_box) {
        if clear([0.0; D]) {
            return ([0.0; D], w);
        }
    }
    let mean = cell.vertex_mean();
    let vertices = cell.vertices();
    let mut candidate = mean;
    let mut fallback = None;
    for step in 0..64 {
        if let Some(w) = Euclid::winding_number(boundary, &add_point(candidate, site)) {
            if clear(candidate) {
                return (candidate, w);
            }
            fallback = fallback.or(Some((candidate, w)));
        }
        // Deterministic nudge: a convex combination of the vertices with irregular positive
        // weights (golden-ratio sequence), so strictly inside the cell and on no line
        // through the mean. Nudges along fixed directions stayed on the boundary: a
        // square cell of a site on a slope-1 edge counted twice its area, and the box
        // cell of a pinched bow-tie had every vertex direction along an edge.
        if vertices.is_empty() {
            break;
        }
        let mut sum = [0.0; D];
        let mut total = 0.0;
        for (j, v) in vertices.iter().enumerate() {
            let w = 0.25 + ((j as f64 + 1.0) * GOLDEN * (step as f64 + 1.0)).fract();
            total += w;
            for k in 0..D {
                sum[k] += w * v[k];
            }
        }
        candidate = sum.map(|x| x / total);
    }
    fallback.unwrap_or((mean, 0))
}

#[inline]
fn mat_vec<const D: usize>(m: &[[f64; D]; D], v: [f64; D]) -> [f64; D] {
    m.map(|row| dot(row, v))
}

#[inline]
fn add_point<const D: usize>(a: [f64; D], b: [f64; D]) -> [f64; D] {
    std::array::from_fn(|k| a[k] + b[k])
}

/// Signed face measures of a cell, summed over its pieces, and for the Hessian the
/// integrals over its faces; buffers reused from cell to cell.
#[derive(Debug)]
struct FaceSums<const D: usize> {
    neighbors: Vec<(u32, f64)>,
    /// With the Hessian: `H_ij = (2/d_ij) ∫_{F_ij} y (y − q_ij)ᵀ` (`y = x − x_i`,
    /// `q_ij = x_j − x_i`) for each entry of `neighbors`; else empty.
    blocks: Vec<Block<D>>,
    /// With the Hessian: `Σ_j (2/d_ij) ∫_{F_ij} y yᵀ`.
    face_second: Block<D>,
    boundary: f64,
}

impl<const D: usize> Default for FaceSums<D> {
    fn default() -> Self {
        Self {
            neighbors: Vec::new(),
            blocks: Vec::new(),
            face_second: [[0.0; D]; D],
            boundary: 0.0,
        }
    }
}

impl<const D: usize> FaceSums<D> {
    /// Forget the last cell.
    fn clear(&mut self) {
        self.neighbors.clear();
        self.blocks.clear();
        self.face_second = [[0.0; D]; D];
        self.boundary = 0.0;
    }

    /// Add the faces of `piece` with `sign` (and their Hessian terms, for a `hessian`
    /// row), and return its moments (not signed).
    fn integrate<C: ConvexCell<D>>(
        &mut self,
        piece: &C,
        sign: f64,
        hessian: Option<HessianRow<'_, D>>,
    ) -> Moments<D> {
        match hessian {
            Some(row) => piece.moments_and_face_moments(|f, m| self.add_moments(f, sign, &m, row)),
            None => piece.moments_and_faces(|f, m| {
                self.add(f, sign * m);
            }),
        }
    }

    /// Add a face's measure; the index of its neighbour's entry, if it has one.
    fn add(&mut self, face: Face, measure: f64) -> Option<usize> {
        match face {
            Face::Neighbor(j) => Some(match self.neighbors.iter().position(|(k, _)| *k == j) {
                Some(at) => {
                    self.neighbors[at].1 += measure;
                    at
                }
                None => {
                    self.neighbors.push((j, measure));
                    self.neighbors.len() - 1
                }
            }),
            // Each piece's face on T is T ∩ C itself, whatever the piece's sign.
            Face::Boundary(_) => {
                self.boundary += measure.abs();
                None
            }
            Face::Box | Face::Cone => None,
        }
    }

    /// Add a face with its moments `m` about the site, and its terms of row `row` of the
    /// Hessian.
    fn add_moments(&mut self, face: Face, sign: f64, m: &FaceMoments<D>, row: HessianRow<'_, D>) {
        let Some(at) = self.add(face, sign * m.measure) else {
            return;
        };
        let j = self.neighbors[at].0 as usize;
        let q = sub(row.sites[j], row.sites[row.site]);
        let w = sign * 2.0 / norm2(q).sqrt();
        if at == self.blocks.len() {
            self.blocks.push([[0.0; D]; D]);
        }
        let rows = self.blocks[at].iter_mut().zip(self.face_second.iter_mut());
        for ((block_row, face_row), (s2_row, &s1)) in rows.zip(m.second.iter().zip(&m.first)) {
            let entries = block_row.iter_mut().zip(face_row.iter_mut());
            for ((b, f), (&s2, &qc)) in entries.zip(s2_row.iter().zip(&q)) {
                *b += w * (s2 - s1 * qc);
                *f += w * s2;
            }
        }
    }

    /// `H_ii = 2 m_i I − Σ_j (2/d_ij) ∫_{F_ij} y yᵀ` for a cell of measure `mass`.
    fn hessian_diagonal(&self, mass: f64) -> Block<D> {
        std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                let diagonal = if r == c { 2.0 * mass } else { 0.0 };
                diagonal - self.face_second[r][c]
            })
        })
    }

    /// Keep the faces of positive measure, sorted by neighbour, with their Hessian blocks
    /// if kept: both lists together, in place.
    fn sort_neighbors(&mut self) {
        let paired = !self.blocks.is_empty();
        let mut kept = 0;
        for k in 0..self.neighbors.len() {
            if self.neighbors[k].1 > 0.0 {
                self.neighbors.swap(kept, k);
                if paired {
                    self.blocks.swap(kept, k);
                }
                kept += 1;
            }
        }
        self.neighbors.truncate(kept);
        self.blocks.truncate(kept);
        // Insertion sort by neighbour: a dozen entries or so.
        for k in 1..kept {
            let mut at = k;
            while at > 0 && self.neighbors[at - 1].0 > self.neighbors[at].0 {
                self.neighbors.swap(at - 1, at);
                if paired {
                    self.blocks.swap(at - 1, at);
                }
                at -= 1;
            }
        }
    }
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

    /// Cell centroids in absolute coordinates, `L`; the site itself for an empty cell.
    pub fn centroids(&self, sites: &[[f64; D]]) -> Vec<[f64; D]> {
        self.moments
            .iter()
            .zip(sites)
            .map(|(m, &s)| m.centroid().map_or(s, |c| add_point(s, c)))
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

    /// Each cell's energy term `∫ |x - x_i|²` about its site, `L^(d+2)`.
    pub fn energy_terms(&self) -> Vec<f64> {
        self.moments.iter().map(|m| m.second).collect()
    }

    /// CVT energy `E = Σ_i ∫ |x - x_i|²`, summed in index order.
    pub fn energy(&self) -> f64 {
        self.moments.iter().map(|m| m.second).sum()
    }

    /// Energy gradient `∂E/∂x_i = 2 m_i (x_i - c_i) = -2 ∫(x - x_i)` (DESIGN §4), `L^(d+1)`.
    pub fn gradient(&self) -> Vec<[f64; D]> {
        self.moments.iter().map(|m| scale(m.first, -2.0)).collect()
    }

    /// The same diagram for the sites renamed by `order`: row `k` becomes row `order[k]`
    /// and neighbour `j` becomes `order[j]` (each row's neighbours sorted again, their
    /// measures and Hessian blocks with them). `order` must be a permutation of `0..n`.
    pub fn reordered(&self, order: &[u32]) -> Self {
        let n = self.len();
        let mut out = Diagram {
            moments: vec![Moments::zero(); n],
            boundary_measure: vec![0.0; n],
            neighbor_offsets: vec![0; n + 1],
            neighbor_sites: vec![0; self.neighbor_sites.len()],
            neighbor_measures: vec![0.0; self.neighbor_measures.len()],
            hessian: self.hessian.as_ref().map(|h| Hessian {
                diagonal: vec![[[0.0; D]; D]; n],
                off_diagonal: vec![[[0.0; D]; D]; h.off_diagonal.len()],
            }),
        };
        for (k, &i) in order.iter().enumerate() {
            let i = i as usize;
            out.moments[i] = self.moments[k];
            out.boundary_measure[i] = self.boundary_measure[k];
            out.neighbor_offsets[i + 1] = self.neighbor_offsets[k + 1] - self.neighbor_offsets[k];
        }
        for i in 0..n {
            out.neighbor_offsets[i + 1] += out.neighbor_offsets[i];
        }
        let mut row: Vec<(u32, usize)> = Vec::new();
        for (k, &i) in order.iter().enumerate() {
            let i = i as usize;
            row.clear();
            row.extend(
                (self.neighbor_offsets[k]..self.neighbor_offsets[k + 1])
                    .map(|e| (order[self.neighbor_sites[e] as usize], e)),
            );
            row.sort_unstable();
            let from = out.neighbor_offsets[i];
            for (slot, &(j, e)) in row.iter().enumerate() {
                out.neighbor_sites[from + slot] = j;
                out.neighbor_measures[from + slot] = self.neighbor_measures[e];
            }
            if let (Some(h), Some(to)) = (self.hessian.as_ref(), out.hessian.as_mut()) {
                to.diagonal[i] = h.diagonal[k];
                for (slot, &(_, e)) in row.iter().enumerate() {
                    to.off_diagonal[from + slot] = h.off_diagonal[e];
                }
            }
        }
        out
    }

    /// The product `H v` of the energy's [`Hessian`] with `v` (one row per site), `None`
    /// unless the diagram was computed with [`Options::hessian`]. Rows in parallel, each
    /// summed in neighbour order: the result does not depend on the thread count.
    pub fn hessian_product(&self, v: &[[f64; D]]) -> Option<Vec<[f64; D]>> {
        let mut out = vec![[0.0; D]; self.len()];
        self.hessian_product_into(v, &mut out).then_some(out)
    }

    /// [`Diagram::hessian_product`] into `out` (one row per site); `false` (and `out`
    /// untouched) without the Hessian.
    pub fn hessian_product_into(&self, v: &[[f64; D]], out: &mut [[f64; D]]) -> bool {
        let Some(h) = self.hessian.as_ref() else {
            return false;
        };
        let row = |i: usize| -> [f64; D] {
            let mut sum = mat_vec(&h.diagonal[i], v[i]);
            for e in self.neighbor_offsets[i]..self.neighbor_offsets[i + 1] {
                let j = self.neighbor_sites[e] as usize;
                sum = add_point(sum, mat_vec(&h.off_diagonal[e], v[j]));
            }
            sum
        };
        out.par_chunks_mut(PRODUCT_ROWS)
            .enumerate()
            .for_each(|(c, rows)| {
                for (k, o) in rows.iter_mut().enumerate() {
                    *o = row(c * PRODUCT_ROWS + k);
                }
            });
        true
    }
}

/// Rows of a Hessian product per parallel task: a few microseconds of work each.
const PRODUCT_ROWS: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::{Polygon, Solid};
    use crate::sample::interior_sites;

    /// Over several batches, the error names the first offending site in index order,
    /// whichever batch met it first.
    #[test]
    fn the_first_duplicate_in_index_order_is_reported() {
        let square = Polygon::new(
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        )
        .unwrap();
        let mut sites = interior_sites(&square, 3 * BATCH, 5);
        sites[2 * BATCH + 1] = sites[2 * BATCH];
        sites[BATCH + 7] = sites[10];
        let error = clipped_diagram::<2, PolygonCell>(&square, &sites, Options::default(), false)
            .unwrap_err();
        match error {
            CoreError::DuplicateSites { first, second, .. } => {
                assert_eq!((first, second), (10, BATCH + 7))
            }
            other => panic!("{other:?}"),
        }
    }

    /// Cutting boundary cells by the domain's planes inside `voronoi_cell` gives the cells
    /// that `clip_convex` gives after it, to round-off, faces and their tags included.
    #[test]
    fn early_boundary_cut_matches_the_late_one() {
        let cuboid = Solid::cuboid([0.0; 3], [1.0, 0.6, 0.8]).unwrap();
        for solid in [cuboid, Solid::octahedron([1.3, 0.7, 1.1]).unwrap()] {
            assert!(solid.is_convex());
            let sites = interior_sites(&solid, 400, 7);
            let index = SiteIndex::new(&sites).unwrap();
            let (mut late, mut early) = (CellScratch::default(), CellScratch::default());
            let (mut a, mut b) = (MeasureScratch::default(), MeasureScratch::default());
            let h = (solid.volume() / sites.len() as f64).cbrt();
            let mut cut_early = 0;
            for (i, &site) in sites.iter().enumerate() {
                let (cell, inside) =
                    voronoi_cell::<3, PolyhedronCell>(&solid, &index, &sites, i, false, &mut late)
                        .unwrap();
                assert!(!inside);
                let ma = clip_by_domain(&solid, cell, site, Some(1), None, &mut a);
                let (cell, inside) =
                    voronoi_cell::<3, PolyhedronCell>(&solid, &index, &sites, i, true, &mut early)
                        .unwrap();
                let mb = if inside {
                    measure(cell, None, &mut b.faces)
                } else {
                    clip_by_domain(&solid, cell, site, Some(1), None, &mut b)
                };
                cut_early += inside as usize;
                assert!((ma.mass - mb.mass).abs() <= 1e-12 * ma.mass, "cell {i}");
                assert!(
                    (ma.second - mb.second).abs() <= 1e-12 * ma.second,
                    "cell {i}"
                );
                for k in 0..3 {
                    assert!(
                        (ma.first[k] - mb.first[k]).abs() <= 1e-12 * ma.mass * h,
                        "cell {i}"
                    );
                }
                let db = a.faces.boundary - b.faces.boundary;
                assert!(db.abs() <= 1e-12 * h * h, "cell {i}: boundary {db:e}");
                // Faces of more than round-off, with their measures.
                let faces = |o: &mut MeasureScratch<3, PolyhedronCell>| -> Vec<(u32, f64)> {
                    o.faces.sort_neighbors();
                    o.faces
                        .neighbors
                        .iter()
                        .copied()
                        .filter(|&(_, m)| m > 1e-12 * h * h)
                        .collect()
                };
                let (fa, fb) = (faces(&mut a), faces(&mut b));
                assert_eq!(fa.len(), fb.len(), "cell {i}");
                for ((ja, ma), (jb, mb)) in fa.into_iter().zip(fb) {
                    assert!(ja == jb && (ma - mb).abs() <= 1e-12 * h * h, "cell {i}");
                }
            }
            assert!(
                cut_early > 0 && cut_early < sites.len(),
                "{cut_early} cells cut early"
            );
        }
    }
}
