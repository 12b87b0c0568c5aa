//! A density ρ in the optimiser (DESIGN §8): the ρ-weighted gradient and Hessian against
//! central differences, in a non-convex polygon with a hole and in a dented cube; a field
//! that happens to be the polynomial gives the polynomial's moments.

use crate::common::{central_difference_error, dented_cube, interior_sites, polygon};

use hcvt_core::CoreError;
use hcvt_core::{
    evaluate, Boundary, ConvexCell, Density, DomainKind, Euclid, Field, PointRequest, PolygonCell,
    PolyhedronCell, Quadratic, Space,
};

fn rho_2d() -> Quadratic<2> {
    Quadratic::new(2.0, [0.3, -0.2], [[0.4, 0.1], [0.1, 0.6]]).unwrap()
}

fn rho_3d() -> Quadratic<3> {
    let a = [[0.5, 0.1, -0.1], [0.1, 0.3, 0.05], [-0.1, 0.05, 0.7]];
    Quadratic::new(1.5, [0.2, -0.1, 0.3], a).unwrap()
}

/// Relative errors of central differences of the weighted energy against the gradient
/// (every third site) and of the gradient along a direction against the Hessian product.
fn errors<const D: usize, C: ConvexCell<D>>(
    boundary: &Boundary<D>,
    sites: Vec<[f64; D]>,
    rho: Quadratic<D>,
) -> (f64, f64)
where
    Euclid: Space<D>,
    Boundary<D>: DomainKind<D>,
{
    let density = Density::Polynomial(rho);
    let eval = |s: Vec<[f64; D]>, hessian: bool| {
        evaluate::<D, C, _>(
            boundary,
            s,
            &PointRequest {
                hessian,
                density: Some(&density),
            },
        )
        .unwrap()
    };
    let h = (boundary.volume() / sites.len() as f64).powf(1.0 / D as f64);
    let point = eval(sites.clone(), true);
    let step = 1e-6 * h;
    let (mut err2, mut norm2) = (0.0, 0.0);
    for i in (0..sites.len()).step_by(3) {
        for k in 0..D {
            let energy_at = |delta: f64| {
                let mut moved = sites.clone();
                moved[i][k] += delta;
                eval(moved, false).energy
            };
            let fd = (energy_at(step) - energy_at(-step)) / (2.0 * step);
            err2 += (fd - point.gradient[i][k]).powi(2);
            norm2 += point.gradient[i][k].powi(2);
        }
    }
    let gradient_error = (err2 / norm2).sqrt();
    let v: Vec<[f64; D]> = (sites.iter())
        .map(|s| s.map(|x| (x * 1e4).sin() * 1e-6 * h))
        .collect();
    let exact = point.hessian_product(&v).unwrap();
    let hessian_error =
        central_difference_error(&sites, &v, &exact, |moved| eval(moved, false).gradient);
    (gradient_error, hessian_error)
}

#[test]
fn weighted_gradient_and_hessian_match_central_differences() {
    let l = polygon(&[
        &[[0., 0.], [4., 0.], [4., 2.], [2., 2.], [2., 4.], [0., 4.]],
        &[[0.5, 0.5], [0.5, 1.0], [1.0, 1.0], [1.0, 0.5]],
    ]);
    let (g, h) = errors::<2, PolygonCell>(&l, interior_sites(&l, 60, 1), rho_2d());
    assert!(g < 1e-6 && h < 1e-6, "2D: gradient {g:e}, Hessian {h:e}");
    let dented = dented_cube();
    let (g, h) = errors::<3, PolyhedronCell>(&dented, interior_sites(&dented, 60, 2), rho_3d());
    assert!(g < 1e-6 && h < 1e-6, "3D: gradient {g:e}, Hessian {h:e}");
    // A constant ρ = c weighs the Hessian by c too (the uniform path, scaled).
    let c = Quadratic::constant(2.5);
    let (g, h) = errors::<2, PolygonCell>(&l, interior_sites(&l, 30, 3), c);
    assert!(
        g < 1e-6 && h < 1e-6,
        "constant: gradient {g:e}, Hessian {h:e}"
    );
}

/// The polynomial as a field.
struct Sampled(Quadratic<3>);

impl Field<3> for Sampled {
    fn values(&self, points: Vec<[f64; 3]>) -> Result<Vec<f64>, CoreError> {
        Ok(points.iter().map(|&x| self.0.value(x)).collect())
    }
}

#[test]
fn a_field_sampled_by_a_rule_of_degree_4_equals_the_polynomial() {
    let dented = dented_cube();
    let sites = interior_sites(&dented, 80, 4);
    let rho = rho_3d();
    let field = Sampled(rho);
    let exact = Density::Polynomial(rho);
    let sampled = Density::Sampled {
        field: &field,
        degree: 4,
    };
    let a = evaluate::<3, PolyhedronCell, _>(
        &dented,
        sites.clone(),
        &PointRequest {
            hessian: false,
            density: Some(&exact),
        },
    )
    .unwrap();
    let b = evaluate::<3, PolyhedronCell, _>(
        &dented,
        sites,
        &PointRequest {
            hessian: false,
            density: Some(&sampled),
        },
    )
    .unwrap();
    for (x, y) in a.diagram.weighted.iter().zip(&b.diagram.weighted) {
        assert!((x.mass - y.mass).abs() <= 1e-12 * x.mass, "{x:?} {y:?}");
        assert!(
            (x.second - y.second).abs() <= 1e-12 * x.second,
            "{x:?} {y:?}"
        );
    }
    assert!((a.energy - b.energy).abs() <= 1e-12 * a.energy);
    let too_high = Density::Sampled {
        field: &field,
        degree: 6,
    };
    let err = evaluate::<3, PolyhedronCell, _>(
        &dented,
        vec![[0.5; 3]],
        &PointRequest {
            hessian: false,
            density: Some(&too_high),
        },
    );
    assert!(
        matches!(err, Err(CoreError::InvalidDensity { .. })),
        "{err:?}"
    );
}
