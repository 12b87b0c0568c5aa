//! The L-BFGS memory and its two-loop recursion, over the sites or over the Gram matrix of
//! a partitioned run's pairs (module docs of [`super`]).

use std::collections::VecDeque;

use crate::error::CoreError;
use crate::geometry::dot;

use super::rows::{axpy, dot_rows};

/// One correction pair `s = x_{k+1} − x_k`, `y = g_{k+1} − g_k`, `rho = 1/(s·y)`.
#[derive(Debug, Clone)]
struct Pair<const D: usize> {
    s: Vec<[f64; D]>,
    y: Vec<[f64; D]>,
    rho: f64,
}

/// The last `capacity` correction pairs.
#[derive(Debug, Clone)]
pub struct Memory<const D: usize> {
    pairs: VecDeque<Pair<D>>,
    capacity: usize,
}

impl<const D: usize> Memory<D> {
    /// An empty memory that keeps `capacity` pairs (at least one).
    pub fn new(capacity: usize) -> Self {
        Self {
            pairs: VecDeque::new(),
            capacity: capacity.max(1),
        }
    }

    /// Forget every pair (after a reseed or a Lloyd step the curvature is stale).
    pub fn clear(&mut self) {
        self.pairs.clear();
    }

    /// Number of pairs held.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// No pairs held.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Add the pair from `x → x + s` with gradient change `y`, dropping the oldest when
    /// full. A pair without positive curvature (`s·y ≤ eps |s| |y|`) would make the
    /// update indefinite and is skipped; returns whether it was kept.
    pub fn push(&mut self, s: Vec<[f64; D]>, y: Vec<[f64; D]>) -> bool {
        let sy = dot_rows(&s, &y);
        if !positive_curvature(sy, dot_rows(&s, &s), dot_rows(&y, &y)) {
            return false;
        }
        if self.pairs.len() == self.capacity {
            self.pairs.pop_front();
        }
        self.pairs.push_back(Pair {
            s,
            y,
            rho: 1.0 / sy,
        });
        true
    }

    /// The quasi-Newton direction `−H g` by the two-loop recursion (one for both drivers), with
    /// `H0 = γ P`, `P` the diagonal `preconditioner[i]` on the coordinates of site `i`.
    pub fn direction(&self, gradient: &[[f64; D]], preconditioner: &[f64]) -> Vec<[f64; D]> {
        let sites = Sites {
            memory: self,
            gradient,
            preconditioner,
        };
        let r = two_loop(&sites);
        r.iter().map(|v| v.map(|x| -x)).collect()
    }
}

/// Whether a pair with these products has positive curvature, `s·y > eps |s| |y|`; NaN
/// has not. A pair without would make the update indefinite.
pub fn positive_curvature(sy: f64, ss: f64, yy: f64) -> bool {
    let scale = (ss * yy).sqrt();
    sy.partial_cmp(&(f64::EPSILON * scale)) == Some(std::cmp::Ordering::Greater)
}

/// The vectors a two-loop recursion works on, and its operations on them: the gradient
/// `g`, the pairs `(s_k, y_k)` oldest first, the diagonal preconditioner `P`.
///
/// Two spaces implement it, so that one recursion serves both drivers: the per-site
/// arrays of one process ([`Memory::direction`]), and, in a partitioned run where the
/// vectors are spread over the parts, coefficients over `[s, y, g]` whose inner products
/// come from Gram matrices summed over the parts ([`gram_coefficients`]).
trait TwoLoopSpace {
    type Vector;
    /// Pairs held.
    fn pairs(&self) -> usize;
    /// `1 / (s_k · y_k)`.
    fn rho(&self, k: usize) -> f64;
    /// `y_k · P y_k`.
    fn y_weighted_y(&self, k: usize) -> f64;
    /// `g`.
    fn gradient(&self) -> Self::Vector;
    /// `s_k · v`.
    fn s_dot(&self, k: usize, v: &Self::Vector) -> f64;
    /// `y_k · v`.
    fn y_dot(&self, k: usize, v: &Self::Vector) -> f64;
    /// `v += t y_k`.
    fn add_y(&self, v: &mut Self::Vector, k: usize, t: f64);
    /// `v += t s_k`.
    fn add_s(&self, v: &mut Self::Vector, k: usize, t: f64);
    /// `γ P v`.
    fn precondition(&self, v: Self::Vector, gamma: f64) -> Self::Vector;
}

