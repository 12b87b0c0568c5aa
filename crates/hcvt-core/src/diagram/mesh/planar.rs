//! A convex polygon restricted to the domain, in its plane (DESIGN §9): the 2D cell `C ∩ Ω`
//! and, one dimension down, each bisector face `F ∩ Ω` of a 3D cell. The boundary loops of
//! the result are stitched from the polygon's edge pieces inside the domain and the
//! domain's boundary segments (2D) or slice segments (3D) inside the polygon, joined where
//! their vertex names ([`Key`]) agree. Every side test that decides topology is exact
//! (`robust::orient2d`) and a point on a line counts on its left, so that an edge and a
//! segment agree on whether they cross.

use super::key::Key;
use crate::geometry::{norm2, sub};

/// A point of the plane: its projection `p` (where the tests are made), its position `x`
/// relative to the cell's site, and its name.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Node<const D: usize> {
    pub p: [f64; 2],
    pub x: [f64; D],
    pub key: Key,
}

/// A directed segment with the domain on its left, from boundary element `elem`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Segment<const D: usize> {
    pub a: Node<D>,
    pub b: Node<D>,
    pub elem: u32,
}

/// What an edge of a result loop lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EdgeOf {
    /// Edge `k` of the polygon (from its vertex `k` to `k + 1`).
    Ring(u32),
    /// Segment `s` of the input.
    Segment(u32),
}

/// Where polygon edge `edge` meets segment `seg`.
#[derive(Debug, Clone, Copy)]
struct Crossing<const D: usize> {
    edge: usize,
    seg: usize,
    /// Parameters along the edge and along the segment.
    t: f64,
    u: f64,
    node: Node<D>,
    /// The edge is inside the domain just after the crossing.
    edge_enters: bool,
    /// The segment is inside the polygon just after the crossing.
    seg_enters: bool,
}

/// A directed piece of a loop.
#[derive(Debug, Clone, Copy)]
struct Piece<const D: usize> {
    from: Node<D>,
    to: Node<D>,
    on: EdgeOf,
}

/// `orient2d(a, b, c)`: positive when `c` lies left of `a -> b`, exact in sign.
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let p = |v: [f64; 2]| robust::Coord { x: v[0], y: v[1] };
    robust::orient2d(p(a), p(b), p(c))
}

fn lerp<const D: usize>(a: [f64; D], b: [f64; D], t: f64) -> [f64; D] {
    std::array::from_fn(|k| a[k] + t * (b[k] - a[k]))
}

/// Buffers of [`clip_ring`], reused from face to face.
#[derive(Debug, Default)]
pub(crate) struct PlanarScratch<const D: usize> {
    crossings: Vec<Crossing<D>>,
    pieces: Vec<Piece<D>>,
    used: Vec<bool>,
}

/// The loops bounding `ring ∩ Ω`, appended to `out` (nodes, each with the edge leaving
/// it) and `ends` (the end of each loop in `out`). `ring` is convex and counter-clockwise
/// in the projection, `segments` are the parts of `∂Ω` in its plane that may meet it,
/// oriented with `Ω` on their left; `cross_key(edge, segment)` names their crossing and
/// `inside()` says whether the ring lies in `Ω` when no segment crosses it. Returns the
/// number of chains that did not close (zero unless round-off made the pieces disagree).
pub(crate) fn clip_ring<const D: usize>(
    ring: &[Node<D>],
    segments: &[Segment<D>],
    cross_key: impl Fn(usize, usize) -> Key,
    inside: impl FnOnce() -> bool,
    scratch: &mut PlanarScratch<D>,
    out: &mut Vec<(Node<D>, EdgeOf)>,
    ends: &mut Vec<usize>,
) -> u32 {
    let m = ring.len();
    let PlanarScratch {
        crossings,
        pieces,
        used,
    } = scratch;
    crossings.clear();
    pieces.clear();
    for (s, seg) in segments.iter().enumerate() {
        let (a, b) = (seg.a.p, seg.b.p);
        for k in 0..m {
            let (v, w) = (ring[k], ring[(k + 1) % m]);
            let (ov, ow) = (orient(a, b, v.p), orient(a, b, w.p));
            let (oa, ob) = (orient(v.p, w.p, a), orient(v.p, w.p, b));
            if (ov >= 0.0) == (ow >= 0.0) || (oa >= 0.0) == (ob >= 0.0) {
                continue;
            }
            let t = (ov / (ov - ow)).clamp(0.0, 1.0);
            let u = (oa / (oa - ob)).clamp(0.0, 1.0);
            crossings.push(Crossing {
                edge: k,
                seg: s,
                t,
                u,
                node: Node {
                    p: lerp(v.p, w.p, t),
                    x: lerp(v.x, w.x, t),
                    key: cross_key(k, s),
                },
                edge_enters: ow >= 0.0,
                seg_enters: ob >= 0.0,
            });
        }
    }
    ring_pieces(ring, crossings, inside, pieces);
    segment_pieces(ring, segments, crossings, pieces);
    // Points closer than this (squared) are one point: `MERGE_REL` of the polygon's size.
    let size2 = ring.iter().map(|n| norm2(n.x)).fold(0.0, f64::max);
    let tol2 = super::MERGE_REL * super::MERGE_REL * size2;
    trace(pieces, tol2, used, out, ends)
}

