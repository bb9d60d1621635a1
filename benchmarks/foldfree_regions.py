"""Fold-free grids on the eight Roache regions with corners: table and figure.

Usage (from the repository root)::

    .venv/bin/python benchmarks/foldfree_regions.py [--sizes 20 80] [--weights paper]
        [--big 256] [--figure docs/foldfree-regions.png]

Prints a Markdown table per size: folded cells, min scaled Jacobian and max
orthogonality deviation of the length-functional grid and of the fold-free grid
(``generate(..., functional="foldfree")``), and the time of the fold-free stage.
``--big N`` adds one N x N row per region with the times only. The figure shows
each region at the first size, length functional (folded cells red) above the
fold-free grid.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import clothgrid
from clothgrid import generate, quality

ROOT = Path(__file__).resolve().parents[1]
REGIONS = ROOT / "tests" / "data" / "regions"


def regions() -> list[Path]:
    """The region files that mark their four corners."""
    return [p for p in sorted(REGIONS.glob("roache-*.json")) if "corners" in json.loads(p.read_text())]


def run(path: Path, n: int, weights: str) -> tuple:
    b = clothgrid.load_boundary(path)
    nodes = None if b.shape == (n, n) else n
    t0 = time.perf_counter()
    length = generate(b, nodes, weights=weights)
    t_len = time.perf_counter() - t0
    t0 = time.perf_counter()
    ff = generate(b, nodes, weights=weights, functional="foldfree")
    t_ff = time.perf_counter() - t0
    return length, ff, t_len, t_ff


def table(n: int, weights: str) -> tuple[str, dict]:
    rows = [f"### {n} x {n} nodes, {weights} weights", "",
            "| region | folded before | folded after | min scaled Jacobian before / after "
            "| max orthogonality dev. before / after (deg) | length solve (s) | fold-free total (s) |",
            "|---|---:|---:|---|---|---:|---:|"]
    grids = {}
    for path in regions():
        length, ff, t_len, t_ff = run(path, n, weights)
        q0, q1 = quality(length), quality(ff)
        grids[path.stem] = (length, ff, q0, q1)
        rows.append(f"| {path.stem.removeprefix('roache-')} | {q0.folded} | {q1.folded} "
                    f"| {q0.min_scaled_jacobian:.3f} / {q1.min_scaled_jacobian:.3f} "
                    f"| {q0.max_orthogonality_deviation_deg:.1f} / {q1.max_orthogonality_deviation_deg:.1f} "
                    f"| {t_len:.3f} | {t_ff:.2f} |")
    return "\n".join(rows), grids


def figure(grids: dict, path: Path, n: int, weights: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    from clothgrid.plot import plane_coordinates

    names = list(grids)
    fig = Figure(figsize=(2.0 * len(names), 4.2), dpi=90)
    FigureCanvasAgg(fig)
    for col, name in enumerate(names):
        length, ff, q0, q1 = grids[name]
        for row, (grid, q, label) in enumerate(((length, q0, "length"), (ff, q1, "fold-free"))):
            ax = fig.add_subplot(2, len(names), row * len(names) + col + 1)
            xy = plane_coordinates(grid)
            lines = [xy[i] for i in range(xy.shape[0])] + [xy[:, j] for j in range(xy.shape[1])]
            ax.add_collection(LineCollection(lines, colors="0.3", linewidths=0.35))
            if q.folded:
                i, j = np.asarray(q.folded_cells).T
                cells = np.stack([xy[i, j], xy[i + 1, j], xy[i + 1, j + 1], xy[i, j + 1]], axis=1)
                ax.add_collection(PolyCollection(cells, facecolors="red", edgecolors="none", alpha=0.7))
            ax.set_aspect("equal")
            ax.autoscale_view()
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{name.removeprefix('roache-')}: {label}\n{q.folded} folded", fontsize=8)
    fig.suptitle(f"{n} x {n} nodes, {weights} weights: length functional (top) and fold-free (bottom)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, format="png")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 80])
    parser.add_argument("--weights", choices=("paper", "uniform"), default="paper")
    parser.add_argument("--big", type=int, default=None, metavar="N")
    parser.add_argument("--figure", type=Path, default=ROOT / "docs" / "foldfree-regions.png")
    args = parser.parse_args()
    first = None
    for n in args.sizes:
        text, grids = table(n, args.weights)
        print(text, "\n", flush=True)
        first = first or (n, grids)
    if args.big:
        print(f"### {args.big} x {args.big} nodes, {args.weights} weights", "")
        print("| region | folded before | folded after | min scaled Jacobian after | fold-free total (s) |")
        print("|---|---:|---:|---:|---:|")
        for path in regions():
            length, ff, _, t_ff = run(path, args.big, args.weights)
            print(f"| {path.stem.removeprefix('roache-')} | {ff.info['folded_before']} | {ff.info['folded']} "
                  f"| {quality(ff).min_scaled_jacobian:.3f} | {t_ff:.2f} |", flush=True)
        print()
    if args.figure and first:
        figure(first[1], args.figure, first[0], args.weights)
        print(f"figure: {args.figure} ({args.figure.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
