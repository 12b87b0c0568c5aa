//! A periodic box as a kind of domain (DESIGN §14): the torus `[lo, hi)` along its periodic
//! axes (all of them, or some), an ordinary box ([`super::BoxDomain`]) along the others.
//!
//! **Cells.** Site `i`'s cell is the set of points nearer to `z_i` than to every image
//! `z_j + k∘L` of every site (`L = hi − lo`, `k` integer, zero on the non-periodic axes).
//! It starts from the box of the torus' size centred on its site (a little larger,
//! [`DomainKind::start`]), which its own images `z_i ± L_m e_m` cut exactly in half
//! periods: no side clips it along a periodic axis; along the others the box's sides clip
//! it as they clip a [`super::BoxDomain`] cell. Each neighbour face carries its image
//! shift `k` ([`super::Diagram::neighbor_images`]), so a site can have another site as
//! neighbour across several faces (few sites), or itself (one site: the whole box).
//!
//! **Images in the kNN.** The cells are computed by the ordinary driver among the sites
//! and a band of their images: each image `z_j + k∘L`, `k ∈ {−1, 0, 1}^d` on the periodic
//! axes, whose coordinates lie within `band` of the box, appended after the sites
//! ([`Images`]). Chosen over wrapped queries (a kNN grid that wraps its rings) because
//! the kNN index, the streaming of neighbours, the security radius, the localisation and
//! the vertex checks are then those of the other kinds, unchanged (no branch on their hot
//! path), and because each cell already reports its reach, the distance within which it
//! read sites (the partitions' certificate, DESIGN §10): that the band held every image a
//! cell needed is checked, not assumed (freud's cells depend on the size of its ghost
//! buffer, freud #128). The cells whose reach passes the band's cover are computed again
//! with the band doubled (only they: a few per 100k sites). Once the band reaches the
//! largest period all `3^p − 1` images of every site are present, which certifies every
//! cell: it lies in the half-period box around its site, where an image with some
//! `|k_m| ≥ 2` is never nearer than the image with `k_m` one step nearer zero (the sites
//! being in `[lo, hi)`), so images beyond ±1 cut nothing. So a box of few sites, whose
//! cells reach their own images (ALGORITHMS, pitfalls), needs no special case. A band of `b` spacings ([`FIRST_BAND`]: 8 in 2D, 3 in 3D) adds about
//! `2 d b / n^{1/d}` of the sites as images: 10% at 100k sites in 2D, 40% in 3D.
//!
//! **Sites.** Along periodic axes a site may lie anywhere: its cell is that of its image in
//! `[lo, hi)` ([`Torus::wrap`]) and, as moments are taken about the site, the same
//! for both; the centroid ([`super::Diagram::centroids`]) is next to the site as given, and
//! the image shifts are those between the wrapped sites. The optimisers need nothing more:
//! a step may carry a site across a periodic side, and [`DomainKind::locate`] says it is
//! still inside (a torus has no side), so no site is held or pinned there;
//! [`crate::optimise::cvt`] returns the sites wrapped. A lattice tiles the torus only when
//! its cells fit the box (e.g. `2m³` BCC sites in a cube).

use crate::error::CoreError;
use crate::geometry::{sub, Aabb, Euclid, Space};
use crate::moments::{FaceMoments, Moments};

use super::box_domain::BoxDomain;
use super::clip::MeasureScratch;
use super::convex_cell::ConvexCell;
use super::domain_kind::{DomainKind, BOX_MARGIN};
use super::faces::{FaceIntegrals, FaceIntegrand, FaceRow, Matrix};
use super::knn::SiteIndex;
use super::order::morton_order;
use super::output::PartCells;
use super::output::{Batch, Clipped, Diagram};
use super::power::Power;
use super::request::{checked_part, checked_windings, Request};
use super::torus::Torus;
use super::visit::{without_errors, Visit};
use super::weighted_sums::WeightedSums;

