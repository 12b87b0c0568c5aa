//! Each cell's faces, summed over its signed pieces (DESIGN §3, step 5): the measure of the
//! faces shared with each neighbour (the restricted Delaunay edges) and the cell's share of
//! the domain boundary. A caller may also have a [`FaceIntegrand`] summed over the faces
//! between cells in the same pass: the optimiser's Hessian (DESIGN §4, `optimise::hessian`,
//! a layer above) is one. The diagram hands it each piece's face moments and keeps the sums
//! in [`FaceIntegrals`], knowing nothing of what they mean.

use crate::moments::{FaceMoments, Moments};

use super::convex_cell::{ConvexCell, Face};
use super::weighted_sums::WeightedSums;

/// A `D × D` matrix, row-major: what a [`FaceIntegrand`] sums per face and per cell.
pub type Matrix<const D: usize> = [[f64; D]; D];

/// A `D × D` matrix integrated over the faces between cells while the diagram measures
/// them: one entry per face shared with a neighbour, and one sum per cell.
pub trait FaceIntegrand<const D: usize>: Sync {
    /// Add one signed piece of the face between cell `i` and its neighbour `j` to `face`
    /// (the entry of `j` in row `i`, zero at first) and to `cell` (row `i`'s sum): `m` holds
    /// the piece's moments about site `i`, and `sign` (±1) is the sign of the piece in the
    /// cone identity of DESIGN §3. `to_neighbor` is `z_j − z_i` as the cell sees it when it
    /// is not the sites' own difference: in a periodic box, where `j` borders `i` through
    /// one of its images (`None` elsewhere).
    #[allow(clippy::too_many_arguments)] // the face, its two cells and the two sums
    fn add(
        &self,
        i: usize,
        j: usize,
        to_neighbor: Option<[f64; D]>,
        sign: f64,
        m: &FaceMoments<D>,
        face: &mut Matrix<D>,
        cell: &mut Matrix<D>,
    );

    /// Whether this integrand is each face's mass alone (with a density, `∫_F ρ`): its
    /// [`FaceIntegrand::add`] adds `sign * m.measure` to `face[0][0]` and nothing else
    /// (the optimal transport's face masses). A density that weighs faces then sums that
    /// entry itself, without a call to `add` a face simplex, as the face measures are
    /// summed ([`FaceSums::add`]), and a polynomial takes each face's `∫ρ` from the nodes
    /// that integrate its cone, in the same pass.
    fn is_face_mass(&self) -> bool {
        false
    }

    /// With [`FaceIntegrand::is_face_mass`]: whether the diagram's caller reads the
    /// cells' ρ-weighted masses and nothing else of their weighted moments (the transport's
    /// trial diagrams). A polynomial density then sums each cone's `∫ρ` and its face's
    /// mean alone, by a face rule of degree 2 ([`WeightedSums::cone_masses`]), and
    /// [`super::Diagram::weighted`] holds zero first and second moments.
    fn reads_cell_masses_only(&self) -> bool {
        false
    }
}

/// What a [`FaceIntegrand`] summed over a diagram, in the diagram's rows.
#[derive(Debug, Clone, Default)]
pub struct FaceIntegrals<const D: usize> {
    /// One per cell: the sum over its faces shared with neighbours.
    pub cells: Vec<Matrix<D>>,
    /// One per entry of [`super::Diagram::neighbor_sites`].
    pub faces: Vec<Matrix<D>>,
}

/// The integrand of a cell's row: the caller's [`FaceIntegrand`] and the cell's site;
/// opaque outside the diagram.
#[derive(Clone, Copy)]
pub struct FaceRow<'a, const D: usize> {
    pub(super) integrand: &'a dyn FaceIntegrand<D>,
    pub(super) site: usize,
}

/// Signed face measures of a cell, summed over its pieces, and with a [`FaceRow`] its face
/// integrals; buffers reused from cell to cell.
#[derive(Debug)]
pub struct FaceSums<const D: usize> {
    pub(super) neighbors: Vec<(u32, f64)>,
    /// With a [`FaceRow`]: the integral over each face of `neighbors`; else empty.
    pub(super) integrals: Vec<Matrix<D>>,
    /// With a [`FaceRow`]: the cell's sum of the integrals.
    pub(super) cell_integral: Matrix<D>,
    pub(super) boundary: f64,
    /// With a density: the cell's ρ-weighted moments (or nodes), over the same pieces.
    pub(super) weighted: WeightedSums<D>,
    /// With a polynomial and a [`FaceIntegrand::is_face_mass`]: ρ's mean over each
    /// face simplex of the current piece, in [`ConvexCell::for_each_cone`]'s order.
    face_means: Vec<f64>,
}

