"""``clothgrid generate --backend gl`` at 1024 x 1024: wall time, accuracy, and where the time goes.

Run ``python benchmarks/gl_generate.py [--nodes 1024] [--runs 3] [--piece FILE]``.

1. The command of issue 3's bar, as a subprocess, ``--runs`` times::

       clothgrid generate src/clothgrid/data/tshirt_front.json --nodes 1024x1024 \\
           --weights paper --backend gl -o /tmp/.../g.npz

   (solver ``auto`` is ``multigrid`` on the gl backend, ``tol`` 2^-12, ``stop`` error),
   timed from the outside, with its own timing line.
2. The grid written is checked against an exact solve (``solver="fdm"``): the true max
   node error relative to the piece's size, against the bound the command reported.
3. The same pipeline in-process, step by step, with the GL queue drained (``finish``)
   after every multigrid operation so that each step's time is its own: the breakdown.
   Draining costs a little, so the steps add up to slightly more than an undisturbed run.

The machine's load is printed with the results (``os.getloadavg``): on a shared machine
other jobs' load slows llvmpipe, which runs on the CPU cores.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PIECE = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"
TOL = 2.0**-12


def cli_runs(piece: Path, n: int, runs: int, out: Path) -> list[float]:
    cmd = [sys.executable, "-m", "clothgrid", "generate", str(piece), "--nodes", f"{n}x{n}",
           "--weights", "paper", "--backend", "gl", "-o", str(out)]
    print("command: clothgrid " + " ".join(cmd[3:]).replace(str(out), "g.npz").replace(str(ROOT) + "/", ""))
    times = []
    for r in range(runs):
        u0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        res = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        u1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (u1.ru_utime - u0.ru_utime) + (u1.ru_stime - u0.ru_stime)
        if res.returncode != 0:
            sys.exit(f"command failed ({res.returncode}):\n{res.stderr}")
        line = next((s for s in res.stdout.splitlines() if s.startswith("solver ")), "")
        print(f"  run {r + 1}: {wall:.2f} s wall, {cpu:.2f} s CPU (all threads), load {os.getloadavg()[0]:.2f}; "
              f"{line}")
        times.append(wall)
    return times


class _Timed:
    """A GLMultigrid whose every operation is drained and timed."""

    def __init__(self, ops, times, cpu):
        self.ops, self.times, self.cpu, self.levels = ops, times, cpu, ops.levels
        self.ctx = ops.dev.ctx

    def _call(self, name, *args, key=None):
        """``ops.name(*args)``, drained, its time counted under ``key`` (default ``name``)."""
        key = key or name
        t0, c0 = time.perf_counter(), time.process_time()
        out = getattr(self.ops, name)(*args)
        if key != "solution":
            self.ctx.finish()
        self.times[key] += time.perf_counter() - t0
        self.cpu[key] += time.process_time() - c0
        self.times["n_" + key] += 1
        return out

    def smooth(self, level, reverse=False):
        return self._call("smooth", level, reverse)

    def restrict(self, level):
        return self._call("restrict", level)

    def prolong(self, level):
        return self._call("prolong", level)

    def max_step(self):
        return self._call("max_step")

    def solution(self):
        return self._call("solution")

    # The rest of MultigridOps (clothgrid.backends.protocol): the full-multigrid start's passes
    # count as restriction and prolongation, the download as the solution.
    def restrict_full(self, level):
        return self._call("restrict_full", level, key="restrict")

    def prolong_full(self, level):
        return self._call("prolong_full", level, key="prolong")

    def solution_into(self, out):
        return self._call("solution_into", out, key="solution")

    def synchronize(self):
        self.ops.synchronize()

    def extra(self):
        return self.ops.extra()


def _clock() -> tuple[float, float]:
    """(wall, CPU of this process's threads, llvmpipe's included)."""
    return time.perf_counter(), time.process_time()


def breakdown(piece: Path, n: int, out: Path) -> None:
    steps: list[tuple[str, float, float]] = []

    def step(name, t0):
        now = _clock()
        steps.append((name, now[0] - t0[0], now[1] - t0[1]))
        return _clock()

    t = _clock()
    u0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", "import clothgrid.cli, clothgrid.generate"], check=True)
    u1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.perf_counter() - t[0]
    steps.append(("Python start-up and imports (a fresh interpreter)", wall,
                  u1.ru_utime - u0.ru_utime + u1.ru_stime - u0.ru_stime))
    t = _clock()
    import clothgrid
    from clothgrid.backends import gl
    from clothgrid.backends.gl import _device
    from clothgrid.backends.gl._multigrid import GLMultigrid
    from clothgrid.initial import initial_grid
    from clothgrid.quality import quality
    from clothgrid.solvers import Problem
    from clothgrid.solvers.multigrid import build_hierarchy, solve_multigrid
    from clothgrid.weights import make_weights
    from clothgrid.grid import Grid

    t = _clock()
    dev = _device.device()
    t = step(f"EGL context ({dev.renderer})", t)
    clothgrid.generate(clothgrid.load_boundary(piece), (5, 5), backend="gl")
    clothgrid.generate(clothgrid.load_boundary(piece), (5, 5), backend="gl", solver="jacobi")
    t = step("first (5x5) solves: shader compile at the first draw (Mesa's disk cache), "
             "Numba kernels of the hierarchy loaded", t)
    b = clothgrid.load_boundary(piece).resampled(n, n)
    t = step("load the piece and resample its sides", t)
    gl.check_size(n, n, "multigrid")
    t = step("size check (texture limit, free memory, probe texture)", t)
    r0 = initial_grid(b, "tfi")
    w = make_weights("paper", n, n)
    problem = Problem(r0, w, b.size)
    t = step("initial grid (tfi, eq. 4) and weights (eq. 2)", t)
    levels = build_hierarchy(w)
    t = step(f"multigrid hierarchy on the CPU ({len(levels)} levels, Galerkin operators)", t)

    times: dict = defaultdict(float)
    cpu: dict = defaultdict(float)

    def make(levels_, x0, rhs=None):
        t0 = _clock()
        ops = GLMultigrid(levels_, x0, rhs)
        dev.ctx.finish()
        times["upload"] += time.perf_counter() - t0[0]
        cpu["upload"] += time.process_time() - t0[1]
        return _Timed(ops, times, cpu)

    proxy = SimpleNamespace(name="gl", multigrid=make)
    build = [levels]
    import clothgrid.solvers.multigrid as mgmod

    real_build = mgmod.build_hierarchy
    mgmod.build_hierarchy = lambda weights, *a, **k: build[0]   # reuse the hierarchy timed above
    try:
        t = _clock()
        result = solve_multigrid(problem, backend=proxy, tol=TOL)
        total = (time.perf_counter() - t[0], time.process_time() - t[1])
    finally:
        mgmod.build_hierarchy = real_build
    keys = ("upload", "smooth", "restrict", "prolong", "max_step", "solution")
    names = ("textures: upload, Thomas factors, first float64 residual",
             f"line smoothing: {times['n_smooth']:.0f} zebra sweeps (compute shaders)",
             f"restriction: {times['n_restrict']:.0f} times (fragment shaders)",
             f"prolongation: {times['n_prolong']:.0f} times (fragment shader)",
             f"float64 fold, residual and max-reduction: {times['n_max_step']:.0f} times",
             "download the float64 grid")
    for key, name in zip(keys, names):
        steps.append((name, times[key], cpu[key]))
    steps.append(("solver bookkeeping (Python)", total[0] - sum(times[k] for k in keys),
                  total[1] - sum(cpu[k] for k in keys)))
    t = _clock()
    grid = Grid.from_points(result.points, info={}, dim=b.dim)
    q = quality(grid)
    t = step("quality table", t)
    grid.save(out)
    t = step("write the NPZ", t)
    print(f"\nin-process breakdown ({result.iterations} V-cycles, error bound {result.error_estimate:.2e}, "
          f"load {os.getloadavg()[0]:.2f}):\n")
    print("| step | wall s | CPU s (all threads) |")
    print("|---|---|---|")
    for name, secs, cpus in steps:
        print(f"| {name} | {secs:.3f} | {cpus:.3f} |")
    print(f"| **total** | **{sum(s[1] for s in steps):.3f}** | **{sum(s[2] for s in steps):.3f}** |")
    del q


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piece", type=Path, default=PIECE)
    ap.add_argument("--nodes", type=int, default=1024)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "g.npz"
        print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
        times = cli_runs(args.piece, args.nodes, args.runs, out)
        print(f"wall time: best {min(times):.2f} s, median {float(np.median(times)):.2f} s, worst {max(times):.2f} s")

        import clothgrid

        data = np.load(out)
        import json

        info = json.loads(str(data["info"]))
        b = clothgrid.load_boundary(args.piece).resampled(args.nodes, args.nodes)
        exact = clothgrid.generate(b, solver="fdm", tol=1e-9).points
        err = float(np.linalg.norm(data["points"] - exact, axis=-1).max() / b.size)
        print(f"true max error {err:.2e} of the piece's size (tol {TOL:.2e}); bound reported "
              f"{info['error_estimate']:.2e}; renderer {info.get('gl_renderer')}")
        breakdown(args.piece, args.nodes, Path(tmp) / "h.npz")


if __name__ == "__main__":
    main()
