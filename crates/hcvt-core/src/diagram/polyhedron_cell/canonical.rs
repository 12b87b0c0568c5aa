//! The canonical form of a [`PolyhedronCell`] (issue 32): its bits depend only on which
//! half-spaces bound it, not on the order they cut it, so that a warm diagram can rebuild
//! the cell from the previous one's planes and vertex triangles without clipping
//! (`diagram/ring.rs`), bit for bit the clipped cell.
//!
//! Canonical: the planes that bound the cell (all neighbours' bisectors) sorted by their
//! normals ([`normal_order`]: not by neighbour, which a partition numbers its own way),
//! the planes that were cut away dropped; each triangle rotated to start at its least
//! plane and the triangles sorted; each vertex recomputed from its three planes in that
//! order ([`vertex_of`]).

use super::{Plane, PolyhedronCell};
use crate::diagram::convex_cell::{normal_order, Face};
use crate::geometry::{add, cross, dot, norm2, scale, HalfSpace};

/// No plane, no triangle.
const NONE: u32 = u32::MAX;

/// The least `det[n_a n_b n_c] / (|n_a| |n_b| |n_c|)` of a vertex's planes: below it the
/// three are too nearly dependent for Cramer's rule to keep the vertex within 1e-10 of
/// its place (the clips interpolate along edges instead), and the cell has no canonical
/// form. It also asks the triangle to turn counter-clockwise seen from outside.
const MIN_SINE: f64 = 1e-6;

/// Buffers of [`PolyhedronCell::canonicalise_cell`] and [`PolyhedronCell::rebuild`], kept
/// by the cell (made on first use): a thread-local of their own did not fit the static
/// TLS block the dynamic loader gives the Python extension.
#[derive(Debug, Default)]
pub(super) struct Buffers {
    /// Per plane of the cell: its canonical index, or [`NONE`].
    index: Vec<u32>,
    /// The planes that bound the cell, as ([`order_bits`] of the normal, plane).
    used: Vec<([u64; 3], u16)>,
    /// Per triangle: its planes renamed and rotated (8 bits each), its rotation (2 bits)
    /// and its index (30 bits), packed so that sorting the numbers sorts the triangles.
    keys: Vec<u64>,
    /// Per triangle: its canonical position.
    position: Vec<u32>,
    /// Per directed edge `a -> b` (`a * planes + b`): the triangle holding it.
    edges: Vec<u32>,
    planes: Vec<Plane>,
    triangles: Vec<[u16; 3]>,
    neighbors: Vec<[u32; 3]>,
    vertices: Vec<[f64; 3]>,
}

/// Where the planes `a`, `b`, `c` meet, by Cramer's rule in this order; `None` when they
/// are too nearly dependent or turn clockwise ([`MIN_SINE`]).
fn vertex_of(a: &Plane, b: &Plane, c: &Plane) -> Option<[f64; 3]> {
    let (bc, ca, ab) = (
        cross(b.normal, c.normal),
        cross(c.normal, a.normal),
        cross(a.normal, b.normal),
    );
    let det = dot(a.normal, bc);
    let lengths = (norm2(a.normal) * norm2(b.normal) * norm2(c.normal)).sqrt();
    if det.is_nan() || det <= MIN_SINE * lengths {
        return None;
    }
    let v = add(
        add(scale(bc, a.offset), scale(ca, b.offset)),
        scale(ab, c.offset),
    );
    Some(scale(v, 1.0 / det))
}

/// `x`'s bits as a number in [`f64::total_cmp`]'s order: the normals' sort key, worked out
/// once per plane instead of in every comparison.
fn order_bits(x: f64) -> u64 {
    let bits = x.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | (1 << 63)
    }
}

/// `tri` rotated to start at its least entry, and by how much.
fn least_first(tri: [u16; 3]) -> ([u16; 3], u8) {
    let k = if tri[1] < tri[0] && tri[1] < tri[2] {
        1
    } else if tri[2] < tri[0] && tri[2] < tri[1] {
        2
    } else {
        0
    };
    ([tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]], k as u8)
}

