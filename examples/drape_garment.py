"""Sew a GarmentCode garment with clothgrid and drape it on a body proxy with NVIDIA Newton.

The garment is gridded and sewn node for node (``clothgrid.garment``), welded, and handed to
Newton's Style3D cloth solver with the flat pattern as its rest shape (``clothgrid.drape``); the
body is a proxy of capsules in the spec's frame. It runs on the CPU (Warp's CPU device; the first
run compiles Warp's kernels, about 1.5 minutes, cached on disk after) or on a GPU
(``--device cuda:0``). Needs ``pip install 'clothgrid[sim]'``::

    python examples/drape_garment.py ../shared/patterns/gpg_dress_specification.json \\
        --edge-length 3cm --seconds 2 --plot docs/garment-drape.png --json drape.json

Prints the figures (timings, how far the cloth sank into the body, the edge strain against the
pattern) and exits 0 when the checks pass: every position finite, Newton kept every triangle
with the pattern's rest area (the rest shape is the pattern), the median edge within 2 % of its
pattern length, and the cloth caught by the body (its mean height above the lowest body part's top,
no node deeper than 5 cm inside a capsule); 1 otherwise; 2 for a bad input. The 99th percentile
strain is printed, not checked: where a fitted pattern meets a proxy body of other proportions it
stretches (the dress's bodice by 10-30 %).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def plot(res, path: Path, title: str) -> None:
    """Front and side views, before (welded start) and after the drape, with the body."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    cmap = matplotlib.colormaps["viridis"]
    tri_strain = np.abs(res.edge_strain).reshape(3, -1).max(axis=0)     # (T,): two triangles per quad
    strain = tri_strain.reshape(-1, 2).max(axis=1)
    fig = plt.figure(figsize=(13, 5.6))
    views = [("start, front", res.start, (0, 90)), ("start, side", res.start, (0, 0)),
             (f"after {res.frames / 30:.1f} s, front", res.final, (0, 90)),
             (f"after {res.frames / 30:.1f} s, side", res.final, (0, 0))]
    allp = np.vstack([res.start, res.final])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    mid, half = 0.5 * (lo + hi), 0.5 * float((hi - lo).max()) * 1.05
    u = np.linspace(0, 2 * np.pi, 18)
    v = np.linspace(0, np.pi, 9)
    for k, (name, pts, (elev, azim)) in enumerate(views):
        ax = fig.add_axes((0.005 + 0.225 * k, 0.0, 0.225, 0.9), projection="3d")
        for cap in res.body.capsules:                 # the body: capsules as sampled surfaces
            a, b = np.asarray(cap.a), np.asarray(cap.b)
            for t in np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) / 0.03) + 1)):
                c = a + t * (b - a)
                xs = c[0] + cap.radius * np.outer(np.cos(u), np.sin(v))
                ys = c[1] + cap.radius * np.outer(np.ones_like(u), np.cos(v))
                zs = c[2] + cap.radius * np.outer(np.sin(u), np.sin(v))
                ax.plot_surface(xs, zs, ys, color="#d9c3a5", linewidth=0, alpha=0.25, shade=False)
        polys = pts[res.quads][:, :, [0, 2, 1]]        # matplotlib's z up: show (x, z, y)
        nrm = np.cross(polys[:, 2] - polys[:, 0], polys[:, 3] - polys[:, 1])
        shade = 0.55 + 0.45 * np.abs(nrm @ np.array([0.3, -0.5, 0.8])) / np.maximum(
            np.linalg.norm(nrm, axis=1), 1e-12)
        if pts is res.start:
            col = np.column_stack([0.25 * shade, 0.45 * shade, 0.85 * shade, np.ones_like(shade)])
        else:                                          # colour by the quad's largest edge strain
            col = cmap(np.clip(strain / 0.2, 0, 1)) * np.column_stack([shade] * 3 + [np.ones_like(shade)])
        ax.add_collection3d(Poly3DCollection(polys, facecolors=col, edgecolors=(0, 0, 0, 0.15), linewidths=0.2))
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[2] - half, mid[2] + half)
        ax.set_zlim(mid[1] - half, mid[1] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        ax.set_title(name, fontsize=10)
    sm = matplotlib.cm.ScalarMappable(cmap=cmap, norm=matplotlib.colors.Normalize(0, 20))
    fig.colorbar(sm, cax=fig.add_axes((0.925, 0.2, 0.012, 0.55)),
                 label="after: largest edge strain\nagainst the pattern (%)")
    fig.suptitle(title, fontsize=11)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("spec", help="GarmentCode / Garment-Pattern-Generator specification (.json)")
    p.add_argument("--edge-length", default="3cm")
    p.add_argument("--seconds", type=float, default=2.0, help="simulated time (default 2)")
    p.add_argument("--fps", type=int, default=30)
    p.add_argument("--substeps", type=int, default=10)
    p.add_argument("--device", default="cpu", help="Warp device: cpu (default) or cuda:0")
    p.add_argument("--frame", choices=("auto", "garmentcode", "gpg"), default="auto",
                   help="the spec's body frame (auto: by the garment's height)")
    p.add_argument("--plot", type=Path, help="PNG: front and side views before and after")
    p.add_argument("--json", type=Path, help="write the figures as JSON")
    a = p.parse_args(argv)

    from clothgrid.drape import body_proxy, drape, guess_frame
    from clothgrid.errors import ClothgridError
    from clothgrid.garment import garment

    t0 = time.perf_counter()
    try:
        g = garment(a.spec, edge_length=a.edge_length)
        t_sew = time.perf_counter() - t0
        frame = guess_frame(g.points / 1000.0) if a.frame == "auto" else a.frame
        res = drape(g, body_proxy(frame), seconds=a.seconds, fps=a.fps, substeps=a.substeps, device=a.device,
                    progress=lambda s: print(s, flush=True))
    except ClothgridError as exc:
        print(f"drape_garment: error: {exc}", file=sys.stderr)
        return 2
    rep = res.report()
    rep["sew_s"] = t_sew
    rep["body_frame"] = frame
    rep["spec"] = Path(a.spec).name
    rep["edge_length"] = a.edge_length
    rep["panels"] = len(g.panel_names)
    rep["grid_nodes"] = int(len(g.points))
    for k in ("start_mean_y", "final_mean_y", "strain_median", "strain_p99", "deepest_in_body_m"):
        print(f"{k:>18}: {rep[k]:.4f}")
    print(f"{'seconds':>18}: " + ", ".join(f"{k} {v:.2f}" for k, v in rep["seconds"].items()))
    checks = {"finite": rep["finite"],
              "every triangle kept": rep["model_triangles"] == rep["triangles"],
              "rest area = pattern area": abs(rep["rest_area_m2"] - rep["pattern_area_m2"])
              <= 1e-6 * rep["pattern_area_m2"],
              "median edge within 2 % of the pattern": rep["strain_median"] < 0.02,
              "no node 5 cm inside the body": rep["deepest_in_body_m"] < 0.05,
              "caught by the body (above the floor)": rep["final_mean_y"] > res.body.floor + 0.2}
    rep["checks"] = checks
    for k, ok in checks.items():
        print(f"{'ok' if ok else 'FAILED':>6}  {k}")
    if a.json:
        a.json.write_text(json.dumps(rep, indent=1))
    if a.plot:
        plot(res, a.plot, f"{rep['spec']}: {rep['panels']} panels, {rep['vertices']} welded nodes at "
                          f"{a.edge_length}; Newton Style3D on {rep['device']}, {rep['simulated_s']:.1f} s "
                          f"simulated in {rep['seconds']['frames'] + rep['seconds']['first_frame']:.0f} s")
    return 0 if all(checks.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
