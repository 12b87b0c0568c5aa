"""The ``hcvt`` accessor of PyVista datasets: ``mesh.hcvt.voronoi(n)``, ``mesh.hcvt.cvt(n)``.

PyVista (>= 0.48) finds it through the ``pyvista.accessors`` entry point that hcvt's
``pyproject.toml`` declares, and imports this module the first time a dataset's ``hcvt``
attribute is read, so ``import pyvista`` alone is enough::

    import pyvista as pv

    result = pv.read("bunny.off").hcvt.cvt(2000)  # a CVTResult
    result.diagram.to_pyvista().plot(scalars="G")

The dataset is read as a solid by :meth:`hcvt.Domain.from_pyvista` (its triangles as
indexed, a volume mesh by its surface). Importing this module imports pyvista.
"""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from hcvt.api import cvt, voronoi
from hcvt.density import DensityLike
from hcvt.diagram import Diagram
from hcvt.geometry.domain import Domain
from hcvt.lazy import load
from hcvt.optimise import CVTResult
from hcvt.seeding import initialise

pyvista = load("pyvista")
if not hasattr(pyvista, "register_dataset_accessor"):
    raise ImportError(
        f"the mesh.hcvt accessor needs pyvista >= 0.48 (register_dataset_accessor), "
        f"found {pyvista.__version__}: pip install -U 'hcvt[viz]'"
    )


@pyvista.register_dataset_accessor("hcvt", pyvista.DataSet)
class HcvtAccessor:
    """Clipped Voronoi diagrams and CVTs of the solid a PyVista dataset bounds.

    Parameters
    ----------
    dataset : pyvista.DataSet
        A closed triangle surface (``PolyData``, or an ``UnstructuredGrid`` of triangles as
        ``pv.read`` gives for OFF files), any polygonal surface, or a volume mesh.
    """

    def __init__(self, dataset: Any) -> None:
        self._dataset = dataset

    def domain(self, *, repair: bool = False) -> Domain:
        """The dataset as a :class:`hcvt.Domain` (:meth:`hcvt.Domain.from_pyvista`)."""
        return Domain.from_pyvista(self._dataset, repair=repair)

    def _sites(
        self, domain: Domain, n: int | None, sites: ArrayLike | None, init: str, seed: int
    ) -> ArrayLike:
        if sites is None and n is not None:
            return initialise(domain, n, method=init, seed=seed)
        if sites is not None and n is None:
            return sites
        raise ValueError("give either n (sites made by hcvt.initialise) or sites")

    def voronoi(
        self,
        n: int | None = None,
        *,
        sites: ArrayLike | None = None,
        init: str = "random",
        seed: int = 0,
        repair: bool = False,
        density: DensityLike = None,
    ) -> Diagram:
        """The clipped Voronoi diagram of ``n`` new sites (or of ``sites``) in the solid.

        Parameters
        ----------
        n : int, optional
            Number of sites to place with :func:`hcvt.initialise` (``init``, ``seed``).
        sites : array_like of float, shape (n, 3), optional
            The sites themselves, in the dataset's coordinates, instead of ``n``.
        init : {"random", "halton", "hammersley", "lattice"}, default "random"
        seed : int, default 0
        repair : bool, default False
            Repair the surface first (:meth:`hcvt.Domain.from_mesh`).
        density : Polynomial, SizingField or callable, optional
            As in :func:`hcvt.voronoi`.

        Returns
        -------
        Diagram
            ``diagram.to_pyvista()`` is its cells as an ``UnstructuredGrid``.
        """
        domain = self.domain(repair=repair)
        points = self._sites(domain, n, sites, init, seed)
        return voronoi(domain, points, density=density)

    def cvt(
        self,
        n: int | None = None,
        *,
        sites: ArrayLike | None = None,
        method: str | None = None,
        init: str = "random",
        seed: int = 0,
        repair: bool = False,
        **options: Any,
    ) -> CVTResult:
        """A centroidal Voronoi tessellation of ``n`` sites (or from ``sites``) in the solid.

        Parameters
        ----------
        n : int, optional
            Number of starting sites placed with :func:`hcvt.initialise`.
        sites : array_like of float, shape (n, 3), optional
            The starting sites instead of ``n``.
        method : {"newton", "lbfgs", "lloyd"}, optional
            Default: the fastest the solid takes (:func:`hcvt.optimise.fastest_method`).
        init, seed, repair
            As in :meth:`voronoi`.
        **options
            Passed to :func:`hcvt.cvt` (``rule``, ``tol``, ``max_iter``, ``density`` ...).

        Returns
        -------
        CVTResult
            ``result.sites`` (n, 3), ``result.diagram``, ``result.history``.
        """
        domain = self.domain(repair=repair)
        points = self._sites(domain, n, sites, init, seed)
        return cvt(domain, points, method=method, **options)
