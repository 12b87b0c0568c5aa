//! Steihaug's truncated, preconditioned conjugate gradients on Newton's quadratic model in
//! a trust region (Steihaug 1983; Nocedal and Wright, *Numerical Optimization*, Algorithm
//! 7.2), with the direction of negative curvature followed to the region's edge
//! (Steihaug–Toint). [`super::newton`] takes its steps from here.

use rayon::prelude::*;

use crate::geometry::norm2;

use super::lbfgs::{axpy, dot_rows};

/// Most CG iterations per step.
const MAX_CG_ITERATIONS: usize = 200;

/// A step of the quadratic model: the moves, the model's decrease, whether it reached
/// the region's edge.
pub(super) struct ModelStep<const D: usize> {
    /// Per site, `L`.
    pub(super) moves: Vec<[f64; D]>,
    /// `−(g·p + ½ pᵀHp)`, `L^(d+2)`.
    pub(super) decrease: f64,
    pub(super) at_edge: bool,
}

/// `Σ_i |p_i|² / w_i` over the sites of positive weight: the squared region norm of a step
/// (frozen sites, of weight 0, do not move).
pub(super) fn step_norm2<const D: usize>(p: &[[f64; D]], w: &[f64]) -> f64 {
    p.iter()
        .zip(w)
        .filter(|(_, &w)| w > 0.0)
        .map(|(x, &w)| norm2(*x) / w)
        .sum()
}

/// `product(v, out)` writes `Hv` into `out` (one row per site); `false` when there is no
/// Hessian.
pub(super) type HessianProduct<'a, const D: usize> =
    dyn FnMut(&[[f64; D]], &mut [[f64; D]]) -> bool + 'a;

/// Steihaug's truncated, preconditioned CG on `min g·p + ½ pᵀHp` over `‖p‖_M ≤ radius`
/// (`M` the inverse of the diagonal `precondition`; a zero entry keeps a site still), with
/// `product(v, out)` writing `Hv` into `out` (`false`: no Hessian, the step so far). Where
/// CG meets a direction of non-positive curvature it steps along it to the region's edge
/// (Steihaug–Toint): the model is unbounded below along it.
///
/// The region norms `‖z‖²_M`, `⟨z, d⟩_M` and `‖d‖²_M` follow from the CG scalars (Conn,
/// Gould and Toint, *Trust-Region Methods*, §7.5.1) instead of three more passes over
/// the sites, and each iteration makes two passes besides the Hessian product, in
/// parallel ([`CG_ROWS`]).
pub(super) fn steihaug<const D: usize>(
    g: &[[f64; D]],
    product: &mut HessianProduct<'_, D>,
    precondition: &[f64],
    radius: f64,
    forcing: f64,
) -> ModelStep<D> {
    let n = g.len();
    let mut z = vec![[0.0; D]; n];
    let mut r = g.to_vec();
    let mut d: Vec<[f64; D]> = r
        .iter()
        .zip(precondition)
        .map(|(v, &w)| v.map(|x| -w * x))
        .collect();
    let mut hd = vec![[0.0; D]; n];
    let mut ry = -dot_rows(&r, &d);
    let stop = forcing * forcing * ry;
    let mut decrease = 0.0;
    let (mut zz, mut zd, mut dd) = (0.0, 0.0, ry);
    let step = |z, decrease, at_edge| ModelStep {
        moves: z,
        decrease,
        at_edge,
    };
    if ry.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return step(z, decrease, false);
    }
    for iteration in 1..=MAX_CG_ITERATIONS {
        if !product(&d, &mut hd) {
            break;
        }
        let curvature = chunked_dot(&d, &hd);
        let alpha = ry / curvature;
        let inside =
            curvature > 0.0 && zz + 2.0 * alpha * zd + alpha * alpha * dd < radius * radius;
        if !inside {
            // To the edge along d: the positive root of ‖z + τ d‖_M = radius. With r the
            // residual g + Hz, d·r = −ry.
            let tau = (-zd + (zd * zd + dd * (radius * radius - zz)).max(0.0).sqrt()) / dd;
            decrease += tau * ry - 0.5 * tau * tau * curvature;
            axpy(&mut z, tau, &d);
            return step(z, decrease, true);
        }
        let ry_next = advance(&mut z, &mut r, alpha, (&d, &hd), precondition);
        decrease += 0.5 * alpha * ry;
        zz += alpha * (2.0 * zd + alpha * dd);
        if ry_next <= stop || iteration == MAX_CG_ITERATIONS {
            return step(z, decrease, false);
        }
        let beta = ry_next / ry;
        next_direction(&mut d, beta, &r, precondition);
        zd = beta * (zd + alpha * dd);
        dd = ry_next + beta * beta * dd;
        ry = ry_next;
    }
    step(z, decrease, false)
}

