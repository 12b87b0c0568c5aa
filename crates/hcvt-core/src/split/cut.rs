//! One cell cut by a plane (`_Editor.cut` and its helpers in `hcvt.export.split`).
//!
//! Each face wholly on one side is kept as it is; each other face is split along the
//! plane into pieces (a face that is not convex may give several on a side), and the
//! segments of the plane inside it (chords) are chained into the sections: the new faces
//! on the plane. The parts are the connected sets of faces on each side. The order of the
//! output faces and of each loop's vertices is the reference's, so that a caller applying
//! the cut numbers the new faces alike.

use std::cmp::Ordering;

use super::numpy_order::{matvec_dot, vector_dot};
use super::quality::{face_geometry, measure_faces, total_badness, FaceGeometry};
use super::{Across, Loops, Region, RegionQuality};
use crate::error::CoreError;
use crate::geometry::{add, cross, sub};

/// A plane moved along its normal when it passes this close to a vertex, relative to
/// the cell's size: a vertex on the plane would make a degenerate cut.
const CLEARANCE: f64 = 1e-6;

/// A polyhedral cell to cut: its vertices, its outward faces and what lies across each.
#[derive(Debug, Clone, Copy)]
pub struct Cell<'a> {
    /// The cell's vertices, `L`. Their order is the caller's: the crossing on edge `a b`
    /// is interpolated from the lower index, as the reference does with global indices.
    pub points: &'a [[f64; 3]],
    /// Each face's loop, counter-clockwise seen from outside the cell.
    pub faces: &'a Loops,
    /// Per face, the ghost cell across it (an index into `ghost_centroids`), or None on
    /// the domain's boundary.
    pub ghosts: &'a [Option<u32>],
    /// Centroid of each cell across a face, `L`.
    pub ghost_centroids: &'a [[f64; 3]],
}

/// The plane `normal · (x − origin) = 0`; `normal` need not be a unit vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Its normal: the `+` side of a cut is where `normal · (x − origin) > 0`.
    pub normal: [f64; 3],
    /// A point on it, `L`.
    pub origin: [f64; 3],
}

/// Where the plane crosses an edge of the cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The edge's vertices, the lower index first.
    pub edge: [u32; 2],
    /// The new vertex, `L`.
    pub point: [f64; 3],
}

/// A cell cut in parts, measured.
///
/// Vertex indices in `faces` below the cell's `m` points are its vertices; `m + j` is
/// `crossings[j]` (the reference numbers it `-1 - j`), in order of creation.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    /// The new vertices.
    pub crossings: Vec<Crossing>,
    /// The parts' faces, each loop counter-clockwise seen from outside its part: the
    /// pieces of the cell's faces in face order, then the sections.
    pub faces: Loops,
    /// Per face, the cell face it is a piece of; None for a section.
    pub source: Vec<Option<u32>>,
    /// Per face, its part.
    pub part: Vec<u32>,
    /// Per face, what lies across it: the part beyond a section, the source face's ghost
    /// or the boundary for a piece.
    pub across: Vec<Across>,
    /// Number of parts (2 or more).
    pub parts: usize,
    /// The faces' checkMesh quality and the parts' centroids.
    pub quality: RegionQuality,
    /// Per part, its failing faces (a failing section counts for both its parts).
    pub part_failing: Vec<u32>,
    /// Failing faces.
    pub failing: usize,
    /// Total badness of the faces, the reference's `worst`.
    pub worst: f64,
    /// The sources of failing faces, sorted, each once (None: a section).
    pub failing_sources: Vec<Option<u32>>,
}

