//! One cell's ρ-weighted moments, summed over its signed pieces as the diagram measures
//! them (DESIGN §3, §8).
//!
//! **A polynomial** is integrated over each cone simplex `S = (site, v_1 … v_d)` through
//! its face `F = (v_1 … v_d)`: for `f` homogeneous of degree `k` in `y = x − site`,
//! `∫_S f = d |S| / (d + k) · avg_F f` (the cone from the origin over a planar face scales
//! `F` by `t ∈ [0, 1]`, and `∫_0^1 t^(d−1+k) dt = 1/(d+k)`). `ρ = c + b·y + yᵀAy` about the
//! site splits into homogeneous parts, so each moment is a face average of a polynomial of
//! degree ≤ 4: a rule on the `(d−1)`-simplex of degree 4 or more (3 Gauss points on a
//! segment, Dunavant's 6 on a triangle) is exact, with fewer points than a degree-4 rule
//! on `S` itself (6 or 14).
//!
//! **A field** cannot be split so: each cone simplex gets the volume rule asked for. The
//! diagram keeps each cell's simplices (not the nodes, several per simplex), makes the
//! nodes ([`cone_node`]) when it evaluates the field, and sums them ([`sum_sampled`]).

use crate::geometry::{dot, norm2};
use crate::moments::{FaceMoments, Moments};

use super::quadrature::Rule;
use super::Quadratic;

/// A cone simplex of a cell: its `D` vertices besides the site (relative to the site),
/// and its signed measure times the sign of its piece.
pub type Cone<const D: usize> = ([[f64; D]; D], f64);

/// The moments of `ρ = local` (about the site) over the cone simplex from the site over
/// `face`, of signed measure `measure`, by the face averages of the module docs; and ρ's
/// mean over `face` itself (its `∫ρ` divided by its measure), from the same nodes: the
/// face masses of the transport's Hessian (`diagram::faces`) at no second pass.
#[inline]
pub fn polynomial_cone<const D: usize>(
    local: &Quadratic<D>,
    face_rule: &Rule,
    face: &[[f64; D]; D],
    measure: f64,
) -> (Moments<D>, f64) {
    let d = D as f64;
    let c = local.constant;
    // Σ_q w_q of each homogeneous part, already divided by d + k.
    let (mut mass, mut first, mut second) = (0.0, [0.0; D], 0.0);
    // Σ_q w_q of ρ's non-constant part on the face (the weights sum to 1).
    let mut face_mean = 0.0;
    for (lambda, w) in face_rule.nodes_in(D - 1) {
        let y = face_node(face, lambda);
        let linear = dot(local.linear, y);
        let quadratic = dot(std::array::from_fn(|r| dot(local.quadratic[r], y)), y);
        face_mean += w * (linear + quadratic);
        mass += w * (linear / (d + 1.0) + quadratic / (d + 2.0));
        let f = w * (c / (d + 1.0) + linear / (d + 2.0) + quadratic / (d + 3.0));
        for (sum, &yk) in first.iter_mut().zip(&y) {
            *sum += f * yk;
        }
        second += w * norm2(y) * (c / (d + 2.0) + linear / (d + 3.0) + quadratic / (d + 4.0));
    }
    let scale = d * measure;
    let cone = Moments {
        mass: c * measure + scale * mass,
        first: first.map(|x| scale * x),
        second: scale * second,
    };
    (cone, c + face_mean)
}

/// The mass `∫ρ` of the cone simplex from the site over `face`, of signed measure
/// `measure`, for `ρ = local` about the site, and ρ's mean over `face`: what
/// [`polynomial_cone`] gives of them (the same to round-off), without the first and second
/// moments and by a face rule of degree ≥ 2 (`mass_rule`: 2 Gauss points on a segment, 3
/// on a triangle, where the moments take 3 and 6).
#[inline]
pub fn polynomial_cone_mass<const D: usize>(
    local: &Quadratic<D>,
    mass_rule: &Rule,
    face: &[[f64; D]; D],
    measure: f64,
) -> (f64, f64) {
    let d = D as f64;
    // Face averages of ρ's linear and quadratic parts (the weights sum to 1).
    let (mut linear, mut quadratic) = (0.0, 0.0);
    for (lambda, w) in mass_rule.nodes_in(D - 1) {
        let y = face_node(face, lambda);
        linear += w * dot(local.linear, y);
        quadratic += w * dot(std::array::from_fn(|r| dot(local.quadratic[r], y)), y);
    }
    let c = local.constant;
    let mass = measure * (c + d * (linear / (d + 1.0) + quadratic / (d + 2.0)));
    (mass, c + linear + quadratic)
}