/// Rows per task of CG's passes over the sites, and per partial sum of its dot products:
/// fixed, so that the sums (partial sums added in chunk order) do not depend on the number
/// of threads.
///
/// Why the passes run in parallel like the Hessian product between them: with them serial,
/// the second thread fell asleep during each and was woken for the next product, and CG
/// took longer on two threads than on one (square 5k seed 0, 2D: 182 ms of CG in a
/// 634 ms run on two threads, 155 ms with the product serial too).
const CG_ROWS: usize = 512;

/// `Σ_i a_i · b_i` (rows of `D`): partial sums over chunks of [`CG_ROWS`] rows, in
/// parallel, added in chunk order.
fn chunked_dot<const D: usize>(a: &[[f64; D]], b: &[[f64; D]]) -> f64 {
    let partial: Vec<f64> = (a.par_chunks(CG_ROWS).zip(b.par_chunks(CG_ROWS)))
        .map(|(a, b)| dot_rows(a, b))
        .collect();
    partial.iter().sum()
}

/// CG's update `z += α d`, `r += α Hd` (`step = (d, Hd)`, rows of `D`) in one parallel
/// pass; returns the next preconditioned residual's `Σ_i w_i |r_i|²` (`w` the
/// preconditioner), summed as [`chunked_dot`] sums.
fn advance<const D: usize>(
    z: &mut [[f64; D]],
    r: &mut [[f64; D]],
    alpha: f64,
    step: (&[[f64; D]], &[[f64; D]]),
    w: &[f64],
) -> f64 {
    let (d, hd) = step;
    let chunks = (z.par_chunks_mut(CG_ROWS).zip(r.par_chunks_mut(CG_ROWS)))
        .zip(d.par_chunks(CG_ROWS).zip(hd.par_chunks(CG_ROWS)))
        .zip(w.par_chunks(CG_ROWS));
    let partial: Vec<f64> = chunks
        .map(|(((z, r), (d, hd)), w)| {
            let mut sum = 0.0;
            // Zipped: no bounds checks.
            let rows = (z.iter_mut().zip(r)).zip(d.iter().zip(hd).zip(w));
            for ((zi, ri), ((di, hdi), &w)) in rows {
                for k in 0..D {
                    zi[k] += alpha * di[k];
                    ri[k] += alpha * hdi[k];
                    sum += w * ri[k] * ri[k];
                }
            }
            sum
        })
        .collect();
    partial.iter().sum()
}

