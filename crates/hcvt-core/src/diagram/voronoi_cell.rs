//! One site's convex Voronoi cell (DESIGN §3, step 1): the domain's bounding box clipped by
//! the bisectors of the nearest sites in order of distance until the security radius is
//! reached; a cell that reaches outside a non-convex domain localised to a box around its
//! part in the domain and validated by its vertices' nearest sites; a cell of a convex
//! domain cut early by the boundary planes near it. Owns [`voronoi_cell`] and its buffers;
//! the clip by the domain that follows is `clip.rs`'s.

use crate::error::CoreError;
use crate::geometry::{add, norm2, scale, sub, Euclid, HalfSpace, Space};

use super::convex_cell::{ConvexCell, Face};
use super::domain_kind::DomainKind;
use super::knn::{IndexRef, NearScratch, SiteIndex};
use super::power::{at_most, InDomain, Power};
use super::ring::ring_cell;
use super::warm::{margin2, WarmList};

/// Neighbour count, per dimension, after which a cell that has not reached its security
/// radius is localised to the domain (see [`DomainKind::local_radius2`]). 16 in 2D: a CVT of the star
/// spends 23% less per diagram than with 64 (2.36 against 3.05 ms at 2,000 sites), the unit
/// square the same, and with the bucket grid 8 and 32 cost 1% and 3% more instructions per
/// diagram than 16; 3D cells need about 31 neighbours, so 64 there.
const LOCALISE_K: [usize; 4] = [16, 16, 16, 64];

/// [`LOCALISE_K`] for a power cell in a non-convex domain. Its vertex checks each read the
/// sites within the vertex's power reach, which grows with the weights' spread: at 10,000
/// random sites in the L-shape with the weights of equal masses, localising after 16
/// neighbours spent 45% of the transport's time in them (perf). A cell that meets its
/// stopping distance first is finished by the stream and [`Power::clip_heavier`] as in a
/// convex domain; only cells still open after 64 neighbours (at the boundary) are
/// localised. 3D unchanged.
const POWER_LOCALISE_K: [usize; 4] = [64, 64, 64, 64];

/// A cell is localised once its part in the domain lies within `√LOCAL_REACH2` times the
/// distance of the last neighbour taken. At 16 neighbours 0.01% of the cells of uniform
/// random sites in the unit square were still open into the square: localised at once,
/// their vertex checks read sites across the whole domain (measured reach up to 1,370
/// spacings at 1M sites), which a partitioned diagram must then ship to their part.
const LOCAL_REACH2: f64 = 16.0;

/// Neighbour count, per dimension, after which the cell of a site inside a convex domain
/// that has not reached its security radius is cut by the domain's boundary planes near it
/// ([`DomainKind::cut_convex`]). A cell at the boundary otherwise reaches out to the corners of
/// the starting box and never meets its security radius: in a ball of 5,000 sites it
/// streamed 64 neighbours, then [`localise`] and [`validate_vertices`].
const PRECLIP_K: [usize; 4] = [usize::MAX, usize::MAX, usize::MAX, 16];

