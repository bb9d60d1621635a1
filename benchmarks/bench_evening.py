"""The edge evening's two stages against one, on the same input grids in the same run.

    python benchmarks/bench_evening.py [--sizes 128 256 512 1024] [--survey] [--edge-length 10mm]

The evening (``clothgrid.evening.even_edges``) is the last part of the default auto step. Its
input is the relaxed length grid; this script builds those inputs the way ``generate`` does
(the length grid, then ``foldfree.relax`` on its poor cells) and evens each one twice:

- one stage: ``wide_band=None`` (the last stage alone: band 1.4, or a wider one where 1.4's nodes
  are too many for ordered sweeps; the same stop rule), and
- two stages: the default (the wide band 2.5 first).

The start of the ninth pass (one stage of 1.4, whatever its size, the energy's stop rule alone)
is not in this tree: docs/performance.md has it measured from a worktree.

``--sizes``: the bundled T-shirt front resampled to ``n x n`` nodes, uniform weights (best of 3
seconds each). ``--survey``: every piece of every real pattern file in ``../shared/patterns``
(the edge length given, the corners the command would choose): total seconds and the spread
figures over the pieces. The floor of every corner angle is checked on every grid.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import clothgrid  # noqa: E402
from clothgrid.evening import FLOOR_DEG, even_edges  # noqa: E402
from clothgrid.foldfree import relax  # noqa: E402

PIECE = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"
SHARED = ROOT.parent / "shared" / "patterns"
RUNS = {"one stage": dict(wide_band=None), "two stages": {}}


def evening_input(grid) -> np.ndarray:
    """The grid the evening gets in ``generate(..., functional="auto")``: the relaxed length grid."""
    return relax(grid.points, dim=grid.dim)[0]


def floor_holds(p0: np.ndarray, p: np.ndarray) -> bool:
    """Every corner (grid corners aside) at the evening's floor or no worse than before."""
    def sines(P):
        X = P[..., :2]
        c = (X[:-1, :-1], X[1:, :-1], X[1:, 1:], X[:-1, 1:])
        out = []
        for k in range(4):
            a, b = c[(k + 1) % 4] - c[k], c[k - 1] - c[k]
            with np.errstate(invalid="ignore", divide="ignore"):
                out.append((a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
                           / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)))
        s = np.stack(out)
        s[0, 0, 0] = s[1, -1, 0] = s[2, -1, -1] = s[3, 0, -1] = np.nan
        return s
    floor = math.sin(math.radians(FLOOR_DEG))
    before, after = sines(p0), sines(p)
    return bool((np.isnan(before) | (after >= np.minimum(before, floor) - 1e-12)).all())


def even(p0: np.ndarray, dim: int, repeat: int, **kw) -> tuple[float, dict]:
    best, info = math.inf, {}
    for _ in range(repeat):
        t = time.perf_counter()
        out, info = even_edges(p0, dim=dim, **kw)
        best = min(best, time.perf_counter() - t)
    if not floor_holds(p0, out):
        raise SystemExit("the evening lowered a corner below its floor")
    return best, info


def sizes(ns: list[int]) -> None:
    base = clothgrid.load_boundary(PIECE)
    print("| T-shirt front | " + " | ".join(f"{r}: seconds, spread after" for r in RUNS) + " | ratio |")
    print("|---|" + "---|" * (len(RUNS) + 1))
    for n in ns:
        g = clothgrid.generate(base.resampled(n, n), weights="uniform")
        p0 = evening_input(g)
        cells = []
        got = {}
        for name, kw in RUNS.items():
            sec, info = even(p0, g.dim, 3, **kw)
            got[name] = sec
            bands = " then ".join(f"{s['band']:g} ({s['active']:,} nodes)" for s in info["stages"])
            cells.append(f"{sec:.3f} s, {info['spread_after']:.2f} ({bands or 'none'})")
        first, last = got.values()
        print(f"| {n}^2 (spread before {info['spread_before']:.2f}) | " + " | ".join(cells)
              + f" | {last / first:.2f} |", flush=True)


def survey(edge: str) -> None:
    from clothgrid.errors import ClothgridError
    from clothgrid.pipeline import GridOptions, read_jobs

    files = sorted(p for p in SHARED.iterdir() if p.suffix.lower() in (".svg", ".dxf", ".json"))
    inputs = []
    for f in files:
        try:
            jobs = read_jobs(f, ["/tmp/bench_evening_{piece}.npz"], options=GridOptions(edge_length=edge))
        except ClothgridError:
            continue
        for job in jobs:
            try:
                g = clothgrid.generate(job.boundary, job.nodes,
                                       **{**job.options.generate_kwargs(), "functional": "length"})
                inputs.append((evening_input(g), g.dim))
            except ClothgridError:
                continue
    print(f"{len(inputs)} pieces at {edge} edges")
    spreads = {}
    for name, kw in RUNS.items():
        t, sp = 0.0, []
        for p0, dim in inputs:
            sec, info = even(p0, dim, 1, **kw)
            t += sec
            sp.append(info["spread_after"])
        sp = np.array(sp)
        spreads[name] = sp
        print(f"{name:18s} {t:.3f} s  spread median {np.median(sp):.3f} mean {sp.mean():.2f} "
              f"90th {np.percentile(sp, 90):.1f} largest {sp.max():.1f}; above 4: {(sp > 4).sum()}, "
              f"above 5: {(sp > 5).sum()}", flush=True)
    a, b = spreads.values()
    r = b / a
    print(f"two stages against one, per piece: {(r > 1.05).sum()} more than 5 % worse, "
          f"{(r < 0.95).sum()} more than 5 % better")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[128, 256, 512, 1024])
    ap.add_argument("--survey", action="store_true")
    ap.add_argument("--edge-length", default="10mm")
    a = ap.parse_args(argv)
    if a.sizes:
        sizes(a.sizes)
    if a.survey:
        survey(a.edge_length)
    return 0


if __name__ == "__main__":
    sys.exit(main())
