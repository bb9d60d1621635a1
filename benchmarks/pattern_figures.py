"""Before/after pictures of real pattern pieces for docs/patterns.md.

    git worktree add --detach /tmp/old 015215a      # the code before the real-pattern work
    python benchmarks/pattern_figures.py --before-src /tmp/old/src -o docs/patterns-before-after.png

Each piece is gridded twice with the default command (``clothgrid generate FILE --piece NAME
--plot``): once by the code in ``--before-src`` (then: the paper's weights, the length
functional, corners by turning angle) and once by this checkout (uniform weights,
``--functional auto``, ranked corners with darts and rounded corners recognised, node counts
on the typical grid line, outlying edges evened). Folded
cells are red; the grid corners of the new plots are the blue dots. The folded-cell counts
and the quality line of each run go under its picture.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "patterns"
PIECES = [
    ("gcn_rand_L12WU7204Q_specification.json", "skirt_back", "skirt back, 4 darts"),
    ("gcn_rand_JIT6TDX7XB_specification.json", "pant_b_r", "trouser back, 2 darts"),
    ("fs_wahid_layout.svg", "24", "front with a long curved dart"),
    ("fs_simon_collarstandbend.svg", "205", "collar stand, rounded corners"),
    ("astm_GLX4802S19_AAMA.DXF", "GLX4802S19SLL_42", "long sleeve (few long edges)"),
]


def grid(src: Path, file: str, piece: str, png: Path) -> str:
    """Run one default command with ``src`` on the path; return its folded-cell / quality line."""
    env = dict(os.environ, PYTHONPATH=str(src))
    proc = subprocess.run([sys.executable, "-m", "clothgrid", "generate", str(SHARED / file),
                           "--piece", piece, "-o", str(png.with_suffix(".npz")), "--plot", str(png)],
                          capture_output=True, text=True, env=env)
    text = proc.stdout + proc.stderr
    folded = re.findall(r"(\d+) folded cells?", text)
    angles = re.search(r"angles ([\d.]+) to", text)
    line = f"{folded[-1] if folded else 0} folded cells"
    if angles:
        line += f", smallest angle {float(angles.group(1)):.1f}°"
    return line


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before-src", type=Path, required=True, help="src/ of the old checkout")
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "patterns-before-after.png")
    a = ap.parse_args(argv)
    fig, axes = plt.subplots(2, len(PIECES), figsize=(4.2 * len(PIECES), 10), dpi=110)
    with tempfile.TemporaryDirectory() as tmp:
        for k, (file, piece, what) in enumerate(PIECES):
            for row, (src, label) in enumerate(((a.before_src, "before"), (ROOT / "src", "now"))):
                png = Path(tmp) / f"{label}_{k}.png"
                line = grid(src, file, piece, png)
                ax = axes[row, k]
                ax.imshow(plt.imread(png))
                ax.set_axis_off()
                ax.set_title(f"{label}: {what}\n{line}", fontsize=9)
                print(f"{file} {piece} {label}: {line}")
    fig.tight_layout()
    fig.savefig(a.output)
    print(f"wrote {a.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
