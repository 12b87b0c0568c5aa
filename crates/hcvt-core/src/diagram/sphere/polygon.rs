//! A convex spherical polygon in the frame of its site, clipped by great circles
//! (module docs of [`super`], "Route").

use crate::geometry::{add, cross, dot, norm2, scale, sub};
use crate::moments::FaceMoments;

use crate::diagram::convex_cell::{ConvexCell, Face};

/// An orthonormal right-handed frame `(e1, e2, z)` with `z` the site's direction.
#[derive(Debug, Clone, Copy)]
pub(in crate::diagram) struct SiteFrame {
    pub(in crate::diagram) e1: [f64; 3],
    pub(in crate::diagram) e2: [f64; 3],
    pub(in crate::diagram) z: [f64; 3],
}

impl SiteFrame {
    /// Duff et al., "Building an orthonormal basis, revisited" (JCGT 2017): no branch
    /// but the sign, no loss of orthogonality near the poles.
    pub(in crate::diagram) fn at(site: [f64; 3]) -> Self {
        let z = scale(site, 1.0 / norm2(site).sqrt());
        let sign = 1.0_f64.copysign(z[2]);
        let a = -1.0 / (sign + z[2]);
        let b = z[0] * z[1] * a;
        Self {
            e1: [1.0 + sign * z[0] * z[0] * a, sign * b, -sign * z[0]],
            e2: [b, sign + z[1] * z[1] * a, -z[1]],
            z,
        }
    }

    pub(in crate::diagram) fn global(&self, l: [f64; 3]) -> [f64; 3] {
        add(
            add(scale(self.e1, l[0]), scale(self.e2, l[1])),
            scale(self.z, l[2]),
        )
    }

    /// Face moments in the frame turned into global axes: `F m`, `F S Fᵀ` with `F` the
    /// matrix of columns `(e1, e2, ẑ)`.
    pub(super) fn global_moments(&self, m: &FaceMoments<3>) -> FaceMoments<3> {
        // `S` is symmetric: `F` times its row `r` is column `r` of `F S`, and `F` times row
        // `c` of `F S` is column `c` of `F S Fᵀ`.
        let columns = m.second.map(|row| self.global(row));
        let rows = [0, 1, 2].map(|c| self.global([columns[0][c], columns[1][c], columns[2][c]]));
        FaceMoments {
            measure: m.measure,
            first: self.global(m.first),
            second: std::array::from_fn(|r| std::array::from_fn(|c| rows[c][r])),
        }
    }
}

/// A convex spherical polygon in a [`SiteFrame`], inside an open hemisphere: unit
/// vertices counter-clockwise seen from outside; edge `k` (the short arc from vertex `k` to
/// `k + 1`) lies on the great circle `normals[k]·x = 0` (inside: `≤ 0`) and was made by
/// `faces[k]`; [`Face::Box`] marks an edge of the start polygon.
#[derive(Debug, Default)]
pub(in crate::diagram) struct SphericalPolygon {
    pub(in crate::diagram) vertices: Vec<[f64; 3]>,
    pub(in crate::diagram) normals: Vec<[f64; 3]>,
    pub(in crate::diagram) faces: Vec<Face>,
    spare_vertices: Vec<[f64; 3]>,
    spare_normals: Vec<[f64; 3]>,
    spare_faces: Vec<Face>,
}

/// The start polygon of the common cell: the square cap of corners `(±1, ±1, 1)` in the
/// site's frame (45° from the site along the axes), counter-clockwise from outside.
pub(super) const CAP: [[f64; 3]; 4] = [
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
];

impl SphericalPolygon {
    /// The polygon with these corners (counter-clockwise from outside, within an open
    /// hemisphere), every edge [`Face::Box`].
    pub(super) fn reset(&mut self, corners: &[[f64; 3]]) {
        let m = corners.len();
        self.vertices.clear();
        self.vertices.extend(corners.iter().map(|&c| unit(c)));
        self.normals.clear();
        self.normals
            .extend((0..m).map(|k| scale(cross(corners[k], corners[(k + 1) % m]), -1.0)));
        self.faces.clear();
        self.faces.extend(std::iter::repeat_n(Face::Box, m));
    }

    /// The octant `(sx e1, sy e2, sz ẑ)` of the site's frame, `s = ±1`.
    pub(super) fn reset_to_octant(&mut self, sx: f64, sy: f64, sz: f64) {
        let (a, b, c) = ([sx, 0.0, 0.0], [0.0, sy, 0.0], [0.0, 0.0, sz]);
        if sx * sy * sz > 0.0 {
            self.reset(&[a, b, c]);
        } else {
            self.reset(&[b, a, c]);
        }
    }