impl PolyhedronCell {
    /// [`crate::diagram::ConvexCell::canonicalise`]: `false`, the cell unchanged, when a face
    /// is not a neighbour's, two faces share one, or a vertex's planes are too nearly
    /// dependent.
    pub(super) fn canonicalise_cell(&mut self) -> bool {
        if self.triangles.len() < 4 {
            return false;
        }
        let mut b = self.buffers.take().unwrap_or_default();
        let made = self.canonical_into(&mut b) && self.take(&mut b);
        self.buffers = Some(b);
        made
    }

    /// The canonical arrays of this cell into `b`.
    fn canonical_into(&self, b: &mut Buffers) -> bool {
        b.index.clear();
        b.index.resize(self.planes.len(), NONE);
        b.used.clear();
        for tri in &self.triangles {
            for &p in tri {
                if b.index[p as usize] == NONE {
                    let Face::Neighbor(_) = self.planes[p as usize].face else {
                        return false;
                    };
                    b.index[p as usize] = 0;
                    let normal = self.planes[p as usize].normal;
                    b.used.push((normal.map(order_bits), p));
                }
            }
        }
        // In `normal_order`: the keys compare as the normals do.
        b.used.sort_unstable();
        let same = |w: &[([u64; 3], u16)]| w[0].0 == w[1].0;
        let too_many = b.used.len() > usize::from(u8::MAX) + 1 || self.triangles.len() >= 1 << 30;
        if too_many || b.used.windows(2).any(same) {
            return false;
        }
        for (k, &(_, p)) in b.used.iter().enumerate() {
            b.index[p as usize] = k as u32;
        }
        b.keys.clear();
        for (t, tri) in self.triangles.iter().enumerate() {
            let (key, rotation) = least_first(tri.map(|p| b.index[p as usize] as u16));
            let key = (u64::from(key[0]) << 16) | (u64::from(key[1]) << 8) | u64::from(key[2]);
            b.keys
                .push((key << 32) | (u64::from(rotation) << 30) | t as u64);
        }
        b.keys.sort_unstable();
        b.position.clear();
        b.position.resize(self.triangles.len(), 0);
        for (s, &packed) in b.keys.iter().enumerate() {
            b.position[(packed & ((1 << 30) - 1)) as usize] = s as u32;
        }
        b.planes.clear();
        b.planes
            .extend(b.used.iter().map(|&(_, p)| self.planes[p as usize]));
        b.triangles.clear();
        b.neighbors.clear();
        for &packed in &b.keys {
            let old = self.neighbors[(packed & ((1 << 30) - 1)) as usize];
            let r = ((packed >> 30) & 3) as usize;
            let key = packed >> 32;
            let planes = [key >> 16, (key >> 8) & 0xff, key & 0xff];
            b.triangles.push(planes.map(|p| p as u16));
            b.neighbors.push(std::array::from_fn(|k| {
                b.position[old[(k + r) % 3] as usize]
            }));
        }
        vertices_into(b)
    }

    /// Become the cell held in `b` (its buffers swapped with this cell's).
    fn take(&mut self, b: &mut Buffers) -> bool {
        std::mem::swap(&mut self.planes, &mut b.planes);
        std::mem::swap(&mut self.triangles, &mut b.triangles);
        std::mem::swap(&mut self.neighbors, &mut b.neighbors);
        std::mem::swap(&mut self.vertices, &mut b.vertices);
        self.max_dist2 =
            (self.vertices.iter()).fold(0.0, |m, &v| if norm2(v) > m { norm2(v) } else { m });
        true
    }

    /// The neighbours of a canonical cell in plane order, and its triangles.
    pub(super) fn canonical_ring(&self, neighbours: &mut Vec<u32>, triangles: &mut Vec<[u8; 3]>) {
        neighbours.extend(self.planes.iter().map(|p| match p.face {
            Face::Neighbor(j) => j,
            _ => NONE,
        }));
        triangles.extend(self.triangles.iter().map(|t| t.map(|p| p as u8)));
    }

