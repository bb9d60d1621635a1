"""Two clothgrid runs side by side on a machine's cores: with libgomp's default spin and with clothgrid's.

    python benchmarks/bench_contention.py            # about 1-2 min on 2 cores
    python benchmarks/bench_contention.py --solves 3 --pieces 40

Numba's parallel kernels run on GNU OpenMP threads (Numba's ``omp`` threading layer). A thread
that has finished its share of a parallel loop busy-waits for the next loop, ``GOMP_SPINCOUNT``
times, before it sleeps; a loop ends only when its last thread does. On an idle machine the spin
saves a wake-up a loop; on a busy one the system parks one thread behind other work while the
other spins on, and every parallel loop waits a whole time slice. clothgrid sets
``GOMP_SPINCOUNT`` to :data:`clothgrid._startup.OPENMP_SPIN` on import where the user set
neither it nor ``OMP_WAIT_POLICY``.

Each run is a fresh process doing the same work: ``--solves`` multigrid solves of the bundled
T-shirt front at ``--nodes`` (paper weights, to the true 2^-12 bound) and the default
(``functional="auto"``) grid of ``--pieces`` resamplings of it at 24-120 nodes a side, the sizes
of real pieces at 10 mm. For each spin setting it prints the seconds of one run alone, and of
each of two runs started together (the slower one), and their ratio: two runs sharing the cores
fairly take about twice as long as one.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

WORK = r"""
import sys, time
import clothgrid
from clothgrid.readers import load_boundary
b = load_boundary(sys.argv[1])
n, solves, pieces = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
clothgrid.generate(b.resampled(33, 33), weights="paper")          # compiled kernels loaded: not timed
clothgrid.generate(b.resampled(33, 33))
t = time.perf_counter()
for _ in range(solves):
    clothgrid.generate(b.resampled(n, n), solver="multigrid", weights="paper")
for k in range(pieces):
    m = 24 + (37 * k) % 97
    clothgrid.generate(b.resampled(m, m + 7 * (k % 5)))
print(time.perf_counter() - t)
"""

#: libgomp's own default spin count (where neither GOMP_SPINCOUNT nor OMP_WAIT_POLICY is set)
LIBGOMP_DEFAULT = "300000"


def runs(together: int, spin: str | None, args) -> float:
    """Seconds of the slowest of ``together`` runs started at once, with ``GOMP_SPINCOUNT=spin``
    (None: clothgrid's own choice)."""
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    if spin is not None:
        env["GOMP_SPINCOUNT"] = spin
    cmd = [sys.executable, "-c", WORK, str(args.piece), str(args.nodes), str(args.solves), str(args.pieces)]
    procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True) for _ in range(together)]
    outs = [p.communicate()[0] for p in procs]
    if any(p.returncode for p in procs):
        raise SystemExit(f"a run failed: {outs}")
    return max(float(o.split()[-1]) for o in outs)


def main() -> None:
    from bench_speed import PIECE

    import clothgrid
    from clothgrid._startup import OPENMP_SPIN

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piece", default=PIECE)
    ap.add_argument("--nodes", type=int, default=512)
    ap.add_argument("--solves", type=int, default=3)
    ap.add_argument("--pieces", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=2, help="best of this many, alone and together")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, clothgrid {clothgrid.__version__}, load {os.getloadavg()[0]:.2f}; "
          f"work: {args.solves} solves at {args.nodes}^2 (paper weights), {args.pieces} auto grids of 24-120 nodes a side\n")
    print("| GOMP_SPINCOUNT | one run alone, s | two runs at once, s (the slower) | at once / alone |")
    print("|---|---|---|---|")
    for spin, what in ((LIBGOMP_DEFAULT, f"{LIBGOMP_DEFAULT} (libgomp's default)"), (None, f"{OPENMP_SPIN} (clothgrid's)")):
        alone = min(runs(1, spin, args) for _ in range(args.repeat))
        both = min(runs(2, spin, args) for _ in range(args.repeat))
        print(f"| {what} | {alone:.3f} | {both:.3f} | {both / alone:.1f}x |", flush=True)
    print(f"\nload at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    main()