/// The convex Voronoi cell of site `i` inside the domain's bounding box, relative to the
/// site, exact wherever it meets the domain, and whether it already lies in the domain.
///
/// A site near the boundary of a non-convex domain has a Voronoi cell reaching far into
/// the empty part of the bounding box, and the security radius would pull in most sites.
/// Only the cell's part inside the domain matters, so every `LOCALISE_K` neighbours, while
/// they do not suffice and that part lies near the site (`LOCAL_REACH2`), the cell is cut
/// to a box that holds that part ([`localise`]) and finished by checking its vertices'
/// nearest sites ([`validate_vertices`]). A kind whose cells matter only where they meet
/// it (a surface) has its part of the cell validated after
/// [`DomainKind::validate_part_after`] neighbours instead.
///
/// With `convex_inside` (the domain is convex and the site strictly inside it), a cell
/// still open after `PRECLIP_K` neighbours is instead cut by the nearby boundary planes:
/// it then lies in the domain, its radius shrinks to the domain's scale there, and the
/// security radius stays valid (a site beyond twice the radius of any region holding the
/// cell cannot cut it). The cell returned is then the clipped cell itself, `true`.
///
/// When `sites` is part of a problem of `total_sites` sites (a partition
/// and its halo), computed as the whole problem would; [`CellScratch::reach2`] then tells
/// how far from the site the cell depended on the sites present.
///
/// The cell reads the sites streamed before the stop (each nearer than the last one), the
/// stopping distance `2 r` (`r` the final radius: a site within it but missing would have
/// been clipped), and for a localised cell the nearest site of each vertex `v` it checks,
/// found at some distance `δ` from `v`: the answer only depends on the sites within
/// `|v| + δ` of the site. Its reach is the largest of these distances.
///
/// With `power`, the power cell (DESIGN §14): the planes and the stopping distance are
/// [`Power`]'s, a vertex is checked against the site of least power there, and a cell that
/// empties stops streaming (an empty cell: mass 0, no faces).
///
/// With `warm`, the site's list of near sites from a previous diagram and the squared
/// distance within which it holds every site: the cell is rebuilt from its previous ring
/// where that certifies it ([`ring_cell`]), else the nearest sites are streamed from the
/// list ([`IndexRef::near_warm`]); either way the cell is the same bit for bit, and the
/// index (possibly deferred, [`super::knn::DeferredIndex`]) is filled only if some cell
/// needs it. With `record`, the cell's own list for the next diagram is left in
/// [`CellScratch::record`].
///
/// A cell of a plain Voronoi diagram bounded by its neighbours alone is left canonical
/// ([`ConvexCell::canonicalise`]; 2D), its bits independent of the order of the clips.
#[allow(clippy::too_many_arguments)]
pub fn voronoi_cell<'a, 'i, const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    index: impl Into<IndexRef<'i, D>>,
    sites: &[[f64; D]],
    power: Option<&Power<'_, D>>,
    total_sites: usize,
    i: usize,
    convex_inside: bool,
    warm: Option<WarmList<'_>>,
    record: bool,
    scratch: &'a mut CellScratch<C>,
) -> Result<(&'a C, bool), CoreError>
where
    Euclid: Space<D>,
{
    scratch.rebuilt = false;
    if let Some(w) = warm.filter(|w| w.ring > 0 && power.is_none()) {
        if let Some(inside) = try_ring_cell(domain, sites, i, convex_inside, w, scratch) {
            let cell = scratch.cell.as_ref().expect("the cell just built");
            return Ok((cell, inside));
        }
    }
    let index = index.into();
    let (inside, stayed_warm, vouched2) = streamed_cell(
        domain,
        index,
        sites,
        power,
        total_sites,
        i,
        convex_inside,
        warm,
        scratch,
    )?;
    if record {
        remember(index, sites, i, stayed_warm, vouched2, warm, scratch);
    }
    let cell = scratch.cell.as_ref().expect("the cell just computed");
    Ok((cell, inside))
}

/// Site `i`'s cell rebuilt from the ring of `warm` ([`ring_cell`]) into `scratch`, with
/// its record for the next diagram, and whether it lies in the domain; `None` when it must
/// be clipped. Only where the clipped cell would be plain and canonical: no power, no part
/// validated early. A cell inside a convex domain that the cold stream would have cut by
/// the boundary planes near it (after `PRECLIP_K` sites) is cut by them here too: it is
/// the cold cell, and in the domain, only if they leave it as it was (else the cold
/// cell has boundary faces and no canonical form).
fn try_ring_cell<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    i: usize,
    convex_inside: bool,
    warm: WarmList<'_>,
    scratch: &mut CellScratch<C>,
) -> Option<bool> {
    if domain.validate_part_after().is_some() {
        return None;
    }
    let start = domain.start(sites[i]);
    let cell = scratch.cell.get_or_insert_with(|| C::from_box(&start));
    let localise_after = LOCALISE_K.get(D).copied().unwrap_or(64);
    let made = ring_cell(sites, i, &start, warm, cell, &mut scratch.record);
    let made = made?;
    let preclip_after = PRECLIP_K.get(D).copied().unwrap_or(usize::MAX);
    let inside = convex_inside && made.taken >= preclip_after;
    // A cell the cold stream would localise (it is not inside by then).
    if !inside && made.taken >= localise_after {
        return None;
    }
    if inside {
        let planes = plane_count(cell);
        if !domain.cut_convex(cell, sites[i], &mut scratch.candidates)
            || plane_count(cell) != planes
        {
            return None;
        }
    }
    scratch.reach2 = made.reach2;
    scratch.record2 = warm.certified2;
    scratch.record_warm = true;
    scratch.record_ring = warm.ring as u8;
    scratch.record_triangles.clear();
    scratch.record_triangles.extend_from_slice(warm.triangles);
    scratch.canonical = true;
    scratch.rebuilt = true;
    Some(inside)
}

