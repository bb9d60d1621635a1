"""The memory check's cost on real pieces: ``generate`` on every piece of the shared pattern files
with small grids checked against the system (``memory.SMALL_BYTES = 0``) and not (the default),
alternating in one process, for the default functional and ``functional="length"``.

    python benchmarks/bench_memory_check.py [--edge-length 10mm] [--rounds 3]

Prints each round's summed ``generate`` seconds and the ratio of the best rounds.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from clothgrid import generate, memory  # noqa: E402
from clothgrid.errors import ClothgridError  # noqa: E402
from clothgrid.pipeline import GridOptions, read_jobs  # noqa: E402

SHARED = ROOT.parent / "shared" / "patterns"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--edge-length", default="10mm")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    jobs = []
    for f in sorted(p for p in SHARED.iterdir() if p.suffix.lower() in (".svg", ".dxf", ".json")):
        try:
            jobs += read_jobs(f, ["/tmp/unused_{piece}.npz"], options=GridOptions(edge_length=a.edge_length))
        except ClothgridError:
            pass

    def run(functional: str) -> float:
        total = 0.0
        for job in jobs:
            kw = job.options.generate_kwargs()
            kw["functional"] = functional
            t0 = time.perf_counter()
            try:
                generate(job.boundary, job.nodes, **kw)
            except ClothgridError:
                pass
            total += time.perf_counter() - t0
        return total

    default = memory.SMALL_BYTES
    run("auto"), run("length")                       # warm: Numba's cache, the files' pages
    rows: dict[tuple[str, str], list[float]] = {}
    for _ in range(a.rounds):
        for label, small in (("every grid checked", 0), ("small grids not checked", default)):
            memory.SMALL_BYTES = small
            for functional in ("auto", "length"):
                rows.setdefault((functional, label), []).append(run(functional))
    memory.SMALL_BYTES = default
    print(f"{len(jobs)} pieces at {a.edge_length}, generate seconds summed, {a.rounds} rounds")
    print("| functional | every grid checked | small grids not checked | ratio (best rounds) |")
    print("|---|---|---|---|")
    for functional in ("auto", "length"):
        full, small = rows[(functional, "every grid checked")], rows[(functional, "small grids not checked")]
        print(f"| {functional} | {min(full):.3f}-{max(full):.3f} s | {min(small):.3f}-{max(small):.3f} s "
              f"| {min(small) / min(full):.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