impl<const D: usize> Default for FaceSums<D> {
    fn default() -> Self {
        Self {
            neighbors: Vec::new(),
            integrals: Vec::new(),
            cell_integral: [[0.0; D]; D],
            boundary: 0.0,
            weighted: WeightedSums::default(),
            face_means: Vec::new(),
        }
    }
}

impl<const D: usize> FaceSums<D> {
    /// Forget the last cell.
    pub(super) fn clear(&mut self) {
        self.neighbors.clear();
        self.integrals.clear();
        self.cell_integral = [[0.0; D]; D];
        self.boundary = 0.0;
        self.weighted.clear();
    }

    /// Add the faces of `piece` with `sign` (and their integrals, for a `row`; its weighted
    /// moments, with a density), and return its moments (not signed).
    pub(super) fn integrate<C: ConvexCell<D>>(
        &mut self,
        piece: &C,
        sign: f64,
        row: Option<FaceRow<'_, D>>,
    ) -> Moments<D> {
        match row {
            Some(row) if self.weighted.weighs_faces() => {
                if row.integrand.is_face_mass() {
                    self.integrate_face_masses(piece, sign, row)
                } else {
                    self.integrate_weighted_faces(piece, sign, row)
                }
            }
            Some(row) => {
                self.weighted.add_piece(piece, sign, None);
                piece.moments_and_face_moments(|f, m| self.add_moments(f, sign, &m, row))
            }
            None => {
                self.weighted.add_piece(piece, sign, None);
                piece.moments_and_faces(|f, m| {
                    self.add(f, sign * m);
                })
            }
        }
    }

    /// [`FaceSums::integrate`] with a polynomial: `row`'s integrand sees each face
    /// simplex's ρ-weighted moments, by the face rule on the simplex; the neighbours their
    /// measure.
    fn integrate_weighted_faces<C: ConvexCell<D>>(
        &mut self,
        piece: &C,
        sign: f64,
        row: FaceRow<'_, D>,
    ) -> Moments<D> {
        self.weighted.add_piece(piece, sign, None);
        let weighted = std::mem::take(&mut self.weighted);
        piece.for_each_face_simplex(|f, simplex, measure| {
            let m = weighted.face_moments(simplex, measure);
            self.add_weighted_moments(f, sign, measure, &m, row);
        });
        self.weighted = weighted;
        piece.moments()
    }

    /// [`FaceSums::integrate`] with a polynomial for the faces' masses
    /// ([`FaceIntegrand::is_face_mass`]): each face simplex's `∫ρ` is its measure times
    /// ρ's mean over it, which the nodes integrating its cone gave
    /// ([`WeightedSums::add_piece`]); no second pass over the face rule, no face moments.
    fn integrate_face_masses<C: ConvexCell<D>>(
        &mut self,
        piece: &C,
        sign: f64,
        row: FaceRow<'_, D>,
    ) -> Moments<D> {
        if row.integrand.reads_cell_masses_only() {
            return self.integrate_masses_alone(piece, sign, row);
        }
        let mut means = std::mem::take(&mut self.face_means);
        means.clear();
        self.weighted.add_piece(piece, sign, Some(&mut means));
        // The face simplices are the cones' faces, in the same order (`ConvexCell`).
        let mut face_mean = means.iter();
        piece.for_each_face_simplex(|f, _, measure| {
            let mean = face_mean.next().expect("one face simplex per cone");
            self.add_face_mass(f, sign, measure, mean * measure);
        });
        debug_assert!(face_mean.next().is_none(), "one cone per face simplex");
        self.face_means = means;
        piece.moments()
    }

    /// [`FaceSums::integrate_face_masses`] for a caller of the cells' masses alone
    /// ([`FaceIntegrand::reads_cell_masses_only`]): one pass over the face simplices, each
    /// adding its cone's `∫ρ` to the cell's and its own `∫ρ` to its face, both from the
    /// nodes of the face rule of degree 2 ([`WeightedSums::cone_masses`]); the first and
    /// second weighted moments stay zero.
    fn integrate_masses_alone<C: ConvexCell<D>>(
        &mut self,
        piece: &C,
        sign: f64,
        row: FaceRow<'_, D>,
    ) -> Moments<D> {
        let Some(cones) = self.weighted.cone_masses() else {
            return self.integrate_weighted_faces(piece, sign, row);
        };
        let mut mass = 0.0;
        piece.for_each_face_simplex(|f, simplex, measure| {
            let (cone, mean) = cones.of(simplex);
            mass += cone;
            self.add_face_mass(f, sign, measure, mean * measure);
        });
        self.weighted.moments.mass += sign * mass;
        piece.moments()
    }

