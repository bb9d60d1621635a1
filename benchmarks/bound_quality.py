"""How far each a-posteriori error bound is from the true error after a few multigrid cycles.

    python benchmarks/bound_quality.py [--size 513] [--cycles 1 2 3] [--weights paper uniform smooth]

For the bundled T-shirt front and every classic region with corners in ``../shared/regions``
(resampled to ``size x size``), paper and uniform weights (and ``smooth``: per-edge weights, the
paper's times ``exp(sin 6u cos 5v)``): the multigrid solve stopped after 1, 2,
3 V-cycles, its true error against SciPy's sparse direct solve, and two bounds on it, both
relative to the piece's size: ``max|s| max z`` and the band barriers' bound
(``solvers/bounds.py``), and for per-edge weights the residual solve's
(``solvers.multigrid._residual_solve_bound``, asked for a tenth of the band barriers' bound). Prints one
row per piece, weights and cycle count, then the spread of the ratios bound / true error. Every
bound must be at least the true error; the script fails otherwise.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import clothgrid
from clothgrid.backends import get_backend
from clothgrid.backends._cpu_multigrid import CpuMultigrid
from clothgrid.initial import initial_grid
from clothgrid.solvers import Problem, solve
from clothgrid.solvers import multigrid
from clothgrid.solvers.bounds import _analytic_barrier_max
from clothgrid.weights import Weights, make_weights

ROOT = Path(__file__).resolve().parents[1]
PIECE = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"
REGIONS = ROOT.parent / "shared" / "regions"


def pieces() -> list[Path]:
    found = [p for p in sorted(REGIONS.glob("*.json")) if "corners" in json.loads(p.read_text())]
    return [PIECE] + found


def smooth_field(n: int) -> Weights:
    """Per-edge weights: the paper's times ``exp(sin 6u cos 5v)`` (``bench_speed.py``'s smooth field)."""
    pw = make_weights("paper", n, n)
    u, v = np.arange(n)[:, None] / n, np.arange(n)[None, :] / n
    f = np.exp(np.sin(6 * u) * np.cos(5 * v))
    return Weights(pw.wu * 0.5 * (f[:-1] + f[1:]), pw.wv * 0.5 * (f[:, :-1] + f[:, 1:]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=513)
    ap.add_argument("--cycles", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--weights", nargs="+", default=["paper", "uniform"], choices=["paper", "uniform", "smooth"])
    args = ap.parse_args()
    n, cpu = args.size, get_backend("cpu")
    ratios: dict[str, list[float]] = {"max step": [], "band barriers": [], "residual solve": []}
    print(f"| piece | weights | V-cycles | true error | max|s| max z (x true) | band barriers (x true) | "
          f"residual solve (x true) |")
    print("|---|---|---|---|---|---|---|")
    plain_steps = CpuMultigrid.band_steps
    for path in pieces():
        b = clothgrid.load_boundary(path).resampled(n, n)
        r = initial_grid(b, "tfi")
        for weights in args.weights:
            w = smooth_field(n) if weights == "smooth" else make_weights(weights, n, n)
            exact = solve(Problem(r.copy(), w, b.size), "direct", backend=cpu, tol=2.0**-12)[1].points
            for cycles in args.cycles:
                row = {}
                for method in ("band barriers", "max step"):
                    if method == "max step":
                        CpuMultigrid.band_steps = lambda self, barriers: None
                    try:
                        res = solve(Problem(r.copy(), w, b.size), "multigrid", backend=cpu, tol=1e-30,
                                    max_iter=cycles)[1]
                    finally:
                        CpuMultigrid.band_steps = plain_steps
                    # per-edge weights drop the band barriers where they gain nothing at a measure
                    assert res.extra["bound_method"] == method or weights == "smooth"
                    err = float(np.linalg.norm(res.points - exact, axis=-1).max()) / b.size
                    if err > res.error_estimate:
                        print(f"{path.stem} {weights} {cycles}: bound {res.error_estimate:.3g} below the true "
                              f"error {err:.3g}", file=sys.stderr)
                        return 1
                    row[method] = (err, res.error_estimate)
                err = row["band barriers"][0]
                rs = "n/a"
                if not w.unit_stencil:      # the residual solve's bound of the same iterate
                    ops = cpu.multigrid(multigrid.build_hierarchy(w), np.ascontiguousarray(res.points))
                    # asked to reach a tenth of the band bound: its floor eps D then adds about 1 % of that
                    _, bound = multigrid._residual_solve_bound(ops, 0.1 * row["band barriers"][1] * b.size,
                                                               _analytic_barrier_max(n, n))
                    bound /= b.size
                    if err > bound:
                        print(f"{path.stem} {weights} {cycles}: residual solve bound {bound:.3g} below the true "
                              f"error {err:.3g}", file=sys.stderr)
                        return 1
                    row["residual solve"] = (err, bound)
                    rs = f"{bound:.2e} ({bound / err:.1f}x)" if np.isfinite(bound) else "not met"
                for method, (e, bound) in row.items():
                    if np.isfinite(bound):
                        ratios[method].append(bound / e)
                print(f"| {path.stem} | {weights} | {cycles} | {err:.2e} | {row['max step'][1]:.2e} "
                      f"({row['max step'][1] / row['max step'][0]:.0f}x) | {row['band barriers'][1]:.2e} "
                      f"({row['band barriers'][1] / err:.0f}x) | {rs} |", flush=True)
    for method, rs in ratios.items():
        if rs:
            print(f"{method}: bound / true error {min(rs):.1f} to {max(rs):.0f}x, median {np.median(rs):.1f}x "
                  f"({len(rs)} solves)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