/// Width of the first band of images, in mean spacings `(V/n)^{1/d}`, per dimension. The
/// reach of a cell (twice its radius) is about 2.5 spacings for random sites, with a tail:
/// in 2D at 50k random sites a band of 3 left 10 cells uncovered (computed again, with a
/// second index over all sites and twice the band), 5 left 2, 8 none; instructions per
/// diagram 737.8M, 717.1M and 696.2M, the box's 698.2M (callgrind); 8 spacings add 3% of
/// the sites as images at 1M. In 3D images weigh more: 3 spacings add 83% of the sites at
/// 20k and 40% at 100k (where 2 cells of 100k are computed again), and 5 spacings cost
/// 0.9% more instructions than 3 at 20k.
const FIRST_BAND: [f64; 4] = [8.0, 8.0, 8.0, 3.0];

/// The box `[lo, hi]`, periodic along the axes marked so (sides of positive length).
/// Along a non-periodic axis `k` its sides are boundary elements `2k` (`x_k = lo_k`) and
/// `2k + 1` (`x_k = hi_k`), as a [`super::BoxDomain`]'s.
#[derive(Debug, Clone, PartialEq)]
pub struct PeriodicBox<const D: usize> {
    /// The plain box: its corners, and its sides along the axes that are not periodic.
    plain: BoxDomain<D>,
    torus: Torus<D>,
}

impl<const D: usize> PeriodicBox<D> {
    /// The box between the corners `lo` and `hi`, periodic along the axes where `periodic`
    /// is true.
    ///
    /// Errors: a non-finite coordinate (vertex 0 is `lo`, 1 is `hi`), or a side of zero or
    /// negative length.
    pub fn new(lo: [f64; D], hi: [f64; D], periodic: [bool; D]) -> Result<Self, CoreError> {
        let plain = BoxDomain::new(lo, hi)?;
        let torus = Torus::new(Aabb { lo, hi }, periodic);
        if torus.periods().iter().any(|&p| !p.is_finite()) {
            return Err(CoreError::NonPositiveVolume {
                volume: torus.volume(),
            });
        }
        Ok(Self { plain, torus })
    }

    /// The box of `torus` (a [`PeriodicBox`]'s, so checked already).
    fn of(torus: &Torus<D>) -> Self {
        Self {
            plain: BoxDomain::of_checked(torus.bounds()),
            torus: *torus,
        }
    }

    /// The box as a torus: its periods, its periodic axes, the wrap into `[lo, hi)`.
    pub fn torus(&self) -> &Torus<D> {
        &self.torus
    }

    /// The axes that are not periodic: where the box's sides clip.
    fn fixed(&self) -> [bool; D] {
        self.torus.periodic_axes().map(|p| !p)
    }
}

impl<const D: usize> DomainKind<D> for PeriodicBox<D> {
    fn bounds(&self) -> Aabb<D> {
        self.torus.bounds()
    }

    /// The torus' size along the periodic axes, centred on the site (and a thousandth of
    /// a period more: its own images then cut the cell, and each such face is a neighbour
    /// face); the box, a little larger, along the others.
    fn start(&self, site: [f64; D]) -> Aabb<D> {
        let (bounds, periodic) = (self.torus.bounds(), self.torus.periodic_axes());
        let margin = BOX_MARGIN * bounds.diagonal();
        let periods = self.torus.periods();
        let half: [f64; D] = std::array::from_fn(|k| (0.5 + BOX_MARGIN) * periods[k]);
        Aabb {
            lo: std::array::from_fn(|k| {
                if periodic[k] {
                    -half[k]
                } else {
                    bounds.lo[k] - margin - site[k]
                }
            }),
            hi: std::array::from_fn(|k| {
                if periodic[k] {
                    half[k]
                } else {
                    bounds.hi[k] + margin - site[k]
                }
            }),
        }
    }

    fn periodic(&self) -> Option<&Torus<D>> {
        let periodic = self.torus.periodic_axes();
        periodic.iter().any(|&p| p).then_some(&self.torus)
    }

    fn volume(&self) -> f64 {
        self.torus.volume()
    }

