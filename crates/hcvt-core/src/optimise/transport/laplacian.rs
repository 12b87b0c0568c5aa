//! The power diagram's graph Laplacian `L = ∂m/∂w`: assembled from the diagram's faces,
//! its product in parallel rows, and the one conjugate-gradient solver of the transport
//! (module docs of [`super`], "Linear solver").

use std::borrow::Cow;

use rayon::prelude::*;

use crate::diagram::{Diagram, DomainKind, FaceIntegrals};
use crate::geometry::{norm2, sub};

/// The graph Laplacian of a power diagram, `c_ij = ∫_{F_ij} ρ / (2|z_i − z_j|)`, in the
/// diagram's face list; row 0 held fixed. It is `∂m/∂w`, the Jacobian of the cells'
/// masses in the weights, which the sites' reduced Hessian also solves with
/// (`reduction::Reduction`).
pub(in crate::optimise) struct Laplacian<'a, const D: usize> {
    pub(super) diagram: &'a Diagram<D>,
    /// `c_e` per face entry (0 for a cell's faces with its own images).
    pub(super) edge: Cow<'a, [f64]>,
    /// Its row sums.
    pub(super) diagonal: Cow<'a, [f64]>,
}

/// Rows of a Laplacian product per parallel task.
const PRODUCT_ROWS: usize = 2048;

/// `z_j − z_i` across face entry `e` of cell `i` of `diagram`: in a periodic box between
/// the wrapped site `i` and the image of `j` it shares the face with.
pub(in crate::optimise) fn to_neighbor<const D: usize, K: DomainKind<D>>(
    diagram: &Diagram<D>,
    sites: &[[f64; D]],
    domain: &K,
    i: usize,
    e: usize,
) -> [f64; D] {
    let j = diagram.neighbor_sites[e] as usize;
    match domain.periodic() {
        Some(t) => {
            let k = diagram.neighbor_images[e];
            let (zi, zj, l) = (t.wrap(sites[i]), t.wrap(sites[j]), t.periods());
            std::array::from_fn(|m| zj[m] + f64::from(k[m]) * l[m] - zi[m])
        }
        None => sub(sites[j], sites[i]),
    }
}

impl<'a, const D: usize> Laplacian<'a, D> {
    /// The Laplacian of `diagram`, its couplings from `face_mass` (`∫_F ρ` per face entry)
    /// or else the face measures ([`Laplacian::couplings`]).
    pub(super) fn new<K: DomainKind<D>>(
        diagram: &'a Diagram<D>,
        face_mass: Option<&FaceIntegrals<D>>,
        sites: &[[f64; D]],
        domain: &K,
    ) -> Self {
        let (edge, diagonal) = Self::couplings(diagram, face_mass, sites, domain);
        Self {
            diagram,
            edge: Cow::Owned(edge),
            diagonal: Cow::Owned(diagonal),
        }
    }

    /// The Laplacian of `diagram` with the couplings `edge` and their row sums `diagonal`
    /// of [`Laplacian::couplings`].
    pub(in crate::optimise) fn borrowed(
        diagram: &'a Diagram<D>,
        edge: &'a [f64],
        diagonal: &'a [f64],
    ) -> Self {
        Self {
            diagram,
            edge: Cow::Borrowed(edge),
            diagonal: Cow::Borrowed(diagonal),
        }
    }

    /// The couplings `c_e` per face entry of `diagram` (`∫_F ρ` from `face_mass` when
    /// given, else the face measure) and their sums per cell.
    pub(in crate::optimise) fn couplings<K: DomainKind<D>>(
        diagram: &Diagram<D>,
        face_mass: Option<&FaceIntegrals<D>>,
        sites: &[[f64; D]],
        domain: &K,
    ) -> (Vec<f64>, Vec<f64>) {
        let n = diagram.len();
        let mut edge = vec![0.0; diagram.neighbor_sites.len()];
        let mut diagonal = vec![0.0; n];
        for (i, sum) in diagonal.iter_mut().enumerate() {
            let faces = diagram.neighbor_offsets[i]..diagram.neighbor_offsets[i + 1];
            for (e, c) in edge
                .iter_mut()
                .enumerate()
                .take(faces.end)
                .skip(faces.start)
            {
                let j = diagram.neighbor_sites[e] as usize;
                if j == i {
                    continue; // a face with its own image: w_i moves both sides
                }
                let q = to_neighbor(diagram, sites, domain, i, e);
                let mass = match face_mass {
                    Some(f) => f.faces[e][0][0],
                    None => diagram.neighbor_measures[e],
                };
                *c = mass / (2.0 * norm2(q).sqrt());
                *sum += *c;
            }
        }
        (edge, diagonal)
    }