    /// Add a face's measure; the index of its neighbour's entry, if it has one.
    pub(super) fn add(&mut self, face: Face, measure: f64) -> Option<usize> {
        match face {
            Face::Neighbor(j) => Some(match self.neighbors.iter().position(|(k, _)| *k == j) {
                Some(at) => {
                    self.neighbors[at].1 += measure;
                    at
                }
                None => {
                    self.neighbors.push((j, measure));
                    self.neighbors.len() - 1
                }
            }),
            // Each piece's face on T is T ∩ C itself, whatever the piece's sign.
            Face::Boundary(_) => {
                self.boundary += measure.abs();
                None
            }
            Face::Box | Face::Cone => None,
        }
    }

    /// Add a face with its moments `m` about the site, and its terms of the integrand of
    /// `row`.
    pub(super) fn add_moments(
        &mut self,
        face: Face,
        sign: f64,
        m: &FaceMoments<D>,
        row: FaceRow<'_, D>,
    ) {
        self.add_weighted_moments(face, sign, m.measure, m, row);
    }

    /// [`FaceSums::add_moments`] with the face's `measure` apart from its moments `m`
    /// (weighted by a density, DESIGN §8).
    pub(super) fn add_weighted_moments(
        &mut self,
        face: Face,
        sign: f64,
        measure: f64,
        m: &FaceMoments<D>,
        row: FaceRow<'_, D>,
    ) {
        let Some(at) = self.add_with_integral(face, sign * measure) else {
            return;
        };
        let j = self.neighbors[at].0 as usize;
        let (face, cell) = (&mut self.integrals[at], &mut self.cell_integral);
        row.integrand.add(row.site, j, None, sign, m, face, cell);
    }

    /// Add a face's `measure` and its `mass` (`∫ρ`) with `sign`, the mass in entry
    /// `[0][0]` of its integral: what [`FaceIntegrand::add`] of an integrand that
    /// [`FaceIntegrand::is_face_mass`] does, without the call through its vtable nor the
    /// face's moments: 1.0% fewer instructions in a transport with a polynomial density
    /// (10,000 sites, square and L-shape; `docs/results/transport.txt` §21).
    fn add_face_mass(&mut self, face: Face, sign: f64, measure: f64, mass: f64) {
        if let Some(at) = self.add_with_integral(face, sign * measure) {
            self.integrals[at][0][0] += sign * mass;
        }
    }

    /// [`FaceSums::add`], and a zero integral for a neighbour's new entry.
    fn add_with_integral(&mut self, face: Face, measure: f64) -> Option<usize> {
        let at = self.add(face, measure)?;
        if at == self.integrals.len() {
            self.integrals.push([[0.0; D]; D]);
        }
        Some(at)
    }

