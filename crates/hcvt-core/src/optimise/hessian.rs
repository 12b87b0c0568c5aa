//! The exact Hessian of the CVT energy (DESIGN §4, Liu et al. 2009 §3) for Newton's method:
//! its face terms as a [`FaceIntegrand`] that the diagram sums over each cell's faces in the
//! pass that measures them ([`HessianTerms`]), the [`Hessian`] assembled from those sums and
//! the cells' masses, its product with a vector, and its rows renamed with the diagram's.

use rayon::prelude::*;

use crate::diagram::{Diagram, DomainKind, FaceIntegrals, FaceIntegrand, Matrix};
use crate::geometry::{add, dot, norm2, sub};
use crate::moments::FaceMoments;

use super::reduction::Reduction;

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
    /// With prescribed volumes, the term `B L⁻¹ Bᵀ` of the weights eliminated, added to
    /// every product (the Hessian of the transport cost in the sites alone).
    pub reduction: Option<Box<Reduction<D>>>,
}

/// A `D × D` block of the [`Hessian`], row-major.
pub type Block<const D: usize> = Matrix<D>;

/// The face terms of the [`Hessian`] of the diagram of `sites`: per face
/// `H_ij = (2/d_ij) ∫_{F_ij} y (y − q_ij)ᵀ` (`y = x − x_i`, `q_ij = x_j − x_i`), per cell
/// `Σ_j (2/d_ij) ∫_{F_ij} y yᵀ`.
#[derive(Debug, Clone, Copy)]
pub struct HessianTerms<'a, const D: usize> {
    /// Every site, `L`.
    pub sites: &'a [[f64; D]],
}

impl<const D: usize> FaceIntegrand<D> for HessianTerms<'_, D> {
    fn add(
        &self,
        i: usize,
        j: usize,
        to_neighbor: Option<[f64; D]>,
        sign: f64,
        m: &FaceMoments<D>,
        face: &mut Matrix<D>,
        cell: &mut Matrix<D>,
    ) {
        // Across a periodic box's face the neighbour is an image of site `j`.
        let q = to_neighbor.unwrap_or_else(|| sub(self.sites[j], self.sites[i]));
        let w = sign * 2.0 / norm2(q).sqrt();
        let rows = face.iter_mut().zip(cell.iter_mut());
        for ((block_row, face_row), (s2_row, &s1)) in rows.zip(m.second.iter().zip(&m.first)) {
            let entries = block_row.iter_mut().zip(face_row.iter_mut());
            for ((b, f), (&s2, &qc)) in entries.zip(s2_row.iter().zip(&q)) {
                *b += w * (s2 - s1 * qc);
                *f += w * s2;
            }
        }
    }
}

impl<const D: usize> Hessian<D> {
    /// The Hessian of `diagram` from the sums of its [`HessianTerms`]:
    /// `H_ii = 2 m_i I − Σ_j (2/d_ij) ∫_{F_ij} y yᵀ`, and the face terms as they are.
    pub fn new(diagram: &Diagram<D>, terms: FaceIntegrals<D>) -> Self {
        let diagonal = diagram
            .mass_moments()
            .iter()
            .zip(&terms.cells)
            .map(|(m, face_second)| {
                std::array::from_fn(|r| {
                    std::array::from_fn(|c| {
                        let diagonal = if r == c { 2.0 * m.mass } else { 0.0 };
                        diagonal - face_second[r][c]
                    })
                })
            })
            .collect();
        Self {
            diagonal,
            off_diagonal: terms.faces,
            reduction: None,
        }
    }

    /// The product `H v` with `v` (one row per site) over the neighbours of `diagram`. Rows
    /// in parallel, each summed in neighbour order: the result does not depend on the
    /// thread count.
    pub fn product(&self, diagram: &Diagram<D>, v: &[[f64; D]]) -> Vec<[f64; D]> {
        let mut out = vec![[0.0; D]; diagram.len()];
        self.product_into(diagram, v, &mut out);
        out
    }