/// `H g` by the two-loop recursion (Nocedal 1980) with `H0 = γ P` and `γ = s·y / yᵀP y`
/// from the newest pair (Oren–Luenberger scaling; `γ = 1` with no pairs).
fn two_loop<S: TwoLoopSpace>(space: &S) -> S::Vector {
    let m = space.pairs();
    let gamma = match m.checked_sub(1) {
        Some(newest) => 1.0 / (space.rho(newest) * space.y_weighted_y(newest)),
        None => 1.0,
    };
    let mut q = space.gradient();
    let mut alphas = vec![0.0; m];
    for (k, alpha) in alphas.iter_mut().enumerate().rev() {
        let a = space.rho(k) * space.s_dot(k, &q);
        space.add_y(&mut q, k, -a);
        *alpha = a;
    }
    let mut r = space.precondition(q, gamma);
    for (k, &a) in alphas.iter().enumerate() {
        let b = space.rho(k) * space.y_dot(k, &r);
        space.add_s(&mut r, k, a - b);
    }
    r
}

/// The per-site arrays of one process: sums over the sites in index order.
struct Sites<'a, const D: usize> {
    memory: &'a Memory<D>,
    gradient: &'a [[f64; D]],
    preconditioner: &'a [f64],
}

impl<const D: usize> Sites<'_, D> {
    fn pair(&self, k: usize) -> &Pair<D> {
        &self.memory.pairs[k]
    }
}

impl<const D: usize> TwoLoopSpace for Sites<'_, D> {
    type Vector = Vec<[f64; D]>;

    fn pairs(&self) -> usize {
        self.memory.pairs.len()
    }

    fn rho(&self, k: usize) -> f64 {
        self.pair(k).rho
    }

    fn y_weighted_y(&self, k: usize) -> f64 {
        (self.pair(k).y.iter())
            .zip(self.preconditioner)
            .map(|(&y, &w)| w * dot(y, y))
            .sum()
    }

    fn gradient(&self) -> Self::Vector {
        self.gradient.to_vec()
    }

    fn s_dot(&self, k: usize, v: &Self::Vector) -> f64 {
        dot_rows(&self.pair(k).s, v)
    }

    fn y_dot(&self, k: usize, v: &Self::Vector) -> f64 {
        dot_rows(&self.pair(k).y, v)
    }

    fn add_y(&self, v: &mut Self::Vector, k: usize, t: f64) {
        axpy(v, t, &self.pair(k).y);
    }

    fn add_s(&self, v: &mut Self::Vector, k: usize, t: f64) {
        axpy(v, t, &self.pair(k).s);
    }

    fn precondition(&self, v: Self::Vector, gamma: f64) -> Self::Vector {
        v.iter()
            .zip(self.preconditioner)
            .map(|(v, &w)| v.map(|x| gamma * w * x))
            .collect()
    }
}

/// Inner products of `[s_0..s_{m-1}, y_0..y_{m-1}, g]`, row-major `(2m+1) × (2m+1)`:
/// `plain[a][b] = v_a · v_b`, `weighted[a][b] = v_a · P v_b`.
struct Gram<'a> {
    m: usize,
    plain: &'a [f64],
    weighted: &'a [f64],
}

/// A vector of the partitioned two-loop: `Σ_j c_j v_j` over `v = [y_0..y_{m-1}, g]`, with
/// `P` in front once preconditioned, plus `Σ_k e_k s_k`.
struct Combination {
    c: Vec<f64>,
    preconditioned: bool,
    e: Vec<f64>,
}

impl Gram<'_> {
    fn entry(&self, matrix: &[f64], a: usize, b: usize) -> f64 {
        matrix[a * (2 * self.m + 1) + b]
    }

    /// `u_a · v` for basis vector `a`, summed in order: the `v` part, then the `s` part.
    fn dot(&self, a: usize, v: &Combination) -> f64 {
        let matrix = if v.preconditioned {
            self.weighted
        } else {
            self.plain
        };
        let mut over_v = 0.0;
        for (j, &c) in v.c.iter().enumerate() {
            over_v += self.entry(matrix, a, self.m + j) * c;
        }
        if !v.preconditioned {
            return over_v;
        }
        let mut over_s = 0.0;
        for (k, &e) in v.e.iter().enumerate() {
            over_s += self.entry(self.plain, a, k) * e;
        }
        over_v + over_s
    }
}

