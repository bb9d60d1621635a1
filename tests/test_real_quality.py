"""Issue 12: real pattern pieces gridded fold-free by default, corners off the darts, the quality report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from clothgrid.cli import main
from clothgrid.foldfree import relax
from clothgrid.pipeline import generate_piece, select_pieces
from clothgrid.quality import quality, sim_figures

SHARED = Path(__file__).resolve().parents[2] / "shared" / "patterns"
PANTS = SHARED / "gcn_rand_JIT6TDX7XB_specification.json"   # back panels with two deep darts
SKIRT = SHARED / "gpg_skirt_4_panels_specification.json"

needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/patterns is not here")


@needs_shared
def test_default_grid_of_a_dart_panel_is_fold_free_where_the_papers_folds():
    piece = select_pieces(PANTS, ["pant_b_r"])[0]
    paper = generate_piece(piece, weights="paper", functional="length")
    assert quality(paper).folded > 50                         # measured 123 before this issue
    grid = generate_piece(piece)                              # defaults: uniform, auto
    q = grid.info["quality"] if "quality" in grid.info else None
    assert quality(grid).folded == 0
    fig = sim_figures(grid.points, 10.0)
    assert fig["min_angle_deg"] >= 3.0                        # measured 4.3
    assert q is None or q["folded"] == 0
    # boundary nodes are kept bit for bit
    assert np.array_equal(grid.points[0], paper.points[0]) and np.array_equal(grid.points[:, -1], paper.points[:, -1])


@needs_shared
def test_corners_of_a_dart_panel_are_not_at_one_dart():
    piece = select_pieces(PANTS, ["pant_b_r"])[0]
    grid = generate_piece(piece)
    pts = np.asarray(grid.info["piece"]["corners"]["points"])   # bottom-left, bottom-right, top-right, top-left
    width = piece.extent[0]
    assert np.linalg.norm(pts[2] - pts[3]) > 0.4 * width          # was 30 mm apart (both at a dart's mouth)
    assert np.linalg.norm(pts[0] - pts[1]) > 0.8 * width


def test_relax_unfolds_a_folded_grid_and_keeps_the_boundary():
    rng = np.random.default_rng(3)
    u, v = np.meshgrid(np.linspace(0, 1, 12), np.linspace(0, 1, 9), indexing="ij")
    P = np.stack([u, v, 0 * u], -1)
    P[1:-1, 1:-1, :2] += rng.uniform(-0.12, 0.12, P[1:-1, 1:-1, :2].shape)   # scrambled interior
    from clothgrid.grid import Grid
    assert quality(Grid.from_points(P, dim=2)).folded > 0
    Q, info = relax(P, dim=2)
    assert info["untangled"] and quality(Grid.from_points(Q, dim=2)).folded == 0
    ring = np.ones(P.shape[:2], bool)
    ring[1:-1, 1:-1] = False
    assert np.array_equal(Q[ring], P[ring])
    assert sim_figures(Q)["min_angle_deg"] > 45                 # a square's grid comes back near-square


def test_sim_figures_on_a_known_grid():
    # a 2 x 1 grid of a parallelogram sheared by 45 degrees, edges 1 and sqrt(2)
    u, v = np.meshgrid(np.arange(4.0), np.arange(3.0), indexing="ij")
    P = np.stack([u + v, v, 0 * u], -1)
    f = sim_figures(P, 0.5)
    assert f["min_angle_deg"] == pytest.approx(45.0) and f["max_angle_deg"] == pytest.approx(135.0)
    assert f["edge_spread"] == pytest.approx(np.sqrt(2)) and f["shortest_vs_target"] == pytest.approx(2.0)
    assert f["corner_cell_angles_deg"][0] == pytest.approx(45.0)


@needs_shared
def test_report_json_and_a_report_that_cannot_be_written(tmp_path):
    out = tmp_path / "m"
    rep = tmp_path / "q.json"
    assert main(["generate", str(SKIRT), "-o", str(out / "{piece}.npz"), "--report", str(rep), "-q"]) == 0
    data = json.loads(rep.read_text())
    assert sorted(p["name"] for p in data["pieces"]) == ["back", "front", "left", "right"]
    for p in data["pieces"]:
        assert p["folded"] == 0 and p["missed"] == [] and p["min_angle_deg"] > 75   # measured 79.9 / 82.6
        assert p["edge_spread"] < 3.1 and p["corners"]["method"]
    bad = tmp_path / "no" / "such" / "q.json"
    out2 = tmp_path / "m2"
    assert main(["generate", str(SKIRT), "-o", str(out2 / "{piece}.npz"), "--report", str(bad), "-q"]) == 2
    assert not out2.exists() or not any(out2.iterdir())
