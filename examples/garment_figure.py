"""Draw a sewn garment placed around the body, and its flat panels: docs/garment.png.

    python examples/garment_figure.py SPEC [-o docs/garment.png] [--edge-length 2cm]
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from clothgrid.garment import garment  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("spec")
    ap.add_argument("-o", "--output", default="docs/garment.png")
    ap.add_argument("--edge-length", default="2cm")
    a = ap.parse_args()
    g = garment(a.spec, edge_length=a.edge_length)
    colors = plt.cm.tab20(np.linspace(0, 1, max(len(g.panel_names), 2)))
    fig = plt.figure(figsize=(11, 5.5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    P = g.points[:, [0, 2, 1]]                     # Y up -> matplotlib's z
    ax.add_collection3d(Poly3DCollection(P[g.quads], facecolors=colors[g.face_panel], edgecolors="k",
                                         linewidths=0.15, alpha=0.9))
    seam = g.stitches[g.stitches[:, 0] != g.stitches[:, 1]]
    for a_, b_ in seam[:: max(1, len(seam) // 300)]:
        ax.plot(*P[[a_, b_]].T, color="r", lw=0.4)
    lo, hi = P.min(0), P.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(c[0] - r, c[0] + r); ax.set_ylim(c[1] - r, c[1] + r); ax.set_zlim(c[2] - r, c[2] + r)
    ax.view_init(elev=10, azim=-70)
    ax.set_title(f"placed (mm, Y up); red: seam pairs", fontsize=9)
    ax2 = fig.add_subplot(1, 2, 2)
    x0 = 0.0
    for pi, name in enumerate(g.panel_names):
        idx = g.panel == pi
        R = g.rest[idx]
        shift = np.array([x0 - R[:, 0].min(), -R[:, 1].min()])
        q = g.quads[g.face_panel == pi]
        ax2.add_collection(PolyCollection((g.rest + shift)[q], facecolors=colors[pi], edgecolors="k",
                                          linewidths=0.2))
        ax2.text(x0, -40, name, fontsize=6)
        x0 += np.ptp(R[:, 0]) + 30
    ax2.autoscale(); ax2.set_aspect("equal"); ax2.set_title("flat rest shapes (mm)", fontsize=9)
    fig.suptitle(f"{g.spec.path.name}: {len(g.panel_names)} panels, {len(g.spec.stitches)} stitches, "
                 f"{len(g.points)} nodes, edge length {a.edge_length}", fontsize=10)
    fig.tight_layout()
    fig.savefig(a.output, dpi=110)
    print(a.output)


if __name__ == "__main__":
    main()