/// The pieces of the ring's edges inside the domain. Inside or out changes only where a
/// segment crosses; a ring no segment crosses is all in or all out (`inside`).
fn ring_pieces<const D: usize>(
    ring: &[Node<D>],
    crossings: &mut [Crossing<D>],
    inside: impl FnOnce() -> bool,
    pieces: &mut Vec<Piece<D>>,
) {
    let m = ring.len();
    crossings.sort_unstable_by(|a, b| {
        (a.edge, a.t, a.seg)
            .partial_cmp(&(b.edge, b.t, b.seg))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut state = match crossings.first() {
        None => {
            if inside() {
                for k in 0..m {
                    pieces.push(Piece {
                        from: ring[k],
                        to: ring[(k + 1) % m],
                        on: EdgeOf::Ring(k as u32),
                    });
                }
            }
            return;
        }
        // The state before the first crossing of its edge.
        Some(c) => !c.edge_enters,
    };
    let first_edge = crossings[0].edge;
    let mut starts = vec![0usize; m + 1];
    for c in crossings.iter() {
        starts[c.edge + 1] += 1;
    }
    for k in 0..m {
        starts[k + 1] += starts[k];
    }
    for step in 0..m {
        let k = (first_edge + step) % m;
        let here = &crossings[starts[k]..starts[k + 1]];
        if let Some(c) = here.first() {
            state = !c.edge_enters;
        }
        let mut from = ring[k];
        for c in here {
            if state {
                pieces.push(Piece {
                    from,
                    to: c.node,
                    on: EdgeOf::Ring(k as u32),
                });
            }
            from = c.node;
            state = c.edge_enters;
        }
        if state {
            pieces.push(Piece {
                from,
                to: ring[(k + 1) % m],
                on: EdgeOf::Ring(k as u32),
            });
        }
    }
}

/// The part of each segment inside the convex ring: from its start (or its last entering
/// crossing) to its end (or its first leaving crossing).
fn segment_pieces<const D: usize>(
    ring: &[Node<D>],
    segments: &[Segment<D>],
    crossings: &[Crossing<D>],
    pieces: &mut Vec<Piece<D>>,
) {
    let m = ring.len();
    let inside_ring =
        |q: [f64; 2]| (0..m).all(|k| orient(ring[k].p, ring[(k + 1) % m].p, q) >= 0.0);
    for (s, seg) in segments.iter().enumerate() {
        let a_in = inside_ring(seg.a.p);
        let b_in = inside_ring(seg.b.p);
        let mut from = a_in.then_some((seg.a, 0.0));
        let mut to = b_in.then_some((seg.b, 1.0));
        for c in crossings.iter().filter(|c| c.seg == s) {
            if c.seg_enters && !a_in && from.is_none_or(|(_, u)| c.u > u) {
                from = Some((c.node, c.u));
            }
            if !c.seg_enters && !b_in && to.is_none_or(|(_, u)| c.u < u) {
                to = Some((c.node, c.u));
            }
        }
        if let (Some((from, u_from)), Some((to, u_to))) = (from, to) {
            if u_from <= u_to {
                pieces.push(Piece {
                    from,
                    to,
                    on: EdgeOf::Segment(s as u32),
                });
            }
        }
    }
}

/// Join the pieces into closed loops where their names agree; pieces of one point are
/// dropped. Returns the number of chains that did not close.
fn trace<const D: usize>(
    pieces: &[Piece<D>],
    tol2: f64,
    used: &mut Vec<bool>,
    out: &mut Vec<(Node<D>, EdgeOf)>,
    ends: &mut Vec<usize>,
) -> u32 {
    used.clear();
    used.extend(pieces.iter().map(|p| p.from.key == p.to.key));
    let mut open = 0;
    for start in 0..pieces.len() {
        if used[start] {
            continue;
        }
        let begin = out.len();
        let mut at = start;
        loop {
            used[at] = true;
            out.push((pieces[at].from, pieces[at].on));
            let end = pieces[at].to.key;
            if end == pieces[start].from.key {
                ends.push(out.len());
                break;
            }
            let by_name = (0..pieces.len()).find(|&q| !used[q] && pieces[q].from.key == end);
            // Two names of one point (a degenerate crossing) join by position; the mesh
            // assembly merges the names of a cell's coinciding vertices.
            let here = pieces[at].to.x;
            let near = |x: [f64; D]| norm2(sub(x, here)) <= tol2;
            if by_name.is_none() && near(pieces[start].from.x) {
                ends.push(out.len());
                break;
            }
            match by_name
                .or_else(|| (0..pieces.len()).find(|&q| !used[q] && near(pieces[q].from.x)))
            {
                Some(q) => at = q,
                None => {
                    out.truncate(begin);
                    open += 1;
                    break;
                }
            }
        }
    }
    open
}

/// Twice the signed area of a loop in the projection.
fn loop_area<const D: usize>(nodes: &[(Node<D>, EdgeOf)]) -> f64 {
    let m = nodes.len();
    (0..m)
        .map(|k| {
            let (a, b) = (nodes[k].0.p, nodes[(k + 1) % m].0.p);
            a[0] * b[1] - a[1] * b[0]
        })
        .sum()
}

/// Whether `q` lies inside the loop (even-odd rule, in the projection).
fn loop_contains<const D: usize>(nodes: &[(Node<D>, EdgeOf)], q: [f64; 2]) -> bool {
    let m = nodes.len();
    let mut inside = false;
    for k in 0..m {
        let (a, b) = (nodes[k].0.p, nodes[(k + 1) % m].0.p);
        if (a[1] > q[1]) != (b[1] > q[1]) {
            let x = a[0] + (q[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if q[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Join each hole (a clockwise loop) to the counter-clockwise loop around it by a bridge
/// edge walked both ways (a keyhole), so that every face is one loop of vertices: the
/// layout of a mesh face. No vertex is added, so no other face is touched. `out` and
/// `ends` are rewritten in place.
pub(crate) fn bridge_holes<const D: usize>(
    out: &mut Vec<(Node<D>, EdgeOf)>,
    ends: &mut Vec<usize>,
) {
    let mut loops: Vec<Vec<(Node<D>, EdgeOf)>> = Vec::with_capacity(ends.len());
    let mut begin = 0;
    for &end in ends.iter() {
        loops.push(out[begin..end].to_vec());
        begin = end;
    }
    let area: Vec<f64> = loops.iter().map(|l| loop_area(l)).collect();
    if area.iter().all(|&a| a >= 0.0) {
        return;
    }
    let outers: Vec<usize> = (0..loops.len()).filter(|&k| area[k] >= 0.0).collect();
    // Holes right to left: each bridge then runs right into polygon already made.
    let max_x = |l: &[(Node<D>, EdgeOf)]| l.iter().map(|n| n.0.p[0]).fold(f64::MIN, f64::max);
    let mut holes: Vec<usize> = (0..loops.len()).filter(|&k| area[k] < 0.0).collect();
    holes.sort_by(|&a, &b| max_x(&loops[b]).total_cmp(&max_x(&loops[a])));
    for h in holes {
        let probe = loops[h][0].0.p;
        let around = outers
            .iter()
            .copied()
            .filter(|&o| loop_contains(&loops[o], probe))
            .min_by(|&a, &b| area[a].total_cmp(&area[b]));
        let Some(o) = around else {
            continue; // no loop around it: round-off; leave it a loop of its own
        };
        let hole = std::mem::take(&mut loops[h]);
        let merged = keyhole(&loops[o], &hole);
        loops[o] = merged;
    }
    out.clear();
    ends.clear();
    for l in loops.iter().filter(|l| !l.is_empty()) {
        out.extend_from_slice(l);
        ends.push(out.len());
    }
}

/// The outer loop with the hole spliced in through a bridge from the hole's rightmost
/// vertex to a vertex of the outer loop it sees (Eberly, "Triangulation by ear clipping",
/// 2002, §3): the ray to the right meets an edge; its right end, or the reflex vertex in
/// the triangle between, that makes the smallest angle with the ray.
fn keyhole<const D: usize>(
    outer: &[(Node<D>, EdgeOf)],
    hole: &[(Node<D>, EdgeOf)],
) -> Vec<(Node<D>, EdgeOf)> {
    let m = outer.len();
    let (hm, mp) = hole
        .iter()
        .enumerate()
        .map(|(k, n)| (k, n.0.p))
        .max_by(|a, b| a.1[0].total_cmp(&b.1[0]))
        .unwrap_or((0, [0.0; 2]));
    let mut best: Option<(f64, usize)> = None; // (x of the crossing, edge)
    for k in 0..m {
        let (a, b) = (outer[k].0.p, outer[(k + 1) % m].0.p);
        if (a[1] > mp[1]) == (b[1] > mp[1]) {
            continue;
        }
        let x = a[0] + (mp[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
        if x >= mp[0] && best.is_none_or(|(bx, _)| x < bx) {
            best = Some((x, k));
        }
    }
    let target = match best {
        None => (0..m)
            .min_by(|&a, &b| {
                let d = |k: usize| {
                    let p = outer[k].0.p;
                    (p[0] - mp[0]).powi(2) + (p[1] - mp[1]).powi(2)
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap_or(0),
        Some((x, k)) => {
            let (a, b) = (k, (k + 1) % m);
            let p = if outer[a].0.p[0] > outer[b].0.p[0] {
                a
            } else {
                b
            };
            let i = [x, mp[1]];
            let pp = outer[p].0.p;
            // Reflex vertices of the outer loop inside the triangle (M, I, P) hide P.
            let inside = |q: [f64; 2]| {
                let s1 = orient(mp, i, q);
                let s2 = orient(i, pp, q);
                let s3 = orient(pp, mp, q);
                (s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0) || (s1 <= 0.0 && s2 <= 0.0 && s3 <= 0.0)
            };
            let mut choice = p;
            let mut best_angle = f64::MAX;
            for r in 0..m {
                if r == p {
                    continue;
                }
                let (prev, q, next) = (
                    outer[(r + m - 1) % m].0.p,
                    outer[r].0.p,
                    outer[(r + 1) % m].0.p,
                );
                if orient(prev, q, next) >= 0.0 || !inside(q) {
                    continue;
                }
                let d = [q[0] - mp[0], q[1] - mp[1]];
                let angle = d[1].abs().atan2(d[0]);
                if angle < best_angle {
                    best_angle = angle;
                    choice = r;
                }
            }
            choice
        }
    };
    let mut merged = Vec::with_capacity(m + hole.len() + 2);
    merged.extend_from_slice(&outer[..=target]);
    let h = hole.len();
    merged.extend((0..=h).map(|k| hole[(hm + k) % h]));
    merged.push(outer[target]);
    merged.extend_from_slice(&outer[target + 1..]);
    merged
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagram::mesh::key::Key;

    fn node(p: [f64; 2], v: u32) -> Node<2> {
        Node {
            p,
            x: p,
            key: Key::vertex(v),
        }
    }

    /// A unit square cut by a line through it (domain below the line y = 0.5 when walked
    /// from right to left): one loop of area 1/2.
    #[test]
    fn square_cut_by_a_segment() {
        let ring = [
            node([0.0, 0.0], 0),
            node([1.0, 0.0], 1),
            node([1.0, 1.0], 2),
            node([0.0, 1.0], 3),
        ];
        let segments = [Segment {
            a: node([2.0, 0.5], 10),
            b: node([-1.0, 0.5], 11),
            elem: 0,
        }];
        let (mut out, mut ends) = (Vec::new(), Vec::new());
        let open = clip_ring(
            &ring,
            &segments,
            |k, s| Key::vertex(100 + 10 * k as u32 + s as u32),
            || unreachable!(),
            &mut PlanarScratch::default(),
            &mut out,
            &mut ends,
        );
        assert_eq!(open, 0);
        assert_eq!(ends, vec![4]);
        let area: f64 = (0..4)
            .map(|k| {
                let (a, b) = (out[k].0.p, out[(k + 1) % 4].0.p);
                0.5 * (a[0] * b[1] - a[1] * b[0])
            })
            .sum();
        assert!((area - 0.5).abs() < 1e-15, "{area}");
    }
}