    /// Along periodic axes every point is inside (it stands for its image in the box); the
    /// box test along the others.
    fn locate(&self, point: &[f64; D]) -> Option<i32> {
        self.plain.locate_along(point, self.fixed())
    }

    fn density_checkpoints(&self) -> &[[f64; D]] {
        self.plain.density_checkpoints()
    }

    fn is_convex(&self) -> bool {
        true
    }

    fn cut_convex<C: ConvexCell<D>>(&self, cell: &mut C, site: [f64; D], _: &mut Vec<u32>) -> bool {
        self.plain.cut_along(cell, site, self.fixed());
        true
    }

    fn local_radius2<C: ConvexCell<D>>(&self, cell: &C, _: [f64; D]) -> f64 {
        cell.max_dist2()
    }

    fn clip<C: ConvexCell<D>>(
        &self,
        cell: &C,
        site: [f64; D],
        _: Option<i32>,
        row: Option<FaceRow<'_, D>>,
        scratch: &mut MeasureScratch<D, C>,
    ) -> Moments<D> {
        self.plain
            .clip_along(cell, site, self.fixed(), row, scratch)
    }
}

/// The sites wrapped into the box, then the images within `band` of it: what the cells of
/// a periodic box are computed among.
struct Images<const D: usize> {
    /// `n` wrapped sites, then the images.
    sites: Vec<[f64; D]>,
    n: usize,
    /// Per image (entry `n + g` of `sites`): its site and its shift `k`.
    source: Vec<u32>,
    shift: Vec<[i8; D]>,
    /// Images within this distance of the box along every periodic axis are present; all
    /// `3^p − 1` of every site when infinite.
    band: f64,
}

impl<const D: usize> Images<D> {
    fn new(torus: &Torus<D>, wrapped: &[[f64; D]], band: f64) -> Self {
        let (Aabb { lo, hi }, periods) = (torus.bounds(), torus.periods());
        let periodic = torus.periodic_axes();
        // Shift codes: digit m of the code in base 3 is k_m = 0, +1, −1; code 0 is the site.
        let shifts: Vec<[i8; D]> = (1..3usize.pow(D as u32))
            .map(|code| {
                std::array::from_fn(|m| match code / 3usize.pow(m as u32) % 3 {
                    0 => 0,
                    1 => 1,
                    _ => -1,
                })
            })
            .filter(|k: &[i8; D]| (0..D).all(|m| k[m] == 0 || periodic[m]))
            .collect();
        let mut sites = wrapped.to_vec();
        let (mut source, mut shift) = (Vec::new(), Vec::new());
        // A site farther than the band (and a margin for rounding) from every periodic
        // side has no image in it: most sites, skipped before trying the 3^p − 1 shifts.
        let reach: [f64; D] = std::array::from_fn(|m| band + 1e-9 * periods[m]);
        let near_a_side = |z: &[f64; D]| {
            (0..D).any(|m| periodic[m] && (z[m] - lo[m] <= reach[m] || hi[m] - z[m] <= reach[m]))
        };
        for (i, z) in wrapped.iter().enumerate() {
            if !near_a_side(z) {
                continue;
            }
            for k in &shifts {
                let p: [f64; D] = std::array::from_fn(|m| z[m] + f64::from(k[m]) * periods[m]);
                let near =
                    (0..D).all(|m| k[m] == 0 || (lo[m] - band <= p[m] && p[m] <= hi[m] + band));
                if near {
                    sites.push(p);
                    source.push(i as u32);
                    shift.push(*k);
                }
            }
        }
        Self {
            sites,
            n: wrapped.len(),
            source,
            shift,
            band,
        }
    }

    /// The site and shift of entry `j` of `sites`.
    fn image(&self, j: usize) -> (u32, [i8; D]) {
        match j.checked_sub(self.n) {
            Some(g) => (self.source[g], self.shift[g]),
            None => (j as u32, [0; D]),
        }
    }

