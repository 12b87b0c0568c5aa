//! Cell geometry and the conforming mesh (DESIGN §9): every clipped cell as faces made
//! from the core's own convex cells and boundary elements, each vertex named by what
//! makes it ([`key`]), and all cells assembled into one mesh whose neighbouring cells share
//! exactly the same vertices and faces ([`PolyMesh`]).
//!
//! | file | owns |
//! |------|------|
//! | `mod.rs` | [`PolyMesh`], [`MeshDomain`], the drivers [`conforming_mesh`] (and for a partition's own cells among its sites and halo, [`conforming_mesh_part`], DESIGN §10) and the global assembly: names to one vertex index, degenerate names merged, each interior face once |
//! | `key.rs` | the combinatorial vertex names |
//! | `planar.rs` | a convex polygon restricted to the domain in its plane (2D cells, 3D bisector faces) |
//! | `cell2.rs` | one 2D cell's edges |
//! | `cell3.rs` | one 3D cell's faces: boundary triangles clipped by the cell, bisector faces restricted to the domain |
//!
//! Degenerate configurations (cocircular or cospherical sites, lattices, boundary vertices
//! on bisectors) give several names to one point, or faces of no area. Two names are
//! merged when one cell has both at one point (to `MERGE_REL` of the cell's size), or when a face's vertex seen from one of its cells
//! finds no vertex of that name in the other cell's view of the face but one at its
//! position. Merging is a union of names, so every cell sees the same result; faces left
//! with fewer than `d` vertices are dropped.

mod cell2;
mod cell3;
mod key;
mod planar;

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use rayon::prelude::*;

use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::knn::{NearScratch, SiteIndex};
use super::order::morton_order;
use super::polygon_cell::PolygonCell;
use super::polyhedron_cell::PolyhedronCell;
use super::power::Power;
use super::request::{checked_part, checked_windings, Options};
use super::voronoi_cell::{voronoi_cell, CellScratch};
use crate::domain::{Boundary, Polygon, Solid, WindingNumber};
use crate::error::CoreError;
use crate::geometry::{add, dot, norm2, scale, sub, Euclid, Space};
use key::{Gen, Key};

/// Cells of a diagram as one mesh with shared vertices and faces (the layout of
/// `hcvt.polymesh.PolyMesh`, OpenFOAM's): interior faces first, sorted by
/// `(owner, neighbour)`, then boundary faces by owner.
#[derive(Debug, Clone, Default)]
pub struct PolyMesh<const D: usize> {
    /// Every vertex once, absolute, `L`.
    pub points: Vec<[f64; D]>,
    /// Face `k` is `face_vertices[face_offsets[k]..face_offsets[k + 1]]`.
    pub face_offsets: Vec<usize>,
    /// 3D: a vertex loop counter-clockwise seen from outside the owner. 2D: an edge with
    /// its owner on the left.
    pub face_vertices: Vec<u32>,
    /// The cell each face belongs to (the smaller site index of an interior face).
    pub owner: Vec<u32>,
    /// The cell on the other side, `-1` on the domain boundary.
    pub neighbour: Vec<i64>,
    /// The boundary triangle (3D) or segment (2D) of a boundary face, `-1` inside.
    pub boundary_element: Vec<i64>,
    /// Chains of a cell's boundary that did not close (round-off in a degenerate
    /// configuration): zero on a sound mesh.
    pub open_chains: u32,
}

/// What a face of a cell lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Side {
    /// The bisector with site `j`.
    Neighbor(u32),
    /// Boundary element `t`.
    Boundary(u32),
}

/// One cell's faces, each a loop of named absolute points: face `k` is
/// `nodes[starts[k]..starts[k + 1]]`.
#[derive(Debug, Default)]
pub(crate) struct CellFaces<const D: usize> {
    sides: Vec<Side>,
    starts: Vec<u32>,
    nodes: Vec<(Key, [f64; D])>,
    open: u32,
}

impl<const D: usize> CellFaces<D> {
    pub(crate) fn push_face(&mut self, side: Side, nodes: impl Iterator<Item = (Key, [f64; D])>) {
        if self.starts.is_empty() {
            self.starts.push(0);
        }
        self.nodes.extend(nodes);
        self.sides.push(side);
        self.starts.push(self.nodes.len() as u32);
    }
}

/// A convex cell that can give the faces of its part inside the domain.
pub(crate) trait CellGeometry<const D: usize>: ConvexCell<D> {
    type Scratch: Default + Send;

    /// The faces of this cell (of site `i`, relative to it) restricted to the domain,
    /// appended to `out`; `winding` is the winding number of a point of the cell (its
    /// site's, or for a power cell without its site, a vertex's), `weights` those of a
    /// power diagram.
    #[allow(clippy::too_many_arguments)]
    fn clipped_faces(
        &self,
        boundary: &Boundary<D>,
        sites: &[[f64; D]],
        weights: Option<&[f64]>,
        i: usize,
        winding: Option<i32>,
        out: &mut CellFaces<D>,
        scratch: &mut Self::Scratch,
    );
}

