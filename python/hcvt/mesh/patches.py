"""Boundary patches: which named group each boundary face of a mesh belongs to.

A patch is a region of the input boundary: by default each connected component of the
domain's boundary (triangles joined by edges in 3D, segments joined by vertices in 2D),
or the groups of a label per boundary element the user gives.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from hcvt.errors import InvalidMeshError

if TYPE_CHECKING:
    from hcvt.geometry.domain import Domain
    from hcvt.mesh.polymesh import PolyMesh


def boundary_patches(
    mesh: PolyMesh, domain: Domain | None = None, labels: ArrayLike | None = None
) -> tuple[NDArray[np.intp], list[str]]:
    """The patch of every face and the patches' names.

    Parameters
    ----------
    mesh : PolyMesh
    domain : Domain, optional
        The domain the mesh fills: its boundary components become the patches
        ``boundary`` (one component) or ``boundary0``, ``boundary1``, ... in the order of
        their first element.
    labels : array_like of int or str, shape (E,), optional
        A label for each boundary element of the domain (triangle in 3D, segment in 2D,
        in ``Domain`` order): one patch per distinct label, named by it (characters other
        than letters, digits, ``_``, ``-`` and ``.`` become ``_``), in sorted order. Takes
        precedence over the components.

    Returns
    -------
    patch : ndarray of intp, shape (f,)
        Index into ``names`` for a boundary face, -1 for an interior face.
    names : list of str
        Distinct names; without ``domain`` and ``labels`` the single patch ``boundary``.

    Raises
    ------
    InvalidMeshError
        A boundary face without a boundary element (when patches need one), or an element
        beyond ``labels``.
    ValueError
        ``labels`` not one-dimensional.
    """
    boundary = ~mesh.interior
    patch = np.full(mesh.n_faces, -1, dtype=np.intp)
    if labels is None and domain is None:
        patch[boundary] = 0
        return patch, ["boundary"]
    element = mesh.boundary_element[boundary]
    if labels is not None:
        values = np.asarray(labels)
        if values.ndim != 1:
            raise ValueError(f"labels must have shape (E,), got {values.shape}")
        unique, of_element = np.unique(values, return_inverse=True)
        names = [_word(str(u)) for u in unique.tolist()]
        if len(set(names)) != len(names):
            raise ValueError(f"labels give clashing patch names: {names}")
    else:
        assert domain is not None
        count, of_element = _components(domain)
        names = ["boundary"] if count == 1 else [f"boundary{k}" for k in range(count)]
    missing = np.flatnonzero((element < 0) | (element >= len(of_element)))
    if len(missing):
        face = np.flatnonzero(boundary)[missing[0]]
        raise InvalidMeshError(
            f"boundary face {face} has element {mesh.boundary_element[face]}, "
            f"not one of the {len(of_element)} boundary elements"
        )
    patch[boundary] = of_element[element]
    return patch, names


def _components(domain: Domain) -> tuple[int, NDArray[np.intp]]:
    """Number of boundary components and the component of each element, shape (E,).

    Components are numbered in the order of their first element.
    """
    simplices = np.asarray(domain.faces if domain.dim == 3 else domain._core.segments)
    e = len(simplices)
    if domain.dim == 3:  # triangles sharing an edge: join each to the edge's first triangle
        edges = np.sort(simplices[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
        _, edge_id = np.unique(edges, axis=0, return_inverse=True)
        owner = np.repeat(np.arange(e), 3)
        first = np.full(edge_id.max() + 1, -1, dtype=np.intp)
        first[edge_id[::-1]] = owner[::-1]
        rows, cols = owner, first[edge_id]
    else:  # segments sharing a vertex: segment k ends where the next one starts
        start = np.full(simplices.max() + 1, -1, dtype=np.intp)
        start[simplices[:, 0]] = np.arange(e)
        rows, cols = np.arange(e), start[simplices[:, 1]]
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(e, e))
    count, label = connected_components(graph, directed=False)
    # Renumber by first element, so that names do not depend on scipy's numbering.
    _, first_seen = np.unique(label, return_index=True)
    order = np.argsort(np.argsort(first_seen))
    return int(count), order[label].astype(np.intp)


def _word(name: str) -> str:
    """``name`` as an OpenFOAM word (no spaces, quotes, brackets or semicolons)."""
    word = re.sub(r"[^A-Za-z0-9_.\-]", "_", name)
    return word if word and not word[0].isdigit() else f"patch_{word}"
