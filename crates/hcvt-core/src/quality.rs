//! Mesh quality as OpenFOAM's `checkMesh` measures it, from a mesh's arrays alone.
//!
//! The geometry is OpenFOAM's (`primitiveMeshTools`), so that the figures are those
//! `checkMesh` prints for the same mesh:
//!
//! - a **face** (3D) is cut into a fan of triangles from the average `e` of its vertices;
//!   its area vector `S` is half the sum of the fan's normals `(q - p) × (e - p)`, its
//!   centre `c_f` the fan's centroids weighted by the normals' lengths (exact for a planar
//!   face). A 2D face is an edge `a → b` with its owner on the left: centre `(a + b) / 2`,
//!   `S` its right-hand normal `(b_y - a_y, a_x - b_x)`;
//! - a **cell** is cut into one cone per face from the average `x0` of its face centres;
//!   a cone's measure is `S_f · (c_f - x0) / d` (`S_f` out of the cell), its centroid
//!   `(d c_f + x0) / (d + 1)`, and the cell's volume and centroid are their sums.
//!
//! and the figures are `checkMesh`'s, against the cell centres `C`:
//!
//! | figure | faces | definition |
//! |--------|-------|------------|
//! | non-orthogonality | interior | angle (degrees) between `S` and `d = C_N - C_P` |
//! | skewness | all | `|s| / max(0.2 |d|, max_v |ŝ·(v - c_f)|)`, `s = (c_f - C_P) - (S·(c_f - C_P) / S·d) d` |
//! | inverted pyramid | all | a cone `S·(c_f - C_P) / d` or `S·(C_N - c_f) / d` below `-1e-15` |
//! | volume ratio | interior | smaller over larger volume of the two cells (`minVolRatio`) |
//! | aspect ratio | cells | `max(s) / min(s)` of `s = Σ_f |S_f|` per component; 3D at least `Σ s / 6 / V^(2/3)` |
//!
//! A boundary face measures against its owner's mirror image: `d` is the normal part of
//! `c_f - C_P`, and its skewness floor `0.4 |d|`.
//!
//! Determinism: a face's figures come from its own vertices and its cells' centres, a
//! cell's sums run over its faces in increasing face index; nothing is summed in an order
//! that depends on the thread count or on a library's vector width, so the result depends
//! on the input bits alone (issue 29: the numpy implementation it replaces changed its
//! last bits with numpy's summation order from one numpy version to the next).
//! Positions are taken relative to the face's vertex average and the cell's face-centre
//! average before they are weighted, which also keeps faces `1e±100` wide finite.

use rayon::prelude::*;

use crate::diagram::PolyMesh;
use crate::error::CoreError;
use crate::geometry::{add, dot, norm2, scale, sub, Euclid, Space};

/// OpenFOAM's `ROOTVSMALL`: keeps `0 / 0` out of the ratios (a face of no area, a cell of
/// no volume, `s = 0`).
const ROOT_VSMALL: f64 = 1e-150;
/// OpenFOAM's `SMALL`: a cone more negative than this (`L^d`) is an inverted pyramid.
const SMALL: f64 = 1e-15;

/// A mesh in OpenFOAM's face-based layout, borrowed: what [`mesh_quality`] measures.
///
/// The types are those of [`PolyMesh`] ([`MeshArrays::of`] borrows one).
#[derive(Debug, Clone, Copy)]
pub struct MeshArrays<'a, const D: usize> {
    /// Vertices, `L`.
    pub points: &'a [[f64; D]],
    /// `f + 1` entries from 0: face `k` is `face_vertices[face_offsets[k]..face_offsets[k + 1]]`.
    pub face_offsets: &'a [usize],
    /// 3D: each face's loop of at least 3 vertices, counter-clockwise seen from outside
    /// its owner. 2D: each face an edge of 2 vertices with its owner on the left.
    pub face_vertices: &'a [u32],
    /// The cell of each face whose outside its area vector points to, `< n_cells`.
    pub owner: &'a [u32],
    /// The cell on the other side, or `-1` for a boundary face.
    pub neighbour: &'a [i64],
    /// Number of cells; a cell may have no faces.
    pub n_cells: usize,
}

impl<'a, const D: usize> MeshArrays<'a, D> {
    /// The arrays of `mesh`, whose cells are the `n_cells` sites it was made from.
    pub fn of(mesh: &'a PolyMesh<D>, n_cells: usize) -> Self {
        Self {
            points: &mesh.points,
            face_offsets: &mesh.face_offsets,
            face_vertices: &mesh.face_vertices,
            owner: &mesh.owner,
            neighbour: &mesh.neighbour,
            n_cells,
        }
    }

    fn faces(&self) -> usize {
        self.owner.len()
    }

    /// Face `k`'s vertices, in order (after [`check`]).
    fn face(&self, k: usize) -> &'a [u32] {
        &self.face_vertices[self.face_offsets[k]..self.face_offsets[k + 1]]
    }

    /// The neighbour of face `k` (after [`check`]).
    fn neighbour_of(&self, k: usize) -> Option<usize> {
        usize::try_from(self.neighbour[k]).ok()
    }
}

