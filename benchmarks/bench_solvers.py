"""Every solver and backend side by side: time, peak memory, true error (issue 4).

    python benchmarks/bench_solvers.py                     # 16 .. 4096 on this machine
    python benchmarks/bench_solvers.py --max 1024 --out /tmp/bench
    python benchmarks/bench_solvers.py --factors           # multigrid convergence factors, 65 .. 4097

Each (solver, backend, size) runs in a fresh subprocess on the bundled T-shirt
front with the paper's weights (eq. 2), ``tol = 2^-12``: the subprocess warms
up (Numba's cached kernels, GL shader compilation) on a 33x33 grid, then times
``clothgrid.generate`` (best of three up to 2048 a side, else once) and reports
its wall time, the solver's own time (``info["solve_seconds"]``), and the
process's peak resident memory (``ru_maxrss``, which includes
the warm-up and the interpreter: ~150 MB). The true error is measured against
an exact reference computed in its own subprocess: SciPy's sparse direct
solve up to ``--direct-max`` nodes a side; above, a grid whose a-posteriori
bound, recomputed from a plain NumPy residual, certifies it within 1e-8 of
the exact solution (see ``reference``). Results go to ``solvers.csv``,
``solvers.md`` and ``solvers.png`` (time against nodes, log-log: the paper's
Fig. 5 redone) in ``--out`` (default ``docs/bench``).

Which runs are made (the rest would take hours or not fit):
direct up to 1024 a side (2048 with ``--direct-max 2048``), Jacobi with the
paper's rule up to 512, Jacobi with the true rule up to 128, fdm up to 4096,
multigrid at every size, gl (multigrid and the paper's Jacobi) where an EGL
context opens, cuda where CuPy finds a GPU.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PIECE = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"

# (label, solver, backend, stop, largest side)
RUNS = [
    ("direct", "direct", "cpu", "error", 1024),
    ("jacobi (paper rule)", "jacobi", "cpu", "paper", 512),
    ("jacobi (true rule)", "jacobi", "cpu", "error", 128),
    ("fdm", "fdm", "cpu", "error", 4096),
    ("multigrid", "multigrid", "cpu", "error", 1 << 20),
    ("gl multigrid", "multigrid", "gl", "error", 2048),
    ("gl jacobi (paper rule)", "jacobi", "gl", "paper", 512),
    ("cuda multigrid", "multigrid", "cuda", "error", 1 << 20),
    ("cuda fdm", "fdm", "cuda", "error", 8192),
]

CHILD = r"""
import json, resource, sys, time
import numpy as np
import clothgrid
from clothgrid import load_boundary
piece, n, solver, backend, stop, out = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5], sys.argv[6]
b = load_boundary(piece)
try:
    for m in (33, 300):  # load every kernel (serial ones for small levels, threaded for large)
        clothgrid.generate(b, (m, m), solver=solver, backend=backend, stop=stop, weights="paper",
                           allow_unconverged=True)
    wall = solve = float("inf")
    for _ in range(3 if n <= 2048 else 1):   # best of three where that is cheap
        t = time.perf_counter()
        g = clothgrid.generate(b, (n, n), solver=solver, backend=backend, stop=stop, weights="paper",
                               allow_unconverged=True)
        wall = min(wall, time.perf_counter() - t)
        solve = min(solve, g.info.get("solve_seconds", wall))
except clothgrid.ClothgridError as e:
    print(json.dumps({"skipped": str(e)}))
    sys.exit(0)
if out != "-":
    np.save(out, g.points)