/// `cell` cut by `plane` and measured; None where the reference (`_Editor.cut`) gives
/// None.
///
/// A plane passing within [`CLEARANCE`] times the cell's size (its largest extent along
/// an axis) of a vertex is first moved by ten times that along its normal. None if it is
/// still that close, if it leaves every vertex on one side, if a face's crossings cannot
/// be paired into chords or its pieces traced, if the chords do not close into sections
/// facing `-normal` out of the `+` side, or if a part has no positive volume.
///
/// # Errors
///
/// [`CoreError::InvalidFace`] for an index out of range, [`CoreError::InvalidPoint`] for a
/// non-finite vertex, [`CoreError::InvalidPlane`] for a non-finite plane.
///
/// # Example
///
/// ```
/// use hcvt_core::split::{cut_cell, Across, Cell, Loops, Plane};
///
/// // The unit cube (corner i at its bits), its faces on the boundary, halved at x = 0.5:
/// // four sides in two pieces each, two whole, and the section between the halves.
/// let points: Vec<[f64; 3]> = (0..8)
///     .map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(f64::from))
///     .collect();
/// let rings = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
/// let faces = Loops::new((0..=6).map(|k| 4 * k).collect(), rings.concat())?;
/// let cell = Cell { points: &points, faces: &faces, ghosts: &[None; 6], ghost_centroids: &[] };
/// let plane = Plane { normal: [1.0, 0.0, 0.0], origin: [0.5, 0.5, 0.5] };
/// let cut = cut_cell(&cell, plane)?.expect("the plane crosses the cube");
/// assert_eq!((cut.parts, cut.crossings.len(), cut.faces.len()), (2, 4, 11));
/// assert_eq!((cut.part[10], cut.across[10]), (1, Across::Part(0))); // the section: + to -
/// let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-15);
/// assert!(close(&cut.quality.volumes, &[0.5, 0.5]));
/// assert!(close(&cut.quality.centroids.concat(), &[0.25, 0.5, 0.5, 0.75, 0.5, 0.5]));
/// # Ok::<(), hcvt_core::CoreError>(())
/// ```
pub fn cut_cell(cell: &Cell<'_>, plane: Plane) -> Result<Option<Cut>, CoreError> {
    Ok(cut_cell_by_planes(cell, &[plane])?.pop().flatten())
}

/// `cell` cut by each of `planes`: row `i` is [`cut_cell`] by `planes[i]`. Every plane is
/// tried, so that the search can choose among the cuts that pass (the least oblique).
///
/// # Errors
///
/// As [`cut_cell`]; an invalid plane is reported whether or not it would be reached.
pub fn cut_cell_by_planes(
    cell: &Cell<'_>,
    planes: &[Plane],
) -> Result<Vec<Option<Cut>>, CoreError> {
    validate(cell, planes)?;
    // A face the plane leaves whole is the same loop in every cut: measured once.
    let mut normals = Vec::new();
    let whole: Vec<FaceGeometry> = (cell.faces.iter())
        .map(|ring| face_geometry(cell.points, ring, &mut normals))
        .collect();
    Ok(planes
        .iter()
        .map(|&plane| cut(cell, &whole, plane))
        .collect())
}

/// Every index of `cell` in range, its points and the planes finite.
fn validate(cell: &Cell<'_>, planes: &[Plane]) -> Result<(), CoreError> {
    cell.faces.check_vertices(cell.points.len())?;
    let faces = cell.faces.len();
    if cell.ghosts.len() != faces {
        return Err(CoreError::InvalidFace {
            face: cell.ghosts.len().min(faces),
            reason: format!("{faces} faces but {} ghost entries", cell.ghosts.len()),
        });
    }
    let count = cell.ghost_centroids.len();
    if let Some((face, g)) = (cell.ghosts.iter().enumerate())
        .find_map(|(k, g)| g.filter(|&g| g as usize >= count).map(|g| (k, g)))
    {
        let reason = format!("ghost {g}, but {count} ghost centroids");
        return Err(CoreError::InvalidFace { face, reason });
    }
    for (index, p) in cell.points.iter().enumerate() {
        if let Some(&value) = p.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::InvalidPoint { index, value });
        }
    }
    let finite = |v: [f64; 3]| v.iter().all(|x| x.is_finite());
    for (index, plane) in planes.iter().enumerate() {
        if !(finite(plane.normal) && finite(plane.origin)) {
            return Err(CoreError::InvalidPlane {
                index,
                reason: format!("normal {:?}, origin {:?}", plane.normal, plane.origin),
            });
        }
    }
    Ok(())
}

