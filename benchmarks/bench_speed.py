"""Issue 16: how close the CPU path runs to its floor, everything measured in this one run.

    python benchmarks/bench_speed.py                 # 1024^2 (and the CLI at 1024^2)
    python benchmarks/bench_speed.py --sizes 256     # a quick run
    python benchmarks/bench_speed.py --sizes 256 1024 --repeat 3 --no-direct

For each size (the bundled T-shirt front, resampled to ``n x n``, ``tol = 2^-12``) it prints:

- **floor**: one fused Numba Jacobi sweep over x, y, z (``backends/_cpu_kernels._sweep``), the
  least a solver can do per pass over the grid (best of ``--sweeps`` runs);
- the multigrid solve (``info["solve_seconds"]``) to the true bound: paper and uniform weights, and
  per-edge weights (four a node: a smooth field, and blocks of 10:1 jumps) including their
  barrier solve;
- SciPy's sparse direct solve of the same grid (the baseline the issue's ratios use);
- two more baselines in the same run: PyAMG's smoothed aggregation (with CG) solving the same
  system to the tolerance (its loosest residual tolerance that meets it, found against the direct
  solution), and the paper's own method, Jacobi sweeps with the paper's stop rule (with its true
  error, which misses the tolerance);
- the whole ``generate`` with ``functional="auto"`` and ``"foldfree"`` against the length solve
  (``foldfree`` only up to ``--foldfree-max``: it relaxes every interior node);
- the whole command ``clothgrid generate BOUNDARY.json --nodes NxN -o grid.npz -q`` as a
  subprocess (interpreter start included), default functional (auto) and ``--functional length``,
  against the floor of any command with a Numba kernel in its path, also in fresh interpreters:
  ``import numpy`` alone, and NumPy and Numba with one cached parallel kernel called once
  (Numba's import, its target context's first refresh and one cache load).

Each row: seconds (best of ``--repeat``), ``x floor`` (seconds / floor) and a ratio to its
baseline (the direct solve, or the length solve for the fold-free rows).

``--cpu-time`` adds rows measured on one thread in CPU time (``time.process_time``): the floor and
the multigrid solve alone (``solvers.solve`` on a fresh copy of the initial grid). On a shared
machine whose load is above its cores, two threads' wall times swing by 2-10x between runs (a
descheduled thread stalls each parallel region), and the floor, one short parallel region,
swings most; one thread's CPU time is the figure that compares across runs.
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
from clothgrid.weights import make_weights

PIECE = Path(__file__).resolve().parents[1] / "src" / "clothgrid" / "data" / "tshirt_front.json"
TOL = 2.0**-12


def best(fn, repeat: int):
    out, t_best = None, np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        t_best = min(t_best, time.perf_counter() - t)
    return out, t_best


def sweep_floor(b, n: int, sweeps: int) -> float:
    from clothgrid.backends._cpu_kernels import _sweep
    from clothgrid.initial import initial_grid

    w = make_weights("paper", n, n)
    wu, wv = np.ascontiguousarray(w.wu), np.ascontiguousarray(w.wv)
    r = initial_grid(b, "tfi")
    out = r.copy()
    _sweep(r, out, wu, wv)   # compile / load
    return best(lambda: _sweep(r, out, wu, wv), sweeps)[1]


def cpu_rows(b, n: int, repeat: int, sweeps: int, row) -> None:
    """The floor and the multigrid solves on one thread, in CPU time (``--cpu-time``)."""
    import numba

    from clothgrid.backends import get_backend
    from clothgrid.backends._cpu_kernels import _sweep
    from clothgrid.initial import initial_grid
    from clothgrid.solvers import Problem, solve

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        w = make_weights("paper", n, n)
        wu, wv = np.ascontiguousarray(w.wu), np.ascontiguousarray(w.wv)
        r = initial_grid(b, "tfi")
        out = r.copy()
        _sweep(r, out, wu, wv)

        def cpu(fn, k):
            ts = []
            for _ in range(k):
                t = time.process_time()
                res = fn()
                ts.append(time.process_time() - t)
            return res, min(ts)

        floor = cpu(lambda: _sweep(r, out, wu, wv), sweeps)[1]
        row("floor, 1 thread, CPU time", floor, "1 (floor)", floor)
        for weights in ("paper", "uniform"):
            ww = make_weights(weights, n, n)
            res, sec = cpu(lambda: solve(Problem(r.copy(), ww, b.size, overwrite=True), "multigrid",
                                         backend=get_backend("cpu"), tol=TOL)[1], repeat)
            row(f"multigrid solve, {weights} weights, 1 thread, CPU time (bound {res.error_estimate:.2g}, "
                f"{res.iterations} V-cycles)", sec, "", floor)
    finally:
        numba.set_num_threads(threads)


MEMORY_CHILD = """
import sys, time
import clothgrid
base = clothgrid.load_boundary(sys.argv[1])
n, kind = int(sys.argv[2]), sys.argv[3]
if kind == "paper":
    weights = "paper"