    /// Keep the faces of positive measure, sorted by neighbour, with their integrals if
    /// kept: both lists together, in place.
    pub(super) fn sort_neighbors(&mut self) {
        let paired = !self.integrals.is_empty();
        let mut kept = 0;
        for k in 0..self.neighbors.len() {
            if self.neighbors[k].1 > 0.0 {
                self.neighbors.swap(kept, k);
                if paired {
                    self.integrals.swap(kept, k);
                }
                kept += 1;
            }
        }
        self.neighbors.truncate(kept);
        self.integrals.truncate(kept);
        // Insertion sort by neighbour: a dozen entries or so.
        for k in 1..kept {
            let mut at = k;
            while at > 0 && self.neighbors[at - 1].0 > self.neighbors[at].0 {
                self.neighbors.swap(at - 1, at);
                if paired {
                    self.integrals.swap(at - 1, at);
                }
                at -= 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::density::{Density, Quadratic};
    use crate::diagram::{PolygonCell, PolyhedronCell};
    use crate::geometry::{Aabb, HalfSpace};

    /// Sums each face's `∫ρ` in entry `[0][0]`, as a face mass or from the face's
    /// moments, and the cells' masses alone or not.
    struct Masses {
        face_mass: bool,
        cells_alone: bool,
    }

    impl<const D: usize> FaceIntegrand<D> for Masses {
        fn add(
            &self,
            _: usize,
            _: usize,
            _: Option<[f64; D]>,
            sign: f64,
            m: &FaceMoments<D>,
            face: &mut Matrix<D>,
            _: &mut Matrix<D>,
        ) {
            face[0][0] += sign * m.measure;
        }

        fn is_face_mass(&self) -> bool {
            self.face_mass
        }

        fn reads_cell_masses_only(&self) -> bool {
            self.cells_alone
        }
    }

    /// `cell` and a piece of it with sign −1 (as a cell crossing the boundary has),
    /// integrated by `FaceSums` for an integrand of face masses and one reading the
    /// faces' moments: the same faces, `∫ρ` over each to round-off, the cell's
    /// moments and weighted moments bit for bit; and for one reading the cells' masses
    /// alone: the same faces, `∫ρ` over each and over the cell to round-off, no first or
    /// second weighted moments.
    fn same_masses_either_way<const D: usize, C: ConvexCell<D>>(
        rho: Quadratic<D>,
        site: [f64; D],
        cell: &C,
        piece: &C,
    ) {
        let density = Density::Polynomial(rho);
        let sums = |face_mass: bool, cells_alone: bool| {
            let integrand = Masses {
                face_mass,
                cells_alone,
            };
            let row = FaceRow {
                integrand: &integrand,
                site: 0,
            };
            let mut faces = FaceSums::<D> {
                weighted: WeightedSums::new(Some(&density)).unwrap(),
                ..FaceSums::default()
            };
            faces.weighted.start_cell(site);
            let whole = faces.integrate(cell, 1.0, Some(row));
            let part = faces.integrate(piece, -1.0, Some(row));
            faces.sort_neighbors();
            (faces, whole, part)
        };
        let (masses, moments) = (sums(true, false), sums(false, false));
        let alone = sums(true, true);
        assert_eq!(alone.1, moments.1);
        assert_eq!(alone.0.neighbors, moments.0.neighbors);
        let (mass, full) = (alone.0.weighted.moments, moments.0.weighted.moments);
        assert!(
            (mass.mass - full.mass).abs() <= 1e-14 * full.mass,
            "{mass:?} {full:?}"
        );
        assert_eq!((mass.first, mass.second), ([0.0; D], 0.0));
        let pairs = alone.0.integrals.iter().zip(&moments.0.integrals);
        for (a, b) in pairs {
            let (a, b) = (a[0][0], b[0][0]);
            assert!(b > 0.0 && (a - b).abs() <= 1e-14 * b, "{a} vs {b}");
        }
        assert_eq!(masses.1, moments.1);
        assert_eq!(masses.2, moments.2);
        assert_eq!(masses.0.weighted.moments, moments.0.weighted.moments);
        assert_eq!(masses.0.neighbors, moments.0.neighbors);
        assert!(masses.0.neighbors.len() >= 2, "{:?}", masses.0.neighbors);
        let pairs = masses.0.integrals.iter().zip(&moments.0.integrals);
        for (a, b) in pairs {
            let (a, b) = (a[0][0], b[0][0]);
            assert!(b > 0.0 && (a - b).abs() <= 1e-14 * b, "{a} vs {b}");
        }
    }

    #[test]
    fn face_masses_from_the_cones_nodes_are_the_face_rules() {
        let rho = Quadratic::new(1.0, [1.0, 0.5], [[0.0, 0.3], [0.3, 2.0]]).unwrap();
        let site = [0.4, 0.7];
        let mut cell = PolygonCell::from_box(&Aabb {
            lo: [-0.4, -0.7],
            hi: [0.6, 0.3],
        });
        for (normal, offset, j) in [([1.0, 1.0], 0.3, 3), ([-1.0, 0.4], 0.2, 5)] {
            cell.clip(&HalfSpace { normal, offset }, Face::Neighbor(j));
        }
        let mut piece = cell.clone();
        piece.clip(
            &HalfSpace {
                normal: [0.0, 1.0],
                offset: -0.1,
            },
            Face::Boundary(0),
        );
        same_masses_either_way(rho, site, &cell, &piece);

        let rho = Quadratic::new(
            2.0,
            [1.0, -0.5, 0.3],
            [[1.0, 0.2, 0.0], [0.2, 0.5, 0.1], [0.0, 0.1, 2.0]],
        )
        .unwrap();
        let site = [0.5, 0.5, 0.5];
        let mut cell = PolyhedronCell::from_box(&Aabb {
            lo: [-0.5; 3],
            hi: [0.5; 3],
        });
        let planes = [([1.0, 1.0, 0.0], 0.4, 2), ([0.0, -1.0, 1.0], 0.3, 7)];
        for (normal, offset, j) in planes {
            cell.clip(&HalfSpace { normal, offset }, Face::Neighbor(j));
        }
        let mut piece = cell.clone();
        piece.clip(
            &HalfSpace {
                normal: [0.0, 0.0, 1.0],
                offset: -0.2,
            },
            Face::Boundary(0),
        );
        same_masses_either_way(rho, site, &cell, &piece);
    }
}
