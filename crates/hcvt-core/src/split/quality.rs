//! checkMesh's measures of a small region: its parts' volumes and centroids, and on each
//! face the non-orthogonality, skewness and face pyramids (OpenFOAM's
//! `primitiveMeshTools`, as `hcvt.export.quality.face_quality` writes them).

use super::numpy_order::{array_sum, reduceat_sum, row_dot, row_norm};
use super::{Across, Loops};
use crate::error::CoreError;
use crate::geometry::{cross, sub};

/// checkMesh's skewness limit: a face above it is reported.
pub const SKEWNESS_LIMIT: f64 = 4.0;

/// The skewness a face must not exceed to pass: the limit less a margin far above the
/// 1e-9 by which our figures and checkMesh's printed ones have been seen to differ
/// (`hcvt.export.quality.SKEWNESS_TARGET`).
pub const SKEWNESS_TARGET: f64 = SKEWNESS_LIMIT * (1.0 - 1e-6);

/// The largest aspect ratio of a part: checkMesh's limit 1000 less the same margin.
const ASPECT_TARGET: f64 = 1000.0 * (1.0 - 1e-6);

/// OpenFOAM's guard against 0/0 (`ROOTVSMALL`).
const ROOT_VSMALL: f64 = 1e-150;

/// OpenFOAM's face-pyramid tolerance (`SMALL`), in `L³`.
const SMALL: f64 = 1e-15;

/// Non-orthogonality at which checkMesh stops warning and fails a face, degrees.
const FAILING_ANGLE: f64 = 90.0;

/// A few cells ("parts") and the faces that bound them, the cells across those faces
/// from outside ("ghosts") given by their centroids only.
#[derive(Debug, Clone, Copy)]
pub struct Region<'a> {
    /// Vertex positions, `L`.
    pub points: &'a [[f64; 3]],
    /// Each face's loop of indices into `points`, counter-clockwise seen from outside its
    /// owner.
    pub faces: &'a Loops,
    /// Each face's part, `0..parts`.
    pub owner: &'a [u32],
    /// What lies on the other side of each face.
    pub across: &'a [Across],
    /// Number of parts.
    pub parts: usize,
    /// Centroid of each ghost cell, `L`.
    pub ghost_centroids: &'a [[f64; 3]],
}

/// What [`measure_region`] found: one entry per face, one centroid per part.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionQuality {
    /// Whether the face fails checkMesh: skewness above [`SKEWNESS_TARGET`], an inverted
    /// pyramid, or non-orthogonality of 90° or more.
    pub bad: Vec<bool>,
    /// 0 for a passing face; else its skewness over [`SKEWNESS_LIMIT`] (at least 1), plus
    /// 1 for an inverted pyramid (`_Editor.measure` in `hcvt.export.split`).
    pub badness: Vec<f64>,
    /// How far the faces with a cell across are from orthogonal: the sum over them of
    /// `1 − cos θ`, θ the non-orthogonality (checkMesh's average is the angle of the mean
    /// cosine). The search prefers, among cuts that fail alike, the least oblique.
    pub oblique: f64,
    /// Each part's volume, `L³`.
    pub volumes: Vec<f64>,
    /// Each part's centroid, `L`.
    pub centroids: Vec<[f64; 3]>,
}

/// The checkMesh quality of `region`'s faces against its parts' centroids and the ghosts'.
///
/// Face centre and area by OpenFOAM's fan from the vertex average, a part's volume and
/// centroid by pyramids from the average of its face centres (the rules of
/// `hcvt.polymesh.PolyMesh`), then the formulas of `hcvt.export.quality.face_quality`,
/// rounded as numpy rounds them there ([`super::numpy_order`]).
///
/// `Ok(None)` when a part's volume is not positive (or NaN).
///
/// # Errors
///
/// [`CoreError::InvalidFace`] naming the first face whose vertex, owner or neighbour does
/// not exist, or a per-face array of the wrong length.
pub fn measure_region(region: &Region<'_>) -> Result<Option<RegionQuality>, CoreError> {
    validate(region)?;
    Ok(measure(region))
}