    /// [`crate::diagram::ConvexCell::rebuild_from_ring`]: the canonical cell of the
    /// neighbours `ring` (`plane(j)` the half-space of `j`'s face) and the vertex
    /// `triangles` (canonical plane indices, as [`PolyhedronCell::canonical_ring`] gave
    /// them), if every vertex lies inside every plane but its own three by `separation`.
    ///
    /// Then the triangles are the cell's: each vertex is a vertex of the intersection of
    /// the half-spaces with exactly its three planes, two triangles across an edge are the
    /// two ends of that edge of the intersection, and a closed surface of such vertices,
    /// each with its three edges, holds them all.
    pub(super) fn rebuild(
        &mut self,
        ring: &[u32],
        triangles: &[[u8; 3]],
        plane: impl Fn(u32) -> HalfSpace<3>,
        separation: f64,
    ) -> bool {
        let m = ring.len();
        if m < 4 || triangles.len() < 4 || triangles.iter().flatten().any(|&p| usize::from(p) >= m)
        {
            return false;
        }
        let mut b = self.buffers.take().unwrap_or_default();
        let made = {
            let b = &mut *b;
            b.planes.clear();
            b.planes.extend(ring.iter().map(|&j| {
                let h = plane(j);
                Plane {
                    normal: h.normal,
                    offset: h.offset,
                    face: Face::Neighbor(j),
                }
            }));
            b.triangles.clear();
            b.triangles
                .extend(triangles.iter().map(|t| t.map(u16::from)));
            adjacency(b) && vertices_into(b) && separated(b, separation) && self.take(b)
        };
        self.buffers = Some(b);
        made && self.in_normal_order()
    }

    /// Whether the planes are in [`normal_order`]: a rebuilt cell whose normals turned
    /// past each other is put in order again.
    fn in_normal_order(&mut self) -> bool {
        let sorted =
            (self.planes.windows(2)).all(|w| normal_order(&w[0].normal, &w[1].normal).is_lt());
        sorted || self.canonicalise_cell()
    }
}

/// The vertices of `b`'s triangles ([`vertex_of`]); `false` when one has none.
fn vertices_into(b: &mut Buffers) -> bool {
    b.vertices.clear();
    for tri in &b.triangles {
        let plane = |k: usize| &b.planes[tri[k] as usize];
        match vertex_of(plane(0), plane(1), plane(2)) {
            Some(v) => b.vertices.push(v),
            None => return false,
        }
    }
    true
}

/// `b.neighbors` from the triangles: across edge `a -> b` of one lies the triangle holding
/// `b -> a`. `false` unless every edge has exactly one twin.
fn adjacency(b: &mut Buffers) -> bool {
    let m = b.planes.len();
    b.edges.clear();
    b.edges.resize(m * m, NONE);
    for (t, tri) in b.triangles.iter().enumerate() {
        for k in 0..3 {
            let at = usize::from(tri[k]) * m + usize::from(tri[(k + 1) % 3]);
            if b.edges[at] != NONE {
                return false;
            }
            b.edges[at] = t as u32;
        }
    }
    b.neighbors.clear();
    for tri in &b.triangles {
        let across: [u32; 3] = std::array::from_fn(|k| {
            b.edges[usize::from(tri[(k + 1) % 3]) * m + usize::from(tri[k])]
        });
        if across.contains(&NONE) {
            return false;
        }
        b.neighbors.push(across);
    }
    true
}

/// Every vertex inside every plane but its own three by `separation` of the plane's
/// `|normal|²`.
fn separated(b: &Buffers, separation: f64) -> bool {
    (b.triangles.iter().zip(&b.vertices)).all(|(tri, &v)| {
        (b.planes.iter().enumerate()).all(|(l, p)| {
            tri.contains(&(l as u16)) || dot(p.normal, v) - p.offset < -separation * norm2(p.normal)
        })
    })
}
