//! Each cell's faces, summed over its signed pieces (DESIGN §3, step 5): the measure of the
//! faces shared with each neighbour (the restricted Delaunay edges), the cell's share of
//! the domain boundary, and, for the Hessian of the CVT energy (DESIGN §4), the integrals
//! over the faces between cells.

use rayon::prelude::*;

use crate::geometry::{add, dot, norm2, sub};
use crate::moments::{FaceMoments, Moments};

use super::convex_cell::{ConvexCell, Face};
use super::Diagram;

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

/// What a cell's row of the [`Hessian`] needs besides its faces: every site, and which one
/// is the cell's.
#[derive(Debug, Clone, Copy)]
pub(super) struct HessianRow<'a, const D: usize> {
    pub(super) sites: &'a [[f64; D]],
    pub(super) site: usize,
}

#[inline]
fn mat_vec<const D: usize>(m: &[[f64; D]; D], v: [f64; D]) -> [f64; D] {
    m.map(|row| dot(row, v))
}

/// Signed face measures of a cell, summed over its pieces, and for the Hessian the
/// integrals over its faces; buffers reused from cell to cell.
#[derive(Debug)]
pub(super) struct FaceSums<const D: usize> {
    pub(super) neighbors: Vec<(u32, f64)>,
    /// With the Hessian: `H_ij = (2/d_ij) ∫_{F_ij} y (y − q_ij)ᵀ` (`y = x − x_i`,
    /// `q_ij = x_j − x_i`) for each entry of `neighbors`; else empty.
    pub(super) blocks: Vec<Block<D>>,
    /// With the Hessian: `Σ_j (2/d_ij) ∫_{F_ij} y yᵀ`.
    face_second: Block<D>,
    pub(super) boundary: f64,
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
    pub(super) fn clear(&mut self) {
        self.neighbors.clear();
        self.blocks.clear();
        self.face_second = [[0.0; D]; D];
        self.boundary = 0.0;
    }

    /// Add the faces of `piece` with `sign` (and their Hessian terms, for a `hessian`
    /// row), and return its moments (not signed).
    pub(super) fn integrate<C: ConvexCell<D>>(
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
    pub(super) fn add(&mut self, face: Face, measure: f64) -> Option<usize> {
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
    pub(super) fn hessian_diagonal(&self, mass: f64) -> Block<D> {
        std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                let diagonal = if r == c { 2.0 * mass } else { 0.0 };
                diagonal - self.face_second[r][c]
            })
        })
    }

    /// Keep the faces of positive measure, sorted by neighbour, with their Hessian blocks
    /// if kept: both lists together, in place.
    pub(super) fn sort_neighbors(&mut self) {
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
                sum = add(sum, mat_vec(&h.off_diagonal[e], v[j]));
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