/// Every index of `region` in range.
fn validate(region: &Region<'_>) -> Result<(), CoreError> {
    let faces = region.faces.len();
    region.faces.check_vertices(region.points.len())?;
    for (what, len) in [
        ("owner", region.owner.len()),
        ("across", region.across.len()),
    ] {
        if len != faces {
            return Err(CoreError::InvalidFace {
                face: len.min(faces),
                reason: format!("{faces} faces but {len} entries of {what}"),
            });
        }
    }
    let invalid = |face, reason| Err(CoreError::InvalidFace { face, reason });
    for (k, (&owner, &across)) in region.owner.iter().zip(region.across).enumerate() {
        if owner as usize >= region.parts {
            return invalid(k, format!("owner {owner}, but {} parts", region.parts));
        }
        match across {
            Across::Part(p) if p as usize >= region.parts => {
                return invalid(k, format!("across part {p}, but {} parts", region.parts));
            }
            Across::Ghost(g) if g as usize >= region.ghost_centroids.len() => {
                let count = region.ghost_centroids.len();
                return invalid(k, format!("across ghost {g}, but {count} ghost centroids"));
            }
            _ => {}
        }
    }
    Ok(())
}

/// [`measure_region`] on a region whose indices are known to be in range.
pub(super) fn measure(region: &Region<'_>) -> Option<RegionQuality> {
    let mut normals = Vec::new();
    let faces: Vec<FaceGeometry> = (region.faces.iter())
        .map(|ring| face_geometry(region.points, ring, &mut normals))
        .collect();
    measure_faces(region, &faces)
}

/// [`measure`] with each face's centre and area known (`faces`, one per face of `region`).
pub(super) fn measure_faces(region: &Region<'_>, faces: &[FaceGeometry]) -> Option<RegionQuality> {
    let (volumes, centroids): (Vec<f64>, Vec<[f64; 3]>) =
        part_geometry(region, faces)?.into_iter().unzip();
    let centroid_of = |across: Across| match across {
        Across::Part(p) => Some(centroids[p as usize]),
        Across::Ghost(g) => Some(region.ghost_centroids[g as usize]),
        Across::Boundary => None,
    };
    let mut bad = Vec::with_capacity(faces.len());
    let mut badness = Vec::with_capacity(faces.len());
    let mut oblique = 0.0;
    for (k, face) in faces.iter().enumerate() {
        let ring = region.faces.get(k);
        let owner = centroids[region.owner[k] as usize];
        let quality = face_quality(
            region.points,
            ring,
            face,
            owner,
            centroid_of(region.across[k]),
        );
        let fails = quality.fails();
        if !quality.non_orthogonality.is_nan() {
            oblique += 1.0 - quality.non_orthogonality.to_radians().cos();
        }
        bad.push(fails);
        badness.push(if fails { quality.badness() } else { 0.0 });
    }
    Some(RegionQuality {
        bad,
        badness,
        oblique,
        volumes,
        centroids,
    })
}

/// A face's centre and area vector (normal, length its area), `L` and `L²`.
#[derive(Debug, Clone, Copy)]
pub(super) struct FaceGeometry {
    centre: [f64; 3],
    area: [f64; 3],
}

