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
    /// The planes that bound the cell, as [`order_bits`] of the normal's x (high half)
    /// and plane (low half): one number per plane decides the order but for ties in x.
    used: Vec<u128>,
    /// Per triangle: its planes renamed and rotated (8 bits each), its rotation (2 bits)
    /// and its index (30 bits), packed so that sorting the numbers sorts the triangles.
    keys: Vec<u64>,
    /// `keys` sorted ([`sort_by_least_plane`]).
    sorted: Vec<u64>,
    /// Per canonical plane: where its triangles start in `sorted`.
    starts: Vec<u32>,
    /// Per triangle: its canonical position.
    position: Vec<u32>,
    /// Per directed edge `a -> b` (`a * planes + b`): the triangle holding it.
    edges: Vec<u32>,
    planes: Vec<Plane>,
    triangles: Vec<[u16; 3]>,
    neighbors: Vec<[u32; 3]>,
    vertices: Vec<[f64; 3]>,
    /// Per plane: `|normal|²`, worked out once for its vertices ([`vertices_into`]).
    lengths: Vec<f64>,
    /// The largest `|v|²` of `vertices`.
    max_dist2: f64,
}

/// Where the planes `a`, `b`, `c` meet, by Cramer's rule in this order; `None` when they
/// are too nearly dependent or turn clockwise ([`MIN_SINE`]). `lengths`: their normals'
/// `|n|²`.
fn vertex_of(a: &Plane, b: &Plane, c: &Plane, lengths: [f64; 3]) -> Option<[f64; 3]> {
    let (bc, ca, ab) = (
        cross(b.normal, c.normal),
        cross(c.normal, a.normal),
        cross(a.normal, b.normal),
    );
    let det = dot(a.normal, bc);
    let lengths = (lengths[0] * lengths[1] * lengths[2]).sqrt();
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
    let [a, b, c] = tri;
    if b < a && b < c {
        ([b, c, a], 1)
    } else if c < a && c < b {
        ([c, a, b], 2)
    } else {
        (tri, 0)
    }
}

/// The triangle a packed key ([`Buffers::keys`]) stands for.
fn triangle_of(packed: u64) -> usize {
    (packed & ((1 << 30) - 1)) as usize
}

