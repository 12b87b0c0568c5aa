"""Exceptions raised by hcvt; all are ``ValueError`` subclasses, so ``except ValueError`` works."""


class InvalidDomainError(ValueError):
    """The polygon or mesh cannot bound a domain (open, self-intersecting, flat, ...).

    The message names the defect and where it is, and says whether ``repair=True`` can fix it.
    """


class InvalidSitesError(ValueError):
    """The sites cannot generate a diagram (non-finite, coinciding, outside the domain, ...).

    The message names the first offending site by its row index.
    """


class InvalidMeshError(ValueError):
    """A :class:`hcvt.mesh.polymesh.PolyMesh` is not a conforming mesh (open cell, bad index, ...).

    The message names the first offending cell or face.
    """


class InvalidDensityError(ValueError):
    """The density cannot be used (not finite and positive where evaluated, a bad option).

    Non-positive or non-finite values, bad coefficients, a bad quadrature degree. The
    message names the point (absolute coordinates) and the value found there.
    """


class UnrepresentableError(ValueError):
    """A result exists but its value in the input's unit is outside float64's range.

    A domain of size 1e-150 has cells whose volumes (3D) underflow, one of size 1e100 has
    second moments that overflow. The core works in the domain's own frame
    (:mod:`hcvt.geometry.frame`), so the other results (positions, G, ...) stay available;
    the message names the quantity and the power of the scale it needed.
    """
