//! Exact mass, first and second moments of simplices, and the regularity measure `G`.
//!
//! All moments are taken about an origin that the caller chooses (the site, DESIGN §3):
//! differences are formed before products so that small cells far from the coordinate
//! origin keep their accuracy.

use crate::geometry::{add, dot, norm2, scale, sub, Euclid};

/// Signed moments of a region about an origin.
///
/// | field    | value            | unit      |
/// |----------|------------------|-----------|
/// | `mass`   | `∫ dx`           | L^d       |
/// | `first`  | `∫ x dx`         | L^(d+1)   |
/// | `second` | `∫ |x|² dx`      | L^(d+2)   |
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moments<const D: usize> {
    /// Signed measure (area in 2D, volume in 3D).
    pub mass: f64,
    /// First moment about the origin.
    pub first: [f64; D],
    /// Trace of the second moment about the origin.
    pub second: f64,
}

impl<const D: usize> Moments<D> {
    /// The zero region.
    pub fn zero() -> Self {
        Self {
            mass: 0.0,
            first: [0.0; D],
            second: 0.0,
        }
    }

    /// `self += s · other`, the signed sum of the cone identity (DESIGN §3).
    #[inline]
    pub fn add_scaled(&mut self, other: &Self, s: f64) {
        self.mass += s * other.mass;
        self.first = add(self.first, scale(other.first, s));
        self.second += s * other.second;
    }

    /// Centroid relative to the origin, `None` (not NaN) for zero mass.
    pub fn centroid(&self) -> Option<[f64; D]> {
        (self.mass != 0.0).then(|| scale(self.first, 1.0 / self.mass))
    }

    /// Second moment about the centroid, `∫ |x - c|² dx` (parallel-axis rule); 0 for zero mass.
    pub fn central_second(&self) -> f64 {
        if self.mass == 0.0 {
            return 0.0;
        }
        (self.second - norm2(self.first) / self.mass).max(0.0)
    }

    /// Dimensionless second moment of Conway and Sloane, eq. (2) of the paper:
    /// `G = ∫|x - c|² / (d · V^((d+2)/d))`. `None` for zero mass.
    pub fn dimensionless_second_moment(&self) -> Option<f64> {
        if self.mass <= 0.0 {
            return None;
        }
        let d = D as f64;
        Some(self.central_second() / (d * self.mass.powf((d + 2.0) / d)))
    }

    /// The same moments about `origin` instead of the current origin, where `origin` is
    /// given in the current frame.
    pub fn about(&self, origin: [f64; D]) -> Self {
        // ∫|x - o|² = ∫|x|² - 2 o·∫x + m|o|²
        Self {
            mass: self.mass,
            first: sub(self.first, scale(origin, self.mass)),
            second: self.second - 2.0 * dot(origin, self.first) + self.mass * norm2(origin),
        }
    }
}

/// Signed moments of the triangle `(0, a, b)` about the origin.
///
/// Positive when `0, a, b` turn counter-clockwise. With `c = a × b`:
/// mass `c/2`, first `mass·(a+b)/3`, second `mass·(a·a + a·b + b·b)/6`.
///
/// # Example
///
/// ```
/// use hcvt_core::triangle_moments;
///
/// // Unit right triangle, counter-clockwise: area 1/2, centroid (1/3, 1/3).
/// let m = triangle_moments([1.0, 0.0], [0.0, 1.0]);
/// assert_eq!(m.mass, 0.5);
/// assert_eq!(m.centroid(), Some([1.0 / 3.0, 1.0 / 3.0]));
/// assert!((m.second - 1.0 / 6.0).abs() < 1e-15);
/// assert_eq!(triangle_moments([0.0, 1.0], [1.0, 0.0]).mass, -0.5); // clockwise
/// ```
#[inline]
pub fn triangle_moments(a: [f64; 2], b: [f64; 2]) -> Moments<2> {
    let mass = 0.5 * (a[0] * b[1] - a[1] * b[0]);
    Moments {
        mass,
        first: add(a, b).map(|s| mass * s / 3.0),
        second: mass * (dot(a, a) + dot(a, b) + dot(b, b)) / 6.0,
    }
}

/// Signed moments of the tetrahedron `(0, a, b, c)` about the origin.
///
/// Positive when `det[a b c] > 0`, i.e. `(a, b, c)` counter-clockwise seen from outside
/// with the origin behind. With `D = det[a b c]`: mass `D/6`, first `mass·(a+b+c)/4`,
/// second `mass·(|a|²+|b|²+|c|²+a·b+b·c+c·a)/10` (ALGORITHMS §2).
///
/// # Example
///
/// ```
/// use hcvt_core::tetra_moments;
///
/// let m = tetra_moments([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
/// assert!((m.mass - 1.0 / 6.0).abs() < 1e-16);
/// let c = m.centroid().unwrap();
/// assert!(c.iter().all(|x| (x - 0.25).abs() < 1e-15));
/// assert!((m.second - 0.05).abs() < 1e-16); // ∫|x|² over the corner tetrahedron = 1/20
/// ```
#[inline]
pub fn tetra_moments(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Moments<3> {
    let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]);
    let mass = det / 6.0;
    let s = add(add(a, b), c);
    Moments {
        mass,
        first: s.map(|x| mass * x / 4.0),
        second: mass * (dot(a, a) + dot(b, b) + dot(c, c) + dot(a, b) + dot(b, c) + dot(c, a))
            / 10.0,
    }
}

