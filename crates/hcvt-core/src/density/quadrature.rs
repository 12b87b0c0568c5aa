//! Symmetric quadrature rules on simplices with positive weights and interior points
//! (DESIGN §8): what integrates a density over the signed cones of a cell.
//!
//! A rule lists barycentric points and weights that sum to 1; the integral of `f` over a
//! simplex `S` is `|S| Σ_k w_k f(x_k)`, exact for polynomials up to the rule's degree.
//! Sources (values refined to 20 digits by Gauss–Newton on the moment equations, in
//! 40-digit arithmetic; the tests check every monomial):
//!
//! | rule | points | degree | source |
//! |------|--------|--------|--------|
//! | `SEGMENT_3` | 2 | 3 | Gauss–Legendre |
//! | `SEGMENT_5` | 3 | 5 | Gauss–Legendre |
//! | `TRIANGLE_1`, `TETRA_1` | 1 | 1 | the centroid |
//! | `TRIANGLE_2` | 3 | 2 | Strang and Fix 1973, table 4.1 |
//! | `TRIANGLE_4` | 6 | 4 | Dunavant 1985, "High degree efficient symmetrical Gaussian quadrature rules for the triangle", degree 4 |
//! | `TRIANGLE_5` | 7 | 5 | Dunavant 1985, degree 5 (Radon's rule) |
//! | `TETRA_2` | 4 | 2 | Keast 1986, "Moderate-degree tetrahedral quadrature formulas", rule 2 |
//! | `TETRA_5` | 14 | 5 | Walkington 2000, "Quadrature on simplices of arbitrary dimension", 14-point rule |
//!
//! Degree 3 has no small positive symmetric rule on the tetrahedron (Keast's degree-3
//! rules have a negative weight), and Dunavant's degree-3 triangle rule has one too: a
//! request for degree 3 gets the degree-4 triangle and degree-5 tetrahedron rules.

// The constants keep the 20 digits they were computed to: the compiler rounds them
// correctly, and the digits can be checked against the sources as they stand.
#![allow(clippy::excessive_precision)]

/// A rule on the `d`-simplex: barycentric coordinates of the vertices `1..=d` (that of
/// vertex 0 is one minus their sum), and the weights, summing to 1.
#[derive(Debug, Clone, Copy)]
pub struct Rule {
    /// Dimension `d` of the simplex.
    pub dim: usize,
    /// Barycentric coordinates of each point on vertices `1..=d`, point after point.
    pub points: &'static [f64],
    /// Weight of each point; `Σ w = 1`.
    pub weights: &'static [f64],
    /// Every polynomial of at most this degree is integrated exactly.
    pub degree: usize,
}

/// The degrees the rules reach: a request above this is refused.
pub const MAX_DEGREE: usize = 5;

const T1: f64 = 1.0 / 3.0;
// Dunavant degree 4: two orbits (a, a, 1 − 2a).
const T4A: f64 = 0.445_948_490_915_964_886_32;
const T4B: f64 = 0.091_576_213_509_770_743_46;
const T4WA: f64 = 0.223_381_589_678_011_465_7;
const T4WB: f64 = 0.109_951_743_655_321_867_64;
// Dunavant degree 5: the centroid and two orbits (a, a, 1 − 2a).
const T5A: f64 = 0.470_142_064_105_115_089_77;
const T5B: f64 = 0.101_286_507_323_456_338_8;
const T5WA: f64 = 0.132_394_152_788_506_180_74;
const T5WB: f64 = 0.125_939_180_544_827_152_6;

/// `√(1/3)/2`: the 2-point Gauss–Legendre points sit this far from the middle of [0, 1].
const G2: f64 = 0.288_675_134_594_812_882_25;

/// Degree 3 on the segment: 2-point Gauss–Legendre.
pub const SEGMENT_3: Rule = Rule {
    dim: 1,
    points: &[0.5 - G2, 0.5 + G2],
    weights: &[0.5, 0.5],
    degree: 3,
};

/// `√(3/5)/2`: the outer Gauss–Legendre points sit this far from the middle of [0, 1].
const G3: f64 = 0.387_298_334_620_741_688_52;

/// Degree 5 on the segment: 3-point Gauss–Legendre.
pub const SEGMENT_5: Rule = Rule {
    dim: 1,
    points: &[0.5 - G3, 0.5, 0.5 + G3],
    weights: &[5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0],
    degree: 5,
};

