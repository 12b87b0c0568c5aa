//! The direct solve of `L δ = b`: `L` grounded at one cell, factorised by faer's sparse
//! Cholesky, its AMD ordering and last factor kept from one Newton step to the next
//! (module docs of [`super`], "Linear solver").

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};

use super::laplacian::{conjugate_gradients, Laplacian};

/// A factorisation whose factor holds more than this many entries a row (supernodal
/// storage) is not carried out: the conjugate gradients solve the system instead. 2D
/// diagrams gave 17 to 21 with AMD at 10,000 sites; 3D ones 200 to 250 at 5,000, where CG
/// needs only 6 to 104 iterations a step.
const MAX_FILL_PER_ROW: usize = 60;

impl<const D: usize> Laplacian<'_, D> {
    /// `δ` with `L δ = b` by a sparse Cholesky factorisation (faer, serial), or `None`
    /// when it does not apply: a diagram whose face graph is not connected, a factor too
    /// full (`MAX_FILL_PER_ROW`) or a failed factorisation. `L` is singular by the
    /// constants; one weight, of the cell with the largest coupling, is held fixed (its
    /// row and column replaced by the identity): the others' equations then hold to
    /// round-off, and the fixed cell's through their sum, `b` summing to zero. The matrix
    /// is symmetrised, each face's coupling read from its lower-numbered cell and the
    /// diagonal summed from the couplings, so that it is exactly positive semi-definite.
    /// The fill-reducing ordering is AMD's, or an earlier step's while its factor stays
    /// small ([`analyse`]); the symbolic factorisation is the last step's when the matrix
    /// has its pattern ([`Kept`]). Before factorising, the system is solved to `goal`
    /// (relative to `targets`, as [`Laplacian::solve`]) by conjugate gradients
    /// preconditioned by the last factorisation, when there is one
    /// ([`Kept::preconditioned`]), unless `refresh` asks for this matrix's own factor
    /// ([`REFACTORISE_BELOW`]); the iterations are returned with the solution.
    ///
    /// [`REFACTORISE_BELOW`]: super::REFACTORISE_BELOW
    pub(super) fn direct(
        &self,
        b: &[f64],
        targets: &[f64],
        goal: f64,
        kept: &mut Kept,
        refresh: bool,
    ) -> Option<(Vec<f64>, usize)> {
        let n = b.len();
        if n < 2 {
            return None;
        }
        let held = kept.analysed.as_ref().map(|a| a.fixed).filter(|&f| f < n);
        let (matrix, fixed) = self.grounded(held)?;
        let par = Par::Seq;
        let mean = b.iter().sum::<f64>() / n as f64;
        let mut x: Vec<f64> = b.iter().map(|b| b - mean).collect();
        x[fixed] = 0.0;
        if !refresh {
            if let Some(solved) = kept.preconditioned(&matrix, fixed, &x, targets, goal) {
                return Some(solved);
            }
        }
        let pattern = matrix.symbolic();
        let same = kept.analysed.as_ref().is_some_and(|a| {
            a.fixed == fixed && a.col_ptr == pattern.col_ptr() && a.rows == pattern.row_idx()
        });
        if !same {
            // A refreshed factor takes a fresh ordering: the kept one, the first step's, had
            // let the fill grow past `REUSE_FILL` by then (the benchmark's square and
            // L-shape at 10,000 sites), so its analysis, tried first, was wasted: 2% of
            // the run's instructions.
            if refresh {
                kept.ordering = None;
            }
            let symbolic = analyse(&matrix, &mut kept.ordering)?;
            kept.analysed = Some(Analysed {
                fixed,
                col_ptr: pattern.col_ptr().to_vec(),
                rows: pattern.row_idx().to_vec(),
                symbolic,
            });
        }
        kept.values = None;
        let symbolic = &kept.analysed.as_ref()?.symbolic;
        if symbolic.len_val() > MAX_FILL_PER_ROW * n {
            return None;
        }
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mut memory = MemBuffer::try_new(scratch).ok()?;
        let mut values = vec![0.0; symbolic.len_val()];
        let factor = symbolic
            .factorize_numeric_llt(
                &mut values,
                matrix.as_ref(),
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut memory),
                Default::default(),
            )
            .ok()?;
        factor.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut x, n, 1),
            par,
            MemStack::new(&mut memory),
        );
        if !x.iter().all(|x| x.is_finite()) {
            return None;
        }
        kept.values = Some(values);
        Some((x, 0))
    }

    /// The symmetrised Laplacian's lower triangle in compressed columns with the row and
    /// column of cell `held` (when given), else of the cell with the largest diagonal,
    /// replaced by the identity, and that cell; `None` when the face graph is not
    /// connected (a zero coupling counts as none).
    fn grounded(&self, held: Option<usize>) -> Option<(SparseColMat<usize, f64>, usize)> {
        let d = self.diagram;
        let n = d.len();
        // Each column's couplings to higher-numbered cells, merged (a periodic cell can
        // meet one neighbour through two of its images).
        let mut lower_ptr = Vec::with_capacity(n + 1);
        let mut lower: Vec<(usize, f64)> = Vec::with_capacity(d.neighbor_sites.len() / 2 + n);
        let mut diagonal = vec![0.0; n];
        let mut components = Components::new(n);
        lower_ptr.push(0);
        for i in 0..n {
            let from = lower.len();
            for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                let j = d.neighbor_sites[e] as usize;
                if j > i && self.edge[e] > 0.0 {
                    lower.push((j, self.edge[e]));
                }
            }
            lower[from..].sort_unstable_by_key(|&(j, _)| j);
            let mut kept = from;
            for k in from..lower.len() {
                if kept > from && lower[kept - 1].0 == lower[k].0 {
                    lower[kept - 1].1 += lower[k].1;
                } else {
                    lower[kept] = lower[k];
                    kept += 1;
                }
            }
            lower.truncate(kept);
            for &(j, c) in &lower[from..] {
                diagonal[i] += c;
                diagonal[j] += c;
                components.join(i, j);
            }
            lower_ptr.push(lower.len());
        }
        if !components.connected() {
            return None;
        }
        let fixed = held.unwrap_or_else(|| {
            (0..n).fold(0, |best, i| {
                if diagonal[i] > diagonal[best] {
                    i
                } else {
                    best
                }
            })
        });
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut rows = Vec::with_capacity(lower.len() + n);
        let mut values = Vec::with_capacity(lower.len() + n);
        col_ptr.push(0);
        for i in 0..n {
            rows.push(i);
            if i == fixed {
                values.push(1.0);
            } else {
                values.push(diagonal[i]);
                for &(j, c) in &lower[lower_ptr[i]..lower_ptr[i + 1]] {
                    if j != fixed {
                        rows.push(j);
                        values.push(-c);
                    }
                }
            }
            col_ptr.push(rows.len());
        }
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows);
        Some((SparseColMat::new(pattern, values), fixed))
    }
}

