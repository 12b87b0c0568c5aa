//! One step of Sutherland–Hodgman: a convex polygon cut by one plane, each node carrying
//! what the caller tags it with. Shared by the conforming mesh's boundary pieces (a
//! solid's triangle clipped by a cell, `mesh/cell3.rs`) and the surface's cell pieces (a
//! surface triangle clipped by a cell, `surface/clipper.rs`): one clipper of triangles by cells.

/// Keep the part of the closed convex polygon `polygon` where the side is `≤ 0`, into `out`
/// (cleared first). `sides[k]` is node `k`'s signed side of the plane (and whether it lies
/// exactly on it, for a caller whose side rule says so); `cut(u, w, side_u, side_w)` makes
/// the node where the edge `u → w` crosses the plane, tagged as the caller wants (the
/// edge leaving it lies on the plane when `u` is kept, on `u`'s edge when it is not).
pub(crate) fn clip_polygon<N: Copy>(
    polygon: &[N],
    sides: &[(f64, bool)],
    out: &mut Vec<N>,
    mut cut: impl FnMut(&N, &N, (f64, bool), (f64, bool)) -> N,
) {
    out.clear();
    let m = polygon.len();
    for k in 0..m {
        let (u, w) = (&polygon[k], &polygon[(k + 1) % m]);
        let (su, sw) = (sides[k], sides[(k + 1) % m]);
        if su.0 <= 0.0 {
            out.push(*u);
        }
        if (su.0 <= 0.0) != (sw.0 <= 0.0) {
            out.push(cut(u, w, su, sw));
        }
    }
}
