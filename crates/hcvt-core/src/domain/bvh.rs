//! Bounding-volume hierarchy over boundary elements (segments in 2D, triangles in 3D).
//!
//! Built once per domain by median splits on the longest axis of the element centres;
//! queried with a box, it reports every element whose box overlaps, in a fixed order
//! (so results do not depend on threads).

use crate::geometry::Aabb;

const LEAF_SIZE: usize = 4;

#[derive(Debug, Clone)]
struct Node<const D: usize> {
    bounds: Aabb<D>,
    /// Leaf: `items[start..start + count]`; inner node: children at `start`, `start + 1`.
    start: u32,
    count: u32,
    /// The subtree's elements: `items[span.0..span.0 + span.1]` (contiguous by construction).
    span: (u32, u32),
}

/// A static BVH over axis-aligned boxes.
#[derive(Debug, Clone)]
pub struct Bvh<const D: usize> {
    nodes: Vec<Node<D>>,
    items: Vec<u32>,
    boxes: Vec<Aabb<D>>,
}

impl<const D: usize> Bvh<D> {
    /// Build over `boxes`; element `i` of a query result refers to `boxes[i]`.
    pub fn new(boxes: Vec<Aabb<D>>) -> Self {
        let mut items: Vec<u32> = (0..boxes.len() as u32).collect();
        let centers: Vec<[f64; D]> = boxes.iter().map(Aabb::center).collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len() / LEAF_SIZE + 1);
        nodes.push(Node {
            bounds: Aabb::empty(),
            start: 0,
            count: boxes.len() as u32,
            span: (0, boxes.len() as u32),
        });
        let mut stack = vec![0usize];
        while let Some(at) = stack.pop() {
            let (start, count) = (nodes[at].start as usize, nodes[at].count as usize);
            let slice = &mut items[start..start + count];
            let mut bounds = Aabb::empty();
            let mut center_box = Aabb::empty();
            for &i in slice.iter() {
                bounds.merge(&boxes[i as usize]);
                center_box.grow(&centers[i as usize]);
            }
            nodes[at].bounds = bounds;
            if count <= LEAF_SIZE {
                continue;
            }
            let axis = (0..D)
                .max_by(|&a, &b| {
                    let ea = center_box.hi[a] - center_box.lo[a];
                    let eb = center_box.hi[b] - center_box.lo[b];
                    ea.total_cmp(&eb)
                })
                .unwrap_or(0);
            let mid = count / 2;
            slice.select_nth_unstable_by(mid, |&a, &b| {
                centers[a as usize][axis]
                    .total_cmp(&centers[b as usize][axis])
                    .then(a.cmp(&b))
            });
            let first_child = nodes.len();
            nodes.push(Node {
                bounds: Aabb::empty(),
                start: start as u32,
                count: mid as u32,
                span: (start as u32, mid as u32),
            });
            nodes.push(Node {
                bounds: Aabb::empty(),
                start: (start + mid) as u32,
                count: (count - mid) as u32,
                span: ((start + mid) as u32, (count - mid) as u32),
            });
            nodes[at].start = first_child as u32;
            nodes[at].count = 0;
            stack.push(first_child + 1);
            stack.push(first_child);
        }
        Self {
            nodes,
            items,
            boxes,
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.boxes.len()
    }

    /// No elements at all.
    pub fn is_empty(&self) -> bool {
        self.boxes.is_empty()
    }

    /// Number of nodes; node `0` is the root.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The elements under node `i` (all of its subtree), empty for a bad index.
    pub fn node_items(&self, i: usize) -> &[u32] {
        self.nodes.get(i).map_or(&[], |n| {
            let (s, c) = (n.span.0 as usize, n.span.1 as usize);
            &self.items[s..s + c]
        })
    }

    /// Depth-first walk from the root: `visit(node, is_leaf)` returns whether to descend
    /// into the node's children (ignored at leaves). Fixed order, as [`Bvh::query`].
    pub fn walk(&self, visit: impl FnMut(usize, bool) -> bool) {
        self.walk_from(0, visit);
    }

