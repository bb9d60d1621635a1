"""Where a fresh process's first ``generate`` goes (issue 16, item 3): the imports, the first call
and a second call of the same grid in one process, then a cProfile of a first call in a second fresh
process (its largest cumulative entries).

    python benchmarks/bench_first_call.py [--nodes 1024] [--top 30]

The first call's excess over the second is what the command pays once: Numba's import, its target
context's first refresh and the cached kernels' loading.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PIECE = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"

CHILD = r"""
import sys, time
t0 = time.perf_counter()
import clothgrid
from clothgrid.readers import load_boundary
t1 = time.perf_counter()
b = load_boundary(sys.argv[1]).resampled(int(sys.argv[2]), int(sys.argv[2]))
if sys.argv[3] == "profile":
    import cProfile, pstats
    cProfile.run("clothgrid.generate(b)", sys.argv[4])
    pstats.Stats(sys.argv[4]).sort_stats("cumulative").print_stats(int(sys.argv[5]))
else:
    t2 = time.perf_counter(); clothgrid.generate(b); t3 = time.perf_counter(); clothgrid.generate(b)
    t4 = time.perf_counter()
    print(f"import clothgrid {t1 - t0:.3f} s; first generate {t3 - t2:.3f} s; second {t4 - t3:.3f} s; "
          f"first / second {(t3 - t2) / (t4 - t3):.2f}x")
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nodes", type=int, default=1024)
    ap.add_argument("--top", type=int, default=30)
    a = ap.parse_args(argv)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    run = [sys.executable, "-c", CHILD, str(PIECE), str(a.nodes)]
    print(subprocess.run(run + ["time"], env=env, capture_output=True, text=True, check=True).stdout.strip())
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(run + ["profile", str(Path(tmp) / "p.prof"), str(a.top)], env=env,
                             capture_output=True, text=True, check=True).stdout
    print("\n".join(line for line in out.splitlines() if line.strip())[-4000:])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