/// The faces of the parts as they are made, before the parts are known: their loops,
/// and per loop the cell face it comes from (None for a section), whether it is all of
/// that face, and its side of the plane (±1).
#[derive(Debug, Default)]
struct Pieces {
    faces: Loops,
    source: Vec<Option<u32>>,
    whole: Vec<bool>,
    side: Vec<i8>,
}

impl Pieces {
    fn push(&mut self, ring: &[u32], source: Option<u32>, side: i8) {
        self.faces.push(ring);
        self.source.push(source);
        self.whole.push(false);
        self.side.push(side);
    }

    fn push_whole(&mut self, ring: &[u32], source: u32, side: i8) {
        self.push(ring, Some(source), side);
        if let Some(last) = self.whole.last_mut() {
            *last = true;
        }
    }
}

/// [`cut_cell`] on a validated cell whose faces' geometry is `whole`.
fn cut(cell: &Cell<'_>, whole: &[FaceGeometry], plane: Plane) -> Option<Cut> {
    let dist = signed_distances(cell.points, plane)?;
    let mut crossings = Crossings::new(cell.points, &dist);
    let (mut pieces, chords) = face_pieces(cell, &mut crossings)?;
    let cut_pieces = pieces.faces.len();
    for ring in chain_sections(&chords)? {
        // Out of the + side is along -normal; a hole in the section would be along +.
        if vector_dot(newell(&crossings.positions, &ring), plane.normal) >= 0.0 {
            return None;
        }
        pieces.push(&ring, None, 1);
    }
    let part_of = components(&pieces);
    let across = (0..pieces.faces.len())
        .map(|j| match pieces.source[j] {
            Some(k) => Some(cell.ghosts[k as usize].map_or(Across::Boundary, Across::Ghost)),
            None => part_across(pieces.faces.get(j), &pieces, cut_pieces, &part_of),
        })
        .collect::<Option<Vec<Across>>>()?;
    let region = Region {
        points: &crossings.positions,
        faces: &pieces.faces,
        owner: &part_of,
        across: &across,
        parts: part_of.iter().max().map_or(0, |&p| p as usize + 1),
        ghost_centroids: cell.ghost_centroids,
    };
    let mut normals = Vec::new();
    let geometry: Vec<FaceGeometry> = (0..pieces.faces.len())
        .map(|j| match (pieces.source[j], pieces.whole[j]) {
            (Some(k), true) => whole[k as usize],
            _ => face_geometry(&crossings.positions, pieces.faces.get(j), &mut normals),
        })
        .collect();
    let quality = measure_faces(&region, &geometry)?;
    let crossings = crossings.list;
    Some(measured_cut(crossings, pieces, part_of, across, quality))
}

/// The pieces of the cell's faces, in face order, and the chords; None where a face
/// cannot be split ([`split_loop`]).
fn face_pieces(cell: &Cell<'_>, crossings: &mut Crossings<'_>) -> Option<(Pieces, Vec<[u32; 2]>)> {
    let mut pieces = Pieces::default();
    let mut chords = Vec::new();
    for (k, ring) in cell.faces.iter().enumerate() {
        let above = ring.iter().filter(|&&v| crossings.above(v)).count();
        if above == 0 || above == ring.len() {
            pieces.push_whole(ring, k as u32, if above > 0 { 1 } else { -1 });
        } else {
            split_loop(ring, k as u32, crossings, &mut pieces, &mut chords)?;
        }
    }
    Some((pieces, chords))
}

/// The cut's faces with their quality, and the reference's tallies of it.
fn measured_cut(
    crossings: Vec<Crossing>,
    pieces: Pieces,
    part: Vec<u32>,
    across: Vec<Across>,
    quality: RegionQuality,
) -> Cut {
    let parts = quality.centroids.len();
    let mut part_failing = vec![0; parts];
    let mut failing_sources = Vec::new();
    for (k, &bad) in quality.bad.iter().enumerate() {
        if bad {
            part_failing[part[k] as usize] += 1;
            if let Across::Part(p) = across[k] {
                part_failing[p as usize] += 1;
            }
            failing_sources.push(pieces.source[k]);
        }
    }
    failing_sources.sort_unstable();
    failing_sources.dedup();
    Cut {
        crossings,
        faces: pieces.faces,
        source: pieces.source,
        part,
        across,
        parts,
        failing: quality.bad.iter().filter(|&&b| b).count(),
        worst: total_badness(&quality),
        quality,
        part_failing,
        failing_sources,
    }
}

