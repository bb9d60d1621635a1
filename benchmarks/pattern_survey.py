"""Survey: the default `generate` on every piece of every real pattern file.

    python benchmarks/pattern_survey.py [--edge-length 10mm] [FILES...] [--json out.json]
    python benchmarks/pattern_survey.py --edge-length 10mm --vs-length 3     # issue 16, item 4

Per piece: corners method, folded cells, smallest/largest angle (corner cells
aside), edge spread, seconds. A summary at the end.

``--vs-length N``: also times ``clothgrid.generate`` alone on each piece's boundary (no reading,
corner choice, quality or writing), with the options' functional against ``functional="length"``
in the same run, alternating, best of ``N`` each: the per-piece ratios (median, how many at most
2x) and the totals' ratio.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from clothgrid.errors import ClothgridError  # noqa: E402
from clothgrid.pipeline import GridOptions, read_jobs, run_job  # noqa: E402
from clothgrid.quality import sim_figures  # noqa: E402

SHARED = ROOT.parent / "shared" / "patterns"


def _vs_length(job, repeat: int) -> tuple[float, float]:
    """Seconds of ``generate`` on the job's boundary with its options' functional and with
    ``functional="length"``: best of ``repeat`` each, alternating."""
    from clothgrid import generate

    kw = job.options.generate_kwargs()
    best = {kw.pop("functional"): np.inf, "length": np.inf}
    for _ in range(repeat):
        for fun in best:
            t0 = time.perf_counter()
            generate(job.boundary, job.nodes, functional=fun, **kw)
            best[fun] = min(best[fun], time.perf_counter() - t0)
    return tuple(best.values())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="*")
    ap.add_argument("--edge-length", default=None)
    ap.add_argument("--functional", default=None)
    ap.add_argument("--weights", default=None)
    ap.add_argument("--json")
    ap.add_argument("--vs-length", type=int, default=0, metavar="N",
                    help="also time generate alone against functional='length', best of N each, alternating")
    a = ap.parse_args(argv)
    files = [Path(f) for f in a.files] or sorted(p for p in SHARED.iterdir()
                                                 if p.suffix.lower() in (".svg", ".dxf", ".json"))
    kw = {}
    if a.edge_length:
        kw["edge_length"] = a.edge_length
    if a.functional:
        kw["functional"] = a.functional
    if a.weights:
        kw["weights"] = a.weights
    opts = GridOptions(**kw)
    rows = []
    for f in files:
        t0 = time.perf_counter()
        try:
            jobs = read_jobs(f, ["/tmp/survey_{piece}.npz"], options=opts)
        except ClothgridError as exc:
            rows.append({"file": f.name, "piece": None, "error": str(exc)})
            print(f"{f.name}: FILE ERROR {exc}", flush=True)
            continue
        for job in jobs:
            t1 = time.perf_counter()
            try:
                r = run_job(job)
            except ClothgridError as exc:
                rows.append({"file": f.name, "piece": job.name, "error": str(exc)})
                print(f"  {f.name}:{job.name}: ERROR {exc}", flush=True)
                continue
            P = r.grid.points
            fig = sim_figures(P)
            row = {"file": f.name, "piece": job.name, "nodes": list(P.shape[:2]),
                   "method": job.piece["corners"]["method"], "folded": int(r.quality.folded),
                   "min_angle": fig["min_angle_deg"], "max_angle": fig["max_angle_deg"],
                   "spread": fig["edge_spread"], "shortest": fig["shortest_edge"],
                   "edge_length": job.edge_length, "seconds": time.perf_counter() - t1}
            if a.vs_length:
                row["generate"], row["length"] = _vs_length(job, a.vs_length)
            rows.append(row)
        print(f"{f.name}: {len(jobs)} pieces, {time.perf_counter() - t0:.1f} s, folded pieces "
              f"{sum(1 for r in rows if r['file'] == f.name and r.get('folded'))}", flush=True)
    ok = [r for r in rows if "folded" in r]
    err = [r for r in rows if "error" in r]
    if ok:
        ang = np.array([r["min_angle"] for r in ok])
        sp = np.array([r["spread"] for r in ok])
        print(f"\npieces {len(ok)}, errors {len(err)}, folded pieces {sum(r['folded'] > 0 for r in ok)} "
              f"({sum(r['folded'] for r in ok)} cells)")
        print(f"min angle >= 10: {np.mean(ang >= 10) * 100:.1f} %, >= 3: {np.mean(ang >= 3) * 100:.1f} %, "
              f"worst {ang.min():.2f}")
        print(f"edge spread median {np.median(sp):.2f}, max {sp.max():.1f}")
        print(f"seconds total {sum(r['seconds'] for r in ok):.1f}")
        if a.vs_length:
            g = np.array([r["generate"] for r in ok])
            n = np.array([r["length"] for r in ok])
            ratio = g / n
            print(f"generate alone, best of {a.vs_length}: {opts.functional} {g.sum():.3f} s against length "
                  f"{n.sum():.3f} s ({g.sum() / n.sum():.2f}x); per piece median {np.median(ratio):.2f}x, "
                  f"{int(np.sum(ratio <= 2))} of {len(ok)} pieces at most 2x")
            step = (g - n) / n          # the step after the length solve, against that solve
            print(f"the step alone (generate less its length run) against the length run: summed "
                  f"{(g - n).sum() / n.sum():.2f}x, per piece median {np.median(step):.2f}x, "
                  f"{int(np.sum(step <= 2))} of {len(ok)} pieces at most 2x")
        worst = sorted(ok, key=lambda r: r["min_angle"])[:10]
        for r in worst:
            print(f"  {r['file']}:{r['piece']} {r['method']} folded {r['folded']} angle {r['min_angle']:.1f} spread {r['spread']:.1f}")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
