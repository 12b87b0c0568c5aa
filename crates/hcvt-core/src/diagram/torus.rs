//! The torus of a periodic box (DESIGN §14) as a plain value: the box `[lo, hi)`, its
//! period along each axis and which axes are periodic. What the driver and the optimisers
//! ask of a periodic domain ([`super::DomainKind::periodic`]): where a site's image in the
//! box is, and how far apart the images of a site are. The cells themselves are
//! `periodic_box.rs`'s.

use crate::geometry::{sub, Aabb};

/// The box `[lo, hi)`, periodic along the axes marked so, `L`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Torus<const D: usize> {
    bounds: Aabb<D>,
    periodic: [bool; D],
    /// `hi − lo`, `L`.
    periods: [f64; D],
}

impl<const D: usize> Torus<D> {
    /// The torus of the box `bounds` (finite, sides of positive length: checked by the
    /// caller), periodic along the axes where `periodic` is true.
    pub(super) fn new(bounds: Aabb<D>, periodic: [bool; D]) -> Self {
        Self {
            bounds,
            periodic,
            periods: sub(bounds.hi, bounds.lo),
        }
    }

    /// The box `[lo, hi]`.
    pub fn bounds(&self) -> Aabb<D> {
        self.bounds
    }

    /// Which axes are periodic.
    pub fn periodic_axes(&self) -> [bool; D] {
        self.periodic
    }

    /// `hi − lo` along each axis, `L`.
    pub fn periods(&self) -> [f64; D] {
        self.periods
    }

    /// The box's measure, the product of [`Torus::periods`], `L^d`.
    pub fn volume(&self) -> f64 {
        self.periods.iter().product()
    }

    /// `p` moved by whole periods into `[lo, hi)` along the periodic axes (unchanged along
    /// the others, and where it is in already). Non-finite coordinates stay non-finite.
    pub fn wrap(&self, p: [f64; D]) -> [f64; D] {
        std::array::from_fn(|k| {
            let (lo, hi, x) = (self.bounds.lo[k], self.bounds.hi[k], p[k]);
            if !self.periodic[k] || (lo <= x && x < hi) || !x.is_finite() {
                return x;
            }
            let wrapped = lo + (x - lo).rem_euclid(self.periods[k]);
            // Rounding may land on `hi` itself (a site just below `lo`): the same point.
            if wrapped < hi {
                wrapped
            } else {
                lo
            }
        })
    }

    /// The largest period along a periodic axis, `L`.
    pub(super) fn largest_period(&self) -> f64 {
        (0..D)
            .filter(|&k| self.periodic[k])
            .fold(0.0, |m: f64, k| m.max(self.periods[k]))
    }
}
