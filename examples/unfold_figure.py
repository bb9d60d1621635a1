"""Draw a pattern's halves cut on the fold and the garment sewn from them unfolded: docs/garment-unfold.png.

    python examples/unfold_figure.py [PATTERN] [--stitches FILE] [-o docs/garment-unfold.png] [--edge-length 2cm]

Left: the pieces as the file draws them (a half cut on the fold, its fold line dashed). Right: the
panels of ``clothgrid garment PATTERN --stitches FILE`` (FreeSewing's Aaron by default: its front and
back unfolded and sewn at the sides and shoulders), their grids, with the stitched node pairs of
each seam joined in red.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection, PolyCollection  # noqa: E402

from clothgrid.garment import garment  # noqa: E402
from clothgrid.pipeline import select_pieces  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("pattern", nargs="?", default=str(ROOT / "tests" / "data" / "freesewing" / "aaron_v3_pattern.svg"))
    ap.add_argument("--stitches", default=str(ROOT / "examples" / "fs_aaron_stitches.json"))
    ap.add_argument("-o", "--output", default="docs/garment-unfold.png")
    ap.add_argument("--edge-length", default="2cm")
    a = ap.parse_args()
    halves = select_pieces(a.pattern)
    g = garment(a.pattern, stitches=a.stitches, edge_length=a.edge_length)
    colors = plt.cm.tab10(np.arange(10))
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 6))
    for k, p in enumerate(halves):
        o = np.vstack([p.outline, p.outline[:1]])
        left.fill(o[:, 0], o[:, 1], color=colors[k % 10], alpha=0.35)
        left.plot(o[:, 0], o[:, 1], color="k", lw=0.8)
        if p.meta.get("fold_line") is not None:
            f = np.array(p.meta["fold_line"])
            left.plot(f[:, 0], f[:, 1], "k--", lw=2)
        c = p.outline.mean(axis=0)
        left.text(c[0], c[1], p.name + (" (half)" if p.meta.get("fold_line") is not None else ""), ha="center")
    left.set_title("as drawn: halves cut on the fold (dashed)")
    # the panels side by side, each moved right of the last
    shift = np.zeros(2)
    moved = np.zeros_like(g.rest)
    for k, name in enumerate(g.panel_names):
        on = g.panel == k
        r = g.rest[on]
        moved[on] = r - [r[:, 0].min(), r[:, 1].min()] + shift
        shift[0] += np.ptp(r[:, 0]) + 40.0
    right.add_collection(PolyCollection(moved[g.quads], facecolors=colors[g.face_panel % 10], edgecolors="k",
                                        linewidths=0.2, alpha=0.5))
    seam = g.stitches[g.stitches[:, 0] != g.stitches[:, 1]]
    right.add_collection(LineCollection(moved[seam], colors="r", linewidths=0.4))
    for k, name in enumerate(g.panel_names):
        c = moved[g.panel == k].mean(axis=0)
        right.text(c[0], c[1], name, ha="center")
    right.autoscale()
    right.set_title(f"unfolded and sewn: {len(g.panel_names)} panels, {len(seam)} stitched node pairs")
    for ax in (left, right):
        ax.set_aspect("equal")
        ax.set_xlabel("mm")
    fig.tight_layout()
    fig.savefig(a.output, dpi=110)
    print(f"wrote {a.output}")


if __name__ == "__main__":
    main()
