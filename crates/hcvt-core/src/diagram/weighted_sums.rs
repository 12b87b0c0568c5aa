//! One cell's ρ-weighted sums over its signed pieces (DESIGN §8), as the faces and pieces
//! are measured ([`WeightedSums`]): a polynomial's weighted moments in closed form, or a
//! sampled field's cone simplices and face nodes ([`FaceNodes`]) kept for its one
//! evaluation over the whole diagram (`weighted.rs`).

use crate::density::quadrature::{self, Rule};
use std::sync::Arc;

use crate::density::{
    cone_measure, linear_face_moments, polynomial_cone, polynomial_cone_mass,
    polynomial_face_moments, Cone, Density, Quadratic, POLYNOMIAL_DEGREE, POLYNOMIAL_MASS_DEGREE,
};
use crate::error::CoreError;
use crate::geometry::{add, scale};
use crate::moments::{FaceMoments, Moments};

use super::convex_cell::ConvexCell;

/// Nodes per [`FaceNodes`]: those of [`quadrature::SEGMENT_5`] (3-point Gauss–Legendre).
pub const FACE_NODES: usize = 3;

/// A face piece whose ρ-weighted moments wait for a sampled field's values: the sphere's
/// arcs, for Newton's Hessian (DESIGN §13). Its neighbour, its nodes relative to the site
/// with the measure each stands for, and its geometric moments (exact).
#[derive(Debug, Clone, Copy)]
pub struct FaceNodes<const D: usize> {
    /// The cell across the face.
    pub neighbor: u32,
    /// `(x − site, weight)` per node, `(L, L^(d−1))`.
    pub nodes: [([f64; D], f64); FACE_NODES],
    /// `∫1`, `∫y`, `∫y yᵀ` over the face, exact.
    pub geometric: FaceMoments<D>,
}

impl<const D: usize> FaceNodes<D> {
    /// The face's ρ-weighted moments from ρ's `values` at its nodes: the rule's sums
    /// `Q[ρ f] + ρ̄ (G − Q[f])` with `ρ̄ = Q[ρ]/Q[1]`, so that a constant is exact to
    /// round-off (as the sphere's cells are, `sphere_density.rs`).
    pub fn weighted(&self, values: &[f64]) -> FaceMoments<D> {
        let (mut rho, mut one) = (FaceMoments::zero(), FaceMoments::zero());
        for (&(y, w), &v) in self.nodes.iter().zip(values) {
            let term = FaceMoments {
                measure: w,
                first: scale(y, w),
                second: y.map(|a| scale(y, w * a)),
            };
            add_face_scaled(&mut one, &term, 1.0);
            add_face_scaled(&mut rho, &term, v);
        }
        if one.measure <= 0.0 {
            return rho;
        }
        let mean = rho.measure / one.measure;
        add_face_scaled(&mut rho, &self.geometric, mean);
        add_face_scaled(&mut rho, &one, -mean);
        rho
    }
}

/// `m += c · term`, every moment.
fn add_face_scaled<const D: usize>(m: &mut FaceMoments<D>, term: &FaceMoments<D>, c: f64) {
    m.measure += c * term.measure;
    m.first = add(m.first, scale(term.first, c));
    for (row, t) in m.second.iter_mut().zip(&term.second) {
        *row = add(*row, scale(*t, c));
    }
}

/// What is summed.
#[derive(Debug, Clone)]
enum Kind<const D: usize> {
    /// No density: nothing.
    Off,
    /// A polynomial, in absolute coordinates and about the current cell's site, with the
    /// face rule of its moments and that of its masses alone.
    Polynomial {
        global: Quadratic<D>,
        local: Quadratic<D>,
        face_rule: Rule,
        mass_rule: Rule,
    },
    /// A field: the cone simplices are kept for one evaluation of the whole diagram.
    Sampled,
    /// A surface's per-vertex field (shared by the threads' copies), with the face rule:
    /// each piece's moments at once.
    PerVertex { values: Arc<[f64]>, face_rule: Rule },
}

