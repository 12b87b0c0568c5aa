"""Check that numpy gives each point the same bits whatever else is in the array.

A callable density on the partitioned path (``hcvt.distributed``) is called once per part
and halo round, on the quadrature nodes of that part's cells, instead of once on every
node of the diagram. The weighted moments are then bitwise the single-process ones exactly
when the callable's value at a point does not depend on the other points of the call
(their number, the point's position in the array, the array's alignment). This checks that
for numpy's elementwise functions and small reductions along a row on this machine: each
function on 200,003 random points, against 60 random contiguous slices (copied into fresh
arrays, as a part's nodes are) and 60 random subsets of rows. Prints, per function, the
number of elements whose bits differ (0 means the partitioned path is bitwise); the last
line is a control that does depend on the other points (it normalises by their mean).

    OPENBLAS_NUM_THREADS=1 python benchmarks/density_elementwise.py
"""

from __future__ import annotations

import numpy as np

N = 200_003
TRIALS = 60


def functions() -> dict[str, object]:
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(3, 3)), rng.normal(size=3)
    column = {
        "exp": np.exp,
        "log": lambda x: np.log(np.abs(x) + 0.1),
        "sin": np.sin,
        "cos": np.cos,
        "tan": lambda x: np.tan(x / 3),
        "tanh": np.tanh,
        "arctan": np.arctan,
        "arcsinh": np.arcsinh,
        "expm1": np.expm1,
        "log1p": lambda x: np.log1p(np.abs(x)),
        "cbrt": np.cbrt,
        "sqrt": lambda x: np.sqrt(np.abs(x)),
        "power": lambda x: np.power(np.abs(x) + 1, 1.7),
        "exp2": np.exp2,
        "log10": lambda x: np.log10(np.abs(x) + 0.1),
        "hypot": lambda x: np.hypot(x, 2.0),
    }
    # Each on the first column of the (m, 3) points, a strided view, as a user writes it.
    out: dict[str, object] = {k: _first_column(f) for k, f in column.items()}
    out.update(
        {
            "x @ b": lambda p: p @ b,
            "sum((x @ A) * x, axis=1)": lambda p: np.sum((p @ a) * p, axis=1),
            "norm(x, axis=1)": lambda p: np.linalg.norm(p, axis=1),
            "einsum('ij,ij->i')": lambda p: np.einsum("ij,ij->i", p, p),
            "1 + 5 exp(-|x - 0.3|^2 / 0.1)": _bump,
            "control: x / mean(x)": lambda p: p[:, 0] / p[:, 0].mean(),
        }
    )
    return out


def _first_column(f):  # type: ignore[no-untyped-def]
    return lambda p: f(p[:, 0])


def _bump(p: np.ndarray) -> np.ndarray:
    return 1 + 5 * np.exp(-np.sum((p - 0.3) ** 2, axis=1) / 0.1)


def main() -> None:
    print(f"numpy {np.__version__}")
    rng = np.random.default_rng(0)
    points = rng.uniform(-3, 3, size=(N, 3))
    for name, f in functions().items():
        whole = f(points)
        differ = 0
        for _ in range(TRIALS):
            start = int(rng.integers(0, N - 1))
            stop = min(N, start + int(rng.integers(1, 5000)))
            part = f(np.array(points[start:stop]))
            differ += int((part.view(np.uint64) != whole[start:stop].view(np.uint64)).sum())
            rows = np.sort(rng.choice(N, size=int(rng.integers(1, 3000)), replace=False))
            differ += int((f(points[rows]).view(np.uint64) != whole[rows].view(np.uint64)).sum())
        print(f"{name:32s} elements differing: {differ}")


if __name__ == "__main__":
    main()
