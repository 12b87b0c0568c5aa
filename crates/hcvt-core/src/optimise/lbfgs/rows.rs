//! Row helpers shared by the optimisers: sums over sites in index order, moves, and the
//! mass preconditioner `1/(2 m_i)`.

use crate::geometry::dot;

use crate::optimise::point::Point;

/// `Σ_i a_i · b_i` over rows, in index order.
pub fn dot_rows<const D: usize>(a: &[[f64; D]], b: &[[f64; D]]) -> f64 {
    a.iter().zip(b).map(|(&x, &y)| dot(x, y)).sum()
}

/// `a += t · b`, row by row.
pub fn axpy<const D: usize>(a: &mut [[f64; D]], t: f64, b: &[[f64; D]]) {
    for (x, y) in a.iter_mut().zip(b) {
        for k in 0..D {
            x[k] += t * y[k];
        }
    }
}

/// The sites `x + t p`.
pub fn moved<const D: usize>(x: &[[f64; D]], t: f64, p: &[[f64; D]]) -> Vec<[f64; D]> {
    let mut out = x.to_vec();
    axpy(&mut out, t, p);
    out
}

/// The preconditioner `1/(2 m_i)` of site `i` (`m_i = ∫ρ` with a density): the inverse of
/// the energy's Hessian without its neighbour terms. A cell of zero mass is reseeded before
/// we get here; the floor only keeps it finite.
pub fn mass_preconditioner<const D: usize>(point: &Point<D>) -> Vec<f64> {
    preconditioner(point.diagram.mass_moments().iter().map(|m| m.mass))
}

/// [`mass_preconditioner`] from the masses `m_i` alone (a part of a partitioned run).
pub fn preconditioner(masses: impl IntoIterator<Item = f64>) -> Vec<f64> {
    masses
        .into_iter()
        .map(|m| 0.5 / m.max(f64::MIN_POSITIVE))
        .collect()
}