    /// The cell of the wrapped `site`, which read the sites within `√reach2` of it, read
    /// every image it needed.
    fn covers(&self, torus: &Torus<D>, site: [f64; D], reach2: f64) -> bool {
        if self.band == f64::INFINITY {
            return true;
        }
        let reach = reach2.sqrt() * (1.0 + 1e-9);
        let (Aabb { lo, hi }, periodic) = (torus.bounds(), torus.periodic_axes());
        (0..D)
            .filter(|&m| periodic[m])
            .all(|m| reach <= self.band + (site[m] - lo[m]).min(hi[m] - site[m]))
    }
}

/// [`super::clipped_diagram`] in a periodic box: the cells of the wrapped sites among the
/// images in a band ([`Images`]); the cells whose reach passes the band's cover computed
/// again with the band doubled, until none does; then each neighbour named by its site and
/// image shift, rows sorted by both.
///
/// A face integrand is summed over each face with the neighbour's index that of its site
/// and `z_j − z_i` that of the image the face is shared with ([`ThroughImages`]).
///
/// Errors: those of [`super::clipped_diagram`] (coinciding sites are also sites at the
/// same point of the torus), and a density, which a periodic box does not take yet.
pub(super) fn clipped_diagram<const D: usize, C: ConvexCell<D>>(
    torus: &Torus<D>,
    sites: &[[f64; D]],
    weights: Option<&[f64]>,
    request: &Request<'_, D>,
) -> Result<Clipped<D, C>, CoreError>
where
    Euclid: Space<D>,
{
    let wrapped = wrapped_sites(torus, sites, request)?;
    let domain = PeriodicBox::of(torus);
    let windings = checked_windings(&domain, &wrapped, request.options)?;
    let n = sites.len();
    let passes = band_passes::<D, C>(
        &domain,
        &wrapped,
        &windings,
        morton_order(&wrapped),
        weights,
        request.integrand,
        request.keep_cells,
        n,
    )?;
    Ok(assemble_passes(
        n,
        passes,
        request.integrand.is_some(),
        request.keep_cells,
    ))
}

/// [`super::clipped_cells`] in a periodic box: the cells of the sites `own` among
/// `sites` (a part and its halo, some of the problem's `total_sites` sites), each among
/// the images of the sites given in a band grown until it covers the cell's reach (as
/// [`clipped_diagram`] does for all the sites), neighbours named by their index in
/// `sites` and their image shift. The sites and their images stand in the same relative
/// order as in the whole problem (sites by index, then images by site and shift), so a
/// cell whose reach (in the torus) the sites given cover is the whole problem's, bit for
/// bit. Not with a density or weights yet.
pub(super) fn clipped_cells<const D: usize, C: ConvexCell<D>>(
    torus: &Torus<D>,
    sites: &[[f64; D]],
    own: &[u32],
    total_sites: usize,
    request: &Request<'_, D>,
) -> Result<PartCells<D>, CoreError>
where
    Euclid: Space<D>,
{
    let wrapped = wrapped_sites(torus, sites, request)?;
    if request.weights.is_some() {
        return Err(CoreError::InvalidWeights {
            reason: "the cells of a part of a periodic power diagram are not computed yet".into(),
        });
    }
    let domain = PeriodicBox::of(torus);
    let (windings, _) = checked_part(&domain, &wrapped, own, request.options)?;
    let n = sites.len();
    let passes = band_passes::<D, C>(
        &domain,
        &wrapped,
        &windings,
        own.to_vec(),
        None,
        None,
        false,
        total_sites.max(n),
    )?;
    // Each cell's reach from the last pass that computed it (the one whose band covered it).
    let mut reach2 = vec![0.0; n];
    for pass in &passes {
        for b in &pass.batches {
            for (&i, &r2) in b.sites.iter().zip(&b.reach2) {
                reach2[i as usize] = r2;
            }
        }
    }
    let whole = assemble_passes::<D, C>(n, passes, false, false).diagram;
    Ok(PartCells {
        diagram: whole.rows(own),
        reach2: own.iter().map(|&i| reach2[i as usize]).collect(),
    })
}