/// Each vertex's signed distance `(x − origin) · normal` from the plane, moved off the
/// vertices first if it passes too close; None if it still does, or if every vertex lies
/// on one side.
fn signed_distances(points: &[[f64; 3]], plane: Plane) -> Option<Vec<f64>> {
    let Plane { normal, origin } = plane;
    let extent = |k: usize| {
        let column = points.iter().map(|p| p[k]);
        column.clone().fold(f64::NEG_INFINITY, f64::max) - column.fold(f64::INFINITY, f64::min)
    };
    let size = (0..3).map(extent).fold(f64::NEG_INFINITY, f64::max);
    let distances = |origin| -> Vec<f64> {
        points
            .iter()
            .map(|&p| matvec_dot(sub(p, origin), normal))
            .collect()
    };
    let too_close = |dist: &[f64]| {
        dist.iter().map(|d| d.abs()).fold(f64::INFINITY, f64::min) < CLEARANCE * size
    };
    let mut dist = distances(origin);
    if too_close(&dist) {
        let shift = 10.0 * CLEARANCE * size;
        dist = distances(add(origin, normal.map(|n| shift * n)));
        if too_close(&dist) {
            return None;
        }
    }
    let one_side = dist.iter().all(|&d| d > 0.0) || dist.iter().all(|&d| d < 0.0);
    (!one_side).then_some(dist)
}

/// The cell's vertices and the crossings made so far, each crossing once per edge.
struct Crossings<'a> {
    dist: &'a [f64],
    /// The cell's points, then the crossings' in order of creation.
    positions: Vec<[f64; 3]>,
    list: Vec<Crossing>,
}

impl<'a> Crossings<'a> {
    fn new(points: &[[f64; 3]], dist: &'a [f64]) -> Self {
        Self {
            dist,
            positions: points.to_vec(),
            list: Vec::new(),
        }
    }

    /// The side of the plane vertex `v` of the cell lies on.
    fn above(&self, v: u32) -> bool {
        self.dist[v as usize] > 0.0
    }

    /// The vertex where the plane crosses edge `a b`, made the first time it is asked for.
    fn at(&mut self, a: u32, b: u32) -> u32 {
        let edge = [a.min(b), a.max(b)];
        let m = self.dist.len() as u32;
        if let Some(j) = self.list.iter().position(|c| c.edge == edge) {
            return m + j as u32;
        }
        let [p, q] = edge.map(|v| self.positions[v as usize]);
        let (dp, dq) = (self.dist[edge[0] as usize], self.dist[edge[1] as usize]);
        let t = dp / (dp - dq);
        let point = std::array::from_fn(|k| p[k] + t * (q[k] - p[k]));
        self.list.push(Crossing { edge, point });
        self.positions.push(point);
        m + self.list.len() as u32 - 1
    }
}

