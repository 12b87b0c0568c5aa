//! The kernel of `hcvt.export.split`: a polyhedral cell cut by a plane, its parts
//! measured as OpenFOAM's checkMesh measures them.
//!
//! `hcvt.export.split` splits the boundary cells of a Voronoi mesh whose faces fail
//! checkMesh (skew pieces, centres behind a piece) by trying many planes per cell and
//! keeping the cut whose parts' faces fail least. Trying a plane is this module's work.
//! It replaced a Python version of the same steps ("the reference" below: `_Editor.cut`
//! and `_Editor.measure` before the search moved here), which it matched bit for bit;
//! it keeps that version's orders and numpy's rounding, so that a face it passes is a
//! face the final check on the whole mesh (`hcvt.export.quality`, numpy) passes:
//!
//! | file | owns |
//! |------|------|
//! | `mod.rs` | the shared types: faces as [`Loops`], what lies [`Across`] a face |
//! | `cut.rs` | [`cut_cell`], [`cut_cell_by_planes`]: the pieces of each face, the sections on the plane, the parts |
//! | `quality.rs` | [`measure_region`]: face and part geometry, non-orthogonality, skewness, face pyramids |
//! | `numpy_order.rs` | sums and dot products rounded in numpy's order |

mod cut;
mod numpy_order;
mod quality;
#[cfg(test)]
mod tests;

pub use cut::{cut_cell, cut_cell_by_planes, Cell, Crossing, Cut, Plane};
pub use quality::{measure_region, Region, RegionQuality, SKEWNESS_LIMIT, SKEWNESS_TARGET};

use crate::error::CoreError;

/// What lies on the other side of a face of a part.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Across {
    /// The domain's boundary.
    Boundary,
    /// Another part of the same region.
    Part(u32),
    /// A cell outside the region, known by its centroid (an index into the ghost
    /// centroids).
    Ghost(u32),
}

/// Polygons as loops of vertex indices, in CSR layout: loop `k` is
/// `vertices[offsets[k]..offsets[k + 1]]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Loops {
    offsets: Vec<usize>,
    vertices: Vec<u32>,
}

impl Default for Loops {
    fn default() -> Self {
        Self {
            offsets: vec![0],
            vertices: Vec::new(),
        }
    }
}

impl Loops {
    /// Loops from `offsets` (f + 1,), starting at 0, and `vertices`; every loop has at
    /// least 3 vertices.
    ///
    /// # Errors
    ///
    /// [`CoreError::InvalidFace`] naming the first loop that does not start where the one
    /// before ended, runs past `vertices`, or has fewer than 3 vertices.
    pub fn new(offsets: Vec<usize>, vertices: Vec<u32>) -> Result<Self, CoreError> {
        let invalid = |face, reason: String| Err(CoreError::InvalidFace { face, reason });
        if offsets.first() != Some(&0) {
            return invalid(0, "face offsets must start at 0".into());
        }
        for (k, pair) in offsets.windows(2).enumerate() {
            let size = pair[1].saturating_sub(pair[0]);
            if pair[1] < pair[0].saturating_add(3) {
                return invalid(k, format!("{size} vertices, at least 3 needed"));
            }
        }
        let end = offsets.last().copied().unwrap_or(0);
        if end != vertices.len() {
            let last = offsets.len().saturating_sub(2);
            let count = vertices.len();
            return invalid(last, format!("offsets end at {end}, but {count} vertices"));
        }
        Ok(Self { offsets, vertices })
    }

    /// Number of loops.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// No loops.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Loop `k`'s vertices.
    ///
    /// # Panics
    ///
    /// If `k >= self.len()`.
    pub fn get(&self, k: usize) -> &[u32] {
        &self.vertices[self.offsets[k]..self.offsets[k + 1]]
    }

    /// The loops in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[u32]> + '_ {
        self.offsets
            .windows(2)
            .map(|pair| &self.vertices[pair[0]..pair[1]])
    }

    /// Offsets (f + 1,) into [`Loops::vertices`].
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// Every loop's vertices, one loop after the other.
    pub fn vertices(&self) -> &[u32] {
        &self.vertices
    }

    /// Append a loop.
    pub(crate) fn push(&mut self, ring: &[u32]) {
        self.vertices.extend_from_slice(ring);
        self.offsets.push(self.vertices.len());
    }

    /// Every vertex index below `points`.
    fn check_vertices(&self, points: usize) -> Result<(), CoreError> {
        for (k, ring) in self.iter().enumerate() {
            if let Some(&v) = ring.iter().find(|&&v| v as usize >= points) {
                return Err(CoreError::InvalidFace {
                    face: k,
                    reason: format!("vertex {v}, but {points} points"),
                });
            }
        }
        Ok(())
    }
}
