"""The residual solve's bound against the barrier solve and band barriers, per-edge weights, one process.

    python benchmarks/bench_residual_solve.py                       # 1024^2, smooth field and 10:1 blocks
    python benchmarks/bench_residual_solve.py --sizes 1024 2048 --repeat 7
    python benchmarks/bench_residual_solve.py --sizes 4096 --repeat 1 --kinds smooth
    python benchmarks/bench_residual_solve.py --backend cuda --sizes 1024 2048 4096 --kinds smooth   # on a GPU

For each size (the bundled T-shirt front resampled to ``n x n``, ``tol = 2^-12``) and per-edge field
(``bench_speed.field_weights``: the paper's weights times ``e^(sin 6u cos 5v)``, or 8 x 8 blocks of
10:1), ``clothgrid.generate`` with the multigrid solver runs with
``solvers.multigrid.RESIDUAL_SOLVE_BOUND`` on and off, alternating, in this one process; each column
is the best ``info["solve_seconds"]`` of ``--repeat``, and the ratio is on / off, so the baseline is
measured in the same run as the figure. Also the iterations, the bound and the method it stopped on.
``--backend`` (default cpu) picks where the solves run: the cpu and cuda backends have the residual
solve.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_speed as B  # noqa: E402

import clothgrid  # noqa: E402
import clothgrid.solvers.multigrid as mg  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024])
    ap.add_argument("--kinds", nargs="+", default=["smooth", "blocks"], choices=["smooth", "blocks"])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--backend", default="cpu", choices=["cpu", "cuda", "gl"])
    args = ap.parse_args()
    base = clothgrid.load_boundary(B.PIECE)
    clothgrid.generate(base.resampled(65, 65), solver="multigrid", weights=B.field_weights(65, "smooth"),
                       backend=args.backend)  # warm
    print(f"backend {args.backend}")
    print("| nodes | field | barrier solve + band barriers (s) | residual solve (s) | ratio |")
    print("|---|---|---|---|---|")
    saved = mg.RESIDUAL_SOLVE_BOUND
    try:
        for n in args.sizes:
            b = base.resampled(n, n)
            for kind in args.kinds:
                w = B.field_weights(n, kind)
                best: dict[bool, tuple[float, dict]] = {}
                for _ in range(args.repeat):
                    for flag in (True, False):
                        mg.RESIDUAL_SOLVE_BOUND = flag
                        g = clothgrid.generate(b, solver="multigrid", weights=w, backend=args.backend)
                        s = g.info["solve_seconds"]
                        if flag not in best or s < best[flag][0]:
                            best[flag] = (s, g.info)

                def cell(flag: bool) -> str:
                    s, info = best[flag]
                    return (f"{s:.4g} ({info['iterations']} iterations, {info['bound_method']}, "
                            f"bound {info['error_estimate']:.2g})")

                field = "paper x e^(sin 6u cos 5v)" if kind == "smooth" else "paper x 8x8 blocks of 10:1"
                print(f"| {n}^2 | {field} | {cell(False)} | {cell(True)} | "
                      f"{best[True][0] / best[False][0]:.2f} |", flush=True)
    finally:
        mg.RESIDUAL_SOLVE_BOUND = saved
    return 0


if __name__ == "__main__":
    sys.exit(main())
