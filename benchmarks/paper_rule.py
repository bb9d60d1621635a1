"""Where the paper's stopping rule stops, and how far from the solution that is.

Run ``python benchmarks/paper_rule.py [--piece FILE] [--sizes 16 32 ...]``. For each size and
initial grid (the paper's ``average`` and ``tfi``), Jacobi (eq. 3, paper weights) runs with the
paper's rule (last step < 2^-12 of the piece's size) and with the true rule (every node within
2^-12 of the exact solution, guaranteed); the true max error is measured against a sparse direct
solve. Errors are relative to the piece's bounding-box diagonal.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import clothgrid

PIECE = Path(__file__).resolve().parents[1] / "src" / "clothgrid" / "data" / "tshirt_front.json"
TOL = 2.0**-12


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piece", type=Path, default=PIECE)
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64, 128, 256])
    ap.add_argument("--error-rule-max", type=int, default=128, help="largest size for the true rule (slow)")
    args = ap.parse_args()
    base = clothgrid.load_boundary(args.piece)
    print(f"piece {args.piece.name}, paper weights, tol = 2^-12 = {TOL:.3g}\n")
    print("| nodes | init | paper rule: sweeps | true error at stop | error / tol "
          "| true rule: sweeps | true error | bound reported |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        b = base.resampled(n, n)
        ref = clothgrid.generate(b, solver="direct").points
        for init in ("average", "tfi"):
            p = clothgrid.generate(b, solver="jacobi", stop="paper", init=init)
            err_p = np.linalg.norm(p.points - ref, axis=-1).max() / b.size
            row = f"| {n}x{n} | {init} | {p.info['iterations']} | {err_p:.2e} | {err_p / TOL:.0f} |"
            if n <= args.error_rule_max:
                e = clothgrid.generate(b, solver="jacobi", stop="error", init=init)
                err_e = np.linalg.norm(e.points - ref, axis=-1).max() / b.size
                row += f" {e.info['iterations']} | {err_e:.2e} | {e.info['error_estimate']:.2e} |"
            else:
                row += " (not run) | | |"
            print(row, flush=True)


if __name__ == "__main__":
    main()