impl TwoLoopSpace for Gram<'_> {
    type Vector = Combination;

    fn pairs(&self) -> usize {
        self.m
    }

    fn rho(&self, k: usize) -> f64 {
        1.0 / self.entry(self.plain, k, self.m + k)
    }

    fn y_weighted_y(&self, k: usize) -> f64 {
        self.entry(self.weighted, self.m + k, self.m + k)
    }

    fn gradient(&self) -> Self::Vector {
        let mut c = vec![0.0; self.m + 1];
        c[self.m] = 1.0;
        Combination {
            c,
            preconditioned: false,
            e: vec![0.0; self.m],
        }
    }

    fn s_dot(&self, k: usize, v: &Self::Vector) -> f64 {
        self.dot(k, v)
    }

    fn y_dot(&self, k: usize, v: &Self::Vector) -> f64 {
        self.dot(self.m + k, v)
    }

    fn add_y(&self, v: &mut Self::Vector, k: usize, t: f64) {
        // `P` in front would need `P y_k`, which the basis has not; the recursion adds
        // `y_k` only before preconditioning.
        debug_assert!(!v.preconditioned);
        v.c[k] += t;
    }

    fn add_s(&self, v: &mut Self::Vector, k: usize, t: f64) {
        v.e[k] += t;
    }

    fn precondition(&self, v: Self::Vector, gamma: f64) -> Self::Vector {
        debug_assert!(v.e.iter().all(|&e| e == 0.0));
        Combination {
            c: v.c.iter().map(|&c| gamma * c).collect(),
            preconditioned: true,
            e: v.e,
        }
    }
}

/// The two-loop recursion of [`Memory::direction`] in coefficient space (vector-free
/// L-BFGS, Chen et al. 2014), for a run whose vectors are spread over parts.
///
/// `plain` and `weighted` are the Gram matrices of `[s_0..s_{m-1}, y_0..y_{m-1}, g]`
/// (row-major, `(2m+1)²` entries; `weighted` with `P` between), each the sum of the parts'
/// partial matrices. Returns `(c, e)` with `H g = P Σ_j c_j v_j + Σ_k e_k s_k`,
/// `v = [y_0..y_{m-1}, g]`: each part forms its rows of the direction from its own vectors
/// ([`combine`]).
///
/// Errors: `plain` or `weighted` not of a size `(2m+1)²`, or of different sizes.
pub fn gram_coefficients(
    plain: &[f64],
    weighted: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), CoreError> {
    let side = (plain.len() as f64).sqrt().round() as usize;
    if side % 2 != 1 || side * side != plain.len() {
        return Err(CoreError::ShapeMismatch {
            what: "Gram matrix of [s, y, g], (2m+1)^2 entries",
            expected: (side | 1) * (side | 1),
            got: plain.len(),
        });
    }
    if weighted.len() != plain.len() {
        return Err(CoreError::ShapeMismatch {
            what: "weighted Gram matrix",
            expected: plain.len(),
            got: weighted.len(),
        });
    }
    let gram = Gram {
        m: side / 2,
        plain,
        weighted,
    };
    let r = two_loop(&gram);
    Ok((r.c, r.e))
}