/// The weighted moments of one cell about its site (a [`Quadratic`]), or the cone
/// simplices that give them (a [`Field`](crate::density::Field)); buffers reused from cell to cell.
#[derive(Debug, Clone)]
pub struct WeightedSums<const D: usize> {
    kind: Kind<D>,
    /// With a polynomial: `∫ρ`, `∫ρ y`, `∫ρ |y|²` so far, `y = x − site`.
    pub moments: Moments<D>,
    /// With a field: the cell's cone simplices.
    pub cones: Vec<Cone<D>>,
    /// With a field and a face integrand on the sphere: the cell's arcs, weighted once the
    /// field is sampled.
    pub faces: Vec<FaceNodes<D>>,
}

impl<const D: usize> Default for WeightedSums<D> {
    fn default() -> Self {
        Self {
            kind: Kind::Off,
            moments: Moments::zero(),
            cones: Vec::new(),
            faces: Vec::new(),
        }
    }
}

impl<const D: usize> WeightedSums<D> {
    /// Sums for `density`; off without one. Checks the degree of a field's rule.
    pub fn new(density: Option<&Density<'_, D>>) -> Result<Self, CoreError> {
        let kind = match density {
            None => Kind::Off,
            Some(Density::Polynomial(q)) => {
                let face_rule = |degree| {
                    quadrature::rule(D - 1, degree).ok_or(CoreError::InvalidDensity {
                        reason: format!("no face rule in {D} dimensions"),
                    })
                };
                Kind::Polynomial {
                    global: *q,
                    local: *q,
                    // Face averages of degree ≤ 4 on (D − 1)-simplices; ≤ 2 for the mass.
                    face_rule: face_rule(POLYNOMIAL_DEGREE)?,
                    mass_rule: face_rule(POLYNOMIAL_MASS_DEGREE)?,
                }
            }
            Some(d @ Density::Sampled { .. }) => {
                d.rule()?;
                Kind::Sampled
            }
            Some(d @ Density::PerVertex(values)) => Kind::PerVertex {
                values: Arc::from(*values),
                face_rule: d.rule_in(D - 1)?,
            },
        };
        Ok(Self {
            kind,
            ..Self::default()
        })
    }

    /// Whether there is a density.
    pub fn is_on(&self) -> bool {
        !matches!(self.kind, Kind::Off)
    }

    /// Whether the density is a field, sampled at nodes.
    pub fn is_sampled(&self) -> bool {
        matches!(self.kind, Kind::Sampled)
    }

    /// Whether face moments can be weighted ([`WeightedSums::face_moments`]): a polynomial.
    pub fn weighs_faces(&self) -> bool {
        matches!(self.kind, Kind::Polynomial { .. })
    }

    /// The ρ-weighted moments `∫ρ`, `∫ρ y`, `∫ρ y yᵀ` of the face simplex `simplex`
    /// (relative to the site) of `measure`, exact for a polynomial (degree ≤ 4 on the
    /// face); the geometric ones without a polynomial.
    pub fn face_moments(&self, simplex: &[[f64; D]; D], measure: f64) -> FaceMoments<D> {
        match &self.kind {
            Kind::Polynomial {
                local, face_rule, ..
            } => polynomial_face_moments(local, face_rule, simplex, measure),
            _ => FaceMoments::simplex(simplex, measure),
        }
    }

    /// With a polynomial: the polynomial about the current cell's site (the sphere
    /// samples it at its own nodes).
    pub fn polynomial_about_site(&self) -> Option<&Quadratic<D>> {
        match &self.kind {
            Kind::Polynomial { local, .. } => Some(local),
            _ => None,
        }
    }

    /// Begin the cell of the site at `site`: nothing summed yet.
    pub fn start_cell(&mut self, site: [f64; D]) {
        if let Kind::Polynomial { global, local, .. } = &mut self.kind {
            *local = global.about(site);
        }
        self.clear();
    }

    /// Forget what this cell has summed (an empty cell).
    pub fn clear(&mut self) {
        self.moments = Moments::zero();
        self.cones.clear();
        self.faces.clear();
    }

