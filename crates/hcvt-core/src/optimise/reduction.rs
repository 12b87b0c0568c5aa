//! The Hessian of the transport cost in the sites alone, the weights eliminated
//! (`capacity.rs`, Newton with prescribed volumes): the term `B L⁻¹ Bᵀ` that the
//! [`super::hessian::Hessian`] of the power diagram at fixed weights adds to every product.

use crate::diagram::{Diagram, DomainKind, Matrix};
use crate::geometry::{dot, norm2};

use super::transport::{to_neighbor, Laplacian};

/// The term `B L⁻¹ Bᵀ` of the Hessian of the transport cost `W(z) = Φ(z, w(z))` in the
/// sites, the weights `w(z)` eliminated (`capacity.rs`): `∇²W = H_zz + B L⁻¹ Bᵀ`, with
/// `B = ∂g/∂w` and `L = ∂m/∂w` the transport's Laplacian (`−∂²Φ/∂w²`).
#[derive(Debug, Clone, Default)]
pub struct Reduction<const D: usize> {
    /// Per face entry `e` of row `i` (neighbour `j`): `∂g_i/∂w_j = ∫_{F_e} (x − z_i) / |q_e|`,
    /// `q_e = z_j − z_i` across the face; zero on a face with the cell's own image.
    /// `∂g_i/∂w_i` is minus their sum. `L^d`.
    first: Vec<[f64; D]>,
    /// The Laplacian's couplings per face entry and their sums per cell, `L^(d−2)`.
    edge: Vec<f64>,
    diagonal: Vec<f64>,
}

/// Residual of the Laplacian solves inside a reduced Hessian product, per row, relative
/// to the largest entry of the right-hand side: far below the trust region CG's own
/// (`η ≥ 1e-4` or so) so that the product stays symmetric to the precision CG sees.
const REDUCED_SOLVE_TOL: f64 = 1e-8;

impl<const D: usize> Reduction<D> {
    /// The reduction at the power diagram `diagram` of `sites` and `weights`, whose
    /// Hessian at fixed weights has the face blocks `off_diagonal`
    /// ([`super::hessian::Hessian::off_diagonal`], summed in the same pass, no density).
    ///
    /// Each face's first moment about `z_i` is read off its Hessian block: with
    /// `H_e = (2/d)(S_e − s_e qᵀ)` (`S_e` symmetric, `d = |q|`), `(H_e − H_eᵀ) q =
    /// (2/d)(q (s_e·q) − s_e |q|²)`, and on the power face `x·q − z_i·q` is
    /// `(|q|² + w_i − w_j) / 2` everywhere, so `s_e·q` is the face measure times that.
    pub(super) fn new<K: DomainKind<D>>(
        diagram: &Diagram<D>,
        off_diagonal: &[Matrix<D>],
        sites: &[[f64; D]],
        weights: &[f64],
        domain: &K,
    ) -> Self {
        let (edge, diagonal) = Laplacian::couplings(diagram, None, sites, domain);
        let mut first = vec![[0.0; D]; diagram.neighbor_sites.len()];
        for (i, rows) in diagram.neighbor_offsets.windows(2).enumerate() {
            let row = first.iter_mut().enumerate().take(rows[1]).skip(rows[0]);
            for (e, first) in row {
                let j = diagram.neighbor_sites[e] as usize;
                if j == i {
                    continue;
                }
                let q = to_neighbor(diagram, sites, domain, i, e);
                let q2 = norm2(q);
                let d = q2.sqrt();
                let h = &off_diagonal[e];
                let along = diagram.neighbor_measures[e] * 0.5 * (q2 + weights[i] - weights[j]);
                let turned: [f64; D] =
                    std::array::from_fn(|r| (0..D).map(|c| (h[r][c] - h[c][r]) * q[c]).sum());
                *first = std::array::from_fn(|r| (q[r] * along - 0.5 * d * turned[r]) / (q2 * d));
            }
        }
        Self {
            first,
            edge,
            diagonal,
        }
    }

    /// The weights' change `L⁻¹ Bᵀ v` (`L²`, up to a constant) that keeps every cell's
    /// mass when the sites of `diagram` move by `v` (one row per site), to first order.
    /// `Bᵀ v` is summed in index order and the solve is serial in its sums: independent
    /// of the thread count.
    pub fn weight_change(&self, diagram: &Diagram<D>, v: &[[f64; D]]) -> Vec<f64> {
        let n = diagram.len();
        let mut bt_v = vec![0.0; n];
        for (i, rows) in diagram.neighbor_offsets.windows(2).enumerate() {
            for e in rows[0]..rows[1] {
                let t = dot(self.first[e], v[i]);
                bt_v[diagram.neighbor_sites[e] as usize] += t;
                bt_v[i] -= t;
            }
        }
        let scale = bt_v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        if scale == 0.0 {
            return vec![0.0; n];
        }
        let laplacian = Laplacian::borrowed(diagram, &self.edge, &self.diagonal);
        laplacian
            .solve(&bt_v, &vec![scale; n], REDUCED_SOLVE_TOL, None)
            .0
    }

    /// Add `B L⁻¹ Bᵀ v` to `out` (one row per site), in index order.
    pub fn add_product(&self, diagram: &Diagram<D>, v: &[[f64; D]], out: &mut [[f64; D]]) {
        let u = self.weight_change(diagram, v);
        for (i, (o, rows)) in out
            .iter_mut()
            .zip(diagram.neighbor_offsets.windows(2))
            .enumerate()
        {
            for e in rows[0]..rows[1] {
                let du = u[diagram.neighbor_sites[e] as usize] - u[i];
                *o = std::array::from_fn(|k| o[k] + self.first[e][k] * du);
            }
        }
    }

    /// The reduction for the sites renamed by `order`, faces moved as `faces` says
    /// ([`super::hessian::Hessian::reordered`]).
    pub fn reordered(&self, order: &[u32], faces: &[usize]) -> Self {
        let mut diagonal = vec![0.0; self.diagonal.len()];
        for (k, &i) in order.iter().enumerate() {
            diagonal[i as usize] = self.diagonal[k];
        }
        Self {
            first: faces.iter().map(|&e| self.first[e]).collect(),
            edge: faces.iter().map(|&e| self.edge[e]).collect(),
            diagonal,
        }
    }
}
