"""Real-pattern benchmark: the default command against the paper's length grid, same run.

    python benchmarks/bench_patterns.py [--repeat 3] [--edge-length 5mm] [FILES...]

For each pattern file (default: the Garment-Pattern-Generator jumpsuit in
``../shared/patterns``) it runs the whole command as a subprocess,

- default: ``clothgrid generate FILE --edge-length 5mm -o DIR/{piece}.npz``
  (uniform weights, ``--functional auto``, ranked corners), and
- baseline: the same with ``--functional length --weights paper`` (the paper's
  grid, what the command did before the real-pattern defaults),

alternating the two, ``--repeat`` times each, and prints min / median wall time,
the ratio default / baseline (the goal: at most 3) and the folded cells each
run reported. Python start-up, reading, corner choice, solving, quality and
writing are all included.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "patterns"
DEFAULT_FILES = [SHARED / "gpg_jumpsuit_specification.json"]
BASELINE = ["--functional", "length", "--weights", "paper"]


def run_once(file: Path, edge: str, extra: list[str]) -> tuple[float, int, int]:
    """Wall seconds, pieces written and folded cells reported by one whole command."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "clothgrid", "generate", str(file), "--edge-length", edge,
               "-o", str(Path(out) / "{piece}.npz"), *extra]
        t = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        dt = time.perf_counter() - t
        if proc.returncode not in (0, 1):
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr}")
        folded = sum(int(m) for m in re.findall(r"(\d+) folded cells", proc.stderr + proc.stdout))
        return dt, len(list(Path(out).glob("*.npz"))), folded


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--edge-length", default="5mm")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    files = a.files or DEFAULT_FILES
    print(f"{'file':36s} {'run':9s} {'pieces':>6s} {'folded':>6s} {'min s':>7s} {'median s':>8s}")
    worst = 0.0
    for f in files:
        times: dict[str, list[float]] = {"default": [], "baseline": []}
        seen: dict[str, tuple[int, int]] = {}
        run_once(f, a.edge_length, [])  # warm the Numba cache and the file system
        for _ in range(a.repeat):
            for name, extra in (("default", []), ("baseline", BASELINE)):
                dt, pieces, folded = run_once(f, a.edge_length, extra)
                times[name].append(dt)
                seen[name] = (pieces, folded)
        for name in ("baseline", "default"):
            ts = times[name]
            print(f"{f.name[:36]:36s} {name:9s} {seen[name][0]:6d} {seen[name][1]:6d} "
                  f"{min(ts):7.2f} {statistics.median(ts):8.2f}")
        ratio = statistics.median(times["default"]) / statistics.median(times["baseline"])
        worst = max(worst, ratio)
        print(f"{'':36s} ratio default / baseline (median): {ratio:.2f} (goal <= 3)")
    return 0 if worst <= 3.0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