/// `sites` wrapped into the torus' box, after the checks both entry points make: no
/// density (not taken yet), every coordinate finite (checked first, so that the error
/// names the value given, not its wrap).
fn wrapped_sites<const D: usize>(
    torus: &Torus<D>,
    sites: &[[f64; D]],
    request: &Request<'_, D>,
) -> Result<Vec<[f64; D]>, CoreError> {
    if request.density.is_some() {
        return Err(CoreError::InvalidDensity {
            reason: "a periodic box takes no density yet".into(),
        });
    }
    for (index, s) in sites.iter().enumerate() {
        if let Some(&value) = s.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::NonFiniteSite { index, value });
        }
    }
    Ok(sites.iter().map(|&s| torus.wrap(s)).collect())
}

/// The cells of the wrapped sites `visit_order` among `wrapped` and their images in a
/// band ([`Images`]); the cells whose reach passes the band's cover computed again with
/// the band doubled, until none does (the band of a problem of `total_sites` sites).
#[allow(clippy::too_many_arguments)] // the sites, and what the diagram is asked for
fn band_passes<const D: usize, C: ConvexCell<D>>(
    domain: &PeriodicBox<D>,
    wrapped: &[[f64; D]],
    windings: &[Option<i32>],
    mut visit_order: Vec<u32>,
    weights: Option<&[f64]>,
    integrand: Option<&dyn FaceIntegrand<D>>,
    keep_cells: bool,
    total_sites: usize,
) -> Result<Vec<Pass<D, C>>, CoreError>
where
    Euclid: Space<D>,
{
    let torus = domain.torus();
    let spacing = (torus.volume() / total_sites as f64).powf(1.0 / D as f64);
    let full = torus.largest_period();
    let none = WeightedSums::new(None)?;
    let mut band = FIRST_BAND.get(D).copied().unwrap_or(3.0) * spacing;
    let mut passes: Vec<Pass<D, C>> = Vec::new();
    while !visit_order.is_empty() {
        if band >= full {
            band = f64::INFINITY;
        }
        let images = Images::new(torus, wrapped, band);
        let index = SiteIndex::new(&images.sites)?;
        // Each image carries its site's weight.
        let image_weights: Option<Vec<f64>> = weights.map(|w| {
            (0..images.sites.len())
                .map(|j| w[images.image(j).0 as usize])
                .collect()
        });
        let visit = Visit {
            sites: &images.sites,
            index: (&index).into(),
            windings,
            power: image_weights
                .as_deref()
                .map(|w| Power::new(w, &images.sites)),
            power_start: None,
            total_sites: images.sites.len().max(total_sites),
            warm: None,
            record: false,
            reach: true,
            floor: None,
        };
        let through = integrand.map(|inner| ThroughImages {
            inner,
            images: &images,
        });
        let through = through.as_ref().map(|t| t as &dyn FaceIntegrand<D>);
        let batches =
            visit.batches::<C, PeriodicBox<D>>(domain, &visit_order, through, keep_cells, &none);
        let batches = without_errors(batches)
            .map_err(|e| e.with_site_rows(|j| images.image(j).0 as usize))?;
        // The cells to compute again, in the order they were visited.
        visit_order = batches
            .iter()
            .flat_map(|b| b.sites.iter().zip(&b.reach2))
            .filter(|&(&i, &r2)| !images.covers(torus, wrapped[i as usize], r2))
            .map(|(&i, _)| i)
            .collect();
        passes.push(Pass { images, batches });
        band *= 2.0;
    }
    Ok(passes)
}

/// A caller's [`FaceIntegrand`] over the faces of the cells among a band of images: each
/// face named by the site of its image, with `z_j − z_i` that image's offset from the
/// site (a site's own difference would be off by a period across the box's sides).
struct ThroughImages<'a, const D: usize> {
    inner: &'a dyn FaceIntegrand<D>,
    images: &'a Images<D>,
}