/// The ρ-weighted moments `∫ρ`, `∫ρ y`, `∫ρ y yᵀ` of the face simplex `simplex`
/// (relative to the site) of `measure`, for `ρ = local` about the site: exact with a
/// face rule of degree ≥ 4.
pub fn polynomial_face_moments<const D: usize>(
    local: &Quadratic<D>,
    face_rule: &Rule,
    simplex: &[[f64; D]; D],
    measure: f64,
) -> FaceMoments<D> {
    let mut m = FaceMoments::zero();
    for (lambda, w) in face_rule.nodes_in(D - 1) {
        let y = face_node(simplex, lambda);
        let f = w * measure * local.value(y);
        m.measure += f;
        for r in 0..D {
            m.first[r] += f * y[r];
            for c in 0..D {
                m.second[r][c] += f * y[r] * y[c];
            }
        }
    }
    m
}

/// The signed measure of the cone simplex from the origin over `face` (`D` = 2 or 3),
/// `det(face) / D!`: what the cells' `for_each_cone` give with it.
#[inline]
pub fn cone_measure<const D: usize>(face: &[[f64; D]; D]) -> f64 {
    let v = |i: usize, k: usize| face[i][k];
    match D {
        2 => 0.5 * (v(0, 0) * v(1, 1) - v(0, 1) * v(1, 0)),
        3 => {
            let minor = |a: usize, b: usize| v(1, a) * v(2, b) - v(1, b) * v(2, a);
            (v(0, 0) * minor(1, 2) - v(0, 1) * minor(0, 2) + v(0, 2) * minor(0, 1)) / 6.0
        }
        _ => unreachable!("cells have 2 or 3 dimensions"),
    }
}

/// The point of `face` (the `D` vertices) with barycentric coordinates `lambda` on its
/// vertices `1..D` (vertex 0 takes the rest).
#[inline]
pub fn face_node<const D: usize>(face: &[[f64; D]; D], lambda: &[f64]) -> [f64; D] {
    let rest = 1.0 - lambda.iter().sum::<f64>();
    std::array::from_fn(|k| {
        rest * face[0][k] + (1..D).map(|v| lambda[v - 1] * face[v][k]).sum::<f64>()
    })
}

/// The node of barycentric coordinates `lambda` (on vertices `1..=D`; vertex 0, the
/// site, is the origin) of the cone simplex over `face`.
#[inline]
pub fn cone_node<const D: usize>(face: &[[f64; D]; D], lambda: &[f64]) -> [f64; D] {
    std::array::from_fn(|k| (0..D).map(|v| lambda[v] * face[v][k]).sum())
}

/// The weighted moments of a cell about its site from its `cones`, the volume `rule`
/// and the field's `values` at their nodes (cone after cone, node after node), summed in
/// that order.
pub fn sum_sampled<const D: usize>(cones: &[Cone<D>], rule: &Rule, values: &[f64]) -> Moments<D> {
    sum_nodes(cones, rule, values, cone_node)
}

/// As [`sum_sampled`] for a cell made of face simplices (a surface's cell, of dimension
/// `D − 1`: each "cone" its `D` vertices and its measure, the `rule` on the
/// `(D − 1)`-simplex, nodes by [`face_node`]).
pub fn sum_sampled_on_faces<const D: usize>(
    faces: &[Cone<D>],
    rule: &Rule,
    values: &[f64],
) -> Moments<D> {
    sum_nodes(faces, rule, values, face_node)
}

/// The weighted moments about the site of the face simplex `face` (relative to the site)
/// of `measure` for the ρ linear on it with values `corners` at its vertices, by `rule`
/// on the `(D − 1)`-simplex: exact when the rule has degree ≥ 3 (`ρ |y|²` is cubic).
pub fn linear_face_moments<const D: usize>(
    face: &[[f64; D]; D],
    measure: f64,
    corners: [f64; D],
    rule: &Rule,
) -> Moments<D> {
    // ρ at the rule's nodes (at most 7 on a triangle, 3 on a segment).
    let mut values = [0.0; 16];
    for ((lambda, _), v) in rule.nodes().zip(values.iter_mut()) {
        let rest = 1.0 - lambda.iter().sum::<f64>();
        *v = rest * corners[0] + (1..D).map(|k| lambda[k - 1] * corners[k]).sum::<f64>();
    }
    let count = rule.weights.len().min(values.len());
    sum_on_faces_one(face, measure, rule, &values[..count])
}

