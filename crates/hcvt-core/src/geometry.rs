//! Small fixed-size vector helpers and the per-dimension primitives.
//!
//! Everything generic over the dimension `D` is written once; the few things that
//! differ between the plane and space (the normal of a hyperplane through `D`
//! points, the exact side-of-hyperplane predicate) live behind [`Space`].

/// `a - b`.
#[inline]
pub fn sub<const D: usize>(a: [f64; D], b: [f64; D]) -> [f64; D] {
    std::array::from_fn(|k| a[k] - b[k])
}

/// `a + b`.
#[inline]
pub fn add<const D: usize>(a: [f64; D], b: [f64; D]) -> [f64; D] {
    std::array::from_fn(|k| a[k] + b[k])
}

/// `s · a`.
#[inline]
pub fn scale<const D: usize>(a: [f64; D], s: f64) -> [f64; D] {
    a.map(|x| x * s)
}

/// `a · b`.
#[inline]
pub fn dot<const D: usize>(a: [f64; D], b: [f64; D]) -> f64 {
    a.iter().zip(&b).map(|(x, y)| x * y).sum()
}

/// The cross product `u × v`, each component rounded as numpy's `np.cross` rounds it.
#[inline]
pub fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

/// Squared length `|a|²`.
#[inline]
pub fn norm2<const D: usize>(a: [f64; D]) -> f64 {
    dot(a, a)
}

/// A box cut into equal cells, indexed with axis 0 varying fastest: the buckets of the
/// nearest-site grid and of the winding-number grid.
#[derive(Debug, Clone)]
pub(crate) struct Lattice<const D: usize> {
    /// Lower corner of the box.
    pub lo: [f64; D],
    /// Cell side along each axis.
    pub side: [f64; D],
    /// Cells along each axis.
    pub cells: [usize; D],
    inverse: [f64; D],
}

impl<const D: usize> Lattice<D> {
    /// About `target` cells with equal sides over the box at `lo` of size `extent` (one
    /// cell along a flat axis; each axis at most `target` cells).
    pub fn new(lo: [f64; D], extent: [f64; D], target: usize) -> Self {
        let spread: Vec<f64> = extent.iter().copied().filter(|&e| e > 0.0).collect();
        let volume: f64 = spread.iter().product();
        let wanted = (volume / target.max(1) as f64).powf(1.0 / spread.len().max(1) as f64);
        let cells = extent.map(|e| {
            if e > 0.0 && wanted > 0.0 {
                ((e / wanted).ceil() as usize).clamp(1, target.max(1))
            } else {
                1
            }
        });
        let side: [f64; D] = std::array::from_fn(|k| extent[k] / cells[k] as f64);
        Self {
            lo,
            side,
            cells,
            inverse: side.map(|s| if s > 0.0 { 1.0 / s } else { 0.0 }),
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.iter().product()
    }

    /// Coordinates of the cell holding `p`, clamped to the lattice.
    pub fn coordinates(&self, p: &[f64; D]) -> [usize; D] {
        std::array::from_fn(|k| {
            // A positive `x` truncates to its floor; without SSE4.1 `floor` is a call to
            // libm, 2% of a warm-started 2D diagram's instructions (callgrind).
            let x = (p[k] - self.lo[k]) * self.inverse[k];
            if x > 0.0 {
                (x as usize).min(self.cells[k] - 1)
            } else {
                0
            }
        })
    }

    /// Linear index of the cell at coordinates `c`.
    pub fn index(&self, c: [usize; D]) -> usize {
        (0..D).rev().fold(0, |b, k| b * self.cells[k] + c[k])
    }

    /// Coordinates of the cell of linear index `b`.
    pub fn coordinates_of(&self, mut b: usize) -> [usize; D] {
        std::array::from_fn(|k| {
            let c = b % self.cells[k];
            b /= self.cells[k];
            c
        })
    }

    /// The cell at coordinates `c` as a box.
    pub fn cell_box(&self, c: [usize; D]) -> Aabb<D> {
        let lo: [f64; D] = std::array::from_fn(|k| self.lo[k] + c[k] as f64 * self.side[k]);
        Aabb {
            lo,
            hi: std::array::from_fn(|k| lo[k] + self.side[k]),
        }
    }
}

/// Step `at` to the next cell of the block `from..=to` of a lattice (or any grid indexed
/// by coordinates), axis 0 fastest; false past the last.
pub(crate) fn next_in_box<const D: usize>(
    at: &mut [usize; D],
    from: [usize; D],
    to: [usize; D],
) -> bool {
    for k in 0..D {
        if at[k] < to[k] {
            at[k] += 1;
            return true;
        }
        at[k] = from[k];
    }
    false
}

/// Axis-aligned box `[lo, hi]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb<const D: usize> {
    /// Lower corner.
    pub lo: [f64; D],
    /// Upper corner.
    pub hi: [f64; D],
}

impl<const D: usize> Aabb<D> {
    /// The empty box (contains nothing; `grow` makes it a point).
    pub fn empty() -> Self {
        Self {
            lo: [f64::INFINITY; D],
            hi: [f64::NEG_INFINITY; D],
        }
    }