else:   # per-edge weights, made before the baseline is read (the caller's arrays, not the solve's)
    sys.path.insert(0, sys.argv[4])
    from bench_speed import field_weights
    weights = field_weights(n, kind)
    clothgrid.generate(base.resampled(33, 33), solver="multigrid", weights=field_weights(33, kind))
clothgrid.generate(base.resampled(33, 33), solver="multigrid")      # imports and kernels, not per node
def status(key):
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith(key))
before = status("VmRSS")
t = time.perf_counter()
g = clothgrid.generate(base, nodes=(n, n), solver="multigrid", weights=weights)
wall = time.perf_counter() - t
# VmHWM, this process's own high-water mark: getrusage's ru_maxrss keeps the parent's resident size at
# the fork across exec (a parent that had held 2 GB made a 0.85 GB child read 2.1 GB)
peak = status("VmHWM")
i = g.info
print(wall, i["solve_seconds"], i["iterations"], i["error_estimate"], peak, before, i["memory_estimate"],
      i.get("setup_seconds", 0.0), i.get("cycle_seconds", 0.0), i.get("download_seconds", 0.0))
"""


def memory_row(piece: Path, n: int, kind: str = "paper") -> None:
    """``generate`` at ``n x n`` in a fresh process: time, peak resident memory, the estimate (``--memory``);
    ``kind`` the weights: ``paper``, or per-edge ``smooth`` or ``blocks`` (:func:`field_weights`)."""
    out = subprocess.run([sys.executable, "-c", MEMORY_CHILD, str(piece), str(n), kind, str(Path(__file__).parent)],
                         check=True, capture_output=True, text=True).stdout.split()
    wall, solve, cycles, bound, peak, before, est, setup, cyc, down = (float(x) for x in out)
    what = "paper weights" if kind == "paper" else f"four weights a node ({kind})"
    print(f"| {n}^2 | generate, {what}, fresh process: {wall:.2f} s (solve {solve:.2f} s: set-up {setup:.2f}, "
          f"{cycles:.0f} V-cycles {cyc:.2f}, download {down:.2f}; bound {bound:.2g}); peak resident {peak / 1e9:.3f} GB, {(peak - before) / 1e9:.3f} GB above the "
          f"interpreter's; estimate {est / 1e9:.3f} GB ({(est / (peak - before) - 1) * 100:+.0f} %) | {solve:.3g} | | |",
          flush=True)


def pyamg_row(b, n: int, ref, row, direct: float | None) -> None:
    """PyAMG (smoothed aggregation, as a CG preconditioner) on the same system and weights, in the same run.

    Each active coordinate is solved to a relative residual ``rtol``; with the direct solution at
    hand the loosest ``rtol`` in 1e-4 .. 1e-10 whose true error is within ``TOL`` is found first
    (an oracle PyAMG itself does not have), and that run is timed: set-up (the hierarchy) and
    solve, best of 3 up to 512^2, else that one run (about 25 s at 1024^2). Without the direct
    solution, ``rtol = 1e-8``.
    """
    try:
        import pyamg
    except ImportError:
        print(f"| {n}^2 | PyAMG: not installed (pip install pyamg, or the bench extra) | | | |", flush=True)
        return
    from clothgrid.initial import initial_grid
    from clothgrid.solvers import Problem

    problem = Problem(initial_grid(b, "tfi"), make_weights("paper", n, n), b.size)
    A = problem.interior_matrix().tocsr()
    rhs = problem.interior_rhs().reshape(-1, 3)
    coords = problem.active_coords

    def run(rtol: float):
        ml = pyamg.smoothed_aggregation_solver(A)
        y = np.zeros_like(rhs)
        for c in coords:
            y[:, c] = ml.solve(rhs[:, c], tol=rtol, accel="cg", maxiter=500)
        return problem.with_interior(y.reshape(n - 2, n - 2, 3))

    def error(points) -> float:
        return float(np.max(np.linalg.norm(points - ref.points, axis=-1))) / b.size

    rtol, points, sec = 1e-8, None, None
    if ref is not None:
        for rtol in (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
            points, sec = best(lambda: run(rtol), 1)
            if error(points) <= TOL:
                break
    if n <= 512 or points is None:
        points, sec = best(lambda: run(rtol), 3)
    err = f", true error {error(points):.2g}" if ref is not None else ""
    row(f"PyAMG {pyamg.__version__} smoothed aggregation + CG, paper weights, rtol {rtol:g}{err} (set-up and solve)",
        sec, f"direct / this {direct / sec:.2g}x" if direct else "")


def paper_jacobi_row(b, n: int, ref, row, direct: float | None) -> None:
    """The paper's method: Jacobi sweeps (eq. 3) with the paper's stop rule, paper weights, and its true error."""
    g = clothgrid.generate(b, solver="jacobi", stop="paper", weights="paper")
    err = (f", true error {float(np.max(np.linalg.norm(g.points - ref.points, axis=-1))) / b.size:.2g}"
           if ref is not None else "")
    sec = g.info["solve_seconds"]
    row(f"Jacobi, the paper's stop rule ({g.info['iterations']} sweeps{err}: not the tolerance)", sec,
        f"direct / this {direct / sec:.0f}x" if direct else "")


def field_weights(n: int, kind: str, contrast: float = 10.0):
    """Per-edge weights (the paper's "four weights a node"): the paper's times a smooth field, or
    times 8 x 8 blocks alternating ``contrast`` and 1 (coefficient jumps, where semi-coarsening's
    linear interpolation converges at about 0.5 a cycle at 10:1 instead of 0.05-0.15, and stalls at
    100:1 and 10^4:1: the solve goes on with conjugate gradients)."""
    from clothgrid.weights import Weights

    pw = make_weights("paper", n, n)
    u = np.arange(n)[:, None] / n
    v = np.arange(n)[None, :] / n
    if kind == "smooth":
        f = np.exp(np.sin(6 * u) * np.cos(5 * v))
    else:
        f = np.where((np.floor(8 * u) + np.floor(8 * v)) % 2 == 0, contrast, 1.0)
    return Weights(pw.wu * 0.5 * (f[:-1] + f[1:]), pw.wv * 0.5 * (f[:, :-1] + f[:, 1:]))


def cli_time(piece: Path, n: int, repeat: int, extra: list[str]) -> float:
    exe = Path(sys.executable).with_name("clothgrid")
    head = [str(exe)] if exe.exists() else [sys.executable, "-m", "clothgrid"]
    with tempfile.TemporaryDirectory() as tmp:
        cmd = head + ["generate", str(piece), "--nodes", f"{n}x{n}", "-q", "-o", str(Path(tmp) / "g.npz"), *extra]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)   # warm the disk cache and Numba's cache
        return best(lambda: subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL), repeat)[1]


NUMBA_FLOOR = """
import numba, numpy as np
@numba.njit(cache=True, parallel=True)
def total(a):
    s = 0.0
    for i in numba.prange(a.shape[0]):
        s += a[i]
    return s
total(np.ones(8))
"""


def command_floor(repeat: int) -> tuple[float, float]:
    """The start of any command that runs a Numba kernel, in fresh interpreters: ``import numpy``
    alone, and NumPy and Numba with one cached parallel kernel called once (the kernel compiled and
    cached by a first run): Numba's import, its target context's first refresh and one cache load.
    Best of ``repeat`` each."""
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "numba_floor.py"
        script.write_text(NUMBA_FLOOR)
        subprocess.run([sys.executable, str(script)], check=True)   # compile and cache
        numpy_only = best(lambda: subprocess.run([sys.executable, "-c", "import numpy"], check=True), repeat)[1]
        numba_one = best(lambda: subprocess.run([sys.executable, str(script)], check=True), repeat)[1]
    return numpy_only, numba_one


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piece", type=Path, default=PIECE)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sweeps", type=int, default=20)
    ap.add_argument("--foldfree-max", type=int, default=256)
    ap.add_argument("--no-direct", action="store_true", help="skip SciPy's direct solve (ratios then n/a)")
    ap.add_argument("--no-cli", action="store_true")
    ap.add_argument("--no-baselines", action="store_true", help="skip the PyAMG and paper's-Jacobi rows")
    ap.add_argument("--cpu-time", action="store_true", help="also one thread's CPU time: floor and solves")
    ap.add_argument("--only-solves", action="store_true", help="skip the generate, fold-free and CLI rows")
    ap.add_argument("--memory", type=int, nargs="*", default=[], metavar="N",
                    help="also generate at N x N in a fresh process: peak resident memory against the estimate")
    ap.add_argument("--memory-weights", nargs="*", default=["paper"], choices=["paper", "smooth", "blocks"],
                    help="the weights of the --memory rows (default paper)")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, Python {sys.version.split()[0]}, numpy {np.__version__}, "
          f"clothgrid {clothgrid.__version__}, load {os.getloadavg()[0]:.2f}; piece {args.piece.name}\n")
    base = clothgrid.load_boundary(args.piece)
    clothgrid.generate(base.resampled(33, 33), solver="multigrid")          # load the kernels
    clothgrid.generate(base.resampled(33, 33), functional="auto")
    print("| nodes | what | seconds | x floor | ratio |")
    print("|---|---|---|---|---|")
    for n in args.sizes:
        b = base.resampled(n, n)
        floor = sweep_floor(b, n, args.sweeps)

        def row(what: str, sec: float, ratio: str = "", base: float | None = None) -> None:
            print(f"| {n}^2 | {what} | {sec:.4g} | {sec / (base or floor):.1f} | {ratio} |", flush=True)

        row("floor: one fused Jacobi sweep (x, y, z, Numba)", floor, "1 (floor)")
        direct = ref = None
        if not args.no_direct:
            ref = clothgrid.generate(b, solver="direct")
            direct = ref.info["solve_seconds"]
            row("SciPy sparse direct solve", direct, "1 (baseline)")
        if not args.no_baselines:
            pyamg_row(b, n, ref, row, direct)
            paper_jacobi_row(b, n, ref, row, direct)
        for weights, what in (("paper", "paper weights"), ("uniform", "uniform weights"),
                              (field_weights(n, "smooth"), "four weights a node: paper x a smooth field e^(sin 6u cos 5v)"),
                              (field_weights(n, "blocks"), "four weights a node: paper x 8x8 blocks of 10:1"),
                              (field_weights(n, "blocks", 100.0), "four weights a node: paper x 8x8 blocks of 100:1"),
                              (field_weights(n, "blocks", 1e4), "four weights a node: paper x 8x8 blocks of 10^4:1")):
            g, _ = best(lambda: clothgrid.generate(b, solver="multigrid", weights=weights), args.repeat)
            times = [clothgrid.generate(b, solver="multigrid", weights=weights).info["solve_seconds"]
                     for _ in range(args.repeat)]
            sec = min(times + [g.info["solve_seconds"]])
            ok = "" if g.info["error_estimate"] <= TOL else " NOT CONVERGED"
            cg = g.info.get("cg_iterations")
            how = f"{g.info['iterations']} V-cycles" if cg is None else \
                f"{g.info['iterations'] - cg} V-cycles, {cg} conjugate-gradient iterations"
            row(f"multigrid solve, {what} (bound {g.info['error_estimate']:.2g}{ok}, {how})", sec,
                f"direct / this {direct / sec:.0f}x" if direct else "")
        if args.cpu_time:
            cpu_rows(b, n, args.repeat, args.sweeps, row)
        if args.only_solves:
            continue
        # the fold-free rows use the command line's default weights (uniform): with the paper's, the
        # T-shirt front folds 6864 cells at 1024^2 and relax untangles every interior node (7 s)
        length, t_len = best(lambda: clothgrid.generate(b, weights="uniform"), args.repeat)
        row(f"generate, uniform weights, functional length (solver {length.info['solver']})", t_len, "1 (fold-free baseline)")
        for fun in ("auto", "foldfree"):
            if fun == "foldfree" and n > args.foldfree_max:
                continue
            # best of --repeat like every other row (auto, 0.1-0.2 s at 1024^2: a single call there
            # measured the first loads of the parallel kernels, 0.17 s against 0.09-0.10 s); foldfree,
            # which relaxes every node, once above 512^2
            g, t = best(lambda: clothgrid.generate(b, weights="uniform", functional=fun),
                        1 if n > 512 and fun == "foldfree" else args.repeat)
            ff = g.info.get("foldfree") or g.info.get("relax") or {}
            row(f"generate, uniform weights, functional {fun} ({g.info.get('folded_before')} -> {g.info.get('folded')} folded, "
                f"{ff.get('moved', 0)} nodes moved, {ff.get('sweeps', 0)} sweeps)", t,
                f"{t / t_len:.2f}x length; the step itself {(t - t_len) / t_len:.2f}x")
        if not args.no_cli:
            numpy_only, numba_one = command_floor(max(args.repeat, 3))
            row("command floor: fresh interpreter, `import numpy`", numpy_only, "")
            row("command floor: fresh interpreter, NumPy and Numba, one cached parallel kernel", numba_one,
                "1 (the command's floor with Numba in its path)")
            for extra, what in (([], "default (functional auto)"), (["--functional", "length"], "functional length")):
                sec = cli_time(args.piece, n, args.repeat if n <= 512 or extra else 1, extra)
                row(f"`clothgrid generate ... -o g.npz`, {what}, subprocess", sec,
                    f"{sec / numba_one:.2f}x the Numba floor" + (f"; direct / this {direct / sec:.1f}x" if direct else ""))
    for kind in args.memory_weights:
        for n in args.memory:
            memory_row(args.piece, n, kind)
    print(f"\nload at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