/// The generator of a cell's plane (or 2D line) `p` made by `face`.
pub(crate) fn gen_of(face: Face, p: u16) -> Gen {
    match face {
        Face::Neighbor(j) => Gen::Site(j),
        Face::Boundary(t) => Gen::Elem(t),
        Face::Box | Face::Cone => Gen::Other(u32::from(p)),
    }
}

/// Which side of the bisector of sites `i` and `j` the point `x` (absolute) is on, seen
/// from `i`: positive beyond it (nearer `j`), and whether it lies exactly on it.
///
/// Computed from the pair in index order, so that both cells get the same number (with
/// opposite signs); a point exactly on the bisector counts as nearer the larger index.
/// The boundary's vertices are put on one side once and for all this way, and the two
/// cells of a face slice and clip the boundary alike.
///
/// With `weights`, the power bisector (DESIGN §14): the Voronoi one shifted by
/// `(w_hi − w_lo) / 2` (in units of `|z_hi − z_lo|`), the same number from either cell.
pub(crate) fn bisector_side<const D: usize>(
    sites: &[[f64; D]],
    weights: Option<&[f64]>,
    i: usize,
    j: usize,
    x: [f64; D],
) -> (f64, bool) {
    let (lo, hi) = (i.min(j), i.max(j));
    let mid = scale(add(sites[lo], sites[hi]), 0.5);
    let mut d = dot(sub(x, mid), sub(sites[hi], sites[lo]));
    if let Some(w) = weights {
        d += 0.5 * (w[hi] - w[lo]);
    }
    let zero = d == 0.0;
    let d = if zero { f64::MIN_POSITIVE } else { d };
    (if i == lo { d } else { -d }, zero)
}

/// Vertices of a cell closer than this fraction of the cell's size are one point of
/// several names. Degenerate vertices of lattices coincide to about 1e-15 of the
/// cell; distinct vertices of a CVT are farther apart than 1e-6 of it.
pub(crate) const MERGE_REL: f64 = 1e-10;

/// Cells per parallel task.
const BATCH: usize = 256;

/// A kind of domain whose clipped cells the conforming mesh can build (DESIGN §11 (d)):
/// the cell type that gives the faces, and the boundary pieces they are cut from. A
/// polygon ([`PolygonCell`]s) and a solid ([`PolyhedronCell`]s) today.
pub trait MeshDomain<const D: usize>: DomainKind<D> {
    /// The whole mesh (`subset` None), or the cells `own` of a part of a problem of
    /// `total_sites` sites among `sites` ([`MeshPart`]).
    #[doc(hidden)]
    fn mesh_cells(
        &self,
        sites: &[[f64; D]],
        weights: Option<&[f64]>,
        subset: Option<(&[u32], usize)>,
        options: Options,
    ) -> Result<MeshPart<D>, CoreError>;
}

impl MeshDomain<2> for Polygon {
    fn mesh_cells(
        &self,
        sites: &[[f64; 2]],
        weights: Option<&[f64]>,
        subset: Option<(&[u32], usize)>,
        options: Options,
    ) -> Result<MeshPart<2>, CoreError> {
        mesh_cells::<2, PolygonCell>(self, sites, weights, subset, options)
    }
}

impl MeshDomain<3> for Solid {
    fn mesh_cells(
        &self,
        sites: &[[f64; 3]],
        weights: Option<&[f64]>,
        subset: Option<(&[u32], usize)>,
        options: Options,
    ) -> Result<MeshPart<3>, CoreError> {
        mesh_cells::<3, PolyhedronCell>(self, sites, weights, subset, options)
    }
}

/// The conforming mesh of the clipped diagram of `sites` in `domain`: polygons in 2D,
/// polyhedra in 3D.
///
/// Errors as [`super::clipped_diagram`]: the first offending site in index order.
pub fn conforming_mesh<const D: usize, K: MeshDomain<D>>(
    domain: &K,
    sites: &[[f64; D]],
    options: Options,
) -> Result<PolyMesh<D>, CoreError> {
    domain
        .mesh_cells(sites, None, None, options)
        .map(|part| part.mesh)
}

/// The conforming mesh of the power (Laguerre) diagram of `sites` with `weights` (one per
/// site, `L²`, DESIGN §14) in `domain`: vertices named as for Voronoi cells (the power
/// bisector is the Voronoi one shifted), an empty cell without faces. All-zero weights
/// give [`conforming_mesh`] bit for bit.
///
/// Errors as [`conforming_mesh`], and [`CoreError::InvalidWeights`] for weights of the
/// wrong length or not finite.
pub fn conforming_power_mesh<const D: usize, K: MeshDomain<D>>(
    domain: &K,
    sites: &[[f64; D]],
    weights: &[f64],
    options: Options,
) -> Result<PolyMesh<D>, CoreError> {
    if weights.len() != sites.len() {
        return Err(CoreError::InvalidWeights {
            reason: format!(
                "weights: expected one per site ({}), got {}",
                sites.len(),
                weights.len()
            ),
        });
    }
    if let Some(index) = weights.iter().position(|w| !w.is_finite()) {
        return Err(CoreError::InvalidWeights {
            reason: format!("weight {index} is not finite ({})", weights[index]),
        });
    }
    let weights = weights.iter().any(|&w| w != 0.0).then_some(weights);
    domain
        .mesh_cells(sites, weights, None, options)
        .map(|part| part.mesh)
}

