"""clothgrid.pipeline: one path from a boundary file or a pattern file to the output files."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import REGIONS

from clothgrid import InputError, NotConvergedError, PiecesError, SizeError, pipeline, quality
from clothgrid.pipeline import GridOptions, OutputOptions, read_jobs, run_job, run_jobs, write_results
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


# --------------------------------------------------------------------------- per-piece failures and sizes

SHARED = Path(__file__).parents[2] / "shared" / "patterns"
_UNITS = {"B": 1, "KiB": 2**10, "MiB": 2**20, "GiB": 2**30, "TiB": 2**40, "PiB": 2**50, "EiB": 2**60}

TWO_SIZES = ('<svg xmlns="http://www.w3.org/2000/svg" width="1100mm" height="600mm" viewBox="0 0 1100 600">'
             '<rect id="small" x="0" y="0" width="80" height="80"/>'       # not too small to be a piece
             '<rect id="big" x="100" y="0" width="1000" height="500"/>'
             '<path id="line" d="M 0 550 L 90 550 Z"/></svg>')


def _bytes(number: str, unit: str) -> float:
    return float(number.replace(",", "")) * _UNITS[unit]


def _no_gridding(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("a grid was made before the sizes were checked")
    monkeypatch.setattr(pipeline, "generate", refuse)


def _check_numbers(message: str) -> None:
    """needs N > 90 % of A = B: the numbers of the memory message agree with its rule."""
    m = re.search(r"needs about ([\d.,]+) (\w+) of memory.*?: 90% of the ([\d.]+) (\w+) available is "
                  r"([\d.]+) (\w+)", message)
    assert m, message
    need, have, limit = _bytes(*m.group(1, 2)), _bytes(*m.group(3, 4)), _bytes(*m.group(5, 6))
    assert limit == pytest.approx(0.9 * have, rel=1e-3)
    assert need > limit


def test_a_piece_that_cannot_fit_is_refused_before_any_grid(tmp_path, monkeypatch):
    """Each piece's size is checked first: the big one fails alone (named), the small one goes on."""
    from clothgrid import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 200 * 2**20)     # 200 MiB
    svg = tmp_path / "two.svg"
    svg.write_text(TWO_SIZES)
    _no_gridding(monkeypatch)
    jobs = read_jobs(svg, [tmp_path / "{piece}.npz"], options=GridOptions(edge_length="0.5mm"))
    assert [j.name for j in jobs] == ["small"]
    assert [(f.name, f.stage) for f in jobs.failed] == [("big", "size"), ("line", "read")]
    big = jobs.failed[0]
    assert isinstance(big.error, SizeError) and big.reason.startswith("a 2001x1001 grid with solver")
    assert "piece 'big'" in big.message(svg)
    _check_numbers(big.reason)


@pytest.mark.parametrize("edge", ["0.01mm", "0.001mm"])
def test_tiny_edge_length_on_a_real_dxf_is_refused_quickly(capsys, tmp_path, monkeypatch, edge):
    from clothgrid.cli import main

    src = SHARED / "astm_clo-box.dxf"
    if not src.exists():
        pytest.skip(f"no {src}")
    _no_gridding(monkeypatch)
    t0 = time.perf_counter()
    code = main(["generate", str(src), "-o", str(tmp_path / "{piece}.npz"), "--edge-length", edge])
    _, err = capsys.readouterr()
    assert time.perf_counter() - t0 < 20
    assert code == 2 and list(tmp_path.iterdir()) == []
    line = [ln for ln in err.splitlines() if "needs about" in ln][0]
    assert f"{src}: piece '" in line          # which piece
    _check_numbers(line)


def test_the_grids_kept_for_writing_count_in_the_later_pieces_memory(tmp_path, monkeypatch):
    from clothgrid import memory

    svg = tmp_path / "twins.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="100mm" viewBox="0 0 300 100">'
                   '<rect id="a" x="0" y="0" width="100" height="100"/>'
                   '<rect id="b" x="150" y="0" width="100" height="100"/></svg>')
    nodes = 1001 * 1001
    need = memory.estimate_bytes("multigrid", 1001, 1001, coords=2, separable=True)   # as the pieces ask
    # room for one grid and its solve, not for a second beside the first one's kept result
    monkeypatch.setattr(memory, "available_bytes", lambda: int((need + 0.5 * memory.KEPT_BYTES_PER_NODE * nodes) / 0.9))
    jobs = read_jobs(svg, [tmp_path / "{piece}.npz"], options=GridOptions(edge_length="0.1mm", solver="multigrid"))
    assert [j.name for j in jobs] == ["a"] and [f.name for f in jobs.failed] == ["b"]
    assert "for the grids made before it, kept until the outputs are written" in jobs.failed[0].reason


def test_run_jobs_goes_on_after_a_failed_piece(tmp_path, monkeypatch):
    svg = tmp_path / "two.svg"
    svg.write_text(TWO_SIZES.replace('width="1000" height="500"', 'width="20" height="10"'))
    jobs = read_jobs(svg, [tmp_path / "{piece}.npz"], options=GridOptions(nodes=9, solver="direct"))
    real = pipeline.generate

    def generate(boundary, nodes, **kw):
        if boundary.name == "small":
            raise NotConvergedError("did not converge (test)")
        return real(boundary, nodes, **kw)

    monkeypatch.setattr(pipeline, "generate", generate)
    seen = []
    results, failed = run_jobs(jobs, done=lambda r: seen.append(r.job.name))
    assert [r.job.name for r in results] == seen == ["big"]
    assert [(f.name, f.stage) for f in failed] == [("line", "read"), ("small", "grid")]
    write_results(results)
    assert sorted(p.name for p in tmp_path.glob("*.npz")) == ["big.npz"]
    # nothing left: the error lists every piece
    monkeypatch.setattr(pipeline, "generate", lambda *a, **k: (_ for _ in ()).throw(NotConvergedError("no")))
    with pytest.raises(PiecesError) as info:
        run_jobs(jobs)
    assert sorted(f.name for f in info.value.failed) == ["big", "line", "small"]


def test_run_job_measures_the_quality_of_each_grid_once(monkeypatch):
    """generate's fold-free step measures the length grid's quality first; where it hands that grid
    back (nothing poor, nothing to even), or a grid of its own, run_job reads the measure instead
    of taking it again: never two quality passes over the same grid."""
    import importlib

    from clothgrid import Boundary

    quality_module = importlib.import_module("clothgrid.quality")
    measured = []
    real = quality_module.quality_record

    def counting(grid, **kw):          # quality() is quality_record()'s first half
        measured.append(id(grid))
        return real(grid, **kw)

    monkeypatch.setattr(quality_module, "quality_record", counting)
    t = np.linspace(0.0, 1.0, 9)
    z = np.zeros_like(t)
    b = Boundary.from_sides(np.c_[t, z, z], np.c_[z + 1, t, z], np.c_[t, z + 1, z], np.c_[z, t, z])
    kinds = set()
    for options in (GridOptions(functional="auto"), GridOptions(functional="auto", weights="paper")):
        measured.clear()
        result = run_job(pipeline.Job(name="square", boundary=b, nodes=(33, 21), outputs=[], options=options))
        kinds.add(result.grid.info["functional"])
        assert len(measured) == len(set(measured)) >= 1, measured
    assert "length" in kinds        # a square with uniform weights: nothing to relax or even
