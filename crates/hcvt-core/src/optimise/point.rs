//! An iterate: the sites' diagram, energy, gradient and (for Newton) Hessian, from one
//! clipped diagram.

use crate::density::Density;
use crate::diagram::{
    clipped_diagram, ConvexCell, Diagram, DomainKind, FaceIntegrand, Request as DiagramRequest,
    WarmStart,
};
use crate::error::CoreError;
use crate::geometry::{Euclid, Space};

use super::hessian::{Hessian, HessianTerms};

/// Energy tolerance of the line search relative to `|E|`: 40 times the round-off of the
/// energy (translating the domain and 2,000 random sites changed `E` by at most 2.4e-14
/// relative, star and bunny), far below any decrease that L-BFGS makes before the gap
/// reaches `√eps`.
pub const ENERGY_NOISE: f64 = 1e-12;

/// What [`evaluate`] computes besides the diagram, energy and gradient.
#[derive(Debug, Clone, Copy, Default)]
pub struct PointRequest<'a, const D: usize> {
    /// The energy's [`Hessian`] too (for Newton): its face terms are summed in the
    /// diagram's pass over the faces ([`HessianTerms`]).
    pub hessian: bool,
    /// The density ρ (DESIGN §8): energy and gradient from the ρ-weighted moments, and the
    /// Hessian with `2 m_i` the ρ-weighted mass and its face terms weighted by ρ on each
    /// face (exact for a polynomial; a sampled field has no Hessian, [`cvt`] refuses Newton
    /// with one).
    ///
    /// [`cvt`]: super::cvt
    pub density: Option<&'a Density<'a, D>>,
}

/// Sites with their diagram, energy and gradient.
#[derive(Debug, Clone)]
pub struct Point<const D: usize> {
    /// The sites, `L`.
    pub sites: Vec<[f64; D]>,
    /// Their clipped diagram.
    pub diagram: Diagram<D>,
    /// The energy's Hessian, when asked for ([`PointRequest::hessian`]).
    pub hessian: Option<Hessian<D>>,
    /// `E = Σ_i tr M2_i`, summed in index order, `L^(d+2)`.
    pub energy: f64,
    /// `g_i = −2 m1_i`, `L^(d+1)`.
    pub gradient: Vec<[f64; D]>,
}

impl<const D: usize> Point<D> {
    /// The product `H v` of the energy's [`Hessian`] with `v` (one row per site), `None`
    /// unless the point was evaluated with it ([`Hessian::product`]).
    pub fn hessian_product(&self, v: &[[f64; D]]) -> Option<Vec<[f64; D]>> {
        let h = self.hessian.as_ref()?;
        Some(h.product(&self.diagram, v))
    }

    /// [`Point::hessian_product`] into `out` (one row per site); `false` (and `out`
    /// untouched) without the Hessian.
    pub fn hessian_product_into(&self, v: &[[f64; D]], out: &mut [[f64; D]]) -> bool {
        let Some(h) = self.hessian.as_ref() else {
            return false;
        };
        h.product_into(&self.diagram, v, out);
        true
    }
}

/// The diagram of `sites` with its energy and gradient, and what `request` asks for: one
/// diagram computation.
///
/// Errors are the diagram's: a site outside the domain, coinciding or non-finite sites; a
/// density not finite and positive where it is sampled.
pub fn evaluate<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    request: &PointRequest<'_, D>,
) -> Result<Point<D>, CoreError>
where
    Euclid: Space<D>,
{
    evaluate_from::<D, C, K>(domain, sites, request, None)
}

/// [`evaluate`] warm-started from the previous diagram's near-site lists in `warm`
/// (empty: cold), which it replaces by this diagram's: the same point bit for bit, faster
/// when the sites moved little since (issue 32). Lloyd and L-BFGS evaluate this way.
pub fn evaluate_warm<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    request: &PointRequest<'_, D>,
    warm: &mut WarmStart<D>,
) -> Result<Point<D>, CoreError>
where
    Euclid: Space<D>,
{
    evaluate_from::<D, C, K>(domain, sites, request, Some(warm))
}

/// [`evaluate`], warm-started when `warm` is given (and then replaced by this diagram's
/// lists, when the domain kind records them).
fn evaluate_from<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    request: &PointRequest<'_, D>,
    warm: Option<&mut WarmStart<D>>,
) -> Result<Point<D>, CoreError>
where
    Euclid: Space<D>,
{
    let terms = HessianTerms { sites: &sites };
    let integrand = request.hessian.then_some(&terms as &dyn FaceIntegrand<D>);
    let clipped = clipped_diagram::<D, C, K>(
        domain,
        &sites,
        &DiagramRequest {
            integrand,
            density: request.density,
            warm: warm.as_deref(),
            ..DiagramRequest::default()
        },
    )?;
    if let (Some(warm), Some(next)) = (warm, clipped.warm) {
        *warm = next;
    }
    let diagram = clipped.diagram;
    let ambient = diagram.gradient();
    let hessian = request.hessian.then(|| {
        let mut hessian = Hessian::new(&diagram, clipped.face_integrals);
        if domain.cell_dim() != D {
            // On a surface the Riemannian Hessian, along the tangent planes.
            hessian.along(domain, &diagram, &sites, &ambient);
        }
        hessian
    });
    // The gradient along the domain: itself in a flat one, its tangent part on the sphere.
    let gradient = (ambient.into_iter().zip(&sites))
        .map(|(g, &x)| domain.tangent(x, g))
        .collect();
    Ok(Point {
        energy: diagram.energy(),
        gradient,
        hessian,
        diagram,
        sites,
    })
}