/// CG's next direction `d = β d − w r` (rows of `D`, `w` the preconditioner), in parallel.
fn next_direction<const D: usize>(d: &mut [[f64; D]], beta: f64, r: &[[f64; D]], w: &[f64]) {
    (d.par_chunks_mut(CG_ROWS).zip(r.par_chunks(CG_ROWS)))
        .zip(w.par_chunks(CG_ROWS))
        .for_each(|((d, r), w)| {
            for ((di, ri), &w) in d.iter_mut().zip(r).zip(w) {
                for k in 0..D {
                    di[k] = beta * di[k] - w * ri[k];
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `H v` for a block-diagonal `H` with one 2×2 block per site.
    fn block_product(
        blocks: &[[[f64; 2]; 2]],
    ) -> impl FnMut(&[[f64; 2]], &mut [[f64; 2]]) -> bool + '_ {
        move |v, out| {
            for ((o, b), x) in out.iter_mut().zip(blocks).zip(v) {
                *o = [
                    b[0][0] * x[0] + b[0][1] * x[1],
                    b[1][0] * x[0] + b[1][1] * x[1],
                ];
            }
            true
        }
    }

    /// The model's decrease `−(g·p + ½ pᵀHp)`, computed directly.
    fn model_decrease(g: &[[f64; 2]], blocks: &[[[f64; 2]; 2]], p: &[[f64; 2]]) -> f64 {
        let mut hp = vec![[0.0; 2]; p.len()];
        block_product(blocks)(p, &mut hp);
        -(dot_rows(g, p) + 0.5 * dot_rows(p, &hp))
    }

    #[test]
    fn negative_curvature_at_once_steps_to_the_edge_along_the_preconditioned_gradient() {
        // H negative definite: the first CG direction −Pg has negative curvature, and the
        // step is −Pg scaled to the region's edge in the norm of M = P⁻¹.
        let g = vec![[1.0, 2.0], [-2.0, 0.5]];
        let blocks = [[[-1.0, 0.0], [0.0, -3.0]], [[-2.0, 0.5], [0.5, -1.0]]];
        let precondition = [0.5, 0.25];
        let radius = 0.7;
        let step = steihaug(&g, &mut block_product(&blocks), &precondition, radius, 1e-6);
        assert!(step.at_edge);
        let pg: Vec<[f64; 2]> = g
            .iter()
            .zip(&precondition)
            .map(|(v, &w)| v.map(|x| -w * x))
            .collect();
        let scale = radius / step_norm2(&pg, &precondition).sqrt();
        for (z, d) in step.moves.iter().zip(&pg) {
            for k in 0..2 {
                assert!((z[k] - scale * d[k]).abs() < 1e-14, "{z:?} against {d:?}");
            }
        }
        let direct = model_decrease(&g, &blocks, &step.moves);
        assert!((step.decrease - direct).abs() < 1e-13 * direct.abs());
    }

    #[test]
    fn negative_curvature_met_later_still_reaches_the_edge_and_beats_the_cauchy_step() {
        // An indefinite H whose curvature along −g is positive: CG takes a step inside, then
        // meets negative curvature and follows it to the edge (a CG that stopped there, as
        // plain truncated CG does, would end inside with a smaller decrease).
        let g = vec![[1.0, 0.1]];
        let blocks = [[[2.0, 0.0], [0.0, -1.0]]];
        let precondition = [1.0];
        let radius = 3.0;
        let step = steihaug(&g, &mut block_product(&blocks), &precondition, radius, 1e-6);
        assert!(step.at_edge);
        let length = step_norm2(&step.moves, &precondition).sqrt();
        assert!((length - radius).abs() < 1e-12 * radius, "{length}");
        let direct = model_decrease(&g, &blocks, &step.moves);
        assert!((step.decrease - direct).abs() < 1e-12 * direct.abs());
        // The Cauchy point: the model's minimiser along −g, here inside the region.
        let gg = dot_rows(&g, &g);
        let mut hg = vec![[0.0; 2]];
        block_product(&blocks)(&g, &mut hg);
        let t = (gg / dot_rows(&g, &hg)).min(radius / gg.sqrt());
        let cauchy = model_decrease(&g, &blocks, &[[-t * g[0][0], -t * g[0][1]]]);
        assert!(
            direct > 2.0 * cauchy,
            "{direct} against the Cauchy step's {cauchy}"
        );
    }

    #[test]
    fn a_convex_model_inside_the_region_is_solved_by_cg() {
        // H positive definite, its minimiser −H⁻¹g inside the region: CG finds it.
        let g = vec![[1.0, -1.0], [0.5, 2.0]];
        let blocks = [[[2.0, 0.5], [0.5, 1.0]], [[4.0, 0.0], [0.0, 1.0]]];
        let step = steihaug(&g, &mut block_product(&blocks), &[1.0, 1.0], 100.0, 1e-12);
        assert!(!step.at_edge);
        // −H⁻¹g by hand: block 0 is [[a, b], [b, c]], its inverse [[c, −b], [−b, a]] / det.
        let (a, b, c) = (2.0, 0.5, 1.0);
        let det = a * c - b * b;
        let want = [
            [
                -(c * g[0][0] - b * g[0][1]) / det,
                -(a * g[0][1] - b * g[0][0]) / det,
            ],
            [-g[1][0] / 4.0, -g[1][1]],
        ];
        for (z, w) in step.moves.iter().zip(&want) {
            for k in 0..2 {
                assert!((z[k] - w[k]).abs() < 1e-10, "{z:?} against {w:?}");
            }
        }
    }

    #[test]
    fn cg_over_many_chunks_solves_the_model_and_does_not_depend_on_the_thread_count() {
        // 2,000 sites: four chunks of CG_ROWS, whose partial sums must add up the same on
        // any number of threads. A positive definite block-diagonal H: CG's answer is
        // −H⁻¹g, block by block.
        let n = 2_000;
        let blocks: Vec<[[f64; 2]; 2]> = (0..n)
            .map(|i| {
                let t = i as f64;
                [[2.0 + (t * 0.37).sin(), 0.3], [0.3, 1.5 + (t * 0.11).cos()]]
            })
            .collect();
        let g: Vec<[f64; 2]> = (0..n)
            .map(|i| [(i as f64 * 0.7).sin(), (i as f64 * 1.3).cos()])
            .collect();
        let precondition: Vec<f64> = (0..n).map(|i| 0.5 + (i % 7) as f64 * 0.1).collect();
        let solve = |threads: usize| {
            crate::on_threads::on_threads(threads, || {
                steihaug(&g, &mut block_product(&blocks), &precondition, 1e6, 1e-10)
            })
        };
        let one = solve(1);
        assert!(!one.at_edge);
        for (i, (z, (b, g))) in one.moves.iter().zip(blocks.iter().zip(&g)).enumerate() {
            let det = b[0][0] * b[1][1] - b[0][1] * b[1][0];
            let want = [
                -(b[1][1] * g[0] - b[0][1] * g[1]) / det,
                -(b[0][0] * g[1] - b[1][0] * g[0]) / det,
            ];
            for k in 0..2 {
                assert!(
                    (z[k] - want[k]).abs() < 1e-8,
                    "site {i}: {z:?} against {want:?}"
                );
            }
        }
        let three = solve(3);
        assert_eq!(one.moves, three.moves);
        assert_eq!(one.decrease.to_bits(), three.decrease.to_bits());
    }
}
