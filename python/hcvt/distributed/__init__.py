"""One diagram or one CVT partitioned over dask.distributed workers (DESIGN §10).

The sites are cut into parts by median planes fixed by the data
(:func:`hcvt.distributed.partition.kd_split`, at most ``sites_per_partition`` sites each,
never by the number of workers). Each part
lives on a worker as a dask future; the domain is scattered to every worker once.

**Diagram.** In rounds: a part's cells are computed among its sites and the sites of the
other parts within a distance ``rho = 3 h`` of its sites' box (taken by small tasks where
those parts live, so only the halo travels). Each cell reports its reach; the cells whose
reach leaves that widened box are computed again among the sites within 1.5 times their
reach (a ball per cell), and so on until every cell is certified or its part holds every
site. The per-cell arrays are then bitwise
those of :func:`hcvt.voronoi` in one process (module docs of :mod:`hcvt.distributed.partition`).

**Domain kinds.** Polygons, solids, boxes, the sphere (``h`` by the cells' dimension 2),
and boxes periodic along some axes or all; not surfaces.

- *Periodic boxes*: halos and balls are taken among the sites wrapped into the box, by the
  images ``x + k∘L``, ``k`` in ``{-1, 0, 1}`` on the periodic axes (:class:`~hcvt.
  distributed.partition.Torus`), so a part near a side gets the sites across it. The core
  computes the part's cells among the images of the sites it was given, in a band grown
  until it covers each cell's reach (as for the whole diagram, ``periodic_box.rs``), sites
  before images and images by site and shift as in the whole problem; each neighbour
  comes with its image shift (``neighbor_images``). Lloyd runs keep the sites as the core
  moves them (unwrapped) and :meth:`PartitionedCVTResult.gather` wraps them, as
  :func:`hcvt.cvt` does.
- *The sphere*: a part's sites go back to the core as its steps left them
  (``Frame.steps_to_core``: not normalised again), so Lloyd is bitwise for a radius that
  is a power of two (1 included); the gradient is the core's tangent one, the L-BFGS
  trial sites are retracted by the core.
- *Power diagrams* (``weights=``, :func:`partitioned_voronoi` only): the weights are sent
  to every worker; a part's cells take the whole problem's box of sites and largest weight
  (``hcvt_core::PowerWhole``), so their grid of weights is the whole problem's block for
  block (the heavier sites are clipped in the same order) and each cell's reach bounds the
  heavier sites by the largest weight of all (DESIGN §14): a heavy site far away is inside
  the reach, and the rounds fetch it. Not in a periodic box yet.

**Sums.** Energy, mean G, the stopping measures and the L-BFGS dot products are summed per
part with :func:`math.fsum` in row order, then over the parts in part order. They differ
from the single process's sequential sums by round-off (energies agree to about 1e-15
relative) and do not depend on the number of workers.

**CVT.** Sites, gradients and L-BFGS pairs stay in their parts between iterations; the
client sees only scalars and the small Gram matrices of the pairs:

- Lloyd moves each site to its centroid by the core's Lloyd step and guards (called per
  part: ``step_fields``, ``lloyd_step``), so a partitioned Lloyd run is bitwise the
  single-process ``hcvt.cvt(..., method="lloyd")`` run, site by site.
- L-BFGS runs the core's two-loop recursion on the client in coefficient space
  (vector-free L-BFGS, Chen et al. 2014; ``_core.lbfgs_coefficients``): one reduction of
  the partial Gram matrices of ``[s_k, y_k, g]`` (plain and preconditioned by
  ``1/(2 m_i)``) per iteration, then each part forms its direction with the core
  (``lbfgs_direction``, held inside as the core's). The preconditioner, its
  Oren–Luenberger scaling, the curvature test and the acceptance of a step are the core's;
  the line search is a backtracking search from the unit step (Armijo, or Hager and
  Zhang's approximate Wolfe near round-off: ``LineSearch::accepts``), falling back to a
  Lloyd step, so the iterates are not the core's (whose strong-Wolfe search differs). What
  is guaranteed: the run is bitwise the same for any number of workers.
- Newton is not offered: its truncated CG needs a Hessian product per CG iteration, i.e.
  one halo exchange of the vector per product (tens per step), each a round trip through
  the scheduler; not done here.
- After every step, sites that crossed a plane of the split move, with their per-row
  state, to the part that now holds their position (the split stays fixed).

**Density.** With ``density=`` (DESIGN §8) each part's cells carry their ρ-weighted
moments, integrated by the core exactly as in one process (``clipped_cells_weighted``), so
``mass``, the weighted ``centroid``, ``energy_terms`` and the gradient are bitwise the
single-process ones; Lloyd moves to the weighted centroids and L-BFGS is preconditioned by
``1/(2 m_i)`` with ``m_i = ∫ρ``, as the core. The density is scattered to every worker
with the domain. A callable is called once per part and round, on the quadrature nodes of
the cells computed there: bitwise equality then needs each value to depend on its point
alone (numpy's elementwise functions do; a function that normalises by its whole input
does not). The halo is unchanged: a cell's reach is where its geometry read sites.

**Worker loss.** With ``checkpoint`` (a temporary directory by default), every part is
written at the end of every iteration; if a task fails because a worker died (or its data
was lost), the domain and density are scattered again (the only copy may have gone with
the worker, since dask's active memory manager drops unused replicas) and the iteration is
run again from the files of the last completed one. The result is the same, since every
step is deterministic.
"""

from hcvt.distributed.driver import (
    DEFAULT_SITES_PER_PARTITION,
    PartitionedCVTResult,
    PartitionedDiagram,
    partitioned_cvt,
    partitioned_voronoi,
)

__all__ = [
    "DEFAULT_SITES_PER_PARTITION",
    "PartitionedCVTResult",
    "PartitionedDiagram",
    "partitioned_cvt",
    "partitioned_voronoi",
]