    /// Smallest box holding all `points`.
    pub fn of_points<'a>(points: impl IntoIterator<Item = &'a [f64; D]>) -> Self {
        let mut b = Self::empty();
        for p in points {
            b.grow(p);
        }
        b
    }

    /// Enlarge to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: &[f64; D]) {
        for ((lo, hi), &x) in self.lo.iter_mut().zip(self.hi.iter_mut()).zip(p) {
            *lo = lo.min(x);
            *hi = hi.max(x);
        }
    }

    /// Enlarge to contain `other`.
    #[inline]
    pub fn merge(&mut self, other: &Self) {
        self.grow(&other.lo);
        self.grow(&other.hi);
    }

    /// Closed boxes overlap (touching counts).
    #[inline]
    pub fn overlaps(&self, other: &Self) -> bool {
        (0..D).all(|k| self.lo[k] <= other.hi[k] && other.lo[k] <= self.hi[k])
    }

    /// Centre of the box.
    #[inline]
    pub fn center(&self) -> [f64; D] {
        std::array::from_fn(|k| 0.5 * (self.lo[k] + self.hi[k]))
    }

    /// Length of the box diagonal.
    pub fn diagonal(&self) -> f64 {
        norm2(sub(self.hi, self.lo)).sqrt()
    }

    /// The box grown by `margin` on every side.
    pub fn expanded(&self, margin: f64) -> Self {
        Self {
            lo: self.lo.map(|x| x - margin),
            hi: self.hi.map(|x| x + margin),
        }
    }

    /// The box translated by `-origin`.
    pub fn relative_to(&self, origin: [f64; D]) -> Self {
        Self {
            lo: sub(self.lo, origin),
            hi: sub(self.hi, origin),
        }
    }
}

/// A closed half-space `{x : normal · x <= offset}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace<const D: usize> {
    /// Outward normal (need not be unit length).
    pub normal: [f64; D],
    /// Right-hand side.
    pub offset: f64,
}

impl<const D: usize> HalfSpace<D> {
    /// The half-space bounded by the hyperplane through `point` with outward `normal`.
    #[inline]
    pub fn through(point: [f64; D], normal: [f64; D]) -> Self {
        Self {
            normal,
            offset: dot(normal, point),
        }
    }

    /// Bisector half-space of the origin and `q`: the points closer to the origin.
    #[inline]
    pub fn bisector(q: [f64; D]) -> Self {
        Self {
            normal: q,
            offset: 0.5 * norm2(q),
        }
    }
}

/// Marker type carrying the primitives that differ between 2D and 3D.
#[derive(Debug, Clone, Copy, Default)]
pub struct Euclid;

/// Primitives of `D`-dimensional space used by the dimension-generic algorithms.
pub trait Space<const D: usize> {
    /// Normal of the hyperplane through the `D` points `p`, with the orientation of the
    /// boundary convention: for an outer ring segment `(a, b)` traversed counter-clockwise
    /// (2D), or a triangle `(a, b, c)` counter-clockwise seen from outside (3D), it points
    /// out of the domain. Not normalised.
    fn normal(p: &[[f64; D]; D]) -> [f64; D];

    /// Exact sign of the side of `q` with respect to the oriented hyperplane through the
    /// `D` points `p`: positive on the side [`Space::normal`] points to, negative on the
    /// other, zero exactly on it (Shewchuk's adaptive predicates, crate `robust`).
    fn side(p: &[[f64; D]; D], q: &[f64; D]) -> f64;
}

impl Space<2> for Euclid {
    #[inline]
    fn normal(p: &[[f64; 2]; 2]) -> [f64; 2] {
        let [a, b] = *p;
        [b[1] - a[1], a[0] - b[0]]
    }

    #[inline]
    fn side(p: &[[f64; 2]; 2], q: &[f64; 2]) -> f64 {
        let c = |v: &[f64; 2]| robust::Coord { x: v[0], y: v[1] };
        // orient2d > 0 when q is left of a -> b, the inner side of a CCW ring.
        -robust::orient2d(c(&p[0]), c(&p[1]), c(q))
    }
}

impl Space<3> for Euclid {
    #[inline]
    fn normal(p: &[[f64; 3]; 3]) -> [f64; 3] {
        let u = sub(p[1], p[0]);
        let v = sub(p[2], p[0]);
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    }

    #[inline]
    fn side(p: &[[f64; 3]; 3], q: &[f64; 3]) -> f64 {
        let c = |v: &[f64; 3]| robust::Coord3D {
            x: v[0],
            y: v[1],
            z: v[2],
        };
        // orient3d > 0 when q is below the plane of a counter-clockwise (a, b, c): inside.
        -robust::orient3d(c(&p[0]), c(&p[1]), c(&p[2]), c(q))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_point_out_of_ccw_boundaries() {
        // Bottom edge of a CCW square points down; the top face of a cube seen from above up.
        assert_eq!(
            <Euclid as Space<2>>::normal(&[[0.0, 0.0], [1.0, 0.0]]),
            [0.0, -1.0]
        );
        let top = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        assert_eq!(<Euclid as Space<3>>::normal(&top), [0.0, 0.0, 1.0]);
        assert!(<Euclid as Space<3>>::side(&top, &[0.2, 0.2, 2.0]) > 0.0);
        assert!(<Euclid as Space<3>>::side(&top, &[0.2, 0.2, 0.5]) < 0.0);
        assert!(<Euclid as Space<2>>::side(&[[0.0, 0.0], [1.0, 0.0]], &[0.5, -1.0]) > 0.0);
        assert_eq!(
            <Euclid as Space<2>>::side(&[[0.0, 0.0], [1.0, 0.0]], &[7.0, 0.0]),
            0.0
        );
    }
}