/// `x` rotated left by `r` (0, 1 or 2): as [`least_first`] turns a triangle.
fn rotated<T: Copy>(x: [T; 3], r: u64) -> [T; 3] {
    let [a, b, c] = x;
    match r {
        1 => [b, c, a],
        2 => [c, a, b],
        _ => x,
    }
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
        // Slices held apart from `b`, so that a push into one does not reload the others.
        let (index, used) = (&mut b.index[..], &mut b.used);
        for tri in &self.triangles {
            for &p in tri {
                if index[p as usize] == NONE {
                    let Face::Neighbor(_) = self.planes[p as usize].face else {
                        return false;
                    };
                    index[p as usize] = 0;
                    let x = order_bits(self.planes[p as usize].normal[0]);
                    used.push((u128::from(x) << 64) | u128::from(p));
                }
            }
        }
        let too_many = b.used.len() > usize::from(u8::MAX) + 1 || self.triangles.len() >= 1 << 30;
        if too_many || !self.sort_used(&mut b.used) {
            return false;
        }
        for (k, &packed) in b.used.iter().enumerate() {
            b.index[packed as u16 as usize] = k as u32;
        }
        // Filled by `extend` from slices (no capacity check per element).
        let index = &b.index;
        b.keys.clear();
        b.keys
            .extend(self.triangles.iter().enumerate().map(|(t, tri)| {
                let (key, rotation) = least_first(tri.map(|p| index[p as usize] as u16));
                let key = (u64::from(key[0]) << 16) | (u64::from(key[1]) << 8) | u64::from(key[2]);
                (key << 32) | (u64::from(rotation) << 30) | t as u64
            }));
        sort_by_least_plane(b);
        b.position.clear();
        b.position.resize(self.triangles.len(), 0);
        for (s, &packed) in b.sorted.iter().enumerate() {
            b.position[triangle_of(packed)] = s as u32;
        }
        b.planes.clear();
        b.planes.extend(
            b.used
                .iter()
                .map(|&packed| self.planes[packed as u16 as usize]),
        );
        b.triangles.clear();
        b.triangles.extend(b.sorted.iter().map(|&packed| {
            let key = packed >> 32;
            [key >> 16, (key >> 8) & 0xff, key & 0xff].map(|p| p as u16)
        }));
        let position = &b.position;
        b.neighbors.clear();
        b.neighbors.extend(b.sorted.iter().map(|&packed| {
            let old = rotated(self.neighbors[triangle_of(packed)], (packed >> 30) & 3);
            old.map(|t| position[t as usize])
        }));
        vertices_into(b)
    }

    /// `used` (see [`Buffers::used`]) in [`normal_order`]; `false` when two planes have one
    /// normal. The x bits alone order them unless two share an x: then by the whole
    /// normal, as [`order_bits`] of each coordinate compare as the normals do.
    fn sort_used(&self, used: &mut [u128]) -> bool {
        used.sort_unstable();
        if used.windows(2).all(|w| w[0] >> 64 != w[1] >> 64) {
            return true;
        }
        let key = |packed: &u128| self.planes[*packed as u16 as usize].normal.map(order_bits);
        used.sort_unstable_by_key(key);
        used.windows(2).all(|w| key(&w[0]) != key(&w[1]))
    }

    /// Become the cell held in `b` (its buffers swapped with this cell's).
    fn take(&mut self, b: &mut Buffers) -> bool {
        std::mem::swap(&mut self.planes, &mut b.planes);
        std::mem::swap(&mut self.triangles, &mut b.triangles);
        std::mem::swap(&mut self.neighbors, &mut b.neighbors);
        std::mem::swap(&mut self.vertices, &mut b.vertices);
        self.max_dist2 = b.max_dist2;
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

/// `b.keys` sorted into `b.sorted`: counted out by their least plane (the top byte of
/// their key), then each plane's few sorted by insertion.
fn sort_by_least_plane(b: &mut Buffers) {
    let least = |packed: u64| (packed >> 48) as usize;
    b.starts.clear();
    b.starts.resize(b.used.len() + 1, 0);
    for &packed in &b.keys {
        b.starts[least(packed) + 1] += 1;
    }
    for p in 1..b.starts.len() {
        b.starts[p] += b.starts[p - 1];
    }
    b.sorted.clear();
    b.sorted.resize(b.keys.len(), 0);
    for &packed in &b.keys {
        let at = &mut b.starts[least(packed)];
        b.sorted[*at as usize] = packed;
        *at += 1;
    }
    // `starts[p]` is now where plane `p + 1`'s triangles start.
    let mut from = 0;
    for &end in &b.starts[..b.used.len()] {
        let end = end as usize;
        for i in from + 1..end {
            let mut k = i;
            while k > from && b.sorted[k - 1] > b.sorted[k] {
                b.sorted.swap(k - 1, k);
                k -= 1;
            }
        }
        from = end;
    }
}

/// The vertices of `b`'s triangles ([`vertex_of`]) and their largest `|v|²`; `false` when
/// one has none.
fn vertices_into(b: &mut Buffers) -> bool {
    b.lengths.clear();
    b.lengths.extend(b.planes.iter().map(|p| norm2(p.normal)));
    b.vertices.clear();
    // Slices held apart from `b`, so that a push into `vertices` does not reload them.
    let (planes, lengths, vertices) = (&b.planes[..], &b.lengths[..], &mut b.vertices);
    // `f64::max` as a plain comparison (which passes over a NaN alike).
    let mut max_dist2 = 0.0;
    for tri in &b.triangles {
        let plane = |k: usize| &planes[tri[k] as usize];
        let lengths = tri.map(|p| lengths[p as usize]);
        match vertex_of(plane(0), plane(1), plane(2), lengths) {
            Some(v) => {
                if norm2(v) > max_dist2 {
                    max_dist2 = norm2(v);
                }
                vertices.push(v);
            }
            None => return false,
        }
    }
    b.max_dist2 = max_dist2;
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
    // Held apart from `b`, so that a push into `neighbors` does not reload `edges`.
    let (edges, neighbors) = (&b.edges[..], &mut b.neighbors);
    for tri in &b.triangles {
        let across: [u32; 3] =
            std::array::from_fn(|k| edges[usize::from(tri[(k + 1) % 3]) * m + usize::from(tri[k])]);
        if across.contains(&NONE) {
            return false;
        }
        neighbors.push(across);
    }
    true
}

/// Every vertex inside every plane but its own three by `separation` of the plane's
/// `|normal|²` (`b.lengths`, as [`vertices_into`] left them). Each vertex is tested
/// against each plane first and asks whether the plane is its own only when the test
/// fails: three planes in every dozen or so.
fn separated(b: &Buffers, separation: f64) -> bool {
    (b.triangles.iter().zip(&b.vertices)).all(|(tri, &v)| {
        (b.planes.iter().zip(&b.lengths).enumerate()).all(|(l, (p, &length))| {
            dot(p.normal, v) - p.offset < -separation * length || tri.contains(&(l as u16))
        })
    })
}