    /// The leaves under node `i` (itself if a leaf), in the order [`Bvh::walk`] visits
    /// them: a walk that stops at a node and takes its leaves sees its elements in the
    /// order of one that descended.
    pub fn for_each_leaf_under(&self, i: usize, mut leaf: impl FnMut(usize)) {
        if self.nodes.get(i).is_some_and(|node| node.count > 0) {
            leaf(i); // a leaf itself: no walk
        } else if i < self.nodes.len() {
            self.walk_from(i, |at, is_leaf| {
                if is_leaf {
                    leaf(at);
                }
                true
            });
        }
    }

    fn walk_from(&self, root: usize, mut visit: impl FnMut(usize, bool) -> bool) {
        if self.boxes.is_empty() {
            return;
        }
        let mut stack = [root as u32; 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let at = stack[top] as usize;
            let node = &self.nodes[at];
            let leaf = node.count > 0;
            if visit(at, leaf) && !leaf && top + 2 <= stack.len() {
                stack[top] = node.start;
                stack[top + 1] = node.start + 1;
                top += 2;
            }
        }
    }

    /// The two children of node `i`; None at a leaf (or for a bad index).
    pub fn children(&self, i: usize) -> Option<(usize, usize)> {
        let node = self.nodes.get(i)?;
        (node.count == 0).then_some((node.start as usize, node.start as usize + 1))
    }

    /// The box of node `i` (an empty box for a bad index).
    pub fn node_bounds(&self, i: usize) -> Aabb<D> {
        self.nodes.get(i).map_or_else(Aabb::empty, |n| n.bounds)
    }

    /// Box of the whole hierarchy.
    pub fn bounds(&self) -> Aabb<D> {
        self.nodes.first().map_or_else(Aabb::empty, |n| n.bounds)
    }

    /// Append to `out` every element whose box overlaps `query`, in ascending order.
    pub fn query(&self, query: &Aabb<D>, out: &mut Vec<u32>) {
        let first = out.len();
        self.visit_overlapping(query, |_| false, |i| out.push(i));
        out[first..].sort_unstable();
    }

    /// Call `found(i)` for every element `i` whose box overlaps `query`, less those under
    /// a node whose box `skip` refuses, depth first in a fixed order (not ascending).
    /// `skip` is asked about each node's box before its subtree is read (not about the
    /// elements' own boxes), and may change as elements are found (a bound that tightens).
    pub fn visit_overlapping(
        &self,
        query: &Aabb<D>,
        mut skip: impl FnMut(&Aabb<D>) -> bool,
        mut found: impl FnMut(u32),
    ) {
        if self.boxes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !node.bounds.overlaps(query) || skip(&node.bounds) {
                continue;
            }
            if node.count > 0 {
                let (s, c) = (node.start as usize, node.count as usize);
                for &i in &self.items[s..s + c] {
                    if self.boxes[i as usize].overlaps(query) {
                        found(i);
                    }
                }
            } else if top + 2 <= stack.len() {
                stack[top] = node.start;
                stack[top + 1] = node.start + 1;
                top += 2;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_matches_brute_force() {
        let mut rng = crate::sample::Lcg::new(12345);
        let mut rand = || rng.unit();
        let boxes: Vec<Aabb<2>> = (0..500)
            .map(|_| {
                let (x, y) = (rand(), rand());
                Aabb {
                    lo: [x, y],
                    hi: [x + 0.05 * rand(), y + 0.05 * rand()],
                }
            })
            .collect();
        let bvh = Bvh::new(boxes.clone());
        for _ in 0..200 {
            let (x, y) = (rand(), rand());
            let q = Aabb {
                lo: [x, y],
                hi: [x + 0.1, y + 0.02],
            };
            let mut got = Vec::new();
            bvh.query(&q, &mut got);
            let want: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&i| boxes[i as usize].overlaps(&q))
                .collect();
            assert_eq!(got, want);
        }
    }
}
