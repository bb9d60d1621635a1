"""Core benchmark: the CLI at 1024 x 1024 and every CPU solver by size.

Run ``python benchmarks/bench_core.py [--sizes 64 128 ...] [--cli-size 1024]``
(or ``make bench``). Everything is timed in this one run on this machine, with
SciPy's sparse direct solve as the baseline and the exact reference: for each
size it prints wall time, the speed ratio against the direct solve, and the
true max error (relative to the piece's bounding-box diagonal).

Part 1 runs ``clothgrid generate`` as a subprocess (Python start-up, loading,
solving, quality table and writing an NPZ included), twice, and checks the
written grid against the direct solve.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import clothgrid
from clothgrid.memory import check_memory

PIECE = Path(__file__).resolve().parents[1] / "src" / "clothgrid" / "data" / "tshirt_front.json"
TOL = 2.0**-12


def max_err(points, ref, scale):
    return float(np.linalg.norm(points - ref, axis=-1).max() / scale)


def timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def cli_part(piece: Path, n: int) -> None:
    print(f"## `clothgrid generate` at {n} x {n}, paper weights, default solver\n")
    exe = Path(sys.executable).with_name("clothgrid")
    cmd = [str(exe) if exe.exists() else sys.executable, *([] if exe.exists() else ["-m", "clothgrid"]),
           "generate", str(piece), "--nodes", f"{n}x{n}", "-q"]
    b = clothgrid.load_boundary(piece).resampled(n, n)
    ref = clothgrid.generate(b, solver="direct")
    base = ref.info["seconds"]
    print(f"SciPy sparse direct solve of the same grid, solve alone: {base:.2f} s\n")
    print("| run | wall time of the whole command (s) | max error / tol | direct solve time / command time |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "grid.npz"
        for run in (1, 2):
            t = time.perf_counter()
            subprocess.run(cmd + ["-o", str(out)], check=True, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - t
            pts = np.load(out)["points"]
            err = max_err(pts, ref.points, b.size)
            print(f"| {run} | {wall:.2f} | {err / TOL:.2e} | {base / wall:.1f}x |")
    print()


def solver_part(piece: Path, sizes: list[int], jacobi_error_max: int) -> None:
    print("## Solvers by size (paper weights, tfi start; times in s, errors relative to the piece)\n")
    print("| nodes | direct | fdm | fdm speed-up | fdm error | jacobi paper rule: sweeps, s, true error "
          "| jacobi error rule: sweeps, s, true error |")
    print("|---|---|---|---|---|---|---|")
    base = clothgrid.load_boundary(piece)
    clothgrid.generate(base.resampled(16, 16), solver="jacobi")  # compile the kernels outside the timings
    for n in sizes:
        b = base.resampled(n, n)
        check_memory("direct", n, n)
        ref, t_direct = timed(lambda: clothgrid.generate(b, solver="direct"))
        fdm, t_fdm = timed(lambda: clothgrid.generate(b, solver="fdm"))
        jp, t_jp = timed(lambda: clothgrid.generate(b, solver="jacobi", stop="paper"))
        row = (f"| {n}x{n} | {t_direct:.3f} | {t_fdm:.3f} | {t_direct / t_fdm:.0f}x | "
               f"{max_err(fdm.points, ref.points, b.size):.1e} | {jp.info['iterations']}, {t_jp:.3f}, "
               f"{max_err(jp.points, ref.points, b.size):.1e} |")
        if n <= jacobi_error_max:
            je, t_je = timed(lambda: clothgrid.generate(b, solver="jacobi", stop="error"))
            row += f" {je.info['iterations']}, {t_je:.2f}, {max_err(je.points, ref.points, b.size):.1e} |"
        else:
            row += " (not run: too slow) |"
        print(row, flush=True)
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piece", type=Path, default=PIECE)
    ap.add_argument("--cli-size", type=int, default=1024)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256, 512, 1024])
    ap.add_argument("--jacobi-error-max", type=int, default=128)
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, Python {sys.version.split()[0]}, numpy {np.__version__}, "
          f"clothgrid {clothgrid.__version__}; piece {args.piece.name}\n")
    cli_part(args.piece, args.cli_size)
    solver_part(args.piece, args.sizes, args.jacobi_error_max)


if __name__ == "__main__":
    main()
