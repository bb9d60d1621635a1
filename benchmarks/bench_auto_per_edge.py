"""Where ``solver="auto"`` should switch from the direct solve to multigrid for per-edge weights.

    python benchmarks/bench_auto_per_edge.py
    python benchmarks/bench_auto_per_edge.py --sizes 33 65 97 128 181 257 --kinds smooth blocks jumps

For each size (the bundled T-shirt front resampled to ``n x n``, ``tol = 2^-12``) and per-edge field
(``bench_speed.field_weights``: the paper's weights times a smooth field, times 8 x 8 blocks of 10:1, or
of 10^4:1 for ``jumps``), ``clothgrid.generate`` with ``solver="direct"`` and ``solver="multigrid"``,
warm, in this one process; each column is the best ``info["solve_seconds"]`` of ``--repeat``, the ratio
multigrid / direct, and the solver ``auto`` picks (``solvers.choose_solver`` with the weights'
``edge_contrast``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_speed as B  # noqa: E402

import clothgrid  # noqa: E402
from clothgrid.solvers import choose_solver  # noqa: E402
from clothgrid.weights import edge_contrast  # noqa: E402

FIELDS = {"smooth": ("smooth", 10.0), "blocks": ("blocks", 10.0), "jumps": ("blocks", 1e4)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[33, 65, 97, 128, 181, 257])
    ap.add_argument("--kinds", nargs="+", default=list(FIELDS), choices=list(FIELDS))
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    base = clothgrid.load_boundary(B.PIECE)
    print("| nodes | field | contrast | direct (ms) | multigrid (ms) | multigrid / direct | auto |")
    print("|---|---|---|---|---|---|---|")
    for kind in args.kinds:
        for n in args.sizes:
            b = base.resampled(n, n)
            w = B.field_weights(n, *FIELDS[kind])
            best = {}
            for solver in ("direct", "multigrid"):
                clothgrid.generate(b, solver=solver, weights=w)     # warm: the kernels, SciPy
                best[solver] = min(clothgrid.generate(b, solver=solver, weights=w).info["solve_seconds"]
                                   for _ in range(args.repeat))
            c = edge_contrast(w.wu, w.wv)
            print(f"| {n}^2 | {kind} | {c:.3g} | {best['direct'] * 1e3:.1f} | {best['multigrid'] * 1e3:.1f} | "
                  f"{best['multigrid'] / best['direct']:.2f} | {choose_solver(False, n, n, c)} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