/// The cells of a partition's sites in the conforming mesh of the whole problem (DESIGN
/// §10): what [`conforming_mesh_part`] returns.
#[derive(Debug, Clone, Default)]
pub struct MeshPart<const D: usize> {
    /// Every face of the own cells, cells numbered as the `sites` given: a face between
    /// two own cells once, owned by the smaller; a face between an own cell and another
    /// one owned by the own cell (oriented out of it), `neighbour` the other cell. Each
    /// face's vertex coordinates are bitwise those of the whole problem's mesh.
    pub mesh: PolyMesh<D>,
    /// The cells computed, increasing: the own cells and the ring of other cells that
    /// share a vertex with them (their names and positions decide the shared vertices).
    pub computed: Vec<u32>,
    /// Reach of each computed cell, `L²` ([`super::PartCells::reach2`]): the part is the
    /// whole problem's when `sites` holds every site within each one's reach.
    pub reach2: Vec<f64>,
}

/// The own cells `own` (indices into `sites`) of a partition of a problem of
/// `total_sites` sites, as they are in [`conforming_mesh`] of the whole problem
/// ([`MeshPart`]).
///
/// A vertex of the whole mesh takes its name and position from the first cell, in index
/// order, that has it, and degenerate names merge between the cells that share a point;
/// so besides the own cells this computes every other cell whose site is as near as the
/// cell's own site (to 1e-7 of the cell's size) to one of their vertices: every cell that
/// has that point. Exact when every computed cell is certified by its reach and `sites`
/// lists the problem's sites in their relative order (as [`super::clipped_cells`]).
///
/// Errors as [`super::clipped_cells`], naming indices into `sites`.
pub fn conforming_mesh_part<const D: usize, K: MeshDomain<D>>(
    domain: &K,
    sites: &[[f64; D]],
    own: &[u32],
    total_sites: usize,
    options: Options,
) -> Result<MeshPart<D>, CoreError> {
    domain.mesh_cells(sites, None, Some((own, total_sites)), options)
}

/// A vertex of a cell is shared with every cell whose site is within its distance from
/// the cell's site plus this fraction of the cell's size (names merge at 1e-10 of it).
const RING_REL: f64 = 1e-7;

/// One cell's faces and reach, or its error.
type Made<const D: usize> = (u32, Result<(CellFaces<D>, f64), CoreError>);

/// The whole mesh (`subset` None), or the cells `own` of a part of a problem of
/// `total_sites` sites among `sites` ([`MeshPart`]).
fn mesh_cells<const D: usize, C: CellGeometry<D>>(
    boundary: &Boundary<D>,
    sites: &[[f64; D]],
    weights: Option<&[f64]>,
    subset: Option<(&[u32], usize)>,
    options: Options,
) -> Result<MeshPart<D>, CoreError>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let n = sites.len();
    let Some((own, total_sites)) = subset else {
        let windings = checked_windings(boundary, sites, options)?;
        let index = SiteIndex::new(sites)?;
        let mut cells = Cells::new(n);
        let power = weights.map(|w| Power::new(w, sites));
        let visit = morton_order(sites);
        let made = cell_faces::<D, C>(
            boundary,
            &index,
            sites,
            power.as_ref(),
            n,
            &windings,
            &visit,
        );
        cells.take(made)?;
        return Ok(cells.assemble(sites, boundary.vertices(), None));
    };
    if own.is_empty() {
        return Ok(MeshPart::default());
    }
    let (mut windings, is_own) = checked_part(boundary, sites, own, options)?;
    let index = SiteIndex::new(sites)?;
    let total = total_sites.max(n);
    let mut cells = Cells::new(n);
    let own_sites: Vec<[f64; D]> = own.iter().map(|&i| sites[i as usize]).collect();
    let visit: Vec<u32> = morton_order(&own_sites)
        .iter()
        .map(|&k| own[k as usize])
        .collect();
    cells.take(cell_faces::<D, C>(
        boundary, &index, sites, None, total, &windings, &visit,
    ))?;
    // Rings until no new cell: a ring cell's faces toward the own cells may have vertices
    // the own cells lack (degenerate points), whose other cells are needed in turn.
    let mut frontier: Vec<u32> = own.to_vec();
    loop {
        let ring = cells.ring(&frontier, &is_own, &index, sites);
        if ring.is_empty() {
            break;
        }
        let ring_windings: Vec<Option<i32>> = ring
            .par_iter()
            .map(|&j| Euclid::winding_number(boundary, &sites[j as usize]))
            .collect();
        for (&j, &w) in ring.iter().zip(&ring_windings) {
            windings[j as usize] = w;
        }
        cells.take(cell_faces::<D, C>(
            boundary, &index, sites, None, total, &windings, &ring,
        ))?;
        frontier = ring;
    }
    Ok(cells.assemble(sites, boundary.vertices(), Some(&is_own)))
}