/// What [`mesh_quality`] measures: row `k` of a per-face field is face `k`, row `c` of a
/// per-cell field is cell `c`.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshQuality<const D: usize> {
    /// Per face: area centroid, `L` (module docs).
    pub face_centre: Vec<[f64; D]>,
    /// Per face: normal out of the owner, of length the face's area (length in 2D), `L^(d-1)`.
    pub area_vector: Vec<[f64; D]>,
    /// Per cell: area (2D) or volume (3D), `L^d`; 0 for a cell without faces.
    pub volume: Vec<f64>,
    /// Per cell: centroid, `L`; NaN for a cell without faces, the face-centre average for
    /// a cell of zero volume (OpenFOAM's fallback).
    pub centroid: Vec<[f64; D]>,
    /// Per cell: `checkMesh`'s aspect ratio (0 for a cell without faces).
    pub aspect_ratio: Vec<f64>,
    /// Per face: degrees, NaN on boundary faces.
    pub non_orthogonality: Vec<f64>,
    /// Per face: dimensionless.
    pub skewness: Vec<f64>,
    /// Per face: whether the cone from either cell's centre over the face is inverted.
    pub inverted_pyramid: Vec<bool>,
    /// Per face: smaller over larger volume of its two cells, NaN on boundary faces.
    pub volume_ratio: Vec<f64>,
}

/// The geometry and `checkMesh`'s quality of every face and cell of `mesh` (module docs).
///
/// With `centres`, the face figures (non-orthogonality, skewness, inverted pyramids) are
/// measured against those cell centres instead of the cells' own centroids: a candidate
/// face is judged against the cells it would belong to before the mesh holding it exists
/// (`hcvt.mesh.merge`). NaN centres are allowed (they give NaN figures).
///
/// Errors: [`CoreError::ShapeMismatch`] when the arrays' lengths disagree (or `centres`
/// is not one row per cell); [`CoreError::InvalidFace`] naming the first face with
/// decreasing offsets, the wrong number of vertices (2 in 2D, at least 3 in 3D), a vertex
/// or a cell that does not exist, or one cell on both sides; [`CoreError::InvalidPoint`]
/// for a non-finite point.
///
/// # Example
///
/// ```
/// use hcvt_core::{mesh_quality, MeshArrays};
///
/// // Two unit squares side by side; face 0 is the edge between them.
/// let points = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0], [1.0, 1.0], [2.0, 1.0]];
/// let edges = [1, 4, 0, 1, 4, 3, 3, 0, 1, 2, 2, 5, 5, 4];
/// let mesh = MeshArrays {
///     points: &points,
///     face_offsets: &[0, 2, 4, 6, 8, 10, 12, 14],
///     face_vertices: &edges,
///     owner: &[0, 0, 0, 0, 1, 1, 1],
///     neighbour: &[1, -1, -1, -1, -1, -1, -1],
///     n_cells: 2,
/// };
/// let q = mesh_quality(&mesh, None).unwrap();
/// assert_eq!(q.volume, [1.0, 1.0]);
/// assert_eq!(q.centroid[1], [1.5, 0.5]);
/// assert_eq!((q.non_orthogonality[0], q.skewness[0]), (0.0, 0.0));
/// assert_eq!(q.aspect_ratio, [1.0, 1.0]);
/// ```
pub fn mesh_quality<const D: usize>(
    mesh: &MeshArrays<'_, D>,
    centres: Option<&[[f64; D]]>,
) -> Result<MeshQuality<D>, CoreError>
where
    Euclid: Space<D>,
{
    check(mesh)?;
    if let Some(c) = centres {
        if c.len() != mesh.n_cells {
            return Err(CoreError::ShapeMismatch {
                what: "centres",
                expected: mesh.n_cells,
                got: c.len(),
            });
        }
    }
    let f = mesh.faces();
    let (face_centre, area_vector): (Vec<_>, Vec<_>) = (0..f)
        .into_par_iter()
        .map(|k| face_geometry(mesh.points, mesh.face(k)))
        .unzip();
    let cells = cell_faces(mesh);
    let (volume, (centroid, aspect_ratio)): (Vec<_>, (Vec<_>, Vec<_>)) = (0..mesh.n_cells)
        .into_par_iter()
        .map(|c| {
            let faces = &cells.faces[cells.offsets[c]..cells.offsets[c + 1]];
            let (volume, centroid) = cell_geometry(faces, &face_centre, &area_vector);
            (
                volume,
                (centroid, aspect_ratio(faces, &area_vector, volume)),
            )
        })
        .unzip();
    let centres = centres.unwrap_or(&centroid);
    let per_face: Vec<FaceQuality> = (0..f)
        .into_par_iter()
        .map(|k| {
            let own = mesh.owner[k] as usize;
            let other = mesh.neighbour_of(k);
            let mut figures = face_quality(
                mesh.points,
                mesh.face(k),
                face_centre[k],
                area_vector[k],
                centres[own],
                other.map(|n| centres[n]),
            );
            figures.volume_ratio = other.map_or(f64::NAN, |n| {
                let (a, b) = (volume[own], volume[n]);
                a.min(b) / a.max(b).max(ROOT_VSMALL)
            });
            figures
        })
        .collect();
    Ok(MeshQuality {
        face_centre,
        area_vector,
        volume,
        centroid,
        aspect_ratio,
        non_orthogonality: per_face.iter().map(|q| q.non_orthogonality).collect(),
        skewness: per_face.iter().map(|q| q.skewness).collect(),
        inverted_pyramid: per_face.iter().map(|q| q.inverted_pyramid).collect(),
        volume_ratio: per_face.iter().map(|q| q.volume_ratio).collect(),
    })
}

