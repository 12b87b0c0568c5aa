//! The exact Hessian of the CVT energy (DESIGN §4, Liu et al. 2009 §3) for Newton's method:
//! its face terms as a [`FaceIntegrand`] that the diagram sums over each cell's faces in the
//! pass that measures them ([`HessianTerms`]), the [`Hessian`] assembled from those sums and
//! the cells' masses, its product with a vector, and its rows renamed with the diagram's.

use rayon::prelude::*;

use crate::diagram::{Diagram, DomainKind, FaceIntegrals, FaceIntegrand, Matrix};
use crate::geometry::{add, dot, norm2, sub};
use crate::moments::FaceMoments;

use super::reduction::Reduction;

/// The Hessian of the CVT energy `E(X) = Σ_i ∫_{Ω_i} |x − x_i|²`, exact, in `D × D` blocks.
///
/// With `F_ij` the face shared by cells `i` and `j` inside the domain, `d_ij = |x_j − x_i|`
/// and `y = x − x_i` (Liu et al. 2009, §3; the domain boundary does not move, so only the
/// faces between cells contribute):
/// `H_ij = (2/d_ij) ∫_{F_ij} (x − x_i)(x − x_j)ᵀ` and
/// `H_ii = 2 m_i I − Σ_j (2/d_ij) ∫_{F_ij} (x − x_i)(x − x_i)ᵀ`.
/// Row `i` is computed by cell `i` alone, so `H_ij` and `H_jiᵀ` agree to round-off.
#[derive(Debug, Clone, Default)]
pub struct Hessian<const D: usize> {
    /// `H_ii`, `L^d`.
    pub diagonal: Vec<Block<D>>,
    /// `H_ij` for each entry of [`Diagram::neighbor_sites`], `L^d`.
    pub off_diagonal: Vec<Block<D>>,
    /// With prescribed volumes, the term `B L⁻¹ Bᵀ` of the weights eliminated, added to
    /// every product (the Hessian of the transport cost in the sites alone).
    pub reduction: Option<Box<Reduction<D>>>,
}

/// A `D × D` block of the [`Hessian`], row-major.
pub type Block<const D: usize> = Matrix<D>;

/// The face terms of the [`Hessian`] of the diagram of `sites`: per face
/// `H_ij = (2/d_ij) ∫_{F_ij} y (y − q_ij)ᵀ` (`y = x − x_i`, `q_ij = x_j − x_i`), per cell
/// `Σ_j (2/d_ij) ∫_{F_ij} y yᵀ`.
#[derive(Debug, Clone, Copy)]
pub struct HessianTerms<'a, const D: usize> {
    /// Every site, `L`.
    pub sites: &'a [[f64; D]],
}

impl<const D: usize> FaceIntegrand<D> for HessianTerms<'_, D> {
    fn add(
        &self,
        i: usize,
        j: usize,
        to_neighbor: Option<[f64; D]>,
        sign: f64,
        m: &FaceMoments<D>,
        face: &mut Matrix<D>,
        cell: &mut Matrix<D>,
    ) {
        // Across a periodic box's face the neighbour is an image of site `j`.
        let q = to_neighbor.unwrap_or_else(|| sub(self.sites[j], self.sites[i]));
        let w = sign * 2.0 / norm2(q).sqrt();
        let rows = face.iter_mut().zip(cell.iter_mut());
        for ((block_row, face_row), (s2_row, &s1)) in rows.zip(m.second.iter().zip(&m.first)) {
            let entries = block_row.iter_mut().zip(face_row.iter_mut());
            for ((b, f), (&s2, &qc)) in entries.zip(s2_row.iter().zip(&q)) {
                *b += w * (s2 - s1 * qc);
                *f += w * s2;
            }
        }
    }
}

impl<const D: usize> Hessian<D> {
    /// The Hessian of `diagram` from the sums of its [`HessianTerms`]:
    /// `H_ii = 2 m_i I − Σ_j (2/d_ij) ∫_{F_ij} y yᵀ`, and the face terms as they are.
    pub fn new(diagram: &Diagram<D>, terms: FaceIntegrals<D>) -> Self {
        let diagonal = diagram
            .mass_moments()
            .iter()
            .zip(&terms.cells)
            .map(|(m, face_second)| {
                std::array::from_fn(|r| {
                    std::array::from_fn(|c| {
                        let diagonal = if r == c { 2.0 * m.mass } else { 0.0 };
                        diagonal - face_second[r][c]
                    })
                })
            })
            .collect();
        Self {
            diagonal,
            off_diagonal: terms.faces,
            reduction: None,
        }
    }

