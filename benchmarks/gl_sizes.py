"""The gl backend's multigrid by grid size, next to the CPU's: cycles, time, bound and true error.

Run ``python benchmarks/gl_sizes.py [--sizes 256 512 1024 2048] [--piece FILE]``.

In-process ``generate`` calls (after one small warm-up solve per backend, so that shader
compilation and Numba's start-up are not counted), the T-shirt front with the paper's
weights, tol = 2^-12, init ``tfi``. The true max node error is measured against an exact
solve (``solver="fdm"``), relative to the piece's size. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

import clothgrid
from clothgrid.backends import gl

PIECE = Path(__file__).resolve().parents[1] / "src" / "clothgrid" / "data" / "tshirt_front.json"
TOL = 2.0**-12


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piece", type=Path, default=PIECE)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024, 2048])
    args = ap.parse_args()
    base = clothgrid.load_boundary(args.piece)
    for backend in ("gl", "cpu"):
        clothgrid.generate(base, (33, 33), backend=backend, solver="multigrid")
    print(f"device: {gl.summary()}; {os.cpu_count()} cores\n")
    print("| nodes | gl: cycles | gl: seconds | cpu multigrid: seconds | bound reported | true error |")
    print("|---|---|---|---|---|---|")
    for n in args.sizes:
        b = base.resampled(n, n)
        t0 = time.perf_counter()
        g = clothgrid.generate(b, backend="gl", solver="multigrid", tol=TOL)
        t_gl = time.perf_counter() - t0
        t0 = time.perf_counter()
        clothgrid.generate(b, backend="cpu", solver="multigrid", tol=TOL)
        t_cpu = time.perf_counter() - t0
        exact = clothgrid.generate(b, solver="fdm", tol=1e-9).points
        err = np.linalg.norm(g.points - exact, axis=-1).max() / b.size
        print(f"| {n}x{n} | {g.info['iterations']} | {t_gl:.2f} | {t_cpu:.2f} | {g.info['error_estimate']:.2e} "
              f"| {err:.2e} |", flush=True)
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