/// An AMD ordering kept from one Newton step to the next ([`analyse`]): `forward[k]` the
/// cell eliminated `k`-th, `inverse` its inverse, and `fill` the entries of the factor it
/// gave when it was computed.
struct Ordering {
    forward: Vec<usize>,
    inverse: Vec<usize>,
    fill: usize,
}

/// What the factorisations of a run keep from step to step: the AMD ordering
/// ([`analyse`]), the last symbolic factorisation with the pattern it was made for, and
/// the last numeric factor, a preconditioner for later steps ([`Kept::preconditioned`]).
/// Why: the symbolic analysis and AMD took 22% of the transport's samples at 100,000
/// sites (perf, one thread, the square, power cells started from their neighbours), and
/// once Newton converges the faces stop changing: the last steps' matrices have the
/// pattern of their predecessors', the weight held fixed being the first step's.
#[derive(Default)]
pub(super) struct Kept {
    ordering: Option<Ordering>,
    analysed: Option<Analysed>,
    /// The numeric factor of `analysed` (its values), from the last factorisation.
    values: Option<Vec<f64>>,
}

/// Most iterations of [`Kept::preconditioned`] before the system is factorised afresh.
const PRECONDITIONED_ITERATIONS: usize = 30;

impl Kept {
    /// Whether there is a factor, which a fresh one could replace ([`REFACTORISE_BELOW`]).
    ///
    /// [`REFACTORISE_BELOW`]: super::REFACTORISE_BELOW
    pub(super) fn has_factor(&self) -> bool {
        self.values.is_some() && self.analysed.is_some()
    }