/// [`sum_sampled_on_faces`] of the one face `face`.
fn sum_on_faces_one<const D: usize>(
    face: &[[f64; D]; D],
    measure: f64,
    rule: &Rule,
    values: &[f64],
) -> Moments<D> {
    sum_nodes(&[(*face, measure)], rule, values, face_node)
}

/// The weighted moments from `pieces`, `rule` and ρ's `values` at the nodes `node(piece,
/// lambda)` (piece after piece, node after node), summed in that order.
#[inline]
fn sum_nodes<const D: usize>(
    pieces: &[Cone<D>],
    rule: &Rule,
    values: &[f64],
    node: impl Fn(&[[f64; D]; D], &[f64]) -> [f64; D],
) -> Moments<D> {
    let mut m = Moments::zero();
    let mut value = values.iter();
    for (face, measure) in pieces {
        for ((lambda, w), &rho) in rule.nodes().zip(&mut value) {
            let y = node(face, lambda);
            let f = measure * w * rho;
            m.mass += f;
            for (sum, &yk) in m.first.iter_mut().zip(&y) {
                *sum += f * yk;
            }
            m.second += f * norm2(y);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::density::quadrature::{self, TETRA_5, TRIANGLE_4};

    /// The face-average form of a polynomial over a cone equals the volume rule of
    /// degree ≥ 4 applied to the cone simplex itself.
    #[test]
    fn face_averages_equal_the_volume_rule() {
        let q2 = Quadratic::new(1.3, [0.4, -0.7], [[0.9, 0.2], [0.2, -0.3]]).unwrap();
        let face2 = [[0.3, -0.2], [0.5, 0.6]];
        let measure2 = 0.5 * (face2[0][0] * face2[1][1] - face2[0][1] * face2[1][0]);
        let (by_face, _) = polynomial_cone(&q2, &quadrature::SEGMENT_5, &face2, measure2);
        let by_volume = sum_sampled(
            &[(face2, measure2)],
            &TRIANGLE_4,
            &TRIANGLE_4
                .nodes()
                .map(|(l, _)| q2.value(cone_node(&face2, l)))
                .collect::<Vec<_>>(),
        );
        close(&by_face, &by_volume);
        let q3 = Quadratic::new(
            0.8,
            [0.1, 0.5, -0.2],
            [[0.7, 0.1, 0.0], [0.1, 0.4, -0.2], [0.0, -0.2, 1.1]],
        )
        .unwrap();
        let face3 = [[0.4, 0.1, -0.2], [-0.1, 0.5, 0.3], [0.2, -0.3, 0.6]];
        let det = crate::moments::tetra_moments(face3[0], face3[1], face3[2]).mass;
        let (by_face, _) = polynomial_cone(&q3, &TRIANGLE_4, &face3, det);
        let values: Vec<f64> = (TETRA_5.nodes())
            .map(|(l, _)| q3.value(cone_node(&face3, l)))
            .collect();
        close(&by_face, &sum_sampled(&[(face3, det)], &TETRA_5, &values));
    }

    /// ρ's mean over a cone's face, from the cone's nodes, is the face's `∫ρ` by
    /// [`polynomial_face_moments`] over its measure, in 2D and 3D.
    #[test]
    fn a_cones_face_mean_is_the_faces_mass_over_its_measure() {
        let q2 = Quadratic::new(1.3, [0.4, -0.7], [[0.9, 0.2], [0.2, -0.3]]).unwrap();
        let face2 = [[0.3, -0.2], [0.5, 0.6]];
        let length = crate::geometry::norm2(crate::geometry::sub(face2[1], face2[0])).sqrt();
        let (_, mean) = polynomial_cone(&q2, &quadrature::SEGMENT_5, &face2, 0.17);
        let mass = polynomial_face_moments(&q2, &quadrature::SEGMENT_5, &face2, length).measure;
        assert!((mean * length - mass).abs() < 1e-15 * mass, "{mean} {mass}");
        let q3 = Quadratic::new(
            0.8,
            [0.1, 0.5, -0.2],
            [[0.7, 0.1, 0.0], [0.1, 0.4, -0.2], [0.0, -0.2, 1.1]],
        )
        .unwrap();
        let face3 = [[0.4, 0.1, -0.2], [-0.1, 0.5, 0.3], [0.2, -0.3, 0.6]];
        let (_, mean) = polynomial_cone(&q3, &TRIANGLE_4, &face3, 0.05);
        let mass = polynomial_face_moments(&q3, &TRIANGLE_4, &face3, 0.3).measure;
        assert!((mean * 0.3 - mass).abs() < 1e-15 * mass, "{mean} {mass}");
    }

    /// The mass alone by the degree-2 face rule is the degree-4 rule's cone mass and face
    /// mean to round-off, in 2D and 3D; a degree-1 rule is not.
    #[test]
    fn a_cones_mass_alone_is_its_moments_mass() {
        let q2 = Quadratic::new(1.3, [0.4, -0.7], [[0.9, 0.2], [0.2, -0.3]]).unwrap();
        let face2 = [[0.3, -0.2], [0.5, 0.6]];
        let q3 = Quadratic::new(
            0.8,
            [0.1, 0.5, -0.2],
            [[0.7, 0.1, 0.0], [0.1, 0.4, -0.2], [0.0, -0.2, 1.1]],
        )
        .unwrap();
        let face3 = [[0.4, 0.1, -0.2], [-0.1, 0.5, 0.3], [0.2, -0.3, 0.6]];
        let mass_rule = |dim| quadrature::rule(dim, crate::density::POLYNOMIAL_MASS_DEGREE);
        let (full, mean) = polynomial_cone(&q2, &quadrature::SEGMENT_5, &face2, 0.17);
        let (mass, mass_mean) = polynomial_cone_mass(&q2, &mass_rule(1).unwrap(), &face2, 0.17);
        assert_eq!(mass_rule(1).unwrap().weights.len(), 2);
        assert!(
            (mass - full.mass).abs() < 1e-15 * full.mass,
            "{mass} {full:?}"
        );
        assert!(
            (mass_mean - mean).abs() < 1e-15 * mean,
            "{mass_mean} {mean}"
        );
        let (full, mean) = polynomial_cone(&q3, &TRIANGLE_4, &face3, 0.05);
        let (mass, mass_mean) = polynomial_cone_mass(&q3, &mass_rule(2).unwrap(), &face3, 0.05);
        assert_eq!(mass_rule(2).unwrap().weights.len(), 3);
        assert!(
            (mass - full.mass).abs() < 1e-15 * full.mass,
            "{mass} {full:?}"
        );
        assert!(
            (mass_mean - mean).abs() < 1e-15 * mean,
            "{mass_mean} {mean}"
        );
        let (low, _) = polynomial_cone_mass(&q3, &quadrature::TRIANGLE_1, &face3, 0.05);
        assert!((low - full.mass).abs() > 1e-6 * full.mass, "{low} {full:?}");
    }

    /// A cone's measure is half the cross product in 2D and the tetrahedron's volume in 3D,
    /// signed by the face's orientation.
    #[test]
    fn a_cones_measure_is_its_simplexs() {
        let face2 = [[0.3, -0.2], [0.5, 0.6]];
        assert_eq!(cone_measure(&face2), 0.5 * (0.3 * 0.6 + 0.2 * 0.5));
        assert_eq!(cone_measure(&[face2[1], face2[0]]), -cone_measure(&face2));
        let face3 = [[0.4, 0.1, -0.2], [-0.1, 0.5, 0.3], [0.2, -0.3, 0.6]];
        let volume = crate::moments::tetra_moments(face3[0], face3[1], face3[2]).mass;
        assert!((cone_measure(&face3) - volume).abs() < 1e-17, "{volume}");
        assert!(volume > 0.0);
        let flipped = cone_measure(&[face3[1], face3[0], face3[2]]);
        assert!((flipped + volume).abs() < 1e-17, "{flipped}");
    }

    fn close<const D: usize>(a: &Moments<D>, b: &Moments<D>) {
        assert!((a.mass - b.mass).abs() < 1e-15, "{a:?} {b:?}");
        assert!((a.second - b.second).abs() < 1e-15, "{a:?} {b:?}");
        for k in 0..D {
            assert!((a.first[k] - b.first[k]).abs() < 1e-15, "{a:?} {b:?}");
        }
    }
}