    /// Add the face simplex `face` (relative to the site) of `measure` as a piece of a
    /// cell of dimension `D − 1` (a surface's): a polynomial's moments at once by the
    /// face rule ([`polynomial_face_moments`], exact), a field's simplex kept for its
    /// sampling, a per-vertex field's moments from its values `corners` at the face's
    /// vertices, which `corners` reads from the field's values at the surface's vertices
    /// ([`linear_face_moments`], exact; `corners` is called for this kind only).
    pub fn add_face_piece(
        &mut self,
        face: &[[f64; D]; D],
        measure: f64,
        corners: impl FnOnce(&[f64]) -> [f64; D],
    ) {
        let m = match &self.kind {
            Kind::Off => return,
            Kind::Sampled => {
                self.cones.push((*face, measure));
                return;
            }
            Kind::Polynomial {
                local, face_rule, ..
            } => {
                let f = polynomial_face_moments(local, face_rule, face, measure);
                Moments {
                    mass: f.measure,
                    first: f.first,
                    second: (0..D).map(|k| f.second[k][k]).sum(),
                }
            }
            Kind::PerVertex { values, face_rule } => {
                linear_face_moments(face, measure, corners(values), face_rule)
            }
        };
        self.moments.add_scaled(&m, 1.0);
    }

    /// Add `piece` (relative to the site) with `sign`, cone simplex by cone simplex. With a
    /// polynomial and `face_means`, push ρ's mean over each cone's face there too, cone
    /// after cone, from the nodes that integrate the cone: what gives the faces' `∫ρ` to
    /// an integrand that reads nothing else ([`super::FaceIntegrand::is_face_mass`]).
    pub fn add_piece<C: ConvexCell<D>>(
        &mut self,
        piece: &C,
        sign: f64,
        mut face_means: Option<&mut Vec<f64>>,
    ) {
        match &self.kind {
            Kind::Off | Kind::PerVertex { .. } => {}
            Kind::Polynomial {
                local, face_rule, ..
            } => {
                let m = &mut self.moments;
                piece.for_each_cone(|face, measure| {
                    let (cone, face_mean) = polynomial_cone(local, face_rule, face, measure);
                    m.add_scaled(&cone, sign);
                    if let Some(means) = face_means.as_deref_mut() {
                        means.push(face_mean);
                    }
                });
            }
            Kind::Sampled => {
                let cones = &mut self.cones;
                piece.for_each_cone(|face, measure| cones.push((*face, sign * measure)));
            }
        }
    }

    /// With a polynomial, what gives a cone's `∫ρ` alone ([`ConeMasses`]): for a caller
    /// that reads the cells' masses and nothing else of them (the transport's trial
    /// diagrams), which adds them to [`WeightedSums::moments`]' mass itself.
    pub fn cone_masses(&self) -> Option<ConeMasses<D>> {
        match &self.kind {
            Kind::Polynomial {
                local, mass_rule, ..
            } => Some(ConeMasses {
                local: *local,
                mass_rule: *mass_rule,
            }),
            _ => None,
        }
    }
}

/// A polynomial about the current cell's site with the face rule of degree 2: the masses
/// of the cones alone, apart from the [`WeightedSums`] (copied out, a small value, while
/// the cell's faces are summed).
#[derive(Debug, Clone, Copy)]
pub struct ConeMasses<const D: usize> {
    local: Quadratic<D>,
    mass_rule: Rule,
}

impl<const D: usize> ConeMasses<D> {
    /// The `∫ρ` of the cone simplex from the site over `face` (relative to the site), of
    /// signed measure, and ρ's mean over `face` ([`polynomial_cone_mass`]: what
    /// [`WeightedSums::add_piece`] sums to round-off).
    #[inline]
    pub fn of(&self, face: &[[f64; D]; D]) -> (f64, f64) {
        polynomial_cone_mass(&self.local, &self.mass_rule, face, cone_measure(face))
    }
}