/// The moments of the cone from the origin over one boundary simplex, per dimension: what
/// the domain sums for its own moments (DESIGN §3).
pub trait ConeMoments<const D: usize> {
    /// Signed moments about the origin of the simplex spanned by the origin and the `D`
    /// points `p` (a triangle in 2D, a tetrahedron in 3D); positive when `p` is a boundary
    /// piece oriented outward as seen from the origin.
    fn cone_moments(p: &[[f64; D]; D]) -> Moments<D>;
}

impl ConeMoments<2> for Euclid {
    #[inline]
    fn cone_moments(p: &[[f64; 2]; 2]) -> Moments<2> {
        triangle_moments(p[0], p[1])
    }
}

impl ConeMoments<3> for Euclid {
    #[inline]
    fn cone_moments(p: &[[f64; 3]; 3]) -> Moments<3> {
        tetra_moments(p[0], p[1], p[2])
    }
}

/// Moments of a face (a segment in 2D, a planar polygon in 3D) about an origin: what the
/// Hessian of the CVT energy integrates over the face between two cells (DESIGN §4).
///
/// | field    | value          | unit      |
/// |----------|----------------|-----------|
/// | `measure`| `∫ ds`         | L^(d-1)   |
/// | `first`  | `∫ x ds`       | L^d       |
/// | `second` | `∫ x xᵀ ds`    | L^(d+1)   |
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceMoments<const D: usize> {
    /// Length (2D) or area (3D).
    pub measure: f64,
    /// First moment about the origin.
    pub first: [f64; D],
    /// Second moment tensor about the origin, symmetric.
    pub second: [[f64; D]; D],
}

impl<const D: usize> FaceMoments<D> {
    /// The empty face.
    pub fn zero() -> Self {
        Self {
            measure: 0.0,
            first: [0.0; D],
            second: [[0.0; D]; D],
        }
    }