/// One part's rows of the direction `−(P Σ_j c_j v_j + Σ_k e_k s_k)` from the coefficients
/// of [`gram_coefficients`], `v = [y_0..y_{m-1}, g]`: per site, `g` first, then the pairs
/// oldest first.
///
/// Errors: `c` not of length `m + 1` or `e` not of length `m` for the `m` pairs given, or a
/// pair or `preconditioner` not of one row per site.
pub fn combine<const D: usize>(
    c: &[f64],
    e: &[f64],
    gradient: &[[f64; D]],
    s: &[Vec<[f64; D]>],
    y: &[Vec<[f64; D]>],
    preconditioner: &[f64],
) -> Result<Vec<[f64; D]>, CoreError> {
    let n = gradient.len();
    let lengths = [
        ("y pairs", s.len(), y.len()),
        ("coefficients c", s.len() + 1, c.len()),
        ("coefficients e", s.len(), e.len()),
        ("preconditioner", n, preconditioner.len()),
    ];
    let rows = s.iter().chain(y).map(|v| ("pair rows", n, v.len()));
    if let Some((what, expected, got)) = lengths.into_iter().chain(rows).find(|l| l.1 != l.2) {
        return Err(CoreError::ShapeMismatch {
            what,
            expected,
            got,
        });
    }
    let Some((&last, c)) = c.split_last() else {
        return Ok(Vec::new());
    };
    Ok((0..n)
        .map(|i| {
            std::array::from_fn(|k| {
                let mut combo = last * gradient[i][k];
                for (&cj, yj) in c.iter().zip(y) {
                    combo += cj * yj[i][k];
                }
                let mut r = preconditioner[i] * combo;
                for (&ej, sj) in e.iter().zip(s) {
                    r += ej * sj[i][k];
                }
                -r
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_coefficient_recursion_gives_the_direction_of_the_vector_one() {
        // Three pairs on 40 sites in 2D, and a preconditioner: the partitioned run's
        // coefficients over [s, y, g] (Gram matrices summed in any order) combined per site
        // must give Memory::direction to round-off.
        let mut seed = 7_u64;
        let mut random = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let n = 40;
        let mut rows = |scale: f64| -> Vec<[f64; 2]> {
            (0..n)
                .map(|_| [scale * random(), scale * random()])
                .collect()
        };
        let g = rows(1.0);
        let s: Vec<Vec<[f64; 2]>> = (0..3).map(|_| rows(1.0)).collect();
        let noise: Vec<Vec<[f64; 2]>> = (0..3).map(|_| rows(0.1)).collect();
        let y: Vec<Vec<[f64; 2]>> = (s.iter().zip(&noise))
            .map(|(s, e)| {
                s.iter()
                    .zip(e)
                    .map(|(a, b)| [2.0 * a[0] + b[0], 2.0 * a[1] + b[1]])
                    .collect()
            })
            .collect();
        let w: Vec<f64> = (0..n).map(|_| random() + 1.0).collect();
        let mut memory = Memory::new(7);
        for (s, y) in s.iter().zip(&y) {
            assert!(memory.push(s.clone(), y.clone()));
        }
        let expected = memory.direction(&g, &w);

        let basis: Vec<&Vec<[f64; 2]>> = s.iter().chain(&y).chain([&g]).collect();
        let size = basis.len();
        let (mut plain, mut weighted) = (vec![0.0; size * size], vec![0.0; size * size]);
        for a in 0..size {
            for b in 0..size {
                plain[a * size + b] = dot_rows(basis[a], basis[b]);
                weighted[a * size + b] = (basis[a].iter().zip(basis[b]).zip(&w))
                    .map(|((&u, &v), &w)| w * dot(u, v))
                    .sum();
            }
        }
        let (c, e) = gram_coefficients(&plain, &weighted).unwrap();
        let got = combine(&c, &e, &g, &s, &y, &w).unwrap();
        let scale = expected
            .iter()
            .flatten()
            .fold(0.0_f64, |m, x| m.max(x.abs()));
        for (a, b) in got.iter().flatten().zip(expected.iter().flatten()) {
            assert!((a - b).abs() <= 1e-12 * scale, "{a} against {b}");
        }
        assert!(gram_coefficients(&plain[1..], &weighted).is_err());
        assert!(combine(&c[1..], &e, &g, &s, &y, &w).is_err());
    }

    #[test]
    fn two_loop_with_one_pair_is_exact_on_a_1d_quadratic() {
        // E = 3 x²: g = 6x. One pair (s = 1, y = 6) gives H = 1/6 whatever H0.
        let mut memory = Memory::<1>::new(7);
        assert!(memory.push(vec![[1.0]], vec![[6.0]]));
        let p = memory.direction(&[[12.0]], &[10.0]);
        assert!((p[0][0] + 2.0).abs() < 1e-15, "{p:?}");
        assert!(
            !memory.push(vec![[1.0]], vec![[-1.0]]),
            "negative curvature is skipped"
        );
        assert_eq!(memory.len(), 1);
    }
}
