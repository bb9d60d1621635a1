"""Every weight kind on the GPU: the cuda multigrid against the CPU multigrid on the same host.

    python benchmarks/gpu_weights.py                    # 1024 and 2048, cuda and cpu
    python benchmarks/gpu_weights.py --sizes 1024 --backends cpu

For the bundled T-shirt front resampled to ``n x n`` (``tol = 2^-12``), each weight kind of
``bench_speed.py`` (paper, uniform, per-edge: a smooth field, 8 x 8 blocks of 10:1, 100:1 and
10^4:1) is solved with ``solver="multigrid"`` on each backend, best of ``--repeat`` after a
warm-up. A row gives the solve's seconds (``info["solve_seconds"]``: upload to download on the
GPU), its V-cycles and conjugate-gradient iterations, its guaranteed bound, and the largest node
distance to the first backend's grid, which must be at most the sum of the two bounds (``ok``).
A backend that is not available here is named with its reason and skipped.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import clothgrid  # noqa: E402
from bench_speed import PIECE, TOL, field_weights  # noqa: E402


def kinds(n: int):
    return (("paper", "paper"), ("uniform", "uniform"), ("smooth field", field_weights(n, "smooth")),
            ("blocks 10:1", field_weights(n, "blocks")), ("blocks 100:1", field_weights(n, "blocks", 100.0)),
            ("blocks 10^4:1", field_weights(n, "blocks", 1e4)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024, 2048])
    ap.add_argument("--backends", nargs="+", default=["cpu", "cuda"])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    base = clothgrid.load_boundary(PIECE)
    backends = []
    for name in args.backends:
        try:
            clothgrid.generate(base.resampled(33, 33), solver="multigrid", backend=name)
            for _, w in kinds(65):
                clothgrid.generate(base.resampled(65, 65), solver="multigrid", backend=name, weights=w)
            backends.append(name)
        except clothgrid.BackendUnavailableError as e:
            print(f"backend {name}: not available here ({e})")
    print(f"machine: {os.cpu_count()} host cores, numpy {np.__version__}, clothgrid {clothgrid.__version__}; "
          f"piece {PIECE.name}, tol 2^-12\n")
    print("| nodes | weights | backend | solve s | V-cycles | CG its | bound | vs first backend |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        b = base.resampled(n, n)
        for what, w in kinds(n):
            first = None
            for name in backends:
                gs = [clothgrid.generate(b, solver="multigrid", backend=name, weights=w) for _ in range(args.repeat)]
                g = min(gs, key=lambda g: g.info["solve_seconds"])
                cg = g.info.get("cg_iterations", 0)
                bound = g.info["error_estimate"]
                ok = "" if bound <= TOL and g.info["converged"] else " NOT CONVERGED"
                if first is None:
                    first, vs = g, ""
                else:
                    d = float(np.max(np.linalg.norm(g.points - first.points, axis=-1))) / b.size
                    vs = f"{d:.1e} {'ok' if d <= bound + first.info['error_estimate'] else 'OVER THE BOUNDS'}"
                print(f"| {n}^2 | {what} | {name} | {g.info['solve_seconds']:.4g} | {g.info['iterations'] - cg} | "
                      f"{cg} | {bound:.2g}{ok} | {vs} |", flush=True)


if __name__ == "__main__":
    main()