    /// Moments of the `(D − 1)`-simplex with `vertices` (`D` of them) and the given measure.
    ///
    /// For a `k`-simplex with vertices `v_a` and `s = Σ v_a`: `∫ x = |T| s / (k + 1)` and
    /// `∫ x xᵀ = |T| (Σ v_a v_aᵀ + s sᵀ) / ((k + 1)(k + 2))`, here with `k + 1 = D`.
    ///
    /// # Example
    ///
    /// ```
    /// use hcvt_core::FaceMoments;
    ///
    /// // The segment from (0, 0) to (2, 0): ∫ x² ds = 8/3.
    /// let m = FaceMoments::simplex(&[[0.0, 0.0], [2.0, 0.0]], 2.0);
    /// assert_eq!(m.first, [2.0, 0.0]);
    /// assert!((m.second[0][0] - 8.0 / 3.0).abs() < 1e-15);
    /// ```
    // Not inlined: inlined into `PolygonCell::moments_and_face_moments`, rustc 1.95 built
    // with one codegen unit got the cross term `∫ y_0 y_1` wrong (as if the two vertices
    // had swapped their y: the diagonal terms and the first moment stayed right), and the
    // Hessian missed its finite differences by 57% (`cargo test --release --test it optimise::`
    // with CARGO_PROFILE_RELEASE_CODEGEN_UNITS=1; the debug build and 4 or 16 units were
    // right). scripts/test.sh runs that check. Not reduced (issue 16, 30 minutes): the
    // same face pass and Hessian accumulation copied into an integration test computed
    // right; with the library at 4 units and only the test crate at one, it still fails, and
    // `-C llvm-args=-opt-bisect-limit=N` on the test crate flips at pass 602873 of 728021,
    // MachineBlockPlacement on `PolyhedronCell::clone` (a 3D function, while the 2D test
    // fails): a codegen-stage or layout-dependent fault, not an IR optimisation.
    #[inline(never)]
    pub fn simplex(vertices: &[[f64; D]; D], measure: f64) -> Self {
        let s = vertices.iter().fold([0.0; D], |acc, &v| add(acc, v));
        let d = D as f64;
        let w = measure / (d * (d + 1.0));
        let second = std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                w * (vertices.iter().map(|v| v[r] * v[c]).sum::<f64>() + s[r] * s[c])
            })
        });
        Self {
            measure,
            first: scale(s, measure / d),
            second,
        }
    }

    /// `self += s · other`: faces of signed pieces add up like their moments.
    #[inline]
    pub fn add_scaled(&mut self, other: &Self, s: f64) {
        self.measure += s * other.measure;
        self.first = add(self.first, scale(other.first, s));
        for (row, o) in self.second.iter_mut().zip(&other.second) {
            *row = add(*row, scale(*o, s));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn polygon_moments(v: &[[f64; 2]]) -> Moments<2> {
        let mut m = Moments::zero();
        for i in 0..v.len() {
            m.add_scaled(&triangle_moments(v[i], v[(i + 1) % v.len()]), 1.0);
        }
        m
    }

    #[test]
    fn square_and_hexagon_have_the_closed_form_g() {
        let square = polygon_moments(&[[0.3, 0.1], [1.3, 0.1], [1.3, 1.1], [0.3, 1.1]]);
        let g = square.dimensionless_second_moment().unwrap();
        assert!((g - 1.0 / 12.0).abs() < 1e-15, "square G = {g}");
        let hex: Vec<[f64; 2]> = (0..6)
            .map(|k| {
                let t = std::f64::consts::PI / 3.0 * k as f64;
                [2.0 + t.cos(), -1.0 + t.sin()]
            })
            .collect();
        let g = polygon_moments(&hex).dimensionless_second_moment().unwrap();
        let exact = 5.0 / (36.0 * 3f64.sqrt());
        assert!(
            (g - exact).abs() < 1e-15,
            "hexagon G = {g}, expected {exact}"
        );
    }

    #[test]
    fn cube_has_g_one_twelfth() {
        // Unit cube fanned from a corner-free origin: 12 outward triangles, 2 per face.
        let v = |x: f64, y: f64, z: f64| [x - 0.4, y - 0.3, z - 0.2];
        let quads = [
            [v(0., 0., 0.), v(0., 1., 0.), v(1., 1., 0.), v(1., 0., 0.)],
            [v(0., 0., 1.), v(1., 0., 1.), v(1., 1., 1.), v(0., 1., 1.)],
            [v(0., 0., 0.), v(1., 0., 0.), v(1., 0., 1.), v(0., 0., 1.)],
            [v(0., 1., 0.), v(0., 1., 1.), v(1., 1., 1.), v(1., 1., 0.)],
            [v(0., 0., 0.), v(0., 0., 1.), v(0., 1., 1.), v(0., 1., 0.)],
            [v(1., 0., 0.), v(1., 1., 0.), v(1., 1., 1.), v(1., 0., 1.)],
        ];
        let mut m = Moments::zero();
        for q in quads {
            m.add_scaled(&tetra_moments(q[0], q[1], q[2]), 1.0);
            m.add_scaled(&tetra_moments(q[0], q[2], q[3]), 1.0);
        }
        assert!((m.mass - 1.0).abs() < 1e-15);
        let g = m.dimensionless_second_moment().unwrap();
        assert!((g - 1.0 / 12.0).abs() < 1e-15, "cube G = {g}");
        let c = m.centroid().unwrap();
        assert!(norm2(sub(c, [0.1, 0.2, 0.3])) < 1e-30, "centroid {c:?}");
    }

    #[test]
    fn moving_the_origin_keeps_central_moments() {
        let m = polygon_moments(&[[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]);
        let shifted = m.about([5.0, -3.0]);
        assert!((shifted.central_second() - m.central_second()).abs() < 1e-12);
        assert_eq!(shifted.centroid(), Some([-4.0, 3.5]));
        assert_eq!(Moments::<2>::zero().centroid(), None);
    }

    #[test]
    fn triangle_face_moments_match_a_fine_quadrature() {
        let v = [[0.3, -0.2, 1.0], [1.1, 0.4, 0.7], [-0.5, 0.9, 0.2]];
        let c = {
            let (a, b) = (sub(v[1], v[0]), sub(v[2], v[0]));
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let area = 0.5 * norm2(c).sqrt();
        let exact = FaceMoments::simplex(&v, area);
        // Midpoint rule on a fine barycentric grid: error O(1/k²).
        let k = 400;
        let mut second = [[0.0; 3]; 3];
        for i in 0..k {
            for j in 0..k - i {
                for (u, w, weight) in [
                    (i as f64 + 1.0 / 3.0, j as f64 + 1.0 / 3.0, 1.0),
                    (i as f64 + 2.0 / 3.0, j as f64 + 2.0 / 3.0, 1.0),
                ] {
                    if u + w > k as f64 {
                        continue;
                    }
                    let (u, w) = (u / k as f64, w / k as f64);
                    let x: [f64; 3] = std::array::from_fn(|r| {
                        v[0][r] + u * (v[1][r] - v[0][r]) + w * (v[2][r] - v[0][r])
                    });
                    for r in 0..3 {
                        for s in 0..3 {
                            second[r][s] += weight * x[r] * x[s] * area / (k * k) as f64;
                        }
                    }
                }
            }
        }
        for (r, (row, exact_row)) in second.iter().zip(&exact.second).enumerate() {
            for (s, (value, expected)) in row.iter().zip(exact_row).enumerate() {
                assert!((value - expected).abs() < 1e-4, "{r}{s}");
                assert_eq!(*expected, exact.second[s][r]);
            }
        }
    }
}