/// How many planes have cut `cell` (3D) or how many edges it has (2D): what a clip that
/// changes it changes.
fn plane_count<const D: usize, C: ConvexCell<D>>(cell: &C) -> usize {
    let mut count = 0;
    cell.for_each_plane(|_, _| count += 1);
    count
}

/// Leave in `scratch.record` the sites near site `i` for the next diagram's warm start:
/// a stream that stayed warm keeps its certified candidates; a cold one gathers the sites
/// within a margin beyond the distance it read. A canonical cell's ring goes first
/// ([`ring_cell`] rebuilds the next cell from it), the other sites after it.
fn remember<const D: usize, C: ConvexCell<D>>(
    index: IndexRef<'_, D>,
    sites: &[[f64; D]],
    i: usize,
    stayed_warm: bool,
    vouched2: f64,
    warm: Option<WarmList<'_>>,
    scratch: &mut CellScratch<C>,
) {
    scratch.record.clear();
    scratch.record_triangles.clear();
    scratch.record_warm = false;
    scratch.record_ring = 0;
    let cell = scratch.cell.as_ref().filter(|_| scratch.canonical);
    if let Some(cell) = cell {
        cell.ring(&mut scratch.record, &mut scratch.record_triangles);
        // A ring longer than its count can say is not remembered.
        match u8::try_from(scratch.record.len()) {
            Ok(ring) => scratch.record_ring = ring,
            Err(_) => {
                scratch.record.clear();
                scratch.record_triangles.clear();
            }
        }
    }
    let ring = usize::from(scratch.record_ring);
    let record = &mut scratch.record;
    let mut keep = |j: u32| {
        if !record[..ring].contains(&j) {
            record.push(j);
        }
    };
    if let (true, Some(w)) = (stayed_warm, warm) {
        scratch.near.certified().for_each(&mut keep);
        scratch.record2 = w.certified2;
        scratch.record_warm = true;
        return;
    }
    let record2 = margin2(vouched2);
    let mut near = index.get().near(sites[i], &mut scratch.near);
    while let Some((j, _)) = near.next_within(record2) {
        keep(j);
    }
    scratch.record2 = record2;
}

