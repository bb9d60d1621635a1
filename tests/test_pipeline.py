"""clothgrid.pipeline: one path from a boundary file or a pattern file to the output files."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REGIONS

from clothgrid import InputError, quality
from clothgrid.pipeline import GridOptions, OutputOptions, read_jobs, run_job, write_results
from clothgrid.readers import load_npz

DXF = REGIONS.parent / "patterns" / "square.dxf"
REGION = REGIONS / "roache-horn.json"


def test_options_are_checked_when_made():
    with pytest.raises(InputError, match="not both"):
        GridOptions(nodes=9, edge_length="5mm")
    with pytest.raises(InputError, match="unknown solver"):
        GridOptions(solver="magic")
    with pytest.raises(InputError, match="tol"):
        GridOptions(tol=2.0)
    with pytest.raises(InputError, match="functional"):
        GridOptions(functional="area")
    assert GridOptions(nodes="9x7").nodes == (9, 7)
    with pytest.raises(Exception):          # frozen: checked once, never changed after
        GridOptions().solver = "direct"


def test_boundary_file_and_pattern_file_take_the_same_steps(tmp_path):
    """A boundary JSON is one job, a pattern file one job per piece; both run and write alike."""
    opts = GridOptions(nodes=(17, 13), solver="direct")
    region_jobs = read_jobs(REGION, [tmp_path / "horn.npz"], options=opts)
    pattern_jobs = read_jobs(DXF, [tmp_path / "{piece}.npz"], tmp_path / "{piece}.png", options=opts)
    assert len(region_jobs) == 1 and region_jobs[0].piece is None and region_jobs[0].length_unit == "m"
    assert len(pattern_jobs) == 1 and pattern_jobs[0].piece["name"] == pattern_jobs[0].name
    assert pattern_jobs[0].length_unit == "mm" and pattern_jobs[0].corners
    assert sorted(p.name for p in tmp_path.iterdir()) == []          # nothing written yet
    results = [run_job(j) for j in region_jobs + pattern_jobs]
    for r in results:
        assert r.grid.shape == (17, 13) and r.seconds > 0
        fresh = quality(r.grid)
        assert r.quality.folded == fresh.folded
        assert r.quality.min_scaled_jacobian == pytest.approx(fresh.min_scaled_jacobian)
    written = write_results(results, OutputOptions(cloth=True))
    assert len(written) == 3 and all(p.exists() for p in written)
    for r in results:
        back = load_npz(r.job.outputs[0])
        np.testing.assert_array_equal(back.points, r.grid.points)
        assert back.info["length_unit"] == r.job.length_unit
    with np.load(results[1].job.outputs[0]) as z:
        assert "spring_rest_length" in z.files   # OutputOptions(cloth=True) reached the writer


def test_outputs_checked_before_any_grid(tmp_path):
    opts = GridOptions(nodes=9)
    with pytest.raises(InputError, match="unknown output format"):
        read_jobs(REGION, [tmp_path / "g.xyz"], options=opts)
    (tmp_path / "afile").write_text("")
    with pytest.raises(InputError, match="is not a folder"):
        read_jobs(REGION, [tmp_path / "afile" / "g.npz"], options=opts)
    with pytest.raises(InputError, match="for pattern files"):
        read_jobs(REGION, [tmp_path / "g.npz"], options=opts, pieces=["front"])


def test_a_failed_write_removes_every_file_of_the_call(tmp_path):
    opts = GridOptions(nodes=9, solver="direct")
    jobs = read_jobs(REGION, [tmp_path / "a.npz"], options=opts) + \
        read_jobs(REGION, [tmp_path / "b.npz"], options=opts)
    results = [run_job(j) for j in jobs]
    (tmp_path / "b.npz").mkdir()          # the second output cannot be written
    with pytest.raises(InputError):
        write_results(results)
    assert [p.name for p in tmp_path.iterdir()] == ["b.npz"] and not (tmp_path / "a.npz").exists()