/// OpenFOAM's `makeFaceCentresAndAreas`: a fan of triangles from the vertex average; the
/// area vector their sum, the centre their area-weighted centroid (the average where the
/// face has no area). Each column summed as `np.add.reduceat` sums it; `normals` holds
/// the triangles' (twice their vector areas).
pub(super) fn face_geometry(
    points: &[[f64; 3]],
    ring: &[u32],
    normals: &mut Vec<[f64; 3]>,
) -> FaceGeometry {
    let k = ring.len();
    let at = |i: usize| points[ring[i] as usize];
    let next = |i: usize| points[ring[if i + 1 == k { 0 } else { i + 1 }] as usize];
    let estimate: [f64; 3] = std::array::from_fn(|c| reduceat_sum(k, |i| at(i)[c]) / k as f64);
    normals.clear();
    normals.extend((0..k).map(|i| cross(sub(next(i), at(i)), sub(estimate, at(i)))));
    let weight = |i: usize| row_norm(normals[i]);
    let twice_area = reduceat_sum(k, weight);
    let centre = if twice_area < ROOT_VSMALL {
        estimate
    } else {
        let moment =
            |c: usize| reduceat_sum(k, |i| weight(i) * ((at(i)[c] + next(i)[c]) + estimate[c]));
        std::array::from_fn(|c| moment(c) / (3.0 * twice_area.max(ROOT_VSMALL)))
    };
    let area = std::array::from_fn(|c| 0.5 * reduceat_sum(k, |i| normals[i][c]));
    FaceGeometry { centre, area }
}

/// Each part's volume and centroid by pyramids from the average of its face centres
/// (OpenFOAM's `makeCellCentresAndVols`, `hcvt.polymesh.PolyMesh.cell_geometry`); None
/// unless every part has a positive volume and an aspect ratio checkMesh passes.
///
/// The volume is exact for planar faces; the centroid only where the face centres are,
/// which the fan's unsigned triangle areas miss on a face that is not convex (as in
/// OpenFOAM). A part's faces are taken in face order, summed one after the other as
/// `np.bincount` does.
fn part_geometry(region: &Region<'_>, faces: &[FaceGeometry]) -> Option<Vec<(f64, [f64; 3])>> {
    let mut sides: Vec<Vec<(usize, f64)>> = vec![Vec::new(); region.parts];
    for (k, (&owner, &across)) in region.owner.iter().zip(region.across).enumerate() {
        sides[owner as usize].push((k, 1.0));
        if let Across::Part(p) = across {
            sides[p as usize].push((k, -1.0));
        }
    }
    sides
        .iter()
        .map(|faces_of| {
            let count = faces_of.len().max(1) as f64;
            let mut apex = [0.0; 3];
            for &(k, _) in faces_of {
                apex = std::array::from_fn(|c| apex[c] + faces[k].centre[c]);
            }
            let apex = apex.map(|x| x / count);
            let mut volume = 0.0;
            let mut moment = [0.0; 3];
            for &(k, sign) in faces_of {
                let FaceGeometry { centre, area } = faces[k];
                let cone = row_dot(area.map(|a| a * sign), sub(centre, apex)) / 3.0;
                volume += cone;
                moment =
                    std::array::from_fn(|c| moment[c] + cone * ((3.0 * centre[c] + apex[c]) / 4.0));
            }
            let acceptable = volume > 0.0 && aspect_ratio(faces_of, faces, volume) <= ASPECT_TARGET;
            acceptable.then(|| (volume, moment.map(|m| m / volume)))
        })
        .collect()
}

/// checkMesh's aspect ratio of a cell (`primitiveMeshTools::cellClosedness`): with `s` the
/// sum over its faces of the absolute area components, the larger of `max(s) / min(s)`
/// and `(s_x + s_y + s_z) / 6 / V^(2/3)` (1 for an axis-aligned cube, 1.5 at most for a
/// sphere). checkMesh fails a mesh with a cell above 1000: a sliver cut off a cell.
fn aspect_ratio(faces_of: &[(usize, f64)], faces: &[FaceGeometry], volume: f64) -> f64 {
    let mut sum = [0.0; 3];
    for &(k, _) in faces_of {
        sum = std::array::from_fn(|c| sum[c] + faces[k].area[c].abs());
    }
    let (low, high) = (
        sum.iter().copied().fold(f64::INFINITY, f64::min),
        sum.iter().copied().fold(0.0, f64::max),
    );
    let by_axis = high / (low + ROOT_VSMALL);
    let by_area = (sum[0] + sum[1] + sum[2]) / 6.0 / volume.max(ROOT_VSMALL).powf(2.0 / 3.0);
    by_axis.max(by_area)
}