/// Degree 1 on the triangle.
pub const TRIANGLE_1: Rule = Rule {
    dim: 2,
    points: &[T1, T1],
    weights: &[1.0],
    degree: 1,
};

/// Degree 2 on the triangle: the orbit of `(1/6, 1/6, 2/3)`.
pub const TRIANGLE_2: Rule = Rule {
    dim: 2,
    points: &[
        1.0 / 6.0,
        1.0 / 6.0,
        2.0 / 3.0,
        1.0 / 6.0,
        1.0 / 6.0,
        2.0 / 3.0,
    ],
    weights: &[T1, T1, T1],
    degree: 2,
};

/// Degree 4 on the triangle (Dunavant), 6 points.
pub const TRIANGLE_4: Rule = Rule {
    dim: 2,
    points: &[
        T4A,
        T4A,
        1.0 - 2.0 * T4A,
        T4A,
        T4A,
        1.0 - 2.0 * T4A,
        T4B,
        T4B,
        1.0 - 2.0 * T4B,
        T4B,
        T4B,
        1.0 - 2.0 * T4B,
    ],
    weights: &[T4WA, T4WA, T4WA, T4WB, T4WB, T4WB],
    degree: 4,
};

/// Degree 5 on the triangle (Dunavant), 7 points.
pub const TRIANGLE_5: Rule = Rule {
    dim: 2,
    points: &[
        T1,
        T1,
        T5A,
        T5A,
        1.0 - 2.0 * T5A,
        T5A,
        T5A,
        1.0 - 2.0 * T5A,
        T5B,
        T5B,
        1.0 - 2.0 * T5B,
        T5B,
        T5B,
        1.0 - 2.0 * T5B,
    ],
    weights: &[0.225, T5WA, T5WA, T5WA, T5WB, T5WB, T5WB],
    degree: 5,
};

const Q1: f64 = 0.25;
// Keast rule 2: the orbit of (a, a, a, 1 − 3a), a = (5 − √5)/20.
const Q2A: f64 = 0.138_196_601_125_010_515_18;
const Q2B: f64 = 1.0 - 3.0 * Q2A;
// Walkington's 14 points: orbits (a, a, a, 1 − 3a) twice and (b, b, 1/2 − b, 1/2 − b).
const Q5A: f64 = 0.092_735_250_310_891_226_402;
const Q5B: f64 = 0.310_885_919_263_300_609_8;
const Q5C: f64 = 0.045_503_704_125_649_649_492;
const Q5WA: f64 = 0.073_493_043_116_361_949_544;
const Q5WB: f64 = 0.112_687_925_718_015_850_8;
const Q5WC: f64 = 0.042_546_020_777_081_466_438;
const Q5A3: f64 = 1.0 - 3.0 * Q5A;
const Q5B3: f64 = 1.0 - 3.0 * Q5B;
const Q5C2: f64 = 0.5 - Q5C;

/// Degree 1 on the tetrahedron.
pub const TETRA_1: Rule = Rule {
    dim: 3,
    points: &[Q1, Q1, Q1],
    weights: &[1.0],
    degree: 1,
};

/// Degree 2 on the tetrahedron (Keast), 4 points.
pub const TETRA_2: Rule = Rule {
    dim: 3,
    points: &[Q2A, Q2A, Q2A, Q2B, Q2A, Q2A, Q2A, Q2B, Q2A, Q2A, Q2A, Q2B],
    weights: &[0.25; 4],
    degree: 2,
};

/// Degree 5 on the tetrahedron (Walkington), 14 points.
pub const TETRA_5: Rule = Rule {
    dim: 3,
    points: &[
        Q5A, Q5A, Q5A, Q5A3, Q5A, Q5A, Q5A, Q5A3, Q5A, Q5A, Q5A, Q5A3, Q5B, Q5B, Q5B, Q5B3, Q5B,
        Q5B, Q5B, Q5B3, Q5B, Q5B, Q5B, Q5B3,
        // (b, b, c, c) over the vertices 0..3 with c = 1/2 − b: six ways to place the b's.
        Q5C, Q5C2, Q5C2, // b on vertices 0, 1
        Q5C2, Q5C, Q5C2, // 0, 2
        Q5C2, Q5C2, Q5C, // 0, 3
        Q5C, Q5C, Q5C2, // 1, 2
        Q5C, Q5C2, Q5C, // 1, 3
        Q5C2, Q5C, Q5C, // 2, 3
    ],
    weights: &[
        Q5WA, Q5WA, Q5WA, Q5WA, Q5WB, Q5WB, Q5WB, Q5WB, Q5WC, Q5WC, Q5WC, Q5WC, Q5WC, Q5WC,
    ],
    degree: 5,
};