/// The cell of [`voronoi_cell`] left in `scratch.cell`: whether it lies in the domain,
/// whether its stream stayed warm, and the squared distance the stream vouched for.
#[allow(clippy::too_many_arguments)]
fn streamed_cell<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    index: IndexRef<'_, D>,
    sites: &[[f64; D]],
    power: Option<&Power<'_, D>>,
    total_sites: usize,
    i: usize,
    convex_inside: bool,
    warm: Option<WarmList<'_>>,
    scratch: &mut CellScratch<C>,
) -> Result<(bool, bool, f64), CoreError>
where
    Euclid: Space<D>,
{
    let site = sites[i];
    let start = domain.start(site);
    scratch.canonical = false;
    let cell = scratch.cell.get_or_insert_with(|| C::from_box(&start));
    cell.reset_to_box(&start);
    let mut radius2 = cell.max_dist2();
    // A power cell in a convex domain is not localised: its part in the domain is all of
    // it, and each vertex check would read the sites within that vertex's own (wide)
    // power reach. Streaming on to the stopping distance cost less: at 10,000 random
    // sites in the unit square with random weights of one squared spacing a diagram took
    // 0.34 s instead of 0.78 s, and equal masses by optimal transport 3.4 s instead of
    // 17.8 s (one thread, the machine under load).
    let localise_after = match (power, domain.is_convex()) {
        (Some(_), true) => usize::MAX,
        (Some(_), false) => POWER_LOCALISE_K.get(D).copied().unwrap_or(64),
        (None, _) => LOCALISE_K.get(D).copied().unwrap_or(64),
    };
    let preclip_after = if convex_inside {
        PRECLIP_K.get(D).copied().unwrap_or(usize::MAX)
    } else {
        usize::MAX
    };
    // A power cell is not cut to the domain (`DomainKind::clip` measures it, its site
    // perhaps outside it), but its part in the domain bounds its radius ([`InDomain`]).
    let mut bound2 = f64::INFINITY;
    let mut inside = false;
    let mut near = match warm {
        Some(w) => index.near_warm(site, sites, w.near, w.certified2, &mut scratch.near),
        None => index.get().near(site, &mut scratch.near),
    };
    let mut clipped = 0; // sites taken from the stream, the site itself included
    let mut last2: f64 = 0.0; // squared distance of the last site taken

    // A power cell streams only to the bound for sites no heavier than its own; the
    // heavier ones beyond are clipped by `Power::clip_heavier` after the stream.
    let stop2 = |radius2: f64| match power {
        Some(p) => p.stream_reach2(radius2),
        None => 4.0 * radius2,
    };
    // A kind that validates its cells' parts early (`DomainKind::validate_part_after`;
    // not power cells).
    let validate_after = domain.validate_part_after().filter(|_| power.is_none());
    while let Some((j, dist2)) = near.next_within(stop2(radius2)) {
        last2 = dist2;
        if j as usize != i {
            let q = offset_to(sites, i, j)?;
            let plane = match power {
                None => HalfSpace::bisector(q),
                Some(p) => p.bisector(q, i, j as usize),
            };
            if cell.clip(&plane, Face::Neighbor(j)) {
                radius2 = at_most(cell.max_dist2(), bound2);
                if power.is_some() && cell.is_empty() {
                    // An empty power cell: no site can take anything more from it.
                    scratch.reach2 = last2;
                    return Ok((true, near.is_warm(), near.vouched2()));
                }
            }
        }
        clipped += 1;
        if validate_after == Some(clipped) && clipped < total_sites && !cell.is_empty() {
            let (stayed_warm, vouched2) = (near.is_warm(), near.vouched2());
            // The security radius of the cell's part: every site not taken lies at least
            // `last` from the site, and one that close cannot be nearer than the site to
            // a point of the part within `r` of it when `last > 2 r`.
            let part2 = domain.local_radius2(cell, site);
            if 4.0 * part2 < last2 {
                scratch.reach2 = last2;
                return Ok((false, stayed_warm, vouched2));
            }
            let reach = validate_vertices(domain, cell, index.get(), sites, power, i, true)?;
            scratch.reach2 = last2.max(reach * reach);
            return Ok((false, stayed_warm, vouched2));
        }
        if clipped % preclip_after == 0 && clipped < total_sites && !inside {
            // Every `PRECLIP_K` neighbours until the domain can cut the cell (a solid's
            // and a box's always can at once; a sphere's cell once it is closed).
            let candidates = &mut scratch.candidates;
            if power.is_some() {
                // Only a cell reaching beyond its neighbours so far (open to its box) is
                // worth a copy: in a box domain the part is the cell, and copying every
                // cell cost a power diagram 7% more instructions (docs/results/transport.txt
                // §23).
                if radius2 > last2 {
                    bound2 = InDomain::new(domain, site, &mut scratch.part, candidates)
                        .of(cell)
                        .max_dist2();
                    radius2 = at_most(radius2, bound2);
                }
            } else {
                inside = domain.cut_convex(cell, site, candidates);
                radius2 = cell.max_dist2();
            }
        }
        if clipped % localise_after == 0 && clipped < total_sites && !inside && !cell.is_empty() {
            // Localise only a cell whose part in the domain is already near the site: a
            // cell still open into the domain (its nearest sites all on one side) would be
            // validated out to the domain's far side, and its reach, the sites it depends
            // on, with it. Such a cell streams on and is tried again.
            let local2 = domain.local_radius2(cell, site);
            if local2 <= LOCAL_REACH2 * last2 {
                localise(cell, local2.sqrt());
                let (stayed_warm, vouched2) = (near.is_warm(), near.vouched2());
                let reach = validate_vertices(domain, cell, index.get(), sites, power, i, false)?;
                scratch.reach2 = last2.max(reach * reach);
                return Ok((false, stayed_warm, vouched2));
            }
        }
    }
    if let Some(p) = power {
        // Sites at the last distance not yet taken (a tie): the second pass skips every
        // site within the distance streamed.
        while let Some((j, dist2)) = near.next_within(last2) {
            if j as usize != i {
                let q = offset_to(sites, i, j)?;
                cell.clip(&p.bisector(q, i, j as usize), Face::Neighbor(j));
            }
            last2 = last2.max(dist2);
        }
        radius2 = at_most(cell.max_dist2(), bound2);
        let covered2 = last2.max(stop2(radius2));
        if !cell.is_empty() {
            p.clip_heavier(cell, sites, i, covered2, bound2);
        }
        scratch.reach2 = covered2.max(p.global_reach2(i, radius2));
        // An empty cell is measured as one inside the domain: nothing.
        let empty = cell.is_empty();
        return Ok((inside || empty, near.is_warm(), near.vouched2()));
    }
    // The plain cell in its canonical form, which a warm diagram can rebuild unclipped.
    scratch.canonical = cell.canonicalise(|j| HalfSpace::bisector(sub(sites[j as usize], site)));
    if scratch.canonical {
        radius2 = cell.max_dist2();
    }
    scratch.reach2 = last2.max(stop2(radius2));
    Ok((inside, near.is_warm(), near.vouched2()))
}