/// Refuse what would make an index out of range or a figure undefined, naming the first
/// offender; what merely makes a poor mesh (an open cell, a flat face) is measured.
fn check<const D: usize>(mesh: &MeshArrays<'_, D>) -> Result<(), CoreError> {
    let f = mesh.faces();
    let lengths = [
        ("neighbour", f, mesh.neighbour.len()),
        ("face_offsets", f + 1, mesh.face_offsets.len()),
        (
            "face_vertices",
            mesh.face_offsets.last().copied().unwrap_or(0),
            mesh.face_vertices.len(),
        ),
    ];
    for (what, expected, got) in lengths {
        if expected != got {
            return Err(CoreError::ShapeMismatch {
                what,
                expected,
                got,
            });
        }
    }
    let bad = |face: usize, reason: String| Err(CoreError::InvalidFace { face, reason });
    if let Some(&first) = mesh.face_offsets.first().filter(|&&o| o != 0) {
        return bad(0, format!("face_offsets must start at 0, got {first}"));
    }
    let (p, n) = (mesh.points.len(), mesh.n_cells);
    for k in 0..f {
        let (start, end) = (mesh.face_offsets[k], mesh.face_offsets[k + 1]);
        let size = end.checked_sub(start);
        match size {
            None => return bad(k, format!("face_offsets decrease from {start} to {end}")),
            Some(s) if D == 2 && s != 2 => {
                return bad(k, format!("a 2D face is an edge of 2 vertices, got {s}"))
            }
            Some(s) if D != 2 && s < 3 => {
                return bad(k, format!("a face needs at least 3 vertices, got {s}"))
            }
            Some(_) => {}
        }
        if let Some(v) = mesh.face_vertices[start..end]
            .iter()
            .find(|&&v| v as usize >= p)
        {
            return bad(k, format!("vertex {v} does not exist ({p} points)"));
        }
        let owner = mesh.owner[k];
        if owner as usize >= n {
            return bad(k, format!("owner {owner} is not a cell ({n} cells)"));
        }
        let neighbour = mesh.neighbour[k];
        if neighbour < -1 || usize::try_from(neighbour).is_ok_and(|c| c >= n) {
            return bad(
                k,
                format!("neighbour {neighbour} is neither a cell ({n} cells) nor -1"),
            );
        }
        if neighbour == i64::from(owner) {
            return bad(k, format!("cell {owner} is on both sides"));
        }
    }
    for (index, point) in mesh.points.iter().enumerate() {
        if let Some(&value) = point.iter().find(|x| !x.is_finite()) {
            return Err(CoreError::InvalidPoint { index, value });
        }
    }
    Ok(())
}

/// Each cell's faces in increasing face index, with whether the cell owns the face
/// (its area vector points out): entries `offsets[c]..offsets[c + 1]` for cell `c`.
struct CellFaces {
    offsets: Vec<usize>,
    faces: Vec<(usize, bool)>,
}

fn cell_faces<const D: usize>(mesh: &MeshArrays<'_, D>) -> CellFaces {
    let mut offsets = vec![0; mesh.n_cells + 1];
    for k in 0..mesh.faces() {
        offsets[mesh.owner[k] as usize + 1] += 1;
        if let Some(n) = mesh.neighbour_of(k) {
            offsets[n + 1] += 1;
        }
    }
    for c in 0..mesh.n_cells {
        offsets[c + 1] += offsets[c];
    }
    let mut next = offsets.clone();
    let mut faces = vec![(0, false); offsets[mesh.n_cells]];
    let mut put = |cell: usize, entry: (usize, bool)| {
        faces[next[cell]] = entry;
        next[cell] += 1;
    };
    for k in 0..mesh.faces() {
        put(mesh.owner[k] as usize, (k, true));
        if let Some(n) = mesh.neighbour_of(k) {
            put(n, (k, false));
        }
    }
    CellFaces { offsets, faces }
}

/// The centre and area vector (module docs) of the face with `vertices` (in order).
fn face_geometry<const D: usize>(points: &[[f64; D]], vertices: &[u32]) -> ([f64; D], [f64; D])
where
    Euclid: Space<D>,
{
    let corner = |i: usize| points[vertices[i] as usize];
    if D == 2 {
        let edge: [[f64; D]; D] = std::array::from_fn(corner);
        return (scale(add(edge[0], edge[1]), 0.5), Euclid::normal(&edge));
    }
    let count = vertices.len();
    let estimate = (0..count)
        .fold([0.0; D], |sum, i| add(sum, corner(i)))
        .map(|x| x / count as f64);
    let (mut normal, mut weight, mut moment) = ([0.0; D], 0.0, [0.0; D]);
    for i in 0..count {
        let (p, q) = (corner(i), corner((i + 1) % count));
        let triangle = [p, q, estimate];
        let n = Euclid::normal(&std::array::from_fn(|j| triangle[j]));
        let w = length(n);
        normal = add(normal, n);
        weight += w;
        // w · (p + q + e) about e: the same centroid, without the product of a large
        // weight and a large position overflowing.
        moment = add(moment, scale(add(sub(p, estimate), sub(q, estimate)), w));
    }
    let centre = if weight < ROOT_VSMALL {
        estimate // OpenFOAM keeps the vertex average of a face of no area
    } else {
        add(estimate, moment.map(|x| x / (3.0 * weight)))
    };
    (centre, scale(normal, 0.5))
}

