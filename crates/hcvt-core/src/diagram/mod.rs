//! The clipped Voronoi diagram, exact to round-off (DESIGN §3).
//!
//! Per site, independently and in parallel:
//! 1. the convex Voronoi cell: the domain's bounding box clipped by the bisectors of the
//!    nearest sites in order of distance, until the next site is farther than twice the
//!    cell's radius (security radius); in a convex domain a cell still open after a few
//!    neighbours is cut by the boundary planes near it, and is then finished in step 1;
//! 2. its intersection with the domain, integrated exactly through the identity
//!    `1_Ω(x) = w(q) + Σ_T σ_T 1_K(q,T)(x)` for every `x` in the cell, where `q` is a point
//!    of the cell (the site when possible), `K(q, T)` the part of the cone from `q`
//!    through boundary simplex `T` beyond `T`, and `σ_T = ±1` the side of `T` that `q` is
//!    on. Each `C ∩ K(q, T)` is the cell clipped by `d + 1` more half-spaces.
//!
//! | file | owns |
//! |------|------|
//! | `mod.rs` | the modules and what the crate sees of them (re-exports only) |
//! | `driver.rs` | the drivers [`clipped_diagram`] (and [`trial_diagram`], stopped below a mass floor) and [`clipped_cells`]: validation, the sites' Morton order and index, assembly in index order |
//! | `request.rs` | [`Request`] and [`Options`]: what a caller asks; the checks of the sites and weights it gives |
//! | `visit.rs` | one pass over the cells: batches of cells in Morton order, in parallel, each found, clipped and measured |
//! | `output.rs` | the result [`Diagram`] (and [`Clipped`], [`PartCells`]), batches and their assembly |
//! | `box_domain.rs` | [`BoxDomain`], an axis-aligned box as a domain kind: cells clipped by its sides (the start of the periodic box) |
//! | `periodic_box.rs` | [`PeriodicBox`], a box periodic along some or all axes: cells among the sites' images in a band, each neighbour with its image shift (DESIGN §14) |
//! | `torus.rs` | [`Torus`], a periodic box's periods and axes as a value: what the driver and the optimisers ask of a periodic domain (the wrap into the box) |
//! | `surface/` | [`Surface`], a triangle surface as a domain kind: restricted Voronoi cells, the surface's triangles clipped by each convex cell (DESIGN §12); its restricted Delaunay triangulation |
//! | `polygon_clip.rs` | one Sutherland–Hodgman step, shared by the surface's pieces and the mesh's boundary pieces |
//! | `sphere/` | [`Sphere`], the unit sphere as a domain kind: spherical polygons cut by great circles, their exact area, first moment and energy |
//! | `sphere_density.rs` | a density on the sphere: fan triangles mapped onto it, their rule's nodes and Jacobian, the sums with a constant exact |
//! | `sphere_region.rs` | [`SphereRegion`], a region of the sphere bounded by great-circle polygons (an ocean basin, islands as holes) as a domain kind |
//! | `domain_kind.rs` | [`DomainKind`], what the driver asks of a domain (DESIGN §11), the margin of the box a cell starts from, and its implementation for a [`crate::domain::Boundary`] |
//! | `voronoi_cell.rs` | one site's convex Voronoi cell ([`voronoi_cell`]): kNN and the security radius, localisation to the domain (step 1) |
//! | `clip.rs` | the cell clipped by the domain through signed cones, or by its planes when convex (step 2) |
//! | `faces.rs` | each cell's face measures (neighbours, boundary share) and a caller's [`FaceIntegrand`] over them |
//! | `order.rs` | the Morton order of the sites ([`morton_order`]) and [`Diagram::reordered`] |
//! | `convex_cell.rs`, `polygon_cell.rs`, `polyhedron_cell/` | the convex cell ([`ConvexCell`]) in 2D and 3D |
//! | `knn/` | the nearest-site index ([`SiteIndex`]): a grid of buckets, or a kd-tree for crowded sites, and their streams |
//! | `scratch.rs` | per-thread buffers reused from cell to cell (`with_scratch`) |
//! | `warm.rs` | [`WarmStart`]: the previous diagram's near-site lists, which certify a cell's nearest sites without the index |
//! | `ring.rs` | a warm cell rebuilt from its previous neighbours' ring without clipping, bit for bit the clipped cell (2D) |
//! | `power/` | a power diagram's cells: how far they look for sites (a grid of the largest weight per block), cells started from a previous diagram, stored margins (DESIGN §14) |
//! | `weighted.rs` | with a density (DESIGN §8): the sampled field's one evaluation, checks, [`Diagram::weighted`] |
//! | `weighted_sums.rs` | with a density: one cell's weighted sums over its pieces, as `faces.rs` measures them |
//! | `mesh/` | cell geometry and the conforming mesh of all cells ([`PolyMesh`], DESIGN §9) |

mod box_domain;
mod clip;
mod convex_cell;
mod domain_kind;
mod driver;
mod faces;
mod knn;
mod mesh;
mod order;
mod output;
mod periodic_box;
mod polygon_cell;
mod polygon_clip;
mod polyhedron_cell;
mod power;
mod request;
mod ring;
mod scratch;
mod sphere;
mod sphere_density;
mod sphere_region;
mod surface;
mod torus;
mod visit;
mod voronoi_cell;
mod warm;
mod weighted;
mod weighted_sums;

pub use box_domain::BoxDomain;
pub use convex_cell::{ConvexCell, Face};
pub use domain_kind::DomainKind;
pub use driver::{clipped_cells, clipped_diagram};
pub(crate) use driver::{clipped_diagram_kept, trial_diagram, MarginRequest, SiteSetup};
pub use faces::{FaceIntegrals, FaceIntegrand, Matrix};
pub use knn::SiteIndex;
pub use mesh::{
    conforming_mesh, conforming_mesh_part, conforming_power_mesh, MeshDomain, MeshPart, PolyMesh,
};
pub use order::morton_order;
pub use output::{Clipped, Diagram, PartCells};
pub use periodic_box::PeriodicBox;
pub use polygon_cell::PolygonCell;
pub use polyhedron_cell::PolyhedronCell;
pub(crate) use power::Margins;
pub use power::PowerWhole;
pub use request::{Options, Request};
pub use sphere::{Sphere, ON_SPHERE_TOL};
pub use sphere_region::{SphereRegion, MAX_REACH_DEGREES};
pub use surface::{RestrictedDelaunay, Surface, SurfacePieces};
pub use torus::Torus;
pub use warm::WarmStart;
