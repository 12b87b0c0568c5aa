"""Curvature-adapted remeshing against the uniform remesh, same n, same seed.

For each model, the uniform remesh (``density=None``) and one per ``--powers`` value
``p`` of ``hcvt.remesh(density=hcvt.surface.curvature_density(surface, p))``
(``ρ = (floor + κ/κ̄)^p``, spacing ``∝ ρ^(-1/4)``; ``hcvt.remesh``'s option
``density="curvature"`` is the ``curv^1`` row at floor 1, smooth 5). Every output is measured by
:func:`hcvt.surface_quality` against the input: Q min/mean, θmin, % of angles < 30°,
Hausdorff distance both ways as % of the diagonal, manifold, genus; with the
remeshing's seconds and CVT iterations (``--plain``: without ``tighten``, the CVT's own
mesh). One thread; timings under load.

    OPENBLAS_NUM_THREADS=1 python benchmarks/remesh_density.py [--models bunny kitten]
        [--n 20000] [--powers 0.5 1 2] [--floor 1] [--smooth 5] [--seed 0] [--plain]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import hcvt
from remesh import DATA, MODELS, quality  # benchmarks/remesh.py: the same meshes, columns


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=["bunny", "kitten"], choices=list(MODELS))
    parser.add_argument("--n", type=int, default=20000)
    parser.add_argument("--powers", nargs="+", type=float, default=[0.5, 1.0, 2.0])
    parser.add_argument("--floor", type=float, default=1.0)
    parser.add_argument("--smooth", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--plain", action="store_true", help="tighten=False: the CVT's mesh as it is"
    )
    args = parser.parse_args()
    print(
        f"{'model':8} {'n':>6} {'density':>10} {'verts':>6} {'Qmin':>6} {'Qmean':>6} "
        f"{'θmin':>6} {'%<30':>5} {'Haus%':>6} {'->ref':>6} {'ref->':>6} {'mfld':>5} "
        f"{'genus':>5} {'iters':>5} {'sec':>7}"
    )
    for model in args.models:
        domain = hcvt.load_domain(DATA / MODELS[model], surface=True)
        reference = (domain.vertices, domain.faces)
        cases: list[tuple[str, object]] = [("uniform", None)]
        for p in args.powers:
            start = time.perf_counter()
            rho = hcvt.surface.curvature_density(
                domain, power=p, floor=args.floor, smooth=args.smooth
            )
            built = time.perf_counter() - start
            print(
                f"# {model}: curvature_density power {p}: ρ in [{rho.min():.3g}, "
                f"{rho.max():.3g}], {built:.2f} s"
            )
            cases.append((f"curv^{p:g}", rho))
        for name, density in cases:
            out = hcvt.remesh(
                domain, args.n, seed=args.seed, density=density, tighten=not args.plain
            )
            q = quality(out.vertices, out.faces, reference)
            print(
                f"{model:8} {args.n:6d} {name:>10} {q['vertices']:6d} {q['q_min']:6.3f} "
                f"{q['q_mean']:6.3f} {q['angle_min']:6.2f} {q['below_30']:5.2f} "
                f"{q['hausdorff']:6.3f} {q['hausdorff_to_reference']:6.3f} "
                f"{q['hausdorff_from_reference']:6.3f} {str(q['manifold']):>5} "
                f"{q['genus']:5d} {out.iterations:5d} {out.seconds:7.2f}"
                + (f"  defects: {out.defects}" if out.defects else ""),
                flush=True,
            )


if __name__ == "__main__":
    main()
