"""Draw a grid graded by a weight field next to the plain one: docs/weight-field.png.

    python examples/weight_field_figure.py [-o docs/weight-field.png] [--nodes 49]

Left: the bundled T-shirt front with uniform weights. Middle: the weight field over the piece's
(u, v) square, a bump of 1 + 9 e^(-d^2 / 0.02) about (0.5, 0.85), under the neckline. Right: the same
piece with ``weights=clothgrid.WeightField(field)`` (``clothgrid generate --weight-field field.npy``),
``functional="length"``: finer where the field is larger.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

import clothgrid  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _draw(ax, points: np.ndarray, title: str) -> None:
    p = points[..., :2]
    lines = [p[i] for i in range(p.shape[0])] + [p[:, j] for j in range(p.shape[1])]
    ax.add_collection(LineCollection(lines, linewidths=0.5, colors="0.2"))
    ax.set_xlim(p[..., 0].min() - 0.02, p[..., 0].max() + 0.02)
    ax.set_ylim(p[..., 1].min() - 0.02, p[..., 1].max() + 0.02)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    ax.set_xticks([])
    ax.set_yticks([])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "weight-field.png")
    ap.add_argument("--nodes", type=int, default=49)
    a = ap.parse_args()
    b = clothgrid.load_boundary(Path(clothgrid.__file__).parent / "data" / "tshirt_front.json")
    u = (np.arange(64) + 0.5)[:, None] / 64
    v = (np.arange(64) + 0.5)[None, :] / 64
    field = 1.0 + 9.0 * np.exp(-((u - 0.5) ** 2 + (v - 0.85) ** 2) / 0.02)
    plain = clothgrid.generate(b, a.nodes, weights="uniform", functional="length")
    graded = clothgrid.generate(b, a.nodes, weights=clothgrid.WeightField(field), functional="length")
    fig, axes = plt.subplots(1, 3, figsize=(11, 4.6), gridspec_kw={"width_ratios": [1, 1, 1]})
    _draw(axes[0], plain.points, "uniform weights")
    im = axes[1].imshow(field.T, origin="lower", extent=(0, 1, 0, 1), cmap="viridis")
    axes[1].set_title("weight field over (u, v)", fontsize=10)
    axes[1].set_xlabel("u (bottom side)")
    axes[1].set_ylabel("v (left side)")
    fig.colorbar(im, ax=axes[1], fraction=0.046, pad=0.04)
    _draw(axes[2], graded.points, "WeightField: finer where it is larger")
    fig.tight_layout()
    a.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.output, dpi=110)
    print(f"wrote {a.output}")


if __name__ == "__main__":
    main()
