"""The paper's claim on a real GPU (issue 17): cuda and gl solvers against the copy-bandwidth floor.

    python benchmarks/bench_gpu.py                          # 32 .. 16384 on the GPU, tables in docs/bench/gpu
    python benchmarks/bench_gpu.py --min 1024 --max 4096 --out /tmp/gpu
    python benchmarks/bench_gpu.py --methods "cuda multigrid" "cpu multigrid"

Every method runs in its own subprocess on the bundled T-shirt front (2D, so
two coordinates are solved) with the paper's weights (eq. 2) and
``tol = 2^-12``, at every power of two from ``--min`` to ``--max`` nodes a
side (stopping at the first size that does not fit or fails). After a warm-up
(kernel compilation, shader compilation) each size is timed with
``clothgrid.generate``: best of three up to 4096 a side, else once. Columns:

- ``solve``: ``info["solve_seconds"]``, from the upload of the initial grid to
  the solution back in host memory;
- ``cycles``: for multigrid, ``info["cycle_seconds"]``, the full-multigrid
  start and the V-cycles on the device; every cycle ends by reading one float
  back, so the figure is device-synchronised (uploads are synchronised before it starts);
- ``floor``: the bytes the cycles must move through device memory (below)
  over the copy bandwidth measured in the same run on arrays of the grid's
  size (a CuPy device-to-device copy of a float64 array of ``nu * nv * k``
  values, bytes read plus written, median of 20), and ``floor/cycles``: the
  fraction of the floor reached;
- ``bound``: the solver's guaranteed error bound, relative to the piece's size;
  ``vs cpu``: the largest node distance to the CPU multigrid's grid at the same
  size (its own bound certifies it), which must be at most the sum of the two
  bounds: the ``ok`` column says it is;
- ``peak dev``: the device's used memory (NVML, sampled every millisecond
  during the call) above what was used before it, against ``estimate``, the
  backend's ``device_bytes`` (what ``generate`` prints before allocating).

Bytes a multigrid solve must move (``solve_bytes``): the schedule of
:func:`clothgrid.solvers.multigrid.fmg` and :func:`~clothgrid.solvers.multigrid.vcycle`
is replayed on a counter, and each operation on a level of ``n`` nodes and
``k`` coordinates of ``s`` bytes (8 on level 0, 4 on coarse levels) is
charged each array it must read or write once: a smoothing sweep reads the
iterate and right-hand side and writes the iterate (``3 k s n``; level 0 has no
right-hand side); a restriction reads the iterate and writes the coarse
right-hand side and zero iterate; a prolongation reads the coarse iterate and
updates the even rows; ``max_step`` reads the iterate. The paper's weights
are separable, so the stencil is formed from 1D factors and costs nothing.
Jacobi's sweep (the paper's fragment shader) reads the RGBA32F iterate and
the four weights of the node and writes the iterate: 48 bytes a node.

Results go to ``gpu.csv``, ``gpu.md`` and ``gpu_fig5.png`` (solve time
against nodes, log-log: the paper's Fig. 5 on the GPU) and ``device.json`` in
``--out`` (default ``docs/bench/gpu``).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PIECE = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"

# label: (solver, backend, stop, largest side, best-of-three up to)
METHODS = {
    "cpu multigrid": ("multigrid", "cpu", "error", 1 << 15),
    "cpu direct": ("direct", "cpu", "error", 1024),
    "cuda multigrid": ("multigrid", "cuda", "error", 1 << 15),
    "cuda multigrid (three kernels)": ("multigrid", "cuda", "error", 1 << 15),
    "gl multigrid": ("multigrid", "gl", "error", 1 << 15),
    "gl jacobi (paper rule)": ("jacobi", "gl", "paper", 1 << 15),
    "gl jacobi (true rule)": ("jacobi", "gl", "error", 256),
}
# Module settings a method runs under (its child process sets them): the line solve as it was
# before the fused kernel, for a same-run ratio.
SETTINGS = {"cuda multigrid (three kernels)": ("clothgrid.backends.cuda._multigrid", "FUSED_LINE_SOLVE", False)}
# Methods whose grids the others are compared with (run first).
REFERENCE = "cpu multigrid"
JACOBI_MAX_SWEEPS = 2_000_000


# --- the bytes a solve must move -----------------------------------------------------------------------------

class _Counter:
    """Stands in for a backend's multigrid operations and records which ran on which level."""

    def __init__(self, levels: int):
        self.levels = levels
        self.calls: list[tuple[str, int]] = []

    def __getattr__(self, name):
        if name in ("smooth", "restrict", "prolong", "restrict_full", "prolong_full"):
            return lambda level, *a, **k: self.calls.append((name, level))
        if name == "max_step":
            return lambda: self.calls.append(("max_step", 0)) or 0.0
        raise AttributeError(name)