    /// The product `H v` with `v` (one row per site) over the neighbours of `diagram`. Rows
    /// in parallel, each summed in neighbour order: the result does not depend on the
    /// thread count.
    pub fn product(&self, diagram: &Diagram<D>, v: &[[f64; D]]) -> Vec<[f64; D]> {
        let mut out = vec![[0.0; D]; diagram.len()];
        self.product_into(diagram, v, &mut out);
        out
    }

    /// [`Hessian::product`] into `out` (one row per site).
    pub fn product_into(&self, diagram: &Diagram<D>, v: &[[f64; D]], out: &mut [[f64; D]]) {
        let row = |i: usize| -> [f64; D] {
            let mut sum = mat_vec(&self.diagonal[i], v[i]);
            for e in diagram.neighbor_offsets[i]..diagram.neighbor_offsets[i + 1] {
                let j = diagram.neighbor_sites[e] as usize;
                sum = add(sum, mat_vec(&self.off_diagonal[e], v[j]));
            }
            sum
        };
        out.par_chunks_mut(PRODUCT_ROWS)
            .enumerate()
            .for_each(|(c, rows)| {
                for (k, o) in rows.iter_mut().enumerate() {
                    *o = row(c * PRODUCT_ROWS + k);
                }
            });
        if let Some(reduction) = &self.reduction {
            reduction.add_product(diagram, v, out);
        }
    }

    /// The Riemannian Hessian on a curved domain (the sphere, DESIGN §13) from the ambient
    /// one (`self`, whose face terms the domain measured on its curved faces) at `sites`
    /// with ambient gradients `gradient`: `P_i H_ij P_j`, and on the diagonal also
    /// `− c_i P_i` with `c_i` the domain's [`DomainKind::curvature_term`] (Absil, Mahony and
    /// Sepulchre 2008, §5.5: on the unit sphere `Hess f = P ∇²f P − (x·∇f) P`). `P_i` is
    /// the projection onto the tangent plane at site `i` ([`DomainKind::tangent`]).
    pub fn along<K: DomainKind<D>>(
        &mut self,
        domain: &K,
        diagram: &Diagram<D>,
        sites: &[[f64; D]],
        gradient: &[[f64; D]],
    ) {
        let project = |b: &Block<D>, xi: [f64; D], xj: [f64; D]| -> Block<D> {
            // `B P_j` row by row (P symmetric), then `P_i` on each column.
            let right = b.map(|row| domain.tangent(xj, row));
            let columns: [[f64; D]; D] =
                std::array::from_fn(|c| domain.tangent(xi, std::array::from_fn(|r| right[r][c])));
            std::array::from_fn(|r| std::array::from_fn(|c| columns[c][r]))
        };
        self.diagonal
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, block)| {
                let x = sites[i];
                let c = domain.curvature_term(x, gradient[i]);
                *block = project(block, x, x);
                for (r, row) in block.iter_mut().enumerate() {
                    let unit: [f64; D] = std::array::from_fn(|k| if k == r { 1.0 } else { 0.0 });
                    for (b, p) in row.iter_mut().zip(domain.tangent(x, unit)) {
                        *b -= c * p;
                    }
                }
            });
        let rows: Vec<u32> = (0..diagram.len())
            .flat_map(|i| {
                let count = diagram.neighbor_offsets[i + 1] - diagram.neighbor_offsets[i];
                std::iter::repeat_n(i as u32, count)
            })
            .collect();
        self.off_diagonal
            .par_iter_mut()
            .zip(rows.par_iter().zip(&diagram.neighbor_sites))
            .for_each(|(block, (&i, &j))| {
                *block = project(block, sites[i as usize], sites[j as usize]);
            });
    }

    /// The Hessian for the sites renamed by `order`, with the diagram's face entries moved
    /// as [`Diagram::reordered_faces`] moved them (`faces[e]` the old entry of new entry `e`).
    pub fn reordered(&self, order: &[u32], faces: &[usize]) -> Self {
        let mut diagonal = vec![[[0.0; D]; D]; self.diagonal.len()];
        for (k, &i) in order.iter().enumerate() {
            diagonal[i as usize] = self.diagonal[k];
        }
        Self {
            diagonal,
            off_diagonal: faces.iter().map(|&e| self.off_diagonal[e]).collect(),
            reduction: (self.reduction.as_ref()).map(|r| Box::new(r.reordered(order, faces))),
        }
    }
}

/// `m v`. A loop, not `m.map(..)`: the array's `map` was left a call (`try_map`) in some
/// builds, 4.4% of a ball 1k Newton run's samples inside the Hessian product (perf).
#[inline]
fn mat_vec<const D: usize>(m: &Matrix<D>, v: [f64; D]) -> [f64; D] {
    let mut out = [0.0; D];
    for (o, row) in out.iter_mut().zip(m) {
        *o = dot(*row, v);
    }
    out
}