/// A cell's volume and centroid from its faces (module docs).
fn cell_geometry<const D: usize>(
    faces: &[(usize, bool)],
    centre: &[[f64; D]],
    area: &[[f64; D]],
) -> (f64, [f64; D]) {
    if faces.is_empty() {
        return (0.0, [f64::NAN; D]);
    }
    let d = D as f64;
    let count = faces.len() as f64;
    let apex = faces
        .iter()
        .fold([0.0; D], |sum, &(k, _)| add(sum, centre[k]))
        .map(|x| x / count);
    // d times the cones' volumes and first moments about the apex, divided by d once at
    // the end as OpenFOAM does (a unit cube's eighths come out 1/8 exactly).
    let (mut volume_d, mut first_d) = (0.0, [0.0; D]);
    for &(k, out) in faces {
        let r = sub(centre[k], apex);
        let s = if out { area[k] } else { scale(area[k], -1.0) };
        let cone_d = dot(s, r);
        volume_d += cone_d;
        first_d = add(first_d, scale(r, cone_d)); // a cone's centroid: apex + d r / (d + 1)
    }
    if volume_d == 0.0 {
        return (0.0, apex);
    }
    let centroid = add(apex, first_d.map(|x| x * (d / (d + 1.0)) / volume_d));
    (volume_d / d, centroid)
}

/// `checkMesh`'s aspect ratio of a cell (module docs): 1 for an axis-aligned cube or
/// square, above 1000 for a sliver; a 2D cell is measured as OpenFOAM measures its
/// one-cell-thick extrusion (the empty direction left out).
fn aspect_ratio<const D: usize>(faces: &[(usize, bool)], area: &[[f64; D]], volume: f64) -> f64 {
    let s = faces
        .iter()
        .fold([0.0; D], |sum, &(k, _)| add(sum, area[k].map(f64::abs)));
    let (lo, hi) = s.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
        (lo.min(x), hi.max(x))
    });
    let ratio = hi / (lo + ROOT_VSMALL);
    if D == 3 {
        let total: f64 = s.iter().sum();
        ratio.max(total / 6.0 / volume.max(ROOT_VSMALL).powf(2.0 / 3.0))
    } else {
        ratio
    }
}

/// One face's figures (module docs).
struct FaceQuality {
    non_orthogonality: f64,
    skewness: f64,
    inverted_pyramid: bool,
    volume_ratio: f64,
}

/// Non-orthogonality, skewness and inverted pyramids of the face with `vertices`, centre
/// `centre` and area vector `area`, between the cell centres `own` and `other` (`None` on
/// the boundary). `volume_ratio` is left NaN for the caller.
fn face_quality<const D: usize>(
    points: &[[f64; D]],
    vertices: &[u32],
    centre: [f64; D],
    area: [f64; D],
    own: [f64; D],
    other: Option<[f64; D]>,
) -> FaceQuality {
    let cpf = sub(centre, own);
    let d = match other {
        Some(n) => sub(n, own),
        None => {
            // Against the owner's mirror image across the face: d along the normal.
            let unit = area.map(|x| x / length(area).max(ROOT_VSMALL));
            scale(unit, dot(unit, cpf))
        }
    };
    let (d_length, area_length) = (length(d), length(area));
    let cosine = dot(d, area) / (d_length * area_length + ROOT_VSMALL);
    let non_orthogonality = match other {
        Some(_) => cosine.clamp(-1.0, 1.0).acos().to_degrees(),
        None => f64::NAN,
    };
    let s = sub(cpf, scale(d, dot(area, cpf) / (dot(area, d) + ROOT_VSMALL)));
    let s_length = length(s);
    let s_unit = s.map(|x| x / (s_length + ROOT_VSMALL));
    // The face's extent along s: the largest |ŝ·(v - c_f)| over its vertices.
    let extent = vertices.iter().fold(0.0f64, |m, &v| {
        m.max(dot(s_unit, sub(points[v as usize], centre)).abs())
    });
    let floor = if other.is_some() { 0.2 } else { 0.4 } * d_length + ROOT_VSMALL;
    let skewness = s_length / floor.max(extent);
    let dim = D as f64;
    let own_cone = dot(area, cpf) / dim;
    let other_cone = other.map_or(0.0, |n| dot(area, sub(n, centre)) / dim);
    FaceQuality {
        non_orthogonality,
        skewness,
        inverted_pyramid: own_cone < -SMALL || other_cone < -SMALL,
        volume_ratio: f64::NAN,
    }
}