/// `_split_loop`: a face's loop `ring` cut by the plane into its pieces on each side
/// (those on the `+` side first), appended to `pieces`, and the chords (the plane's
/// segments inside the face, as the `+` pieces walk them) appended to `chords`.
///
/// None where the crossings cannot be paired along the plane or the pieces not traced
/// (the face touches the plane without crossing it, or is not simple).
fn split_loop(
    ring: &[u32],
    source: u32,
    crossings: &mut Crossings<'_>,
    pieces: &mut Pieces,
    chords: &mut Vec<[u32; 2]>,
) -> Option<()> {
    // The loop with its crossings: `aug`, and per entry its side (0 at a crossing).
    let m = ring.len();
    let mut aug = Vec::with_capacity(2 * m);
    let mut sign: Vec<i8> = Vec::with_capacity(2 * m);
    for (i, &a) in ring.iter().enumerate() {
        let b = ring[(i + 1) % m];
        aug.push(a);
        sign.push(if crossings.above(a) { 1 } else { -1 });
        if crossings.above(a) != crossings.above(b) {
            aug.push(crossings.at(a, b));
            sign.push(0);
        }
    }
    let at: Vec<usize> = (0..aug.len()).filter(|&i| sign[i] == 0).collect();
    if at.is_empty() {
        pieces.push_whole(ring, source, sign.first().copied().unwrap_or(1));
        return Some(());
    }
    let partner = pair_crossings(&aug, &at, &crossings.positions)?;
    let n = aug.len();
    let before = |i: usize| sign[(i + n - 1) % n];
    let mut piece = Vec::with_capacity(n);
    for s in [1, -1] {
        // Directed steps on side s: loop edges leaving a vertex of side s (or a crossing
        // followed by one), and at a crossing reached from side s, the chord.
        let mut steps = Steps::new(n);
        for i in 0..n {
            let j = (i + 1) % n;
            if sign[i] == s || (sign[i] == 0 && sign[j] == s) {
                if sign[i] == 0 && before(i) == s {
                    return None; // touches the plane without crossing
                }
                steps.insert(i, j, false);
            }
        }
        for &i in &at {
            if before(i) == s {
                let p = partner[i];
                if sign[(p + 1) % n] != s {
                    return None;
                }
                steps.insert(i, p, true);
                if s == 1 {
                    chords.push([aug[i], aug[p]]);
                }
            }
        }
        while let Some(start) = steps.first() {
            piece.clear();
            let mut i = start;
            loop {
                piece.push(aug[i]);
                i = steps.take(i)?;
                if i == start {
                    break;
                }
                if !steps.has(i) {
                    return None;
                }
            }
            pieces.push(&piece, Some(source), s);
        }
    }
    Some(())
}

/// The steps of a face's pieces on one side: from each entry of the augmented loop, the
/// next one. The reference keeps them in a dict, whose first key is the earliest
/// inserted: loop edges go in by position, then chords by position.
struct Steps {
    next: Vec<Option<usize>>,
    chord: Vec<bool>,
}

impl Steps {
    fn new(n: usize) -> Self {
        Self {
            next: vec![None; n],
            chord: vec![false; n],
        }
    }

    fn insert(&mut self, from: usize, to: usize, chord: bool) {
        self.next[from] = Some(to);
        self.chord[from] = chord;
    }

    fn has(&self, i: usize) -> bool {
        self.next[i].is_some()
    }

    fn take(&mut self, i: usize) -> Option<usize> {
        self.next[i].take()
    }

    /// The earliest inserted step left.
    fn first(&self) -> Option<usize> {
        let left =
            |chord: bool| (0..self.next.len()).find(|&i| self.has(i) && self.chord[i] == chord);
        left(false).or_else(|| left(true))
    }
}

/// Each crossing's partner (`partner[i]` for `i` in `at`): the crossings of a planar face
/// lie on one line, and sorted along it they pair up first with second, third with
/// fourth, ... None for an odd number.
///
/// The reference sorts along the principal axis of the crossings (an SVD) where there
/// are more than two; here along the segment from the first to the farthest. On one line
/// both sort alike, up to crossings that coincide to round-off.
fn pair_crossings(aug: &[u32], at: &[usize], positions: &[[f64; 3]]) -> Option<Vec<usize>> {
    if at.len() % 2 == 1 {
        return None;
    }
    let point = |i: usize| positions[aug[i] as usize];
    let first = point(*at.first()?);
    let direction = if at.len() == 2 {
        sub(point(at[1]), first)
    } else {
        at.iter()
            .map(|&i| sub(point(i), first))
            .max_by(|u, v| numpy_cmp(norm2(*u), norm2(*v)))?
    };
    let along: Vec<f64> = at
        .iter()
        .map(|&i| matvec_dot(point(i), direction))
        .collect();
    let mut order: Vec<usize> = (0..at.len()).collect();
    order.sort_by(|&a, &b| numpy_cmp(along[a], along[b]));
    let mut partner = vec![usize::MAX; aug.len()];
    for pair in order.chunks_exact(2) {
        let (a, b) = (at[pair[0]], at[pair[1]]);
        partner[a] = b;
        partner[b] = a;
    }
    Some(partner)
}