/// One face's checkMesh figures.
#[derive(Debug, Clone, Copy)]
struct FaceQuality {
    /// Degrees; NaN on the boundary.
    non_orthogonality: f64,
    skewness: f64,
    inverted_pyramid: bool,
}

impl FaceQuality {
    /// `hcvt.export.quality.fails_checkmesh` (a NaN angle passes).
    fn fails(&self) -> bool {
        let angle = if self.non_orthogonality.is_nan() {
            0.0
        } else {
            self.non_orthogonality
        };
        self.skewness > SKEWNESS_TARGET || self.inverted_pyramid || angle >= FAILING_ANGLE
    }

    /// The skewness over the limit (at least 1), plus 1 for an inverted pyramid; NaN for a
    /// NaN skewness, as `np.maximum` gives.
    fn badness(&self) -> f64 {
        let ratio = self.skewness / SKEWNESS_LIMIT;
        let skew = if ratio.is_nan() {
            ratio
        } else {
            ratio.max(1.0)
        };
        skew + if self.inverted_pyramid { 1.0 } else { 0.0 }
    }
}

/// `hcvt.export.quality.face_quality` for one face with owner centroid `own` and the
/// centroid across it (None on the boundary, where the owner's mirror image is used).
fn face_quality(
    points: &[[f64; 3]],
    ring: &[u32],
    face: &FaceGeometry,
    own: [f64; 3],
    across: Option<[f64; 3]>,
) -> FaceQuality {
    let FaceGeometry { centre, area } = *face;
    let cpf = sub(centre, own);
    let area_norm = row_norm(area);
    let d = match across {
        Some(other) => sub(other, own),
        None => {
            let unit = area.map(|a| a / area_norm.max(ROOT_VSMALL));
            let along = row_dot(unit, cpf);
            unit.map(|u| u * along)
        }
    };
    let d_norm = row_norm(d);
    let cosine = row_dot(d, area) / (d_norm * area_norm + ROOT_VSMALL);
    let non_orthogonality = match across {
        Some(_) => cosine.clamp(-1.0, 1.0).acos() * (180.0 / std::f64::consts::PI),
        None => f64::NAN,
    };
    let ratio = row_dot(area, cpf) / (row_dot(area, d) + ROOT_VSMALL);
    let s: [f64; 3] = std::array::from_fn(|c| cpf[c] - ratio * d[c]);
    let s_norm = row_norm(s);
    let s_hat = s.map(|x| x / (s_norm + ROOT_VSMALL));
    let extent = ring
        .iter()
        .map(|&v| row_dot(s_hat, sub(points[v as usize], centre)).abs())
        .fold(f64::NEG_INFINITY, nan_max);
    let floor = if across.is_some() { 0.2 } else { 0.4 } * d_norm + ROOT_VSMALL;
    let skewness = s_norm / nan_max(floor, extent);
    let own_cone = row_dot(area, cpf) / 3.0;
    let other_cone = across.map_or(0.0, |other| row_dot(area, sub(other, centre)) / 3.0);
    FaceQuality {
        non_orthogonality,
        skewness,
        inverted_pyramid: own_cone < -SMALL || other_cone < -SMALL,
    }
}