/// Rows of a Hessian product per parallel task: some 5 (2D) to 25 (3D) microseconds of
/// work each. With 1,024 the product of a 1,000-site problem was one task, and the CG
/// iterations (10-13% of a Newton run) kept one of two threads idle.
const PRODUCT_ROWS: usize = 256;

#[cfg(test)]
mod tests {
    //! Newton's Hessian on a triangle surface (issue 33): the arcs weighted by the slope of
    //! their bisectors (`diagram/surface/measure.rs`, `HessianArcs`).
    use super::*;
    use crate::diagram::{PolyhedronCell, Surface};
    use crate::geometry::{cross, scale};
    use crate::optimise::central_difference::central_difference_error;
    use crate::optimise::{evaluate, Point, PointRequest};
    use crate::sample::Lcg;

    const WITH_HESSIAN: PointRequest<'static, 3> = PointRequest {
        hessian: true,
        density: None,
    };

    /// `bunny.off` of the shared data (`$HCVT_DATA/3d`, else `../shared/data/3d` beside
    /// the repository), or `None` where it is absent.
    fn bunny() -> Option<Surface> {
        let dir = std::env::var("HCVT_DATA").map_or_else(
            |_| std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
            std::path::PathBuf::from,
        );
        let text = std::fs::read_to_string(dir.join("3d/bunny.off")).ok()?;
        let mut tokens = text.strip_prefix("OFF")?.split_whitespace();
        let mut next = || tokens.next().unwrap();
        let (nv, nf): (usize, usize) = (next().parse().unwrap(), next().parse().unwrap());
        next();
        let vertices = (0..nv)
            .map(|_| [0; 3].map(|_| next().parse().unwrap()))
            .collect();
        let faces = (0..nf)
            .map(|_| {
                assert_eq!(next(), "3");
                [0; 3].map(|_| next().parse().unwrap())
            })
            .collect();
        Some(Surface::new(vertices, faces).unwrap())
    }

    /// `n` sites near `surface`: points of random triangles off the surface along its
    /// normal by up to a tenth of the mean spacing either way (as a CVT's sites lie).
    fn sites_near(surface: &Surface, n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = Lcg::new(seed);
        let h = (surface.area() / n as f64).sqrt();
        let count = surface.triangles().len();
        (0..n)
            .map(|_| {
                let t = surface.triangles()[((rng.unit() * count as f64) as usize).min(count - 1)];
                let [a, b, c] = t.map(|v| surface.vertices()[v as usize]);
                let (mut u, mut w) = (rng.unit(), rng.unit());
                if u + w > 1.0 {
                    (u, w) = (1.0 - u, 1.0 - w);
                }
                let across = cross(sub(b, a), sub(c, a));
                let off = (2.0 * rng.unit() - 1.0) * 0.1 * h / norm2(across).sqrt();
                let on = add(a, add(scale(sub(b, a), u), scale(sub(c, a), w)));
                add(on, scale(across, off))
            })
            .collect()
    }

    /// The relative error of the Hessian product against central differences of the
    /// gradient along a direction of 1e-6 mean spacings in every coordinate.
    fn fd_error(surface: &Surface, sites: &[[f64; 3]]) -> f64 {
        let point =
            evaluate::<3, PolyhedronCell, _>(surface, sites.to_vec(), &WITH_HESSIAN).unwrap();
        let h = (surface.area() / sites.len() as f64).sqrt();
        let v: Vec<[f64; 3]> = (sites.iter())
            .map(|s| s.map(|x| (x * 1e4).sin() * 1e-6 * h))
            .collect();
        let exact = point.hessian_product(&v).unwrap();
        central_difference_error(sites, &v, &exact, |moved| {
            evaluate::<3, PolyhedronCell, _>(surface, moved, &PointRequest::default())
                .unwrap()
                .gradient
        })
    }

    /// The largest `|H_ij − H_jiᵀ|` over the neighbour pairs, relative to the largest entry.
    fn asymmetry(point: &Point<3>) -> f64 {
        let (d, h) = (&point.diagram, point.hessian.as_ref().unwrap());
        let (mut worst, mut size) = (0.0f64, 0.0f64);
        for i in 0..d.len() {
            for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                let j = d.neighbor_sites[e] as usize;
                let back = (d.neighbor_offsets[j]..d.neighbor_offsets[j + 1])
                    .find(|&b| d.neighbor_sites[b] as usize == i)
                    .expect("neighbours both ways");
                for r in 0..3 {
                    for c in 0..3 {
                        let x = h.off_diagonal[e][r][c];
                        worst = worst.max((x - h.off_diagonal[back][c][r]).abs());
                        size = size.max(x.abs());
                    }
                }
            }
        }
        worst / size
    }

    /// On the bunny (closed) and on the bunny cut open (its triangles above a plane
    /// removed): the Hessian against central differences of the gradient, 300 sites near
    /// the surface; the flat weight `2/|q|` on the arcs misses by far more; `H_ij = H_jiᵀ`;
    /// the same Hessian on 1 and 3 threads.
    #[test]
    fn surface_hessian_matches_central_differences_of_the_gradient() {
        let Some(closed) = bunny() else {
            return; // no shared data here
        };
        let (vertices, faces) = (closed.vertices().to_vec(), closed.triangles().to_vec());
        let top = vertices.iter().map(|v| v[1]).fold(f64::MIN, f64::max);
        let open: Vec<[u32; 3]> = (faces.iter().copied())
            .filter(|t| t.iter().all(|&v| vertices[v as usize][1] < top - 0.05))
            .collect();
        assert!(open.len() < faces.len() - 100);
        for (what, faces) in [("closed", faces), ("open", open)] {
            let surface = Surface::new(vertices.clone(), faces).unwrap();
            let sites = sites_near(&surface, 300, 7);
            let exact = fd_error(&surface, &sites);
            let flat = fd_error(&surface.clone().with_flat_arcs(), &sites);
            println!("{what}: relative error {exact:.1e}, with the flat weight {flat:.1e}");
            assert!(exact < 1e-6, "{what}: {exact:e}");
            assert!(flat > 1e3 * exact && flat > 1e-4, "{what}: {flat:e}");
            // Symmetric to round-off, and the same bit for bit on 1 and 3 threads.
            let hessian = |threads: usize| {
                crate::on_threads::on_threads(threads, || {
                    evaluate::<3, PolyhedronCell, _>(&surface, sites.clone(), &WITH_HESSIAN)
                        .unwrap()
                })
            };
            let (one, three) = (hessian(1), hessian(3));
            let skew = asymmetry(&one);
            assert!(skew < 1e-12, "{what}: {skew:e}");
            let (a, b) = (one.hessian.unwrap(), three.hessian.unwrap());
            assert_eq!(a.diagonal, b.diagonal, "{what}");
            assert_eq!(a.off_diagonal, b.off_diagonal, "{what}");
        }
    }

    /// The unit square (two triangles, `z = 0`) and two sites across it,
    /// `(½ ± δ, ½, ∓1)`: their bisector `δ (x − ½) = z` meets the square on the line
    /// `x = ½` at the angle `θ`, `sin θ = δ / √(1 + δ²)`. `H_12` is
    /// `(2 / (|q| max(sin θ, MIN_ARC_SINE))) ∫ (x − x_1)(x − x_2)ᵀ` over the line (Simpson,
    /// exact for the quadratic): at `δ = 0.2` exactly, and the finite differences agree
    /// (and reject the flat weight, 5x too small); at `δ = 1e-7` (the true weight 1e7
    /// times the flat one) floored at 1,000 times.
    #[test]
    fn an_arc_nearly_parallel_to_its_triangle_is_weighted_by_its_slope_floored() {
        let square = || {
            let v = vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
            Surface::new(v, vec![[0, 1, 2], [0, 2, 3]]).unwrap()
        };
        for delta in [0.2, 1e-7] {
            let sites = vec![[0.5 + delta, 0.5, 1.0], [0.5 - delta, 0.5, -1.0]];
            let point =
                evaluate::<3, PolyhedronCell, _>(&square(), sites.clone(), &WITH_HESSIAN).unwrap();
            let q = sub(sites[1], sites[0]);
            let sine = delta / (1.0 + delta * delta).sqrt();
            let w = 2.0 / (norm2(q).sqrt() * sine.max(1e-3));
            let integrand = |y: f64| -> Matrix<3> {
                let x = [0.5, y, 0.0];
                let (a, b) = (sub(x, sites[0]), sub(x, sites[1]));
                a.map(|ar| b.map(|bc| ar * bc))
            };
            let [s0, s1, s2] = [0.0, 0.5, 1.0].map(integrand);
            let hessian = point.hessian.as_ref().unwrap();
            assert_eq!(point.diagram.neighbor_sites, vec![1, 0]);
            for r in 0..3 {
                for c in 0..3 {
                    let want = w * (s0[r][c] + 4.0 * s1[r][c] + s2[r][c]) / 6.0;
                    let got = hessian.off_diagonal[0][r][c];
                    // The line's position rounds to some 1e-16/δ (its plane's normal).
                    let tol = 1e-15 / sine * w;
                    assert!((got - want).abs() <= tol, "δ {delta} {r}{c}: {got} {want}");
                }
            }
            if delta > 0.1 {
                let exact = fd_error(&square(), &sites);
                let flat = fd_error(&square().with_flat_arcs(), &sites);
                assert!(exact < 1e-7 && flat > 0.1, "{exact:e} {flat:e}");
            }
        }
    }
}