    /// `x` with `A x = rhs` (`A` the grounded Laplacian `matrix`, lower triangle, cell
    /// `fixed` held; `rhs[fixed] = 0`) by conjugate gradients preconditioned by the last
    /// factorisation, an earlier step's matrix with the same cell held, and the iterations
    /// taken; `None` when there is none or it does not reach `goal` within
    /// [`PRECONDITIONED_ITERATIONS`]. Reached: every row's residual within `goal` of its
    /// cell's target (`|r_i| ≤ goal · ν_i`), the held cell's too (`−Σ r_i`, the columns of
    /// the symmetrised Laplacian summing to zero).
    fn preconditioned(
        &self,
        matrix: &SparseColMat<usize, f64>,
        fixed: usize,
        rhs: &[f64],
        targets: &[f64],
        goal: f64,
    ) -> Option<(Vec<f64>, usize)> {
        let analysed = self.analysed.as_ref().filter(|a| a.fixed == fixed)?;
        let values = self.values.as_ref()?;
        let n = rhs.len();
        if analysed.symbolic.nrows() != n {
            return None;
        }
        let factor = LltRef::new(&analysed.symbolic, values);
        let par = Par::Seq;
        let mut memory =
            MemBuffer::try_new(analysed.symbolic.solve_in_place_scratch::<f64>(1, par)).ok()?;
        let precondition = |r: &[f64], z: &mut [f64]| {
            z.copy_from_slice(r);
            factor.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(z, n, 1),
                par,
                MemStack::new(&mut memory),
            );
        };
        let done = |r: &[f64]| {
            r.iter().zip(targets).all(|(r, t)| r.abs() <= goal * t)
                && r.iter().sum::<f64>().abs() <= goal * targets[fixed]
        };
        let mut x = vec![0.0; n];
        let mut r = rhs.to_vec();
        let (iterations, reached) = conjugate_gradients(
            |p, ap| symmetric_product(matrix, p, ap),
            precondition,
            &mut x,
            &mut r,
            done,
            PRECONDITIONED_ITERATIONS,
        );
        (reached && x.iter().all(|x| x.is_finite())).then_some((x, iterations))
    }
}

/// `out = A x` for the symmetric `A` of which `matrix` holds the lower triangle.
fn symmetric_product(matrix: &SparseColMat<usize, f64>, x: &[f64], out: &mut [f64]) {
    let (col_ptr, rows, values) = (
        matrix.symbolic().col_ptr(),
        matrix.symbolic().row_idx(),
        matrix.val(),
    );
    out.fill(0.0);
    for (j, &xj) in x.iter().enumerate() {
        let mut sum = 0.0;
        // Column j's rows and values as slices: no bounds check of theirs in the loop.
        let column = col_ptr[j]..col_ptr[j + 1];
        for (&i, &v) in rows[column.clone()].iter().zip(&values[column]) {
            out[i] += v * xj;
            if i != j {
                sum += v * x[i];
            }
        }
        out[j] += sum;
    }
}

/// A symbolic factorisation and the matrix pattern it was made for: the grounded cell and
/// the lower triangle's compressed columns.
struct Analysed {
    fixed: usize,
    col_ptr: Vec<usize>,
    rows: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
}

/// A kept ordering is used while its factor holds at most this factor more entries than
/// when AMD computed it.
const REUSE_FILL: f64 = 1.1;

/// The symbolic Cholesky factorisation of `matrix` (lower triangle) with the ordering kept
/// in `kept` if its factor is at most `REUSE_FILL` times as full as when it was computed,
/// else with a fresh AMD ordering, then kept. Why: AMD took 12% of the transport's time at
/// 100,000 sites (one ordering a step); the faces change little from step to step once
/// Newton converges (72 of 29,641 faces at 10,000 sites in the fourth step, none after),
/// but the first step's ordering kept for all had let the factor grow from 17 to 165
/// entries a row, the faces having moved, hence the check. Tried and not kept: a
/// geometric nested dissection by the sites' coordinates (no AMD at all): its factor,
/// about `n log n`, passed `MAX_FILL_PER_ROW` at 100,000 sites.
fn analyse(
    matrix: &SparseColMat<usize, f64>,
    kept: &mut Option<Ordering>,
) -> Option<SymbolicCholesky<usize>> {
    let n = matrix.ncols();
    if let Some(k) = kept.as_ref().filter(|k| k.forward.len() == n) {
        let reused = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            SymmetricOrdering::Custom(PermRef::new_checked(&k.forward, &k.inverse, n)),
            CholeskySymbolicParams::default(),
        )
        .ok()
        .filter(|s| s.len_val() as f64 <= REUSE_FILL * k.fill as f64);
        if reused.is_some() {
            return reused;
        }
    }
    let fresh = factorize_symbolic_cholesky(
        matrix.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .ok()?;
    *kept = fresh.perm().map(|p| {
        let (forward, inverse) = p.arrays();
        Ordering {
            forward: forward.to_vec(),
            inverse: inverse.to_vec(),
            fill: fresh.len_val(),
        }
    });
    Some(fresh)
}

/// Union–find over the cells, to tell whether the face graph is connected.
struct Components {
    parent: Vec<usize>,
}

impl Components {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn join(&mut self, i: usize, j: usize) {
        let (a, b) = (self.root(i), self.root(j));
        if a != b {
            self.parent[a.max(b)] = a.min(b);
        }
    }

    fn connected(&mut self) -> bool {
        (0..self.parent.len()).all(|i| self.root(i) == 0)
    }
}