    /// `out = L x`.
    fn product(&self, x: &[f64], out: &mut [f64]) {
        let d = self.diagram;
        out.par_chunks_mut(PRODUCT_ROWS)
            .enumerate()
            .for_each(|(c, rows)| {
                for (k, o) in rows.iter_mut().enumerate() {
                    let i = c * PRODUCT_ROWS + k;
                    let mut sum = self.diagonal[i] * x[i];
                    for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                        sum -= self.edge[e] * x[d.neighbor_sites[e] as usize];
                    }
                    *o = sum;
                }
            });
    }

    /// `δ` with `L δ = b` (`b` summing to zero), by conjugate gradients from `start`
    /// (zero when `None`) preconditioned by the diagonal, until every row's residual is within `goal` of its
    /// cell's target mass, relatively (`|r_i| ≤ goal · ν_i`): an ℓ2 criterion would let
    /// the error of the whole system fall on the smallest cells and empty them in the
    /// step. Returns the iterations taken too.
    pub(in crate::optimise) fn solve(
        &self,
        b: &[f64],
        targets: &[f64],
        goal: f64,
        start: Option<Vec<f64>>,
    ) -> (Vec<f64>, usize) {
        let n = b.len();
        // `b` onto the range of `L`: its mean (round-off) removed.
        let mean = b.iter().sum::<f64>() / n as f64;
        let mut r: Vec<f64> = b.iter().map(|b| b - mean).collect();
        let mut x = match start {
            Some(x) => {
                let mut lx = vec![0.0; n];
                self.product(&x, &mut lx);
                r.iter_mut().zip(&lx).for_each(|(r, l)| *r -= l);
                x
            }
            None => vec![0.0; n],
        };
        let done = |r: &[f64]| r.iter().zip(targets).all(|(r, t)| r.abs() <= goal * t);
        let inverse: Vec<f64> = self
            .diagonal
            .iter()
            .map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 })
            .collect();
        // CG ends in at most n steps in exact arithmetic; the cap stops a stagnating solve.
        let (iterations, _) = conjugate_gradients(
            |p, ap| self.product(p, ap),
            |r, z| {
                z.iter_mut()
                    .zip(r.iter().zip(&inverse))
                    .for_each(|(z, (r, m))| *z = r * m);
            },
            &mut x,
            &mut r,
            done,
            10 * n + 100,
        );
        (x, iterations)
    }
}

/// Summed in index order: the same bits on any number of threads.
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Preconditioned conjugate gradients on the symmetric positive semi-definite `A`
/// (`product(p, out)`: `out = A p`) with the preconditioner `precondition(r, z)`
/// (`z = M⁻¹ r`, `M` symmetric positive definite): `x` improved in place from its value,
/// `r = b − A x` given and kept, until `done(r)` or after `max_iterations`. Returns the
/// iterations taken and whether `done` was reached; a breakdown (`r·z` or `p·A p` not
/// positive, or NaN: a solution in the kernel, or round-off) ends it unreached. The one
/// CG of both solvers: by the diagonal ([`Laplacian::solve`]) and by the last Cholesky
/// factor ([`Kept::preconditioned`]). Every dot product is summed in index order.
///
/// [`Kept::preconditioned`]: super::factor::Kept::preconditioned
pub(super) fn conjugate_gradients(
    mut product: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    x: &mut [f64],
    r: &mut [f64],
    done: impl Fn(&[f64]) -> bool,
    max_iterations: usize,
) -> (usize, bool) {
    if done(r) {
        return (0, true);
    }
    let n = r.len();
    let mut z = vec![0.0; n];
    precondition(r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = dot(r, &z);
    for iteration in 1..=max_iterations {
        if rz <= 0.0 || rz.is_nan() {
            return (iteration - 1, false);
        }
        product(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || pap.is_nan() {
            return (iteration - 1, false);
        }
        let alpha = rz / pap;
        x.iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * p);
        r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * a);
        if done(r) {
            return (iteration, true);
        }
        precondition(r, &mut z);
        let rz_next = dot(r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        p.iter_mut().zip(&z).for_each(|(p, z)| *p = z + beta * *p);
    }
    (max_iterations, false)
}