impl<const D: usize> FaceIntegrand<D> for ThroughImages<'_, D> {
    fn add(
        &self,
        i: usize,
        j: usize,
        _: Option<[f64; D]>,
        sign: f64,
        m: &FaceMoments<D>,
        face: &mut Matrix<D>,
        cell: &mut Matrix<D>,
    ) {
        let sites = &self.images.sites;
        let to_neighbor = sub(sites[j], sites[i]);
        let (source, _) = self.images.image(j);
        let inner = self.inner;
        inner.add(i, source as usize, Some(to_neighbor), sign, m, face, cell);
    }
}

/// The cells of one band of images.
struct Pass<const D: usize, C> {
    images: Images<D>,
    batches: Vec<Batch<D, C>>,
}

/// The diagram in index order, each cell from the last pass that computed it (the first
/// whose band covered it), each neighbour named by its site and image shift
/// ([`Diagram::neighbor_images`]), rows sorted by site, then shift.
fn assemble_passes<const D: usize, C: ConvexCell<D>>(
    n: usize,
    passes: Vec<Pass<D, C>>,
    integrals: bool,
    keep_cells: bool,
) -> Clipped<D, C> {
    let mut last = vec![0u32; n];
    let mut diagram = Diagram {
        moments: vec![Moments::zero(); n],
        boundary_measure: vec![0.0; n],
        neighbor_offsets: vec![0; n + 1],
        ..Diagram::default()
    };
    for (p, pass) in passes.iter().enumerate() {
        for b in &pass.batches {
            for (&i, &count) in b.sites.iter().zip(&b.face_counts) {
                last[i as usize] = p as u32;
                diagram.neighbor_offsets[i as usize + 1] = count as usize;
            }
        }
    }
    for i in 0..n {
        diagram.neighbor_offsets[i + 1] += diagram.neighbor_offsets[i];
    }
    let faces = diagram.neighbor_offsets[n];
    diagram.neighbor_sites = vec![0; faces];
    diagram.neighbor_measures = vec![0.0; faces];
    diagram.neighbor_images = vec![[0; D]; faces];
    let mut sums = FaceIntegrals::default();
    if integrals {
        sums.cells = vec![[[0.0; D]; D]; n];
        sums.faces = vec![[[0.0; D]; D]; faces];
    }
    let mut cells: Vec<Option<C>> = Vec::new();
    if keep_cells {
        cells.resize_with(n, || None);
    }
    // Each face: its site, shift, measure and entry in the batch (for its integral).
    let mut row: Vec<(u32, [i8; D], f64, usize)> = Vec::new();
    for (p, pass) in passes.into_iter().enumerate() {
        for b in pass.batches {
            let mut at = 0;
            for (k, &i) in b.sites.iter().enumerate() {
                let (i, count) = (i as usize, b.face_counts[k] as usize);
                let faces = (b.neighbor_sites[at..at + count].iter())
                    .zip(&b.neighbor_measures[at..at + count])
                    .zip(at..at + count);
                at += count;
                if last[i] != p as u32 {
                    continue;
                }
                diagram.moments[i] = b.moments[k];
                diagram.boundary_measure[i] = b.boundary_measure[k];
                row.clear();
                row.extend(faces.map(|((&j, &measure), entry)| {
                    let (j, shift) = pass.images.image(j as usize);
                    (j, shift, measure, entry)
                }));
                row.sort_unstable_by_key(|x| (x.0, x.1));
                let from = diagram.neighbor_offsets[i];
                for (e, &(j, shift, measure, entry)) in row.iter().enumerate() {
                    diagram.neighbor_sites[from + e] = j;
                    diagram.neighbor_images[from + e] = shift;
                    diagram.neighbor_measures[from + e] = measure;
                    if integrals {
                        sums.faces[from + e] = b.face_integrals[entry];
                    }
                }
                if integrals {
                    sums.cells[i] = b.cell_integrals[k];
                }
            }
            if keep_cells {
                for (&i, cell) in b.sites.iter().zip(b.cells) {
                    if last[i as usize] == p as u32 {
                        cells[i as usize] = Some(cell);
                    }
                }
            }
        }
    }
    Clipped {
        diagram,
        cells: cells.into_iter().flatten().collect(),
        face_integrals: sums,
        warm: None,
    }
}