    /// Keep the side `n·x ≤ 0` of a great circle, tagging its arc `face`
    /// (Sutherland–Hodgman on the sphere: every edge is shorter than a half circle, so a
    /// positive combination of its ends is on it). A vertex on the circle counts as inside.
    pub(in crate::diagram) fn clip(&mut self, n: [f64; 3], face: Face) {
        let count = self.vertices.len();
        if count == 0 {
            return;
        }
        if self.vertices.iter().all(|&v| dot(n, v) <= 0.0) {
            // Nothing cut; an edge with both ends on the circle lies on it (a circle
            // through the start polygon's edge: an antipodal site's bisector).
            for k in 0..count {
                let (a, b) = (self.vertices[k], self.vertices[(k + 1) % count]);
                if dot(n, a) == 0.0 && dot(n, b) == 0.0 {
                    (self.normals[k], self.faces[k]) = (n, face);
                }
            }
            return;
        }
        let mut vertices = std::mem::take(&mut self.spare_vertices);
        let mut normals = std::mem::take(&mut self.spare_normals);
        let mut faces = std::mem::take(&mut self.spare_faces);
        vertices.clear();
        normals.clear();
        faces.clear();
        let mut di = dot(n, self.vertices[0]);
        for k in 0..count {
            let (vi, ni, fi) = (self.vertices[k], self.normals[k], self.faces[k]);
            let vj = self.vertices[(k + 1) % count];
            let dj = dot(n, vj);
            let inside_i = di <= 0.0;
            if inside_i {
                vertices.push(vi);
                normals.push(ni);
                faces.push(fi);
            }
            if inside_i && dj > 0.0 {
                // Leaving: the next edge lies on the circle.
                if di < 0.0 {
                    vertices.push(crossing(vi, vj, di, dj));
                    normals.push(n);
                    faces.push(face);
                } else if let (Some(last_n), Some(last_f)) = (normals.last_mut(), faces.last_mut())
                {
                    (*last_n, *last_f) = (n, face); // vi is on the circle already
                }
            } else if !inside_i && dj < 0.0 {
                // Entering: the old edge goes on from the crossing.
                vertices.push(crossing(vi, vj, di, dj));
                normals.push(ni);
                faces.push(fi);
            }
            di = dj;
        }
        if vertices.len() < 3 {
            vertices.clear();
            normals.clear();
            faces.clear();
        }
        self.spare_vertices = std::mem::replace(&mut self.vertices, vertices);
        self.spare_normals = std::mem::replace(&mut self.normals, normals);
        self.spare_faces = std::mem::replace(&mut self.faces, faces);
    }

    /// Clip by the great circle of every bisector plane of `cell` (relative to its site,
    /// in `frame`), then [`SphericalPolygon::polish`].
    pub(super) fn clip_by_cell<C: ConvexCell<3>>(&mut self, cell: &C, frame: &SiteFrame) {
        self.clip_by_bisectors(cell, frame);
        self.polish();
    }

    /// Clip by the great circle of every bisector plane of `cell` (relative to its site,
    /// in `frame`), as they come: also a polygon that is not convex (a region's,
    /// `sphere_region.rs`), whose pieces along a circle then run both ways.
    pub(in crate::diagram) fn clip_by_bisectors<C: ConvexCell<3>>(
        &mut self,
        cell: &C,
        frame: &SiteFrame,
    ) {
        cell.for_each_plane(|face, h| {
            if let Face::Neighbor(_) = face {
                // The plane `q·v ≤ |q|²/2` relative to the site is `q·x ≤ 0` on the sphere:
                // its normal in the frame, with `q·ẑ = −|q|²/2` exactly for unit sites.
                let q = h.normal;
                self.clip([dot(q, frame.e1), dot(q, frame.e2), -h.offset], face);
            }
        });
    }

    /// Recompute each vertex as the meeting point of its two circles, `n_{k−1} × n_k`
    /// normalised: in the frame their components are exact to relative round-off, so the
    /// vertex is too, where the clip's interpolation along an arc from a far start corner
    /// is only exact to round-off of the sphere's size. Circles meeting at less than about
    /// 1e-8 radians leave the vertex as clipped.
    fn polish(&mut self) {
        let m = self.vertices.len();
        for k in 0..m {
            let (a, b) = (self.normals[(k + m - 1) % m], self.normals[k]);
            let w = cross(a, b);
            let w2 = norm2(w);
            if w2 > 1e-16 * norm2(a) * norm2(b) {
                let w = scale(w, 1.0 / w2.sqrt());
                let v = self.vertices[k];
                self.vertices[k] = if dot(w, v) >= 0.0 { w } else { scale(w, -1.0) };
            }
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.vertices.len() < 3
    }

    /// An edge of the start polygon is left: the cell may go on beyond it.
    pub(super) fn reaches_start(&self) -> bool {
        self.faces.contains(&Face::Box)
    }

    /// `max_k (1 − v_k·ẑ)` over the vertices of a polygon above the equator: how deep the
    /// cap holding it is (`|x − ẑ|² = 2 (1 − x·ẑ)` on the polygon is largest at a vertex).
    pub(in crate::diagram) fn depth(&self) -> f64 {
        self.vertices
            .iter()
            .map(|&v| {
                let u = unit(v);
                (u[0] * u[0] + u[1] * u[1]) / (1.0 + u[2])
            })
            .fold(0.0, f64::max)
    }
}

/// The point where the arc from `a` (`n·a = da`) to `b` (`n·b = db`, of the other sign)
/// crosses the great circle, normalised: interpolated along the chord like a 2D cell's
/// crossing, so that it stays on the arc when `a` and `b` are close.
fn crossing(a: [f64; 3], b: [f64; 3], da: f64, db: f64) -> [f64; 3] {
    let t = da / (da - db);
    unit(add(a, scale(sub(b, a), t)))
}

pub(in crate::diagram) fn unit(v: [f64; 3]) -> [f64; 3] {
    scale(v, 1.0 / norm2(v).sqrt())
}
