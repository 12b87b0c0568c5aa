//! Combinatorial names of mesh vertices (DESIGN §9): a vertex is named by what makes it,
//! never by its rounded coordinates, so that every cell that meets it names it alike.
//!
//! | kind | 3D | 2D |
//! |------|----|----|
//! | sites | four sites: three bisectors of the cell's site | three sites: two bisectors |
//! | sites and element | three sites (two bisectors) and a boundary triangle | two sites and a segment |
//! | sites and mesh edge | two sites (one bisector) and a mesh edge `(a, b)`, `a < b` | — |
//! | mesh vertex | a vertex of the domain's boundary | a vertex of the polygon |
//! | local | anything made with a box side: outside the domain, never shared | same |

/// What makes a plane (3D) or a line (2D) of a cell, or a line of a boundary triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Gen {
    /// The bisector of the cell's site and site `j`.
    Site(u32),
    /// The hyperplane of boundary element `t` (triangle or segment).
    Elem(u32),
    /// The mesh edge between boundary vertices `a` and `b` (3D).
    MeshEdge(u32, u32),
    /// A side of a box, by its plane index in the cell: never shared between cells.
    Other(u32),
}

/// A vertex's name: a kind and up to four sorted indices (unused slots `NONE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) struct Key {
    kind: u8,
    ids: [u32; 4],
}

const NONE: u32 = u32::MAX;
const SITES: u8 = 0;
const SITES_ELEM: u8 = 1;
const SITES_EDGE: u8 = 2;
const VERTEX: u8 = 3;
const LOCAL: u8 = 4;

impl Key {
    /// A vertex of the domain's boundary.
    pub(crate) fn vertex(v: u32) -> Self {
        Self {
            kind: VERTEX,
            ids: [v, NONE, NONE, NONE],
        }
    }

    /// The boundary vertex this names, if it names one.
    pub(crate) fn mesh_vertex(&self) -> Option<u32> {
        (self.kind == VERTEX).then_some(self.ids[0])
    }

    /// Where the generators `gens` meet in cell `cell`: the cell's own site joins every
    /// bisector. A mesh edge already lies in its triangles, so an element beside it adds
    /// nothing; a box side makes the vertex the cell's own.
    pub(crate) fn meet(cell: u32, gens: &[Gen]) -> Self {
        let mut sites = [cell, NONE, NONE, NONE];
        let mut n = 1;
        let (mut elem, mut edge, mut local) = (None, None, false);
        for &g in gens {
            match g {
                Gen::Site(j) if n < 4 => {
                    sites[n] = j;
                    n += 1;
                }
                Gen::Elem(t) => elem = Some(t),
                Gen::MeshEdge(a, b) => edge = Some((a.min(b), a.max(b))),
                Gen::Site(_) | Gen::Other(_) => local = true,
            }
        }
        sites[..n].sort_unstable();
        match (local, edge, elem) {
            (false, Some((a, b)), _) if n == 2 => Self {
                kind: SITES_EDGE,
                ids: [sites[0], sites[1], a, b],
            },
            (false, None, Some(t)) if n <= 3 => {
                let mut ids = [NONE, NONE, NONE, t];
                ids[..n].copy_from_slice(&sites[..n]);
                Self {
                    kind: SITES_ELEM,
                    ids,
                }
            }
            (false, None, None) => Self {
                kind: SITES,
                ids: sites,
            },
            _ => Self::local(cell, gens),
        }
    }

    /// A name private to `cell`: the same generators give the same name within the cell.
    fn local(cell: u32, gens: &[Gen]) -> Self {
        let code = |g: &Gen| -> u64 {
            match *g {
                Gen::Site(j) => u64::from(j),
                Gen::Elem(t) => (1 << 32) | u64::from(t),
                Gen::MeshEdge(a, b) => {
                    (2 << 32) ^ (u64::from(a.min(b)) << 20) ^ u64::from(a.max(b))
                }
                Gen::Other(p) => (3 << 32) | u64::from(p),
            }
        };
        let mut codes: Vec<u64> = gens.iter().map(code).collect();
        codes.sort_unstable();
        // FNV-1a over the sorted codes: only cells with a box side near the domain (never,
        // up to round-off) use these names, and a collision merges two of its vertices.
        let hash = codes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &c| {
            (h ^ c).wrapping_mul(0x0000_0100_0000_01b3)
        });
        Self {
            kind: LOCAL,
            ids: [cell, (hash >> 32) as u32, hash as u32, codes.len() as u32],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_do_not_depend_on_the_cell_that_makes_them() {
        let a = Key::meet(4, &[Gen::Site(9), Gen::Site(1), Gen::Site(7)]);
        let b = Key::meet(7, &[Gen::Site(1), Gen::Site(4), Gen::Site(9)]);
        assert_eq!(a, b);
        let c = Key::meet(4, &[Gen::Site(9), Gen::MeshEdge(5, 2), Gen::Elem(3)]);
        let d = Key::meet(9, &[Gen::MeshEdge(2, 5), Gen::Site(4)]);
        assert_eq!(c, d);
        let e = Key::meet(4, &[Gen::Site(9), Gen::Site(2), Gen::Elem(3)]);
        assert_eq!(e, Key::meet(2, &[Gen::Elem(3), Gen::Site(4), Gen::Site(9)]));
        assert_ne!(e, Key::meet(2, &[Gen::Elem(5), Gen::Site(4), Gen::Site(9)]));
        let boxed = Key::meet(4, &[Gen::Site(9), Gen::Other(0), Gen::Site(2)]);
        assert_ne!(
            boxed,
            Key::meet(9, &[Gen::Site(4), Gen::Other(0), Gen::Site(2)])
        );
    }
}