/// `np.maximum`: NaN if either is.
fn nan_max(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// The total badness of a region's faces, summed as `np.sum` sums.
pub(super) fn total_badness(quality: &RegionQuality) -> f64 {
    array_sum(&quality.badness)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube `[0, 1]³`: its 8 corners and 6 outward faces, the face at x = 1 last.
    fn cube() -> (Vec<[f64; 3]>, Loops) {
        let points = (0..8)
            .map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(f64::from))
            .collect();
        let rings = [
            [0, 4, 6, 2], // x = 0
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 2, 3, 1], // z = 0
            [4, 5, 7, 6], // z = 1
            [1, 3, 7, 5], // x = 1
        ];
        let offsets = (0..=6).map(|k| 4 * k).collect();
        (points, Loops::new(offsets, rings.concat()).unwrap())
    }

    /// The cube's figures at its face x = 1 against a ghost centred at `ghost`.
    fn face_across(ghost: [f64; 3]) -> (FaceQuality, RegionQuality) {
        let (points, faces) = cube();
        let mut across = [Across::Boundary; 6];
        across[5] = Across::Ghost(0);
        let region = Region {
            points: &points,
            faces: &faces,
            owner: &[0; 6],
            across: &across,
            parts: 1,
            ghost_centroids: &[ghost],
        };
        let measured = measure_region(&region).unwrap().unwrap();
        let face = face_geometry(&points, faces.get(5), &mut Vec::new());
        let quality = face_quality(
            &points,
            faces.get(5),
            &face,
            measured.centroids[0],
            Some(ghost),
        );
        (quality, measured)
    }

    /// A cube beside its mirror image: the segment between the centroids is the face's
    /// normal through its centre, so neither angle nor skewness; every face passes.
    #[test]
    fn a_cube_beside_its_mirror_is_orthogonal_and_unskewed() {
        let (quality, measured) = face_across([1.5, 0.5, 0.5]);
        assert_eq!(measured.centroids, vec![[0.5; 3]]);
        assert_eq!(quality.non_orthogonality, 0.0);
        assert_eq!(quality.skewness, 0.0);
        assert!(!quality.inverted_pyramid);
        assert_eq!(measured.bad, vec![false; 6]);
        assert_eq!(measured.badness, vec![0.0; 6]);
    }

    /// The neighbour moved 0.3 along y: the angle is atan(0.3); the segment crosses the
    /// face 0.15 from its centre, whose extent that way is 0.5: skewness 0.3.
    #[test]
    fn a_shifted_neighbour_gives_the_closed_form_angle_and_skewness() {
        let (quality, measured) = face_across([1.5, 0.8, 0.5]);
        let angle = 0.3f64.atan().to_degrees();
        assert!(
            (quality.non_orthogonality - angle).abs() < 1e-12,
            "{quality:?}"
        );
        assert!((quality.skewness - 0.3).abs() < 1e-12, "{quality:?}");
        assert!(!measured.bad[5]);
    }

    /// A ghost centred behind the face (inside the cube) inverts the face's pyramid on its
    /// side; the face fails with badness 1 + 1.
    #[test]
    fn a_ghost_behind_the_face_inverts_its_pyramid() {
        let (quality, measured) = face_across([0.9, 0.5, 0.5]);
        assert!(quality.inverted_pyramid);
        assert_eq!(quality.non_orthogonality, 0.0);
        assert!(measured.bad[5]);
        assert_eq!(measured.badness[5], 2.0);
    }

    /// A part without volume (its faces inside out) is no measurement.
    #[test]
    fn an_inside_out_part_is_none() {
        let (points, faces) = cube();
        let reversed: Vec<u32> = faces.iter().flat_map(|r| r.iter().rev().copied()).collect();
        let faces = Loops::new(faces.offsets().to_vec(), reversed).unwrap();
        let region = Region {
            points: &points,
            faces: &faces,
            owner: &[0; 6],
            across: &[Across::Boundary; 6],
            parts: 1,
            ghost_centroids: &[],
        };
        assert_eq!(measure_region(&region).unwrap(), None);
        let bad_owner = Region {
            owner: &[0, 0, 1, 0, 0, 0],
            ..region
        };
        assert!(matches!(
            measure_region(&bad_owner),
            Err(CoreError::InvalidFace { face: 2, .. })
        ));
    }
}
