"""Batch benchmark: pieces per second of ``clothgrid batch`` (1 and 2 local workers) against a
shell loop of ``clothgrid generate`` over the same files, all in this one run on this machine.

Run ``python benchmarks/bench_batch.py [FILES or FOLDERS ...] [--edge-length 10mm]
[--workers 1 2] [--json OUT.json]``. Default input: the 14 GarmentCode JSON specifications
of ``../shared/patterns`` (9 GarmentCodeData samples, 5 GPG templates), at the pattern default
edge length of 10 mm.

For each way it prints the wall time, the files and pieces gridded, pieces per second, and for
the batch runs the start-up (cluster and warm-up) apart from the gridding. It also prints the
per-garment worker time (sum of the tasks' times / files, from the 1-worker run): the figure
the cluster plan in docs/batch.md starts from. Load average is printed too: the runs share the
machine with whatever else runs there.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "patterns"


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}


def shell_loop(files: list[Path], out: Path, edge: str) -> dict:
    """``for f in FILES; do clothgrid generate "$f" -o OUT/<stem>/{piece}.npz ...; done``."""
    cmd = (f"for f in {' '.join(shlex.quote(str(f)) for f in files)}; do "
           f"s=$(basename \"$f\"); s=\"${{s%.*}}\"; mkdir -p {shlex.quote(str(out))}/\"$s\"; "
           f"{shlex.quote(sys.executable)} -m clothgrid generate \"$f\" -o {shlex.quote(str(out))}/\"$s\"/{{piece}}.npz "
           f"--edge-length {edge} -q > /dev/null 2>&1; done")
    t0 = time.perf_counter()
    subprocess.run(["bash", "-c", cmd], env=_env(), check=False)
    wall = time.perf_counter() - t0
    pieces = len(list(out.rglob("*.npz")))
    return {"way": "shell loop of clothgrid generate", "wall_s": wall, "pieces": pieces, "files": len(files),
            "pieces_per_s": pieces / wall, "command": cmd.replace(str(out), "OUT")}


def batch_run(inputs: list[Path], out: Path, edge: str, workers: int) -> dict:
    cmd = [sys.executable, "-m", "clothgrid", "batch", *map(str, inputs), "-o", str(out),
           "--edge-length", edge, "--workers", str(workers), "-q"]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=_env(), check=False, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    lines = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    s = lines[-1]["summary"]
    entries = lines[:-1]
    task_s = sum(e["timings"]["total"] for e in entries)
    gcn = [e for e in entries if Path(e["input"]).name.startswith("gcn_")]
    return {"way": f"clothgrid batch --workers {workers}", "wall_s": wall, "pieces": s["pieces"],
            "files": s["inputs"], "failed": s["failed"], "pieces_per_s": s["pieces"] / wall,
            "startup_s": s["startup_seconds"], "grid_s": s["seconds"],
            "pieces_per_s_after_startup": s["pieces_per_s"], "task_s_per_file": task_s / len(entries),
            "cpu_s_per_file": sum(e["timings"]["cpu"] for e in entries) / len(entries),
            "gcn_files": len(gcn), "gcn_pieces": sum(len(e["pieces"]) for e in gcn),
            "gcn_cpu_s_per_file": sum(e["timings"]["cpu"] for e in gcn) / len(gcn) if gcn else None,
            "npz_bytes": sum((out / o).stat().st_size for e in entries for o in e["outputs"]),
            "manifest_bytes": (out / "manifest.jsonl").stat().st_size,
            "command": " ".join(shlex.quote(c) for c in cmd[1:]).replace(str(out), "OUT")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("inputs", nargs="*", type=Path)
    ap.add_argument("--edge-length", default="10mm")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    inputs = args.inputs or sorted(SHARED.glob("g*_specification.json"))
    files = []
    for p in inputs:
        files += sorted(q for q in p.rglob("*") if q.suffix.lower() in (".json", ".svg", ".dxf")) if p.is_dir() else [p]
    print(f"{len(files)} files, edge length {args.edge_length}; {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.2f} at the start")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows.append(shell_loop(files, Path(tmp) / "loop", args.edge_length))
        for w in args.workers:
            rows.append(batch_run(files, Path(tmp) / f"batch{w}", args.edge_length, w))
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    print(f"{'way':38s} {'wall s':>8s} {'files':>6s} {'pieces':>7s} {'pieces/s':>9s} {'start-up s':>11s} "
          f"{'pieces/s after start-up':>24s}")
    for r in rows:
        print(f"{r['way']:38s} {r['wall_s']:8.1f} {r['files']:6d} {r['pieces']:7d} {r['pieces_per_s']:9.2f} "
              f"{r.get('startup_s', float('nan')):11.1f} {r.get('pieces_per_s_after_startup') or float('nan'):24.2f}")
    one = next((r for r in rows if r["way"].endswith("--workers 1")), None)
    if one:
        print(f"per file (1 worker, tasks only): {one['task_s_per_file']:.3f} s wall, {one['cpu_s_per_file']:.3f} s CPU; "
              f"{one['pieces'] / one['files']:.1f} pieces per file; {one['npz_bytes'] / max(1, one['pieces']) / 1e3:.0f} kB "
              f"of .npz per piece; {one['manifest_bytes'] / one['files'] / 1e3:.1f} kB of manifest per file")
        if one["gcn_files"]:
            print(f"GarmentCodeData samples (gcn_*): {one['gcn_files']} files, {one['gcn_pieces']} pieces, "
                  f"{one['gcn_cpu_s_per_file']:.3f} s CPU per garment")
    if args.json:
        args.json.write_text(json.dumps({"files": [str(f) for f in files], "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