/// numpy's sort order: NaN after every number.
fn numpy_cmp(a: f64, b: f64) -> Ordering {
    a.partial_cmp(&b)
        .unwrap_or_else(|| a.is_nan().cmp(&b.is_nan()))
}

fn norm2(a: [f64; 3]) -> f64 {
    a.iter().map(|x| x * x).sum()
}

/// The sections: the chords (walked by the `+` pieces) reversed and chained into loops.
/// None if two chords end at one crossing or a chain does not close.
fn chain_sections(chords: &[[u32; 2]]) -> Option<Vec<Vec<u32>>> {
    // `ahead[b] = a` for each chord a -> b, in chord order (the reference's dict).
    let mut ahead: Vec<Option<(u32, u32)>> = Vec::with_capacity(chords.len());
    for &[a, b] in chords {
        if ahead.iter().flatten().any(|&(key, _)| key == b) {
            return None;
        }
        ahead.push(Some((b, a)));
    }
    let mut sections = Vec::new();
    while let Some(start) = ahead.iter().flatten().next().map(|&(key, _)| key) {
        let mut ring = Vec::new();
        let mut v = start;
        loop {
            ring.push(v);
            let slot = ahead
                .iter_mut()
                .find(|e| matches!(e, Some((key, _)) if *key == v));
            let next = slot?.take().map(|(_, a)| a)?;
            if next == start {
                break;
            }
            v = next;
        }
        sections.push(ring);
    }
    Some(sections)
}

/// Twice the vector area of the loop `ring` (`_newell`): the cross products of
/// consecutive vertices, summed in order.
fn newell(positions: &[[f64; 3]], ring: &[u32]) -> [f64; 3] {
    let k = ring.len();
    (0..k).fold([0.0; 3], |sum, i| {
        let p = positions[ring[i] as usize];
        let q = positions[ring[(i + 1) % k] as usize];
        add(sum, cross(p, q))
    })
}

/// `_components`: each piece's part, the pieces of one side joined where they share an
/// edge; parts numbered in order of their first piece.
fn components(pieces: &Pieces) -> Vec<u32> {
    // Per side, each edge as (lower vertex, higher vertex) packed in a u64, with its
    // piece: sorted, the pieces holding one edge are neighbours.
    let mut edges: [Vec<(u64, usize)>; 2] = [Vec::new(), Vec::new()];
    for (j, ring) in pieces.faces.iter().enumerate() {
        let side = &mut edges[usize::from(pieces.side[j] > 0)];
        let k = ring.len();
        for (i, &a) in ring.iter().enumerate() {
            let b = ring[if i + 1 == k { 0 } else { i + 1 }];
            side.push(((u64::from(a.min(b)) << 32) | u64::from(a.max(b)), j));
        }
    }
    let mut parent: Vec<usize> = (0..pieces.faces.len()).collect();
    for side in &mut edges {
        side.sort_unstable();
        for pair in side.windows(2) {
            if pair[0].0 == pair[1].0 {
                let (ri, rj) = (find(&mut parent, pair[0].1), find(&mut parent, pair[1].1));
                parent[rj] = ri;
            }
        }
    }
    let mut number = vec![u32::MAX; parent.len()];
    let mut parts = 0;
    (0..parent.len())
        .map(|j| {
            let root = find(&mut parent, j);
            if number[root] == u32::MAX {
                number[root] = parts;
                parts += 1;
            }
            number[root]
        })
        .collect()
}

/// The root of `i`'s set, halving the path on the way.
fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// `_part_across`: the part on the `-` side of a section, the part of the first of the
/// cell's `-` pieces (the first `cut_pieces`) that walks the section's first edge the same
/// way.
fn part_across(
    ring: &[u32],
    pieces: &Pieces,
    cut_pieces: usize,
    part_of: &[u32],
) -> Option<Across> {
    let (&a, &b) = (ring.first()?, ring.get(1)?);
    (0..cut_pieces)
        .filter(|&j| pieces.side[j] < 0)
        .find(|&j| {
            let piece = pieces.faces.get(j);
            let k = piece.len();
            (0..k).any(|i| piece[i] == a && piece[(i + 1) % k] == b)
        })
        .map(|j| Across::Part(part_of[j]))
}