info = g.info
print(json.dumps({"wall": wall, "solve": solve, "iterations": info["iterations"],
                  "bound": info["error_estimate"], "converged": info["converged"],
                  "factor": info.get("convergence_factor"), "renderer": info.get("gl_renderer") or info.get("cuda_device"),
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def run_child(n: int, solver: str, backend: str, stop: str, out: str, timeout: float) -> dict:
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, str(PIECE), str(n), solver, backend, stop, out],
                           capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    except subprocess.TimeoutExpired:
        return {"skipped": f"over {timeout:.0f} s"}
    if p.returncode != 0:
        tail = (p.stderr.strip().splitlines() or ["?"])[-1]
        return {"skipped": f"failed: {tail}"}
    return json.loads(p.stdout.strip().splitlines()[-1])


CERTIFY = r"""
import sys, numpy as np, clothgrid
from clothgrid import load_boundary
from clothgrid.backends import cpu
from clothgrid.weights import make_weights
b = load_boundary(sys.argv[1]); n = int(sys.argv[2]); out = sys.argv[3]
g = clothgrid.generate(b, (n, n), solver="multigrid", backend="cpu", weights="paper", tol=1e-8)  # never the GPU under test
w = make_weights("paper", n, n)
# the bound recomputed with the plain NumPy residual, independent of the multigrid kernels
h = (n - 1) // 2
bound = cpu.max_step(g.points, w.wu, w.wv) * 2 * h * (n - 1 - h) / b.size
assert bound <= 1e-8, bound
np.save(out, g.points)
print(bound)
"""


def reference(n: int, tmp: Path, direct_max: int) -> Path:
    """SciPy's sparse direct solve; above ``direct_max``, a grid certified within 1e-8.

    Above ``direct_max`` the direct solve does not fit in reasonable time and
    memory (fill-in), and fdm's rounding defeats its refinement at 4096 (its
    own bound says so). The reference is then any grid whose a-posteriori
    bound, recomputed from a plain NumPy float64 residual, is at most 1e-8 of
    the piece's size: by the bound of ``solvers/bounds.py`` it is within 1e-8
    of the exact solution, whatever computed it.
    """
    path = tmp / f"ref_{n}.npy"
    if path.exists():
        return path
    if n <= direct_max:
        r = run_child(n, "direct", "cpu", "error", str(path), timeout=3600)
        if "skipped" in r:
            raise RuntimeError(f"reference at {n}: {r['skipped']}")
    else:
        p = subprocess.run([sys.executable, "-c", CERTIFY, str(PIECE), str(n), str(path)],
                           capture_output=True, text=True, cwd=ROOT)
        if p.returncode != 0:
            raise RuntimeError(f"reference at {n}: {p.stderr.strip()[-300:]}")
        print(f"{n}x{n} reference certified within {float(p.stdout.split()[-1]):.1e}", flush=True)
    return path


def true_error(points_file: Path, ref_file: Path) -> float:
    import numpy as np

    from clothgrid import load_boundary

    size = load_boundary(PIECE).size
    a, b = np.load(points_file), np.load(ref_file)
    return float(np.linalg.norm(a - b, axis=-1).max() / size)


def convergence_factors(sizes: list[int], cycles: int = 10) -> list[dict]:
    """Asymptotic V(1,1) factor from a random error, zero right-hand side."""
    from clothgrid.solvers.multigrid import build_hierarchy, convergence_factor
    from clothgrid.weights import make_weights

    rows = []
    for n in sizes:
        for kind in ("paper", "uniform"):
            w = make_weights(kind, n, n)
            f, ratios = convergence_factor(w, cycles=cycles, seed=n)
            rows.append({"nodes": f"{n}x{n}", "weights": kind, "levels": len(build_hierarchy(w)),
                         "factor": f, "worst": max(ratios[2:])})
            print(f"{n}x{n} {kind}: factor {f:.3f} (worst cycle after the 2nd {rows[-1]['worst']:.3f})", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--min", type=int, default=16)
    ap.add_argument("--max", type=int, default=4096)
    ap.add_argument("--direct-max", type=int, default=1024)
    ap.add_argument("--only", nargs="*", help="labels to run (default: all)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench")
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--factors", action="store_true", help="only measure multigrid's convergence factors")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.factors:
        rows = convergence_factors([65, 129, 257, 513, 1025, 2049, 4097])
        with open(args.out / "factors.md", "w") as f:
            f.write("| nodes | weights | levels | factor (mean of cycles 8-10) | worst cycle 3-10 |\n|---|---|---|---|---|\n")
            for r in rows:
                f.write(f"| {r['nodes']} | {r['weights']} | {r['levels']} | {r['factor']:.3f} | {r['worst']:.3f} |\n")
        return 0
    sizes = []
    n = args.min
    while n <= args.max:
        sizes.append(n)
        n *= 2
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for n in sizes:
            ref = reference(n, tmp, args.direct_max)
            for label, solver, backend, stop, top in RUNS:
                if n > top or (args.only and label not in args.only):
                    continue
                pts = tmp / "pts.npy"
                r = run_child(n, solver, backend, stop, str(pts), args.timeout)
                row = {"solver": label, "nodes": n * n, "side": n}
                if "skipped" in r:
                    row["note"] = r["skipped"]
                    print(f"{n}x{n} {label}: skipped ({r['skipped']})", flush=True)
                    if backend != "cpu":
                        top_note = r["skipped"]
                        RUNS[:] = [x for x in RUNS if x[0] != label]  # unavailable: don't retry
                        print(f"  {label} is unavailable here: {top_note}", flush=True)
                else:
                    row.update(r)
                    row["error"] = true_error(pts, ref)
                    print(f"{n}x{n} {label}: solve {r['solve']:.3f} s, generate {r['wall']:.3f} s, {r['iterations']} it, error {row['error']:.2e} "
                          f"(bound {r['bound']:.2e}), peak {r['peak_mb']:.0f} MB", flush=True)
                results.append(row)
    write(results, args.out)
    return 0


def write(results: list[dict], out: Path) -> None:
    keys = ["solver", "side", "nodes", "wall", "solve", "iterations", "error", "bound", "converged", "peak_mb", "factor",
            "renderer", "note"]
    with open(out / "solvers.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(results)
    by_size: dict[int, dict] = {}
    for r in results:
        by_size.setdefault(r["side"], {})[r["solver"]] = r
    labels = [lab for lab, *_ in RUNS if any(lab in d for d in by_size.values())]
    with open(out / "solvers.md", "w") as f:
        f.write("Solve time in seconds, then the wall time of the whole `generate` call, the true max error "
                "as a fraction of tol, and the peak resident memory.\n\n")
        f.write("| nodes | " + " | ".join(labels) + " |\n|---|" + "---|" * len(labels) + "\n")
        for side in sorted(by_size):
            cells = []
            for lab in labels:
                r = by_size[side].get(lab)
                if r is None:
                    cells.append("")
                elif "wall" not in r:
                    cells.append("n/a")
                else:
                    cells.append(f"{r['solve']:.3g} / {r['wall']:.3g} s, {r['error'] / 2**-12:.2g} tol, "
                                 f"{r['peak_mb']:.0f} MB")
            f.write(f"| {side}x{side} | " + " | ".join(cells) + " |\n")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(7, 5))
    for lab in labels:
        pts = sorted((r["nodes"], r["solve"]) for r in results if r["solver"] == lab and "solve" in r)
        if pts:
            ax.loglog(*zip(*pts), "o-", label=lab)
    ax.set_xlabel("nodes")
    ax.set_ylabel("solve time (s)")
    ax.set_title(f"clothgrid solvers, paper weights, tol 2^-12 ({os.cpu_count()} cores)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "solvers.png", dpi=120)


if __name__ == "__main__":
    sys.exit(main())