/// The rule of fewest points on the `dim`-simplex (1, 2 or 3) that is exact to at least
/// `degree` (`1..=MAX_DEGREE`); `None` otherwise.
pub fn rule(dim: usize, degree: usize) -> Option<Rule> {
    match (dim, degree) {
        (1, 1..=3) => Some(SEGMENT_3),
        (1, 4 | 5) => Some(SEGMENT_5),
        (2, 1) => Some(TRIANGLE_1),
        (2, 2) => Some(TRIANGLE_2),
        (2, 3 | 4) => Some(TRIANGLE_4),
        (2, 5) => Some(TRIANGLE_5),
        (3, 1) => Some(TETRA_1),
        (3, 2) => Some(TETRA_2),
        (3, 3..=5) => Some(TETRA_5),
        _ => None,
    }
}

impl Rule {
    /// The points, `dim` coordinates each, with their weights.
    pub fn nodes(&self) -> impl Iterator<Item = (&'static [f64], f64)> + '_ {
        self.points
            .chunks_exact(self.dim)
            .zip(self.weights.iter().copied())
    }

    /// [`Rule::nodes`] of a rule on the `dim`-simplex, `dim` a constant of the caller: the
    /// points' length known, the compiler unrolls their coordinates (and splits the
    /// points without an integer division per call). The same nodes, the same sums.
    #[inline]
    pub fn nodes_in(&self, dim: usize) -> impl Iterator<Item = (&'static [f64], f64)> + '_ {
        debug_assert_eq!(self.dim, dim, "a rule on the {}-simplex", self.dim);
        self.points
            .chunks_exact(dim)
            .zip(self.weights.iter().copied())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn factorial(k: usize) -> f64 {
        (1..=k).map(|x| x as f64).product()
    }

    /// `∫ x^a` over the unit simplex (vertices 0 and the axes), divided by its volume:
    /// `d! Π a_k! / (d + |a|)!`.
    fn exact<const D: usize>(a: [usize; D]) -> f64 {
        let total: usize = a.iter().sum();
        factorial(D) * a.iter().map(|&k| factorial(k)).product::<f64>() / factorial(D + total)
    }

    fn rule_value<const D: usize>(rule: &Rule, a: [usize; D]) -> f64 {
        rule.nodes()
            .map(|(p, w)| w * (0..D).map(|k| p[k].powi(a[k] as i32)).product::<f64>())
            .sum()
    }

    /// Every monomial up to the rule's degree is exact to round-off, and some monomial
    /// of the next degree is not: the stated degree is the rule's degree.
    fn check<const D: usize>(rule: &Rule) {
        assert_eq!(rule.dim, D);
        assert_eq!(rule.points.len(), D * rule.weights.len());
        assert!(rule.weights.iter().all(|&w| w > 0.0));
        for (p, _) in rule.nodes() {
            let last = 1.0 - p.iter().sum::<f64>();
            assert!(
                p.iter().all(|&x| x > 0.0) && last > 0.0,
                "{p:?} not interior"
            );
        }
        let mut next_degree_error = 0.0f64;
        let limit = rule.degree + 1;
        let mut a = [0usize; D];
        loop {
            let total: usize = a.iter().sum();
            if total <= limit {
                let err = (rule_value(rule, a) - exact(a)).abs() / exact(a);
                if total <= rule.degree {
                    assert!(
                        err < 4e-15,
                        "degree {}: x^{a:?} off by {err:e}",
                        rule.degree
                    );
                } else {
                    next_degree_error = next_degree_error.max(err);
                }
            }
            // Next multi-index with entries up to `limit`.
            let mut k = 0;
            while k < D && a[k] == limit {
                a[k] = 0;
                k += 1;
            }
            if k == D {
                break;
            }
            a[k] += 1;
        }
        assert!(
            next_degree_error > 1e-6,
            "degree {} rule is exact one degree higher",
            rule.degree
        );
    }

    #[test]
    fn every_rule_has_its_stated_degree() {
        check::<1>(&SEGMENT_3);
        check::<1>(&SEGMENT_5);
        for rule in [TRIANGLE_1, TRIANGLE_2, TRIANGLE_4, TRIANGLE_5] {
            check::<2>(&rule);
        }
        for rule in [TETRA_1, TETRA_2, TETRA_5] {
            check::<3>(&rule);
        }
    }
}