/// `|v|`, also where its squares overflow (faces `1e77` wide) or underflow (`1e-77`).
fn length<const D: usize>(v: [f64; D]) -> f64 {
    let plain = norm2(v).sqrt();
    if plain.is_finite() && plain > ROOT_VSMALL {
        return plain;
    }
    let big = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if big == 0.0 || !big.is_finite() {
        return plain;
    }
    big * norm2(v.map(|x| x / big)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// A mesh from cells given as their outward faces (vertex loops): a face met twice is
    /// interior, owned by the cell that listed it first. The brute-force assembly the
    /// tests measure.
    #[derive(Clone)]
    struct Built<const D: usize> {
        points: Vec<[f64; D]>,
        offsets: Vec<usize>,
        vertices: Vec<u32>,
        owner: Vec<u32>,
        neighbour: Vec<i64>,
        n_cells: usize,
    }

    impl<const D: usize> Built<D> {
        fn new(points: Vec<[f64; D]>, cells: &[Vec<Vec<u32>>]) -> Self {
            let mut seen: HashMap<Vec<u32>, usize> = HashMap::new();
            let mut built = Self {
                points,
                offsets: vec![0],
                vertices: vec![],
                owner: vec![],
                neighbour: vec![],
                n_cells: cells.len(),
            };
            for (c, faces) in cells.iter().enumerate() {
                for face in faces {
                    let mut key = face.clone();
                    key.sort_unstable();
                    if let Some(&k) = seen.get(&key) {
                        assert_eq!(built.neighbour[k], -1, "face {face:?} met three times");
                        built.neighbour[k] = c as i64;
                        continue;
                    }
                    seen.insert(key, built.owner.len());
                    built.vertices.extend(face);
                    built.offsets.push(built.vertices.len());
                    built.owner.push(c as u32);
                    built.neighbour.push(-1);
                }
            }
            built
        }

        fn arrays(&self) -> MeshArrays<'_, D> {
            MeshArrays {
                points: &self.points,
                face_offsets: &self.offsets,
                face_vertices: &self.vertices,
                owner: &self.owner,
                neighbour: &self.neighbour,
                n_cells: self.n_cells,
            }
        }

        fn quality(&self) -> MeshQuality<D>
        where
            Euclid: Space<D>,
        {
            mesh_quality(&self.arrays(), None).unwrap()
        }

        /// The face with these vertices, in any order.
        fn face(&self, vertices: &[u32]) -> usize {
            let mut key = vertices.to_vec();
            key.sort_unstable();
            (0..self.owner.len())
                .find(|&k| {
                    let mut f = self.vertices[self.offsets[k]..self.offsets[k + 1]].to_vec();
                    f.sort_unstable();
                    f == key
                })
                .unwrap()
        }
    }

    /// The 6 outward quads of the hexahedron with corners `v[i + 2j + 4k]` at `(i, j, k)`.
    fn hexahedron(v: [u32; 8]) -> Vec<Vec<u32>> {
        let at = |i: usize, j: usize, k: usize| v[i + 2 * j + 4 * k];
        vec![
            vec![at(0, 0, 0), at(0, 0, 1), at(0, 1, 1), at(0, 1, 0)], // x = 0
            vec![at(1, 0, 0), at(1, 1, 0), at(1, 1, 1), at(1, 0, 1)], // x = 1
            vec![at(0, 0, 0), at(1, 0, 0), at(1, 0, 1), at(0, 0, 1)], // y = 0
            vec![at(0, 1, 0), at(0, 1, 1), at(1, 1, 1), at(1, 1, 0)], // y = 1
            vec![at(0, 0, 0), at(0, 1, 0), at(1, 1, 0), at(1, 0, 0)], // z = 0
            vec![at(0, 0, 1), at(1, 0, 1), at(1, 1, 1), at(0, 1, 1)], // z = 1
        ]
    }

    /// The unit cube cut at `xs`, `ys`, `zs` (increasing, from 0 to 1) into boxes.
    fn boxes(xs: &[f64], ys: &[f64], zs: &[f64]) -> Built<3> {
        let (nx, ny) = (xs.len(), ys.len());
        let mut points = vec![];
        for &z in zs {
            for &y in ys {
                for &x in xs {
                    points.push([x, y, z]);
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
        let mut cells = vec![];
        for k in 0..zs.len() - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let v =
                        std::array::from_fn(|c| id(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2)));
                    cells.push(hexahedron(v));
                }
            }
        }
        Built::new(points, &cells)
    }

    fn close(a: f64, b: f64, what: &str) {
        assert!(
            (a - b).abs() <= 1e-12 * b.abs().max(1.0),
            "{what}: {a} != {b}"
        );
    }

    #[test]
    fn a_cube_cut_into_eight_cubes_is_perfect() {
        let mesh = boxes(&[0.0, 0.5, 1.0], &[0.0, 0.5, 1.0], &[0.0, 0.5, 1.0]);
        let q = mesh.quality();
        assert_eq!(q.volume, [0.125; 8]);
        for (c, centroid) in q.centroid.iter().enumerate() {
            let expected = [c & 1, c >> 1 & 1, c >> 2].map(|b| 0.25 + 0.5 * b as f64);
            assert_eq!(*centroid, expected, "cell {c}");
        }
        assert_eq!(q.aspect_ratio, [1.0; 8]);
        let interior = mesh.neighbour.iter().filter(|&&n| n >= 0).count();
        assert_eq!(interior, 12);
        for k in 0..mesh.owner.len() {
            let inner = mesh.neighbour[k] >= 0;
            assert_eq!(q.skewness[k], 0.0, "face {k}");
            assert!(!q.inverted_pyramid[k], "face {k}");
            let (angle, ratio) = (q.non_orthogonality[k], q.volume_ratio[k]);
            if inner {
                assert_eq!((angle, ratio), (0.0, 1.0), "face {k}");
            } else {
                assert!(angle.is_nan() && ratio.is_nan(), "face {k}");
            }
            assert_eq!(length(q.area_vector[k]), 0.25, "face {k}");
        }
    }

    #[test]
    fn uneven_boxes_have_their_aspect_and_volume_ratios() {
        let mesh = boxes(&[0.0, 0.3, 1.0], &[0.0, 1.0], &[0.0, 1.0]);
        let q = mesh.quality();
        close(q.volume[0], 0.3, "volume 0");
        close(q.volume[1], 0.7, "volume 1");
        close(q.centroid[0][0], 0.15, "centroid 0");
        close(q.centroid[1][0], 0.65, "centroid 1");
        // s = (2, 2·0.3, 2·0.3) for the thin box: max / min = 1 / 0.3; the volume term
        // (3.2 / 6 / 0.3^(2/3) = 1.19) is smaller.
        close(q.aspect_ratio[0], 1.0 / 0.3, "aspect 0");
        close(q.aspect_ratio[1], 1.0 / 0.7, "aspect 1");
        let k = mesh.face(&[1, 4, 7, 10]);
        close(q.volume_ratio[k], 0.3 / 0.7, "volume ratio");
        assert_eq!((q.non_orthogonality[k], q.skewness[k]), (0.0, 0.0));
    }

    #[test]
    fn the_cube_cut_into_six_tetrahedra_matches_their_closed_forms() {
        // Kuhn's triangulation: the paths from (0,0,0) to (1,1,1) one axis at a time.
        let corner = |i: usize| [i & 1, i >> 1 & 1, i >> 2].map(|b| b as f64);
        let points: Vec<[f64; 3]> = (0..8).map(corner).collect();
        let mut cells = vec![];
        let mut tets = vec![];
        for order in [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ] {
            let mut v = [0u32; 4];
            for (s, axis) in order.iter().enumerate() {
                v[s + 1] = v[s] | 1 << axis;
            }
            // Each triangle oriented so that its normal points away from the fourth vertex.
            let faces =
                [[0, 1, 2, 3], [0, 1, 3, 2], [0, 2, 3, 1], [1, 2, 3, 0]].map(|[a, b, c, o]| {
                    let (pa, pb, pc, po) = (
                        points[v[a] as usize],
                        points[v[b] as usize],
                        points[v[c] as usize],
                        points[v[o] as usize],
                    );
                    let n = Euclid::normal(&[pa, pb, pc]);
                    if dot(n, sub(po, pa)) < 0.0 {
                        vec![v[a], v[b], v[c]]
                    } else {
                        vec![v[a], v[c], v[b]]
                    }
                });
            cells.push(faces.to_vec());
            tets.push(v);
        }
        let mesh = Built::new(points.clone(), &cells);
        let q = mesh.quality();
        assert_eq!(mesh.neighbour.iter().filter(|&&n| n >= 0).count(), 6);
        let mut total = 0.0;
        for (c, v) in tets.iter().enumerate() {
            close(q.volume[c], 1.0 / 6.0, "tet volume");
            total += q.volume[c];
            let mean = v
                .iter()
                .fold([0.0; 3], |s, &i| add(s, points[i as usize]))
                .map(|x| x / 4.0);
            for (got, want) in q.centroid[c].iter().zip(mean) {
                close(*got, want, "tet centroid");
            }
        }
        close(total, 1.0, "total volume");
        // A triangle's fan centre is its centroid; its area vector half the cross product.
        for k in 0..mesh.owner.len() {
            let f: Vec<[f64; 3]> = mesh
                .arrays()
                .face(k)
                .iter()
                .map(|&v| mesh.points[v as usize])
                .collect();
            let centroid = add(add(f[0], f[1]), f[2]).map(|x| x / 3.0);
            let exact = scale(Euclid::normal(&[f[0], f[1], f[2]]), 0.5);
            for i in 0..3 {
                close(q.face_centre[k][i], centroid[i], "face centre");
                close(q.area_vector[k][i], exact[i], "area vector");
            }
            assert!(!q.inverted_pyramid[k], "face {k}");
        }
    }

    /// The unit cube `P` beside the box `[1, 2] × [0, 1]²` sheared by `y += shear (x - 1)`:
    /// a hexahedron of volume 1 whose centroid is `(1.5, 0.5 + shear / 2, 0.5)`.
    fn sheared_pair(shear: f64) -> Built<3> {
        let mut points = vec![];
        for z in [0.0, 1.0] {
            for y in [0.0, 1.0] {
                for x in [0.0, 1.0, 2.0] {
                    points.push([x, y + shear * (x - 1.0f64).max(0.0), z]);
                }
            }
        }
        let id = |i: u32, j: u32, k: u32| i + 3 * (j + 2 * k);
        let cell = |i0: u32| {
            hexahedron(std::array::from_fn(|c| {
                let c = c as u32;
                id(i0 + (c & 1), c >> 1 & 1, c >> 2)
            }))
        };
        Built::new(points, &[cell(0), cell(1)])
    }

    #[test]
    fn a_sheared_hexahedron_has_the_angles_and_skewness_worked_by_hand() {
        for shear in [0.25, 0.5, 1.0] {
            let mesh = sheared_pair(shear);
            let q = mesh.quality();
            close(q.volume[1], 1.0, "sheared volume");
            close(q.centroid[1][1], 0.5 + shear / 2.0, "sheared centroid");
            // Interior face x = 1, centre (1, 1/2, 1/2), S = (1, 0, 0); d = (1, shear/2, 0):
            // the angle atan(shear / 2). s = c_f - C_P - (S·(c_f - C_P) / S·d) d
            // = (0, -shear/4, 0), and the face reaches 1/2 along y > 0.2 |d|.
            let k = mesh.face(&[1, 4, 7, 10]);
            close(
                q.non_orthogonality[k],
                (shear / 2.0).atan().to_degrees(),
                "angle",
            );
            close(q.skewness[k], shear / 2.0, "interior skewness");
            // Far face x = 2, centre (2, 1/2 + shear, 1/2): d = (1/2, 0, 0) the normal part
            // of c_f - C_N = (1/2, shear/2, 0), s = (0, shear/2, 0), extent 1/2.
            let far = mesh.face(&[2, 5, 8, 11]);
            close(q.skewness[far], shear, "far skewness");
            // Bottom face y = shear (x - 1), a parallelogram with S = (shear, -1, 0): the
            // offset of its centre from C_N, (0, -1/2, 0), has the tangential part of
            // length (shear / 2) / √(1 + shear²) along the face's x edge, over which the
            // face reaches √(1 + shear²) / 2: skewness shear / (1 + shear²).
            let bottom = mesh.face(&[1, 2, 7, 8]);
            close(
                q.skewness[bottom],
                shear / (1.0 + shear * shear),
                "bottom skewness",
            );
            // The cube's own faces: unskewed.
            let left = mesh.face(&[0, 3, 6, 9]);
            close(q.skewness[left], 0.0, "cube face");
            assert!(q.inverted_pyramid.iter().all(|&x| !x));
            assert!(q.non_orthogonality[far].is_nan());
        }
    }

    #[test]
    fn the_2d_sheared_pair_and_a_u_shaped_cell() {
        let shear = 1.0;
        let points = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, shear],
            [0.0, 1.0],
            [1.0, 1.0],
            [2.0, 1.0 + shear],
        ];
        let square = vec![vec![0, 1], vec![1, 4], vec![4, 3], vec![3, 0]];
        let sheared = vec![vec![1, 2], vec![2, 5], vec![5, 4], vec![4, 1]];
        let mesh = Built::new(points, &[square, sheared]);
        let q = mesh.quality();
        assert_eq!(q.volume, [1.0, 1.0]);
        let k = mesh.face(&[1, 4]);
        close(
            q.non_orthogonality[k],
            (shear / 2.0).atan().to_degrees(),
            "2D angle",
        );
        close(q.skewness[k], shear / 2.0, "2D skewness");

        // A U (a bar of 3 x 1 with two arms of 1 x 2): area 7, centroid (3/2, 19/14) lies
        // below the inner edge y = 1 of the gap, whose pyramid is inverted.
        let ring: [[f64; 2]; 8] = [
            [0., 0.],
            [3., 0.],
            [3., 3.],
            [2., 3.],
            [2., 1.],
            [1., 1.],
            [1., 3.],
            [0., 3.],
        ];
        let edges: Vec<Vec<u32>> = (0..8).map(|i| vec![i, (i + 1) % 8]).collect();
        let u = Built::new(ring.to_vec(), &[edges]);
        let q = u.quality();
        close(q.volume[0], 7.0, "U area");
        close(q.centroid[0][0], 1.5, "U centroid x");
        close(q.centroid[0][1], 19.0 / 14.0, "U centroid y");
        // The gap's three walls: its floor y = 1 and its sides x = 1, x = 2 (the centroid,
        // at x = 3/2, is beyond their planes too).
        let inverted: Vec<usize> = (0..8).filter(|&k| q.inverted_pyramid[k]).collect();
        assert_eq!(
            inverted,
            [u.face(&[3, 4]), u.face(&[4, 5]), u.face(&[5, 6])]
        );
    }

    #[test]
    fn given_centres_replace_the_cells_own_for_the_face_figures() {
        let mesh = sheared_pair(0.5);
        let own = mesh.quality();
        let centres = [[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]]; // as if unsheared
        let q = mesh_quality(&mesh.arrays(), Some(&centres)).unwrap();
        let k = mesh.face(&[1, 4, 7, 10]);
        assert_eq!(q.non_orthogonality[k], 0.0);
        assert!(own.non_orthogonality[k] > 10.0);
        assert_eq!((q.volume, q.centroid), (own.volume, own.centroid));
        let short = mesh_quality(&mesh.arrays(), Some(&centres[..1]));
        assert!(matches!(
            short,
            Err(CoreError::ShapeMismatch {
                what: "centres",
                ..
            })
        ));
    }

    #[test]
    fn malformed_meshes_are_refused_by_name() {
        let mesh = sheared_pair(0.5);
        let refused = |edit: &dyn Fn(&mut Built<3>), expected: &str| {
            let mut m = mesh.clone();
            edit(&mut m);
            let message = mesh_quality(&m.arrays(), None).unwrap_err().to_string();
            assert!(message.contains(expected), "{message:?} lacks {expected:?}");
        };
        refused(
            &|m| m.vertices[5] = 99,
            "face 1: vertex 99 does not exist (12 points)",
        );
        refused(
            &|m| m.owner[3] = 2,
            "face 3: owner 2 is not a cell (2 cells)",
        );
        refused(&|m| m.neighbour[4] = 2, "face 4: neighbour 2 is neither");
        refused(&|m| m.neighbour[4] = -2, "face 4: neighbour -2 is neither");
        refused(
            &|m| m.neighbour[0] = i64::from(m.owner[0]),
            "face 0: cell 0 is on both sides",
        );
        refused(
            &|m| m.offsets[2] = 3,
            "face 1: face_offsets decrease from 4 to 3",
        );
        refused(
            &|m| m.offsets[1] = 2,
            "face 0: a face needs at least 3 vertices, got 2",
        );
        refused(
            &|m| m.offsets[0] = 1,
            "face 0: face_offsets must start at 0, got 1",
        );
        refused(
            &|m| {
                m.neighbour.pop();
            },
            "neighbour: expected length 11, got 10",
        );
        refused(
            &|m| {
                m.offsets.pop();
            },
            "face_offsets: expected length 12, got 11",
        );
        refused(
            &|m| {
                m.vertices.push(0);
            },
            "face_vertices: expected length 44, got 45",
        );
        refused(
            &|m| m.points[7][2] = f64::NAN,
            "point 7 has a non-finite coordinate (NaN)",
        );
        let two_d = MeshArrays::<2> {
            points: &[[0.0; 2]; 3],
            face_offsets: &[0, 3],
            face_vertices: &[0, 1, 2],
            owner: &[0],
            neighbour: &[-1],
            n_cells: 1,
        };
        let message = mesh_quality(&two_d, None).unwrap_err().to_string();
        assert_eq!(message, "face 0: a 2D face is an edge of 2 vertices, got 3");
    }

    #[test]
    fn faces_1e100_wide_keep_finite_centres() {
        for size in [1e-100, 1e100] {
            let mut mesh = boxes(&[0.0, 0.5, 1.0], &[0.0, 1.0], &[0.0, 1.0]);
            for p in &mut mesh.points {
                *p = p.map(|x| x * size);
            }
            let q = mesh.quality();
            for k in 0..mesh.owner.len() {
                let area = length(q.area_vector[k]) / (size * size);
                assert!(area == 0.5 || area == 1.0, "face {k}: area {area} size²");
                assert!(q.face_centre[k].iter().all(|x| x.is_finite()), "face {k}");
            }
            // OpenFOAM's guard 1e-150 added to S·d (1e-300 here) swamps it in the small
            // mesh, as it does in checkMesh: the skewness is only exact in the large one.
            if size > 1.0 {
                assert_eq!(q.skewness.iter().fold(0.0f64, |m, &x| m.max(x)), 0.0);
            }
        }
    }

    proptest::proptest! {
        /// Any arrays give a measure or an error, never a panic.
        #[test]
        fn any_arrays_give_a_result_or_an_error(
            points in proptest::collection::vec(proptest::array::uniform3(-2.0f64..2.0), 0..6),
            sizes in proptest::collection::vec(0usize..6, 0..6),
            vertices in proptest::collection::vec(0u32..8, 0..30),
            owner in proptest::collection::vec(0u32..4, 0..6),
            neighbour in proptest::collection::vec(-2i64..4, 0..6),
            n_cells in 0usize..4,
            centres in proptest::option::of(proptest::collection::vec(proptest::array::uniform3(-2.0f64..2.0), 0..4)),
        ) {
            let offsets: Vec<usize> = std::iter::once(0)
                .chain(sizes.iter().scan(0, |end, &s| { *end += s; Some(*end) }))
                .collect();
            let mesh = MeshArrays { points: &points, face_offsets: &offsets, face_vertices: &vertices, owner: &owner, neighbour: &neighbour, n_cells };
            let _ = mesh_quality(&mesh, centres.as_deref());
            let flat: Vec<[f64; 2]> = points.iter().map(|p| [p[0], p[1]]).collect();
            let plane = MeshArrays { points: &flat, face_offsets: &offsets, face_vertices: &vertices, owner: &owner, neighbour: &neighbour, n_cells };
            let _ = mesh_quality(&plane, None);
        }
    }
}
