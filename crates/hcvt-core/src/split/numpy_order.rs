//! Sums and dot products rounded in the order numpy rounds them.
//!
//! The split's search compares the badness of cuts and stops at thresholds (a pyramid
//! below `-1e-15`, a skewness above 4(1 − 1e-6)), and the final check measures the whole
//! mesh with numpy (`hcvt.export.quality`): a result that differs from numpy's in its last
//! bit could pass a face there that fails here. Each helper here reproduces one numpy
//! expression that the reference (the search's former Python version) used, as measured on
//! numpy 2.4 (x86-64, baseline SIMD SSE4.2, OpenBLAS matrix-vector products): the
//! expression is named in each doc. Elsewhere plain Rust arithmetic already matches
//! numpy's elementwise operations (no fused multiply-add unless written).

/// numpy's pairwise summation (`pairwise_sum` in `loops_utils.h.src`): sequential below 8
/// terms, eight running sums up to 128, halves beyond. Starts from `-0.0`, as numpy does.
pub(crate) fn pairwise_sum(values: &[f64]) -> f64 {
    pairwise_sum_of(0, values.len(), &|i| values[i])
}

/// [`pairwise_sum`] of `term(start)`, ..., `term(start + n - 1)`.
fn pairwise_sum_of(start: usize, n: usize, term: &impl Fn(usize) -> f64) -> f64 {
    const BLOCK: usize = 128;
    if n < 8 {
        return (start..start + n).fold(-0.0, |sum, i| sum + term(i));
    }
    if n > BLOCK {
        let half = n / 2;
        let half = half - half % 8;
        return pairwise_sum_of(start, half, term) + pairwise_sum_of(start + half, n - half, term);
    }
    let mut lanes: [f64; 8] = std::array::from_fn(|j| term(start + j));
    let whole = n - n % 8;
    for block in (8..whole).step_by(8) {
        for (j, lane) in lanes.iter_mut().enumerate() {
            *lane += term(start + block + j);
        }
    }
    let [r0, r1, r2, r3, r4, r5, r6, r7] = lanes;
    let sum = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7));
    (whole..n).fold(sum, |sum, i| sum + term(start + i))
}

/// `np.sum(values)` of a 1-D array: the identity 0, plus the pairwise sum.
pub(crate) fn array_sum(values: &[f64]) -> f64 {
    0.0 + pairwise_sum(values)
}

/// One segment of `np.add.reduceat` over `term(0)`, ..., `term(n - 1)`: the first term,
/// plus the pairwise sum of the rest.
pub(crate) fn reduceat_sum(n: usize, term: impl Fn(usize) -> f64) -> f64 {
    match n {
        0 => 0.0,
        _ => term(0) + pairwise_sum_of(1, n - 1, &term),
    }
}

/// `np.einsum("ij,ij->i", a, b)` on rows of 3: two SSE lanes, the third product added to
/// the first lane.
pub(crate) fn row_dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] * b[0] + a[2] * b[2]) + a[1] * b[1]
}

/// `np.linalg.norm(a, axis=1)` on rows of 3: the squares summed in order.
pub(crate) fn row_norm(a: [f64; 3]) -> f64 {
    ((a[0] * a[0] + a[1] * a[1]) + a[2] * a[2]).sqrt()
}

/// A row of `(k, 3) @ (3,)`, which numpy hands to OpenBLAS's `dgemv`: fused, the first
/// product onto the second, then the third.
pub(crate) fn matvec_dot(row: [f64; 3], v: [f64; 3]) -> f64 {
    row[2].mul_add(v[2], row[0].mul_add(v[0], row[1] * v[1]))
}

/// `(3,) @ (3,)`, OpenBLAS's `ddot`: fused, in order.
pub(crate) fn vector_dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[2].mul_add(b[2], a[1].mul_add(b[1], a[0] * b[0]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each order differs from the naive left-to-right one where `1e16 + 1` rounds back
    /// to `1e16`: the sums below tell the orders apart (values found with numpy 2.4).
    #[test]
    fn the_orders_are_numpys() {
        let big = 1e16;
        assert_eq!(array_sum(&[big, 1.0, 1.0]), big);
        let terms = [big, 1.0, 1.0];
        assert_eq!(reduceat_sum(3, |i| terms[i]), big + 2.0);
        assert_eq!(row_dot([1.0, big, 1.0], [1.0; 3]), big + 2.0);
        assert_eq!(row_dot([1.0, 1.0, big], [1.0; 3]), big);
        // Nine terms: eight lanes, then the ninth added to their total.
        let mut nine = [1.0; 9];
        nine[0] = big;
        assert_eq!(pairwise_sum(&nine), big + 8.0);
        // x·y = 1 - 2^-60 rounds to 1; fused with -1 it is kept.
        let (x, y) = (1.0 + 2f64.powi(-30), 1.0 - 2f64.powi(-30));
        assert_eq!(matvec_dot([x, -1.0, 0.0], [y, 1.0, 0.0]), -(2f64.powi(-60)));
        assert_eq!(matvec_dot([-1.0, x, 0.0], [1.0, y, 0.0]), 0.0);
        assert_eq!(vector_dot([-1.0, x, 0.0], [1.0, y, 0.0]), -(2f64.powi(-60)));
    }
}