/// The faces and reach of the cells `visit` (in parallel batches; each cell alone); power
/// cells with `power`.
fn cell_faces<const D: usize, C: CellGeometry<D>>(
    boundary: &Boundary<D>,
    index: &SiteIndex<D>,
    sites: &[[f64; D]],
    power: Option<&Power<'_, D>>,
    total_sites: usize,
    windings: &[Option<i32>],
    visit: &[u32],
) -> Vec<Made<D>>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let batches: Vec<Vec<Made<D>>> = visit
        .par_chunks(BATCH)
        .map_init(
            || (CellScratch::<C>::default(), C::Scratch::default()),
            |(scratch, geometry), chunk| {
                chunk
                    .iter()
                    .map(|&i| {
                        let i = i as usize;
                        // Without the early cut of a convex domain's boundary cells: the
                        // faces are made here, from the bisectors and triangles alone.
                        let made = voronoi_cell::<D, C, Boundary<D>>(
                            boundary,
                            index,
                            sites,
                            power,
                            total_sites,
                            i,
                            false,
                            None,
                            false,
                            scratch,
                        )
                        .map(|(cell, _)| {
                            let mut faces = CellFaces::default();
                            if !cell.is_empty() {
                                let winding = cell_winding(
                                    boundary,
                                    cell,
                                    sites[i],
                                    windings[i],
                                    power.is_some(),
                                );
                                cell.clipped_faces(
                                    boundary,
                                    sites,
                                    power.map(Power::weights),
                                    i,
                                    winding,
                                    &mut faces,
                                    geometry,
                                );
                            }
                            faces
                        });
                        (i as u32, made.map(|faces| (faces, scratch.reach2())))
                    })
                    .collect()
            },
        )
        .collect();
    batches.into_iter().flatten().collect()
}

/// The winding number of a point of `cell` (site `site`'s, `site_winding`): for a power
/// cell that does not hold its site, that of its vertex mean instead (as the diagram
/// measures such a cell from a point of its own).
fn cell_winding<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    cell: &C,
    site: [f64; D],
    site_winding: Option<i32>,
    power: bool,
) -> Option<i32>
where
    Euclid: WindingNumber<D>,
{
    if power && cell.excludes(&[[0.0; D]]) {
        Euclid::winding_number(boundary, &add(site, cell.vertex_mean()))
    } else {
        site_winding
    }
}

/// The cells computed so far, indexed like the sites (empty where not computed).
struct Cells<const D: usize> {
    faces: Vec<CellFaces<D>>,
    reach2: Vec<f64>,
    computed: Vec<bool>,
}

impl<const D: usize> Cells<D> {
    fn new(n: usize) -> Self {
        Self {
            faces: (0..n).map(|_| CellFaces::default()).collect(),
            reach2: vec![0.0; n],
            computed: vec![false; n],
        }
    }

    /// Store `made`, or return the error of its first offending site in index order.
    fn take(&mut self, made: Vec<Made<D>>) -> Result<(), CoreError> {
        let mut first_error: Option<(u32, CoreError)> = None;
        for (i, made) in made {
            match made {
                Ok((faces, reach2)) => {
                    self.faces[i as usize] = faces;
                    self.reach2[i as usize] = reach2;
                    self.computed[i as usize] = true;
                }
                Err(e) => {
                    if first_error.as_ref().is_none_or(|(j, _)| i < *j) {
                        first_error = Some((i, e));
                    }
                }
            }
        }
        first_error.map_or(Ok(()), |(_, e)| Err(e))
    }