def level_rows(nv: int) -> list[int]:
    """Rows of each multigrid level for ``nv`` rows (the hierarchy of a 3-column grid)."""
    from clothgrid.solvers.multigrid import build_hierarchy
    from clothgrid.weights import make_weights

    return [lv.shape[1] for lv in build_hierarchy(make_weights("paper", 3, nv))]


def solve_bytes(nu: int, nv: int, k: int, cycles: int) -> int:
    """Fewest bytes the full-multigrid start and ``cycles`` V-cycles move (module docstring)."""
    from clothgrid.solvers.multigrid import fmg, vcycle

    rows = level_rows(nv)
    c = _Counter(len(rows))
    fmg(c)
    for _ in range(cycles):
        vcycle(c)
        c.max_step()
    total = 0
    for op, lvl in c.calls:
        n, s = nu * rows[lvl], (8 if lvl == 0 else 4)
        nc = nu * rows[lvl + 1] if lvl + 1 < len(rows) else 0
        if op == "smooth":
            total += (2 if lvl == 0 else 3) * k * s * n
        elif op in ("restrict", "restrict_full"):
            total += k * s * n + 2 * k * 4 * nc + (k * s * n // 2 if lvl else 0)
        elif op in ("prolong", "prolong_full"):
            total += k * 4 * nc + (2 * k * s * n // 2 if op == "prolong" else 2 * k * s * n)
        elif op == "max_step":
            total += k * s * n
    return total


# --- the child: one method over the sizes -------------------------------------------------------------------

class MemoryWatch:
    """The device's used memory (NVML), sampled every millisecond in a thread while ``with`` runs."""

    def __init__(self):
        try:
            import pynvml

            pynvml.nvmlInit()
            self._h = pynvml.nvmlDeviceGetHandleByIndex(int(os.environ.get("CUDA_VISIBLE_DEVICES", "0").split(",")[0]
                                                             or 0))
            self._nvml = pynvml
        except Exception:
            self._nvml = None
        self.base = self.peak = 0

    def used(self) -> int:
        return int(self._nvml.nvmlDeviceGetMemoryInfo(self._h).used) if self._nvml else 0

    def __enter__(self):
        self.base = self.peak = self.used()
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()
        return self

    def _run(self):
        while not self._stop.is_set():
            self.peak = max(self.peak, self.used())
            time.sleep(0.001)

    def __exit__(self, *exc):
        self._stop.set()
        self._t.join()
        self.peak = max(self.peak, self.used())

    @property
    def bytes(self) -> int | None:
        return self.peak - self.base if self._nvml else None


def free_device_pool():
    try:
        import cupy

        cupy.get_default_memory_pool().free_all_blocks()
    except Exception:
        pass


def copy_bandwidth(nbytes: int, reps: int = 20) -> float | None:
    """Device-to-device copy bandwidth (bytes read + written per second) of a float64 array of ``nbytes``."""
    try:
        import cupy
    except ImportError:
        return None
    a = cupy.random.random(max(1, nbytes // 8))
    b = cupy.empty_like(a)
    for _ in range(3):
        b[...] = a
    start, end = cupy.cuda.Event(), cupy.cuda.Event()
    times = []
    for _ in range(reps):
        start.record()
        b[...] = a
        end.record()
        end.synchronize()
        times.append(cupy.cuda.get_elapsed_time(start, end) / 1e3)
    times.sort()
    del a, b
    free_device_pool()
    return 2 * (nbytes // 8) * 8 / times[len(times) // 2]


def child(label: str, sizes: list[int], tmp: Path) -> None:
    import numpy as np

    import clothgrid
    from clothgrid import load_boundary
    from clothgrid.backends import get_backend

    solver, backend, stop, _ = METHODS[label]
    if label in SETTINGS:
        import importlib

        module, name, value = SETTINGS[label]
        setattr(importlib.import_module(module), name, value)
    b = load_boundary(PIECE)
    k = 2 if b.dim == 2 else 3
    opts = dict(solver=solver, backend=backend, stop=stop, weights="paper", allow_unconverged=True)
    if solver == "jacobi":
        opts["max_iter"] = JACOBI_MAX_SWEEPS
    try:
        be = get_backend(backend, solver)
        for m in ((33,) if stop == "error" and solver == "jacobi" else (33, 300)):
            clothgrid.generate(b, (m, m), **opts)
    except clothgrid.ClothgridError as e:
        print(json.dumps({"method": label, "skipped": str(e)}), flush=True)
        return
    watch = MemoryWatch()
    for n in sizes:
        row = {"method": label, "side": n, "nodes": n * n}
        try:
            estimate = be.device_bytes(solver, n, n, coords=k, separable=True) or None   # 0: none (cpu)
            best = None
            for _ in range(3 if n <= 4096 else 1):
                free_device_pool()
                with watch:
                    t = time.perf_counter()
                    g = clothgrid.generate(b, (n, n), **opts)
                    wall = time.perf_counter() - t
                info = g.info
                run = {"wall": wall, "solve": info["solve_seconds"], "cycles": info.get("cycle_seconds"),
                       "setup": info.get("setup_seconds"), "download": info.get("download_seconds"),
                       "iterations": info["iterations"], "bound": info["error_estimate"],
                       "converged": info["converged"], "peak_dev": watch.bytes,
                       **{k: v for k, v in info.items() if k.startswith("cuda_") and k.endswith("_seconds")}}
                if best is None or run["solve"] < best["solve"]:
                    best = run
            row.update(best, estimate=estimate,
                       renderer=info.get("gl_renderer") or info.get("cuda_device"))
            pts = g.points
            ref = tmp / f"ref_{n}.npz"
            if label == REFERENCE:
                np.savez(ref, points=pts, bound=info["error_estimate"])
            elif ref.exists():
                with np.load(ref) as r:
                    diff = float(np.linalg.norm(pts - r["points"], axis=-1).max() / b.size)
                    row["vs_cpu"] = diff
                    row["ok"] = bool(diff <= (info["error_estimate"] + float(r["bound"])) * (1 + 1e-6) + 1e-12)
            if solver == "multigrid":
                row["bytes"] = solve_bytes(n, n, k, info["iterations"])
            elif solver == "jacobi":
                row["bytes"] = 48 * n * n * info["iterations"]
            del g, pts
        except clothgrid.ClothgridError as e:
            row["note"] = f"{type(e).__name__}: {e}"
            print(json.dumps(row), flush=True)
            return
        print(json.dumps(row), flush=True)


def bandwidth_child(sizes: list[int], k: int) -> None:
    for n in sizes:
        bw = copy_bandwidth(n * n * k * 8)
        print(json.dumps({"method": "copy", "side": n, "bandwidth": bw}), flush=True)
    big = copy_bandwidth(4 << 30)
    print(json.dumps({"method": "copy", "side": 0, "bandwidth": big}), flush=True)


# --- the parent -------------------------------------------------------------------------------------------------

def run_child(args: list[str], timeout: float) -> list[dict]:
    """Run a child and collect its JSON lines, keeping those printed before a timeout."""
    rows = []
    p = subprocess.Popen([sys.executable, __file__, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, cwd=ROOT)
    timer = threading.Timer(timeout, p.kill)
    timer.start()
    try:
        for line in p.stdout:
            line = line.strip()
            if line.startswith("{"):
                row = json.loads(line)
                rows.append(row)
                print("  " + describe(row), flush=True)
        err = p.stderr.read()
        p.wait()
    finally:
        timer.cancel()
    if p.returncode != 0:
        why = "killed after %.0f s" % timeout if p.returncode in (-9, 137) else (err.strip().splitlines() or ["?"])[-1]
        rows.append({"method": args[1] if len(args) > 1 else "?", "failed": why})
        print(f"  failed: {why}", flush=True)
    return rows


def describe(row: dict) -> str:
    if "bandwidth" in row:
        bw = row["bandwidth"]
        return f"copy {row['side']}^2: {bw / 1e9:.0f} GB/s" if bw else "copy: no CuPy"
    if "skipped" in row:
        return f"{row['method']}: skipped ({row['skipped']})"
    if "solve" not in row:
        return f"{row['method']} {row.get('side')}: {row.get('note') or row.get('failed')}"
    cyc = f", cycles {row['cycles'] * 1e3:.2f} ms" if row.get("cycles") is not None else ""
    peak = f", peak dev {row['peak_dev'] / 2**20:.0f} MiB" if row.get("peak_dev") is not None else ""
    est = f" (est. {row['estimate'] / 2**20:.0f})" if row.get("estimate") else ""
    vs = f", vs cpu {row['vs_cpu']:.1e} {'ok' if row['ok'] else 'MISMATCH'}" if "vs_cpu" in row else ""
    return (f"{row['method']} {row['side']}^2: solve {row['solve']:.4f} s{cyc}, {row['iterations']} it, "
            f"bound {row['bound']:.2e}{vs}{peak}{est}")


def device_facts() -> dict:
    facts = {"date": time.strftime("%Y-%m-%d"), "cpu_count": os.cpu_count()}
    try:
        q = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                           capture_output=True, text=True, timeout=30).stdout.strip()
        facts["nvidia_smi"] = q
    except Exception as e:
        facts["nvidia_smi"] = f"unavailable: {e}"
    code = ("import json, clothgrid.backends.cuda as c, clothgrid.backends.gl as g;"
            "d = {};\n"
            "ok, why = c.available(); d['cuda'] = c.summary() if ok else why\n"
            "ok, why = g.available(); d['gl'] = (g.summary() if ok else why)\n"
            "import numba, numpy, scipy; d['numba'] = numba.__version__; d['numpy'] = numpy.__version__\n"
            "print(json.dumps(d))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    try:
        facts.update(json.loads(p.stdout.strip().splitlines()[-1]))
    except Exception:
        facts["probe_error"] = p.stderr.strip()[-500:]
    return facts


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--min", type=int, default=32)
    ap.add_argument("--max", type=int, default=16384)
    ap.add_argument("--table-min", type=int, default=1024, help="smallest side in the main table")
    ap.add_argument("--methods", nargs="*", default=list(METHODS))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench" / "gpu")
    ap.add_argument("--timeout", type=float, default=240.0, help="seconds per method")
    ap.add_argument("--ref-max", type=int, default=1 << 15, help="largest side of the CPU reference grids")
    ap.add_argument("--render", nargs="*", type=Path, metavar="DIR",
                    help="only write the tables and plot of earlier runs' rows.jsonl (merged) into --out")
    ap.add_argument("--child", nargs=2, metavar=("METHOD", "TMP"), help=argparse.SUPPRESS)
    ap.add_argument("--sizes", nargs="*", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        if args.child[0] == "copy":
            bandwidth_child(args.sizes, int(args.child[1]))
        else:
            child(args.child[0], args.sizes, Path(args.child[1]))
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    if args.render:
        rows = []
        for d in args.render:
            rows += [json.loads(line) for line in (d / "rows.jsonl").read_text().splitlines() if line.strip()]
        facts = json.loads((args.render[0] / "device.json").read_text())
        facts.pop("copy_bandwidth", None)
        write(rows, facts, args.out, args.table_min)
        print((args.out / "gpu.md").read_text())
        return 0
    sizes = []
    n = args.min
    while n <= args.max:
        sizes.append(n)
        n *= 2
    facts = device_facts()
    print(json.dumps(facts, indent=1), flush=True)
    rows: list[dict] = []
    order = sorted(args.methods, key=lambda m: m != REFERENCE)
    with tempfile.TemporaryDirectory() as tmp:
        print("copy bandwidth", flush=True)
        rows += run_child(["--child", "copy", "2", "--sizes", *map(str, sizes)], args.timeout)
        for label in order:
            top = min(METHODS[label][3], args.ref_max) if label == REFERENCE else METHODS[label][3]
            print(label, flush=True)
            rows += run_child(["--child", label, tmp, "--sizes", *map(str, [s for s in sizes if s <= top])],
                              args.timeout)
    write(rows, facts, args.out, args.table_min)
    print((args.out / "gpu.md").read_text())
    return 0


def write(rows: list[dict], facts: dict, out: Path, table_min: int) -> None:
    (out / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    bw = {r["side"]: r["bandwidth"] for r in rows if r.get("bandwidth")}
    for r in rows:
        if "bytes" in r and bw.get(r["side"]) and r.get("renderer"):   # device methods only
            r["floor"] = r["bytes"] / bw[r["side"]]
            spent = r["cycles"] if r.get("cycles") is not None else r["solve"]
            r["floor_fraction"] = r["floor"] / spent if spent else None
    (out / "device.json").write_text(json.dumps({**facts, "copy_bandwidth": bw}, indent=1) + "\n")
    keys = ["method", "side", "nodes", "solve", "cycles", "setup", "download", "wall", "iterations", "bound",
            "converged", "vs_cpu", "ok", "bytes", "floor", "floor_fraction", "peak_dev", "estimate", "renderer",
            "note", "skipped", "failed"]
    with open(out / "gpu.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows([r for r in rows if "bandwidth" not in r])
    timed = [r for r in rows if "solve" in r]
    with open(out / "gpu.md", "w") as f:
        f.write(f"Device: {facts.get('nvidia_smi')}; {facts.get('date')}. T-shirt front, paper weights, "
                "tol 2^-12 (bound relative to the piece's size).\n\n")
        f.write("| method | nodes | solve s | cycles ms | it | bound | vs cpu | floor ms | floor/cycles | "
                "peak dev MiB | estimate MiB |\n|---|---|---|---|---|---|---|---|---|---|---|\n")
        for r in sorted(timed, key=lambda r: (r["method"], r["side"])):
            if r["side"] < table_min:
                continue
            cyc = f"{r['cycles'] * 1e3:.2f}" if r.get("cycles") is not None else ""
            vs = (f"{r['vs_cpu']:.1e} {'ok' if r['ok'] else 'MISMATCH'}") if "vs_cpu" in r else ""
            fl = f"{r['floor'] * 1e3:.2f}" if r.get("floor") else ""
            fr = f"{r['floor_fraction']:.2g}" if r.get("floor_fraction") else ""
            pk = f"{r['peak_dev'] / 2**20:.0f}" if r.get("peak_dev") is not None and r["method"] != REFERENCE else ""
            es = f"{r['estimate'] / 2**20:.0f}" if r.get("estimate") else ""
            f.write(f"| {r['method']} | {r['side']}^2 | {r['solve']:.4f} | {cyc} | {r['iterations']} | "
                    f"{r['bound']:.2e} | {vs} | {fl} | {fr} | {pk} | {es} |\n")
        f.write("\nCopy bandwidth (bytes read + written per second): "
                + ", ".join(f"{s}^2 {b / 1e9:.0f} GB/s" if s else f"4 GiB {b / 1e9:.0f} GB/s"
                            for s, b in sorted(bw.items())) + "\n")
        notes = [r for r in rows if "solve" not in r and "bandwidth" not in r]
        if notes:
            f.write("\nNot run or stopped:\n\n")
            for r in notes:
                f.write(f"- {r['method']} {r.get('side', '')}: {r.get('note') or r.get('skipped') or r.get('failed')}\n")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    for label in dict.fromkeys(r["method"] for r in timed):   # in the order they ran
        pts = sorted((r["nodes"], r["solve"]) for r in timed if r["method"] == label)
        if pts:
            line, = ax.loglog(*zip(*pts), "o-", label=label)
            cyc = sorted((r["nodes"], r["cycles"]) for r in timed if r["method"] == label and r.get("cycles")
                         and r.get("renderer"))
            if cyc:   # a device backend: its cycles alone, without the transfers
                ax.loglog(*zip(*cyc), ":", color=line.get_color(), label=f"{label}: cycles on the device")
    fl = sorted((r["nodes"], r["floor"]) for r in timed if r["method"] == "cuda multigrid" and r.get("floor"))
    if fl:
        ax.loglog(*zip(*fl), "k--", lw=1, label="multigrid bandwidth floor")
    ax.set_xlabel("nodes")
    ax.set_ylabel("seconds (solve: upload to download)")
    ax.set_title(f"Fig. 5 on the GPU: {facts.get('nvidia_smi', '').split(',')[0]}, paper weights, tol 2^-12",
                 fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "gpu_fig5.png", dpi=120)


if __name__ == "__main__":
    sys.exit(main())