/// Buffers of [`voronoi_cell`], reused from cell to cell so that the common cell allocates
/// nothing.
#[derive(Debug)]
pub struct CellScratch<C> {
    near: NearScratch,
    cell: Option<C>,
    /// A power cell's part in a convex domain ([`InDomain`]).
    part: Option<C>,
    candidates: Vec<u32>,
    reach2: f64,
    /// The last cell's near sites for a warm start, complete within `record2`, `L²`.
    record: Vec<u32>,
    record2: f64,
    /// Whether the last cell's stream stayed warm.
    record_warm: bool,
    /// How many sites at the head of `record` are the last cell's ring, and (3D) its
    /// vertex triangles.
    record_ring: u8,
    record_triangles: Vec<[u8; 3]>,
    /// Whether the last cell is canonical ([`ConvexCell::canonicalise`]).
    canonical: bool,
    /// Whether the last cell was rebuilt from its ring ([`ring_cell`]).
    rebuilt: bool,
}

impl<C> CellScratch<C> {
    /// The near sites the last cell recorded for a warm start, the squared distance
    /// within which they are every site (`L²`), and whether its stream stayed warm.
    pub fn record(&self) -> (&[u32], f64, bool) {
        (&self.record, self.record2, self.record_warm)
    }

    /// How many sites at the head of [`CellScratch::record`] are the last cell's ring.
    pub fn record_ring(&self) -> u8 {
        self.record_ring
    }

    /// The vertex triangles of the last cell's ring (3D).
    pub fn record_triangles(&self) -> &[[u8; 3]] {
        &self.record_triangles
    }

    /// Whether the last cell was rebuilt from its ring ([`ring_cell`]), unclipped.
    pub fn rebuilt(&self) -> bool {
        self.rebuilt
    }

    /// The reach of the last cell computed ([`voronoi_cell`]), `L²`.
    pub fn reach2(&self) -> f64 {
        self.reach2
    }
}

impl<C> Default for CellScratch<C> {
    fn default() -> Self {
        Self {
            near: NearScratch::default(),
            cell: None,
            part: None,
            candidates: Vec::new(),
            reach2: 0.0,
            record: Vec::new(),
            record2: 0.0,
            record_warm: false,
            record_ring: 0,
            record_triangles: Vec::new(),
            canonical: false,
            rebuilt: false,
        }
    }
}

/// Site `j` relative to site `i`; two sites at one point have no bisector.
fn offset_to<const D: usize>(sites: &[[f64; D]], i: usize, j: u32) -> Result<[f64; D], CoreError> {
    let q = sub(sites[j as usize], sites[i]);
    if norm2(q) == 0.0 {
        let (first, second) = (i.min(j as usize), i.max(j as usize));
        return Err(CoreError::DuplicateSites {
            first,
            second,
            point: sites[i].to_vec(),
        });
    }
    Ok(q)
}

/// Cut `cell` (relative to its site) to the box of half-width `r` around the site, `r` a
/// bound on the distance of its part inside the domain ([`DomainKind::local_radius2`]): nothing of the domain is lost, and
/// the far reaches of the cell outside it stop costing neighbours and boundary pieces.
fn localise<const D: usize, C: ConvexCell<D>>(cell: &mut C, r: f64) {
    for axis in 0..D {
        let unit: [f64; D] = std::array::from_fn(|j| if j == axis { 1.0 } else { 0.0 });
        cell.clip(&HalfSpace::through(scale(unit, r), unit), Face::Box);
        cell.clip(
            &HalfSpace::through(scale(unit, -r), scale(unit, -1.0)),
            Face::Box,
        );
    }
}

/// Most vertex checks one cell may need before it is accepted as it is.
const MAX_VALIDATIONS: usize = 100_000;