    /// The sites, not yet computed, of the cells that may share a vertex with the own
    /// cells through `frontier`: those at most [`RING_REL`] of the cell's size farther
    /// from a vertex than the cell's site, for every vertex of an own cell and every
    /// vertex of a ring cell's faces toward own cells. Increasing.
    fn ring(
        &self,
        frontier: &[u32],
        is_own: &[bool],
        index: &SiteIndex<D>,
        sites: &[[f64; D]],
    ) -> Vec<u32> {
        let found: Vec<Vec<u32>> = frontier
            .par_chunks(BATCH)
            .map_init(NearScratch::default, |near, chunk| {
                let mut out = Vec::new();
                for &c in chunk {
                    let cell = &self.faces[c as usize];
                    let s = sites[c as usize];
                    let size = cell
                        .nodes
                        .iter()
                        .map(|(_, x)| norm2(sub(*x, s)))
                        .fold(0.0, f64::max);
                    let slack = RING_REL * size.sqrt();
                    for (k, side) in cell.sides.iter().enumerate() {
                        let toward_own = matches!(side, Side::Neighbor(j) if is_own[*j as usize]);
                        if !is_own[c as usize] && !toward_own {
                            continue;
                        }
                        let (a, b) = (cell.starts[k] as usize, cell.starts[k + 1] as usize);
                        for (_, x) in &cell.nodes[a..b] {
                            let limit = norm2(sub(*x, s)).sqrt() + slack;
                            let mut stream = index.near(*x, near);
                            while let Some((j, _)) = stream.next_within(limit * limit) {
                                if !self.computed[j as usize] {
                                    out.push(j);
                                }
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut ring: Vec<u32> = found.into_iter().flatten().collect();
        ring.sort_unstable();
        ring.dedup();
        ring
    }

    /// The mesh of the computed cells, restricted to the faces of the `keep` cells when
    /// given ([`MeshPart`]).
    fn assemble(
        self,
        sites: &[[f64; D]],
        boundary_vertices: &[[f64; D]],
        keep: Option<&[bool]>,
    ) -> MeshPart<D> {
        let mesh = assemble(&self.faces, sites, boundary_vertices, keep);
        let computed: Vec<u32> = (0..self.computed.len() as u32)
            .filter(|&i| self.computed[i as usize])
            .collect();
        let reach2 = computed.iter().map(|&i| self.reach2[i as usize]).collect();
        MeshPart {
            mesh,
            computed,
            reach2,
        }
    }
}

/// A multiplicative hash (FxHash's step) for vertex names: the assembly hashes every
/// vertex of every face, and std's SipHash, made to resist adversarial keys, cost more
/// than the rest of it. Ids are given in insertion order, never in the map's order, so the
/// hash does not affect the result.
#[derive(Default, Clone, Copy)]
struct NameHasher(u64);

impl NameHasher {
    #[inline]
    fn add(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

impl Hasher for NameHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.add(u64::from_le_bytes(word));
        }
    }

    fn write_u8(&mut self, i: u8) {
        self.add(u64::from(i));
    }

    fn write_u32(&mut self, i: u32) {
        self.add(u64::from(i));
    }

    fn write_u64(&mut self, i: u64) {
        self.add(i);
    }

    fn write_usize(&mut self, i: usize) {
        self.add(i as u64);
    }
}

/// Union-find over vertex ids; the root of a class is its smallest id.
struct Classes(Vec<u32>);

impl Classes {
    fn find(&mut self, mut a: u32) -> u32 {
        while self.0[a as usize] != a {
            let up = self.0[self.0[a as usize] as usize];
            self.0[a as usize] = up;
            a = up;
        }
        a
    }

    fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            let (lo, hi) = (a.min(b), a.max(b));
            self.0[hi as usize] = lo;
        }
    }
}

/// One mesh from the cells' faces (in index order, so the result does not depend on the
/// thread count): names to ids in order of first appearance, degenerate names merged
/// (module doc), each interior face taken once from its owner (the smaller site), or from
/// the other cell, reversed, when the owner has no such face.
///
/// With `keep`, only the faces of the kept cells, each owned by a kept cell ([`MeshPart`]):
/// names, merges and faces are made as above, so that what is kept is the whole mesh's.
fn assemble<const D: usize>(
    cells: &[CellFaces<D>],
    sites: &[[f64; D]],
    boundary_vertices: &[[f64; D]],
    keep: Option<&[bool]>,
) -> PolyMesh<D> {
    let kept = |i: usize| keep.is_none_or(|k| k[i]);
    let total: usize = cells.iter().map(|c| c.nodes.len()).sum();
    let mut ids: HashMap<Key, u32, BuildHasherDefault<NameHasher>> =
        HashMap::with_capacity_and_hasher(total / 3, BuildHasherDefault::default());
    let mut positions: Vec<[f64; D]> = Vec::with_capacity(total / 3);
    let mut is_exact: Vec<bool> = Vec::with_capacity(total / 3);
    let node_ids: Vec<Vec<u32>> = cells
        .iter()
        .map(|c| {
            c.nodes
                .iter()
                .map(|(key, x)| {
                    *ids.entry(*key).or_insert_with(|| {
                        // A boundary vertex keeps its input coordinates exactly.
                        let exact = key.mesh_vertex().map(|v| boundary_vertices[v as usize]);
                        is_exact.push(exact.is_some());
                        positions.push(exact.unwrap_or(*x));
                        (positions.len() - 1) as u32
                    })
                })
                .collect()
        })
        .collect();
    drop(ids);
    let mut classes = Classes((0..positions.len() as u32).collect());
    // Each cell's faces toward each neighbour, sorted by neighbour.
    let toward: Vec<Vec<(u32, u32)>> = cells
        .iter()
        .map(|c| {
            let mut v: Vec<(u32, u32)> = (c.sides.iter().enumerate())
                .filter_map(|(k, s)| match s {
                    Side::Neighbor(j) => Some((*j, k as u32)),
                    Side::Boundary(_) => None,
                })
                .collect();
            v.sort_unstable();
            v
        })
        .collect();
    let tol2: Vec<f64> = cells
        .iter()
        .zip(sites)
        .map(|(c, &s)| {
            let r2 = c
                .nodes
                .iter()
                .map(|(_, x)| norm2(sub(*x, s)))
                .fold(0.0, f64::max);
            MERGE_REL * MERGE_REL * r2
        })
        .collect();
    let mut seen = Vec::new();
    for (i, c) in cells.iter().enumerate() {
        merge_coinciding(c, &node_ids[i], tol2[i], &mut seen, &mut classes);
    }
    for i in 0..cells.len() {
        for &(j, _) in dedup_neighbors(&toward[i])
            .iter()
            .filter(|(j, _)| *j as usize > i)
        {
            let mine = view(&cells[i], &node_ids[i], &toward[i], j);
            let theirs = view(
                &cells[j as usize],
                &node_ids[j as usize],
                &toward[j as usize],
                i as u32,
            );
            let tol = tol2[i].max(tol2[j as usize]);
            match_views(&mine, &theirs, tol, &mut classes);
            match_views(&theirs, &mine, tol, &mut classes);
        }
    }
    // Final indices in order of each class's first id; its position is that id's, or a
    // boundary vertex's exact one when the class holds one.
    let mut index = vec![u32::MAX; positions.len()];
    let mut points = Vec::new();
    let mut exact = Vec::new();
    for id in 0..positions.len() as u32 {
        let root = classes.find(id) as usize;
        if index[root] == u32::MAX {
            index[root] = points.len() as u32;
            points.push(positions[root]);
            exact.push(is_exact[root]);
        }
        let at = index[root] as usize;
        index[id as usize] = index[root];
        if is_exact[id as usize] && !exact[at] {
            points[at] = positions[id as usize];
            exact[at] = true;
        }
    }
    let mut mesh = PolyMesh {
        points,
        face_offsets: vec![0],
        open_chains: (cells.iter().enumerate())
            .filter(|&(i, _)| kept(i))
            .map(|(_, c)| c.open)
            .sum(),
        ..PolyMesh::default()
    };
    let mut interior: Vec<(u32, u32, Vec<u32>)> = Vec::new();
    let mut loop_ids = Vec::new();
    for (i, c) in cells.iter().enumerate() {
        for (k, side) in c.sides.iter().enumerate() {
            let (a, b) = (c.starts[k] as usize, c.starts[k + 1] as usize);
            loop_ids.clear();
            loop_ids.extend(node_ids[i][a..b].iter().map(|&id| index[id as usize]));
            match *side {
                Side::Neighbor(j) => {
                    if !kept(i) && !kept(j as usize) {
                        continue;
                    }
                    let theirs = &toward[j as usize];
                    let other_has = theirs
                        .binary_search_by_key(&(i as u32), |&(n, _)| n)
                        .is_ok();
                    if (j as usize) < i && other_has {
                        continue; // the owner, cell j, gives this face
                    }
                    let Some(face) = collapse(&loop_ids, D) else {
                        continue;
                    };
                    if (j as usize) > i {
                        interior.push((i as u32, j, face));
                    } else {
                        interior.push((j, i as u32, face.into_iter().rev().collect()));
                    }
                }
                Side::Boundary(t) => {
                    if !kept(i) {
                        continue;
                    }
                    let Some(face) = collapse(&loop_ids, D) else {
                        continue;
                    };
                    mesh.push(i as u32, -1, i64::from(t), &face);
                }
            }
        }
    }
    // Interior faces first (OpenFOAM's upper-triangular order), boundary faces after.
    let boundary_faces = std::mem::take(&mut mesh);
    let mut mesh = PolyMesh {
        points: boundary_faces.points.clone(),
        face_offsets: vec![0],
        open_chains: boundary_faces.open_chains,
        ..PolyMesh::default()
    };
    interior.sort_by_key(|&(o, n, _)| (o, n));
    for (o, n, face) in &interior {
        if kept(*o as usize) {
            mesh.push(*o, i64::from(*n), -1, face);
        } else {
            // A part's face toward a cell it does not keep: owned by its own cell.
            let reversed: Vec<u32> = face.iter().rev().copied().collect();
            mesh.push(*n, i64::from(*o), -1, &reversed);
        }
    }
    for k in 0..boundary_faces.owner.len() {
        let f = &boundary_faces.face_vertices
            [boundary_faces.face_offsets[k]..boundary_faces.face_offsets[k + 1]];
        mesh.push(
            boundary_faces.owner[k],
            -1,
            boundary_faces.boundary_element[k],
            f,
        );
    }
    mesh.drop_unused_points();
    mesh
}

impl<const D: usize> PolyMesh<D> {
    /// Keep only the points some face uses (those of collapsed faces and of the faces
    /// taken from the other cell are not), in their order.
    fn drop_unused_points(&mut self) {
        let mut index = vec![u32::MAX; self.points.len()];
        for &v in &self.face_vertices {
            index[v as usize] = 0;
        }
        let mut kept = 0;
        for (k, slot) in index.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = kept;
                self.points[kept as usize] = self.points[k];
                kept += 1;
            }
        }
        self.points.truncate(kept as usize);
        for v in &mut self.face_vertices {
            *v = index[*v as usize];
        }
    }

    fn push(&mut self, owner: u32, neighbour: i64, element: i64, face: &[u32]) {
        self.face_vertices.extend_from_slice(face);
        self.face_offsets.push(self.face_vertices.len());
        self.owner.push(owner);
        self.neighbour.push(neighbour);
        self.boundary_element.push(element);
    }
}

/// Merge the names of a cell's vertices that lie at one point (within `tol2`, squared):
/// sorted along the first axis, so that only near neighbours are compared.
fn merge_coinciding<const D: usize>(
    cell: &CellFaces<D>,
    ids: &[u32],
    tol2: f64,
    seen: &mut Vec<(f64, u32, [f64; D])>,
    classes: &mut Classes,
) {
    seen.clear();
    seen.extend(
        ids.iter()
            .zip(&cell.nodes)
            .map(|(&id, (_, x))| (x[0], id, *x)),
    );
    seen.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    seen.dedup_by_key(|e| e.1);
    let tol = tol2.sqrt();
    for a in 0..seen.len() {
        for b in a + 1..seen.len() {
            if seen[b].0 - seen[a].0 > tol {
                break;
            }
            if seen[a].1 != seen[b].1 && norm2(sub(seen[a].2, seen[b].2)) <= tol2 {
                classes.union(seen[a].1, seen[b].1);
            }
        }
    }
}

/// The distinct neighbours of a sorted `(neighbour, face)` list.
fn dedup_neighbors(toward: &[(u32, u32)]) -> Vec<(u32, u32)> {
    let mut v = toward.to_vec();
    v.dedup_by_key(|x| x.0);
    v
}

/// The vertices (id, position) of every face of `cell` toward neighbour `j`.
fn view<const D: usize>(
    cell: &CellFaces<D>,
    ids: &[u32],
    toward: &[(u32, u32)],
    j: u32,
) -> Vec<(u32, [f64; D])> {
    let from = toward.partition_point(|&(n, _)| n < j);
    toward[from..]
        .iter()
        .take_while(|&&(n, _)| n == j)
        .flat_map(|&(_, k)| {
            let (a, b) = (
                cell.starts[k as usize] as usize,
                cell.starts[k as usize + 1] as usize,
            );
            (a..b).map(move |q| (ids[q], cell.nodes[q].1))
        })
        .collect()
}

/// Merge each vertex of `mine` whose id `theirs` lacks with the nearest vertex of
/// `theirs`, if that lies within `tol2` (squared).
fn match_views<const D: usize>(
    mine: &[(u32, [f64; D])],
    theirs: &[(u32, [f64; D])],
    tol2: f64,
    classes: &mut Classes,
) {
    for &(id, x) in mine {
        if theirs.iter().any(|&(other, _)| other == id) {
            continue;
        }
        let nearest = theirs
            .iter()
            .map(|&(other, y)| (norm2(sub(x, y)), other))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((d2, other)) = nearest {
            if d2 <= tol2 {
                classes.union(id, other);
            }
        }
    }
}

/// A face loop without repeated consecutive vertices (cyclically), or `None` when fewer
/// than `min` remain.
fn collapse(ids: &[u32], min: usize) -> Option<Vec<u32>> {
    let mut out: Vec<u32> = Vec::with_capacity(ids.len());
    for &id in ids {
        if out.last() != Some(&id) {
            out.push(id);
        }
    }
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    (out.len() >= min).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::interior_sites;

    /// Each cell's faces as sorted lists of vertex coordinates (bits), sorted; cells in the
    /// numbering `row` gives (`None`: a cell not kept).
    fn faces_by_cell<const D: usize>(
        mesh: &PolyMesh<D>,
        row: impl Fn(usize) -> Option<usize>,
    ) -> HashMap<usize, Vec<Vec<[u64; D]>>> {
        let mut out: HashMap<usize, Vec<Vec<[u64; D]>>> = HashMap::new();
        for k in 0..mesh.owner.len() {
            let mut face: Vec<[u64; D]> = mesh.face_vertices
                [mesh.face_offsets[k]..mesh.face_offsets[k + 1]]
                .iter()
                .map(|&v| mesh.points[v as usize].map(f64::to_bits))
                .collect();
            face.sort_unstable();
            let sides = [i64::from(mesh.owner[k]), mesh.neighbour[k]];
            for cell in sides.into_iter().filter(|&c| c >= 0) {
                if let Some(r) = row(cell as usize) {
                    out.entry(r).or_default().push(face.clone());
                }
            }
        }
        for faces in out.values_mut() {
            faces.sort_unstable();
        }
        out
    }

    /// The sites split at the middle of the first axis; each half's part mesh among its
    /// sites and those within `rho` of its box (in the whole order), then, for every
    /// computed cell whose reach that misses, also those within 1.5 times its reach (as
    /// `hcvt.distributed`), until all are certified: each own cell then has exactly the
    /// whole mesh's faces, vertex coordinates bit for bit, and every face of the part is
    /// owned by an own cell.
    fn parts_match_the_whole<const D: usize>(
        sites: &[[f64; D]],
        rho: f64,
        whole: &PolyMesh<D>,
        part: impl Fn(&[[f64; D]], &[u32], usize) -> MeshPart<D>,
    ) {
        let expected = faces_by_cell(whole, Some);
        let middle = sites.iter().map(|s| s[0]).sum::<f64>() / sites.len() as f64;
        for left in [true, false] {
            let own_rows: Vec<usize> = (0..sites.len())
                .filter(|&i| (sites[i][0] < middle) == left)
                .collect();
            let mut lo = [f64::INFINITY; D];
            let mut hi = [f64::NEG_INFINITY; D];
            for &i in &own_rows {
                for k in 0..D {
                    lo[k] = lo[k].min(sites[i][k] - rho);
                    hi[k] = hi[k].max(sites[i][k] + rho);
                }
            }
            let in_box = |s: &[f64; D]| (0..D).all(|k| s[k] >= lo[k] && s[k] <= hi[k]);
            let mut balls: Vec<([f64; D], f64)> = Vec::new();
            let (rows, got) = loop {
                let rows: Vec<usize> = (0..sites.len())
                    .filter(|&i| {
                        in_box(&sites[i])
                            || balls.iter().any(|(c, r)| norm2(sub(sites[i], *c)) <= r * r)
                    })
                    .collect();
                let local: Vec<[f64; D]> = rows.iter().map(|&i| sites[i]).collect();
                let own: Vec<u32> = own_rows
                    .iter()
                    .map(|i| rows.binary_search(i).unwrap() as u32)
                    .collect();
                let got = part(&local, &own, sites.len());
                assert!(got.computed.len() > own.len(), "a ring of other cells");
                let before = balls.len();
                for (&c, &r2) in got.computed.iter().zip(&got.reach2) {
                    let (s, r) = (local[c as usize], r2.sqrt());
                    let boxed = (0..D).all(|k| s[k] - r > lo[k] && s[k] + r < hi[k]);
                    let balled = balls.iter().any(|(b, rb)| *b == s && r < *rb);
                    if !boxed && !balled && rows.len() < sites.len() {
                        balls.push((s, 1.5 * r));
                    }
                }
                if balls.len() == before {
                    break (rows, got);
                }
            };
            let is_own = |c: usize| own_rows.binary_search(&rows[c]).is_ok();
            assert!(got.mesh.owner.iter().all(|&o| is_own(o as usize)));
            let mine = faces_by_cell(&got.mesh, |c| is_own(c).then(|| rows[c]));
            assert_eq!(mine.len(), own_rows.len());
            for &i in &own_rows {
                assert_eq!(mine[&i], expected[&i], "cell {i}");
            }
        }
    }

    #[test]
    fn a_parts_cells_are_the_whole_meshs_bit_for_bit_2d() {
        let holed = Polygon::from_rings(&[
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            &[[0.3, 0.3], [0.3, 0.6], [0.6, 0.6], [0.6, 0.3]],
        ])
        .unwrap();
        let sites = interior_sites(&holed, 1500, 5);
        let whole = conforming_mesh(&holed, &sites, Options::default()).unwrap();
        parts_match_the_whole(&sites, 0.1, &whole, |local, own, total| {
            conforming_mesh_part(&holed, local, own, total, Options::default()).unwrap()
        });
    }

    #[test]
    fn a_parts_cells_are_the_whole_meshs_bit_for_bit_3d() {
        let cube = Solid::cuboid([0.0; 3], [2.0; 3]).unwrap();
        let sites = interior_sites(&cube, 600, 7);
        let whole = conforming_mesh(&cube, &sites, Options::default()).unwrap();
        parts_match_the_whole(&sites, 0.5, &whole, |local, own, total| {
            conforming_mesh_part(&cube, local, own, total, Options::default()).unwrap()
        });
    }

    /// A part's errors name its own sites only, as indices into the sites given.
    #[test]
    fn an_own_site_outside_is_named_by_its_index() {
        let square = Polygon::new(
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        )
        .unwrap();
        let sites = [[0.2, 0.2], [0.8, 0.8], [1.5, 0.5], [0.5, 0.5]];
        let err =
            conforming_mesh_part(&square, &sites, &[3, 2], 10, Options::default()).unwrap_err();
        assert!(
            matches!(err, CoreError::SiteOutsideDomain { index: 2, .. }),
            "{err:?}"
        );
    }
}
