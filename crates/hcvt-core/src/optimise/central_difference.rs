//! The check of a Hessian against central differences of its gradient: test code only,
//! shared by the unit tests (`capacity.rs`) and the integration tests (`tests/common`,
//! which include this file by its path), so that it is written once.

/// `‖(g(x + v) − g(x − v)) / 2 − H v‖ / ‖H v‖` over every coordinate of every site: the
/// relative error of the Hessian product `hv` (`H v` at `sites`) against the central
/// difference of `gradient` (the gradient at moved sites) along `v`. Its truncation error
/// is of order `|v|²`: steps of 1e-6 spacings leave round-off.
pub fn central_difference_error<const D: usize>(
    sites: &[[f64; D]],
    v: &[[f64; D]],
    hv: &[[f64; D]],
    mut gradient: impl FnMut(Vec<[f64; D]>) -> Vec<[f64; D]>,
) -> f64 {
    let mut gradient_at = |t: f64| {
        let moved: Vec<[f64; D]> = (sites.iter().zip(v))
            .map(|(s, d)| std::array::from_fn(|k| s[k] + t * d[k]))
            .collect();
        gradient(moved)
    };
    let (plus, minus) = (gradient_at(1.0), gradient_at(-1.0));
    let (mut err2, mut norm2) = (0.0, 0.0);
    for ((p, m), e) in plus.iter().zip(&minus).zip(hv) {
        for k in 0..D {
            err2 += ((p[k] - m[k]) / 2.0 - e[k]).powi(2);
            norm2 += e[k].powi(2);
        }
    }
    (err2 / norm2).sqrt()
}