/// Clip `cell` until each of its vertices has site `i` as a nearest site, so that the cell
/// (the convex hull of its vertices) lies in the Voronoi cell; as it already contains the
/// Voronoi cell's part in the box it started from, the two are then equal there. A kind
/// may name other points to check ([`DomainKind::validation_points`]: a surface's pieces,
/// whose hulls then lie in the Voronoi cell, which is all its cells need).
///
/// Used instead of the security radius for cells localised by [`localise`]: each vertex
/// asks the index for its own nearest site, so the work follows where the cell is, not
/// a ball around the site. A vertex within round-off of a bisector already clipped counts
/// as valid; vertices that survive a clip keep their bits and are not checked again.
///
/// Returns the largest `|v| + δ` over the vertices checked, `δ` the distance of the
/// nearest site found for `v`, with a margin for rounding: the sites read lie within it.
///
/// With `power`, each vertex is checked against the site of least power there
/// ([`least_power`]), and `δ` is the distance within which that search read sites.
///
/// `asked`: the domain was asked this cell's [`DomainKind::local_radius2`] just before
/// (so its first [`DomainKind::validation_points`] is not the first look at the cell).
#[allow(clippy::too_many_arguments)]
fn validate_vertices<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    cell: &mut C,
    index: &SiteIndex<D>,
    sites: &[[f64; D]],
    power: Option<&Power<'_, D>>,
    i: usize,
    asked: bool,
) -> Result<f64, CoreError> {
    let site = sites[i];
    let mut valid: Vec<[u64; D]> = Vec::new();
    let mut used: Vec<u32> = Vec::new();
    let mut reach: f64 = 0.0;
    let mut near = NearScratch::default();
    let mut points = Vec::new();
    for round in 0..MAX_VALIDATIONS {
        let mut cut = None;
        let own = domain.validation_points(cell, site, round == 0 && !asked, &mut points);
        let vertices: &[[f64; D]] = if own { &points } else { cell.vertices() };
        for &v in vertices {
            let key = v.map(f64::to_bits);
            if valid.contains(&key) {
                continue;
            }
            let (j, dist2, closer) = match power {
                None => {
                    let (j, dist2) = index.nearest_one(add(v, site));
                    (j, dist2, dist2 < norm2(v) * (1.0 - 1e-12))
                }
                Some(p) => least_power(p, index, sites, i, v, &mut near),
            };
            reach = reach.max((norm2(v).sqrt() + dist2.sqrt()) * (1.0 + 1e-12));
            if j as usize != i && closer && !used.contains(&j) {
                cut = Some(j);
                break;
            }
            valid.push(key);
        }
        let Some(j) = cut else {
            return Ok(reach);
        };
        let q = offset_to(sites, i, j)?;
        let plane = match power {
            None => HalfSpace::bisector(q),
            Some(p) => p.bisector(q, i, j as usize),
        };
        cell.clip(&plane, Face::Neighbor(j));
        used.push(j);
        if cell.is_empty() {
            return Ok(reach);
        }
    }
    Ok(reach)
}

/// The site of least power `|p − z_j|² − w_j` at the vertex `v` of cell `i` (relative to
/// its site, `p = z_i + v`), as `(j, r², lower)`: `lower` when its power is below site
/// `i`'s own `|v|² − w_i` by more than round-off, and `r²` the squared distance within
/// which the sites were read.
///
/// A site `j` has less power at `p` only if `|p − z_j|² < |v|² − w_i + w_j`, so the sites
/// are streamed in increasing distance up to [`Power::vertex_reach2`].
fn least_power<const D: usize>(
    power: &Power<'_, D>,
    index: &SiteIndex<D>,
    sites: &[[f64; D]],
    i: usize,
    v: [f64; D],
    near: &mut NearScratch,
) -> (u32, f64, bool) {
    // Powers shifted by w_max (`|p − z_j|² + w_max − w_j`, every term ≥ 0), so that
    // round-off is relative to them whatever the weights' common offset.
    let own = norm2(v) + power.slack(i);
    let point = add(v, sites[i]);
    let limit2 = power.vertex_reach2(i, point, norm2(v));
    let mut stream = index.near(point, near);
    let mut best = (i as u32, own);
    while let Some((j, dist2)) = stream.next_within(limit2) {
        let value = dist2 + power.slack(j as usize);
        if value < best.1 {
            best = (j, value);
        }
    }
    (best.0, limit2, best.1 < own * (1.0 - 1e-12))
}