    /// [`Hessian::product`] into `out` (one row per site).
    pub fn product_into(&self, diagram: &Diagram<D>, v: &[[f64; D]], out: &mut [[f64; D]]) {
        let row = |i: usize| -> [f64; D] {
            let mut sum = mat_vec(&self.diagonal[i], v[i]);
            for e in diagram.neighbor_offsets[i]..diagram.neighbor_offsets[i + 1] {
                let j = diagram.neighbor_sites[e] as usize;
                sum = add(sum, mat_vec(&self.off_diagonal[e], v[j]));
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
        if let Some(reduction) = &self.reduction {
            reduction.add_product(diagram, v, out);
        }
    }

    /// The Riemannian Hessian on a curved domain (the sphere, DESIGN §13) from the ambient
    /// one (`self`, whose face terms the domain measured on its curved faces) at `sites`
    /// with ambient gradients `gradient`: `P_i H_ij P_j`, and on the diagonal also
    /// `− c_i P_i` with `c_i` the domain's [`DomainKind::curvature_term`] (Absil, Mahony and
    /// Sepulchre 2008, §5.5: on the unit sphere `Hess f = P ∇²f P − (x·∇f) P`). `P_i` is
    /// the projection onto the tangent plane at site `i` ([`DomainKind::tangent`]).
    pub fn along<K: DomainKind<D>>(
        &mut self,
        domain: &K,
        diagram: &Diagram<D>,
        sites: &[[f64; D]],
        gradient: &[[f64; D]],
    ) {
        let project = |b: &Block<D>, xi: [f64; D], xj: [f64; D]| -> Block<D> {
            // `B P_j` row by row (P symmetric), then `P_i` on each column.
            let right = b.map(|row| domain.tangent(xj, row));
            let columns: [[f64; D]; D] =
                std::array::from_fn(|c| domain.tangent(xi, std::array::from_fn(|r| right[r][c])));
            std::array::from_fn(|r| std::array::from_fn(|c| columns[c][r]))
        };
        self.diagonal
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, block)| {
                let x = sites[i];
                let c = domain.curvature_term(x, gradient[i]);
                *block = project(block, x, x);
                for (r, row) in block.iter_mut().enumerate() {
                    let unit: [f64; D] = std::array::from_fn(|k| if k == r { 1.0 } else { 0.0 });
                    for (b, p) in row.iter_mut().zip(domain.tangent(x, unit)) {
                        *b -= c * p;
                    }
                }
            });
        let rows: Vec<u32> = (0..diagram.len())
            .flat_map(|i| {
                let count = diagram.neighbor_offsets[i + 1] - diagram.neighbor_offsets[i];
                std::iter::repeat_n(i as u32, count)
            })
            .collect();
        self.off_diagonal
            .par_iter_mut()
            .zip(rows.par_iter().zip(&diagram.neighbor_sites))
            .for_each(|(block, (&i, &j))| {
                *block = project(block, sites[i as usize], sites[j as usize]);
            });
    }

    /// The Hessian for the sites renamed by `order`, with the diagram's face entries moved
    /// as [`Diagram::reordered_faces`] moved them (`faces[e]` the old entry of new entry `e`).
    pub fn reordered(&self, order: &[u32], faces: &[usize]) -> Self {
        let mut diagonal = vec![[[0.0; D]; D]; self.diagonal.len()];
        for (k, &i) in order.iter().enumerate() {
            diagonal[i as usize] = self.diagonal[k];
        }
        Self {
            diagonal,
            off_diagonal: faces.iter().map(|&e| self.off_diagonal[e]).collect(),
            reduction: (self.reduction.as_ref()).map(|r| Box::new(r.reordered(order, faces))),
        }
    }
}

#[inline]
fn mat_vec<const D: usize>(m: &Matrix<D>, v: [f64; D]) -> [f64; D] {
    m.map(|row| dot(row, v))
}

/// Rows of a Hessian product per parallel task: some 5 (2D) to 25 (3D) microseconds of
/// work each. With 1,024 the product of a 1,000-site problem was one task, and the CG
/// iterations (10-13% of a Newton run) kept one of two threads idle.
const PRODUCT_ROWS: usize = 256;
