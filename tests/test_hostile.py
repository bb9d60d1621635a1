"""Hostile input and interruptions (issue 15): a clear error every time, nothing lost or left behind.

One regression per class of the issue's corpus (``benchmarks/hostile_corpus.py`` runs the full
corpus through the command line): tracebacks, hangs, silently wrong results, partial files,
bad inputs accepted, warnings above errors. Most run ``clothgrid.cli.main`` in-process; the
signal cases run a subprocess with a timeout.
"""

from __future__ import annotations

import json
import math
import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from clothgrid.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _square(n: int = 8) -> list[list[float]]:
    per = n // 4
    pts = []
    for k in range(4):
        for i in range(per):
            t = i / per
            pts.append(list([(t, 0.0), (1.0, t), (1.0 - t, 1.0), (0.0, 1.0 - t)][k]))
    return pts


def _boundary(outline, corners=None) -> dict:
    n = len(outline)
    return {"outline": outline, "corners": corners or [0, n // 4, n // 2, 3 * n // 4]}


def _run(capsys, args: list[str]) -> tuple[int, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, err


def _clean_error(code: int, err: str, out_dir: Path, *, codes=(2,), needle: str = "") -> None:
    """One or more ``clothgrid: error:`` lines, no traceback or warning, no file left."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code in codes, err
    assert "Traceback" not in err and "Warning" not in err, err
    assert any(ln.startswith("clothgrid: error:") for ln in lines), err
    assert all(ln.startswith(("clothgrid:", "usage:", " ")) for ln in lines), err
    assert list(out_dir.iterdir()) == [], list(out_dir.iterdir())
    if needle:
        assert needle in err, err


@pytest.fixture
def out(tmp_path: Path) -> Path:
    d = tmp_path / "out"
    d.mkdir()
    return d


def _gen(src: Path, out: Path, *extra: str, name: str = "g.obj") -> list[str]:
    return ["generate", str(src), "-o", str(out / name), "-q", *extra]


# --------------------------------------------------------------------------- tracebacks


@pytest.mark.parametrize("text,needle", [
    ('{"outline": ' + "[" * 100_000 + "]" * 100_000 + ', "corners": [0,1,2,3]}', "nests"),
    ('{"name": ' + '{"a":' * 100_000 + "1" + "}" * 100_000 + "}", "nests"),
    ('{"outline": [[1' + "0" * 400 + ', 0], [1, 0], [1, 1], [0, 1]], "corners": [0,1,2,3]}', "digits"),
])
def test_json_nesting_and_huge_integers_are_limits(capsys, tmp_path, out, text, needle):
    src = tmp_path / "a.json"
    src.write_text(text)
    code, err = _run(capsys, _gen(src, out))
    _clean_error(code, err, out, needle=needle)
    assert str(src) in err


def test_garmentcode_deep_nesting_and_unhashable_order(capsys, tmp_path, out):
    src = tmp_path / "g.json"
    src.write_text('{"pattern": {"panels": ' + "[" * 50_000 + "]" * 50_000 + "}}")
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="nests")
    sq = [[0, 0], [50, 0], [50, 60], [0, 60]]
    spec = {"pattern": {"panels": {"a": {"vertices": sq, "edges": [{"endpoints": [i, (i + 1) % 4]}
                                                                   for i in range(4)]}},
                        "panel_order": [[1], {"x": 2}, "a"]}}
    src.write_text(json.dumps(spec))
    code, err = _run(capsys, ["pieces", str(src)])      # a malformed file: refused, by both readers
    _clean_error(code, err, out, needle="panel_order must be a list of panel names (strings); entry 0 is [1]")
    code, err = _run(capsys, ["garment", str(src), "-o", str(out / "g.npz")])
    _clean_error(code, err, out, needle="entry 0 is [1]")
    spec["pattern"]["panel_order"] = ["nowhere", "a"]    # a name that is not a panel is passed over
    src.write_text(json.dumps(spec))
    code, err = _run(capsys, ["pieces", str(src)])
    assert code == 0 and err == ""


@pytest.mark.parametrize("curv", [
    {"type": "cubic", "params": [["a", 1], [0.5, None]]},
    {"type": "quadratic", "params": None},
    [None, "a"],
    {"type": "circle", "params": ["r", None, "x"]},
])
def test_garmentcode_malformed_curvature_on_a_reversed_edge(capsys, tmp_path, out, curv):
    sq = [[0, 0], [50, 0], [50, 60], [0, 60]]
    edges = [{"endpoints": [1, 0], "curvature": curv}, {"endpoints": [1, 2]}, {"endpoints": [2, 3]},
             {"endpoints": [3, 0]}]
    src = tmp_path / "g.json"
    src.write_text(json.dumps({"pattern": {"panels": {"front": {"vertices": sq, "edges": edges}}}}))
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="piece 'front'")


def _dxf(tmp_path: Path, points, bulges=None) -> Path:
    ezdxf = pytest.importorskip("ezdxf")
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4
    bulges = bulges or [0.0] * len(points)
    doc.modelspace().add_lwpolyline([(x, y, b) for (x, y), b in zip(points, bulges)], format="xyb",
                                    close=True)
    p = tmp_path / "a.dxf"
    doc.saveas(p)
    return p


def test_dxf_binary_garbage_bulge_and_huge_coordinates(capsys, tmp_path, out):
    src = tmp_path / "b.dxf"
    src.write_bytes(b"AutoCAD Binary DXF\r\n\x1a\x00" + bytes(random.Random(2).randrange(256)
                                                              for _ in range(4000)))
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="not a valid DXF")
    sq = [(0, 0), (50, 0), (50, 60), (0, 60)]
    src = _dxf(tmp_path, sq, [1e308, 0, 0, 0])
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="bulge")
    assert err.startswith(f"clothgrid: error: {src}: LWPOLYLINE "), err     # the file and the entity
    code, err = _run(capsys, ["pieces", str(_dxf(tmp_path, [(0, 0), (1e15, 0), (1e15, 1e15), (0, 1e15)]))])
    _clean_error(code, err, out, needle="limit")
    assert err.startswith(f"clothgrid: error: {src}: LWPOLYLINE "), err


def _dxf_lines(path: Path, n: int) -> Path:
    head = "0\nSECTION\n2\nHEADER\n9\n$ACADVER\n1\nAC1009\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n0\nSECTION\n2\nENTITIES\n"
    path.write_text(head + "".join(f"0\nLINE\n8\n0\n10\n{k}.0\n20\n0.0\n11\n{k}.0\n21\n1.0\n" for k in range(n))
                    + "0\nENDSEC\n0\nEOF\n")
    return path


def test_dxf_with_too_many_records_is_refused_before_ezdxf_reads_it(capsys, tmp_path, out, monkeypatch):
    """ezdxf reads some 10^4 records a second: a file over the limit is refused from a count of its
    text (a 600,000-entity file hung for minutes), before ezdxf is asked to read it."""
    import ezdxf

    from clothgrid import limits
    from clothgrid.patterns.dxf import count_records

    src = _dxf_lines(tmp_path / "many.dxf", 3000)
    # the lines and SECTION, ENDSEC, SECTION, ENDSEC, EOF
    assert count_records(src, 10**6) == 3000 + 5 and count_records(src, 100) == 101
    monkeypatch.setattr(limits, "MAX_DXF_RECORDS", 2000)
    read = []
    monkeypatch.setattr(ezdxf, "readfile", lambda *a, **k: read.append(a) or pytest.fail("ezdxf read it"))
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="more than 2,000 records")
    assert read == []


@pytest.mark.parametrize("edge", ["1e-12", "1e-320"])
def test_tiny_edge_length_is_refused(capsys, tmp_path, out, edge):
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    code, err = _run(capsys, _gen(src, out, "--edge-length", edge))
    _clean_error(code, err, out, needle="edge length")


def test_output_names_over_the_file_system_limit(capsys, tmp_path, out):
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    code, err = _run(capsys, _gen(src, out, name="x" * 300 + ".obj"))
    _clean_error(code, err, out, needle="bytes long")
    svg = tmp_path / "p.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" viewBox="0 0 200 200">'
                   f'<rect id="{"y" * 300}" x="10" y="10" width="50" height="60"/></svg>')
    code, err = _run(capsys, _gen(svg, out, "--nodes", "9", name="{piece}.npz"))
    assert code == 0, err
    (written,) = list(out.iterdir())
    assert len(written.name) < 200


def test_devices_fifos_and_oversized_files_are_not_read(capsys, tmp_path, out):
    (tmp_path / "z.json").symlink_to("/dev/zero")
    code, err = _run(capsys, _gen(tmp_path / "z.json", out))
    _clean_error(code, err, out, needle="device")
    os.mkfifo(tmp_path / "f.svg")
    code, err = _run(capsys, ["pieces", str(tmp_path / "f.svg")])
    _clean_error(code, err, out, needle="FIFO")
    from clothgrid import limits

    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.seek(limits.MAX_FILE_BYTES + 1)
        fh.write(b" ")
    code, err = _run(capsys, _gen(big, out))
    _clean_error(code, err, out, needle="limit")


def test_huge_request_is_refused_before_allocating(capsys, tmp_path, out):
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    code, err = _run(capsys, _gen(src, out, "--nodes", "1000000000x1000000000"))
    _clean_error(code, err, out, needle="along a side")


def _address_space_limit(limit: int):
    def set_limit() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    return set_limit


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc/self/status: Linux")
def test_memory_check_counts_the_address_space_limit(tmp_path, out):
    """Under ``ulimit -v`` a grid the limit cannot hold is refused by the memory check, with the
    limit's figures (which add up), not by a MemoryError half-way through the solve."""
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    limit = 3 * 2**30
    proc = subprocess.run([sys.executable, "-m", "clothgrid", "generate", str(src), "-o", str(out / "g.npz"),
                           "--nodes", "8000x8000", "-q"], env=env, capture_output=True, text=True,
                          timeout=120, preexec_fn=_address_space_limit(limit))
    _clean_error(proc.returncode, proc.stderr, out, needle="under the address-space limit (ulimit -v)")
    m = re.search(r"90% of the ([\d.]+) GiB available under the address-space limit \(ulimit -v\): "
                  r"([\d.]+) GiB less the ([\d.]+) GiB this process maps already, is ([\d.]+) GiB", proc.stderr)
    assert m, proc.stderr
    have, lim, used, may = map(float, m.groups())
    assert lim == pytest.approx(limit / 2**30, rel=1e-3)
    assert have == pytest.approx(lim - used, abs=2e-3) and may == pytest.approx(0.9 * have, rel=1e-3)


def test_memory_check_counts_a_control_groups_memory_limit(tmp_path, out, capsys, monkeypatch):
    """In a container with a memory limit (a cgroup's; ``MemAvailable`` shows the whole machine's) a
    grid the limit cannot hold is refused by the memory check with the limit's figures, not killed
    by the group's out-of-memory killer (seen: exit 137 and no word at 4096^2 under 800 MiB). The
    limits are read from v1 and v2 files, the tightest along the group's ancestors, the group's
    page cache that can be dropped not counted as used."""
    import clothgrid.cgroups as cg

    from conftest import fake_cgroup

    def tree(files: dict[str, str], proc: str) -> tuple[str, str]:
        return fake_cgroup(tmp_path, files, proc)

    mib = 2**20
    # v2: the group's and its parent's limits; the parent's is tighter
    m = cg.memory_headroom(*tree({"fs/cgroup.controllers": "memory",
                                  "fs/a/memory.max": f"{800 * mib}", "fs/a/memory.current": f"{700 * mib}",
                                  "fs/a/memory.stat": f"anon 1\ninactive_file {100 * mib}\n",
                                  "fs/a/b/memory.max": f"{1000 * mib}", "fs/a/b/memory.current": f"{300 * mib}",
                                  "fs/a/b/memory.stat": "inactive_file 0\n"}, "0::/a/b\n"))
    assert (m.limit, m.used, m.room) == (800 * mib, 600 * mib, 200 * mib)
    assert cg.memory_headroom(*tree({"fs/cgroup.controllers": "memory", "fs/memory.max": "max",
                                     "fs/memory.current": "5"}, "0::/\n")) is None
    # v1: the memory controller's files; the kernel's "no limit" is a huge number
    m = cg.memory_headroom(*tree({"fs/memory/g/memory.limit_in_bytes": f"{512 * mib}",
                                  "fs/memory/g/memory.usage_in_bytes": f"{200 * mib}",
                                  "fs/memory/g/memory.stat": f"cache 9\ntotal_inactive_file {50 * mib}\n",
                                  "fs/memory/memory.limit_in_bytes": "9223372036854771712",
                                  "fs/memory/memory.usage_in_bytes": "1"}, "5:memory:/g\n1:cpu:/\n"))
    assert (m.limit, m.used) == (512 * mib, 150 * mib)
    assert cg.memory_headroom(str(tmp_path / "none"), str(tmp_path / "none" / "proc")) is None
    # the check: the group's limit binds, its figures in the message, which add up; nothing written
    monkeypatch.setattr(cg, "memory_headroom", lambda: cg.MemoryLimit(800 * mib, 84 * mib, "/g"))
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    code, err = _run(capsys, ["generate", str(src), "-o", str(out / "g.npz"), "--nodes", "4096x4096", "-q"])
    _clean_error(code, err, out, needle="under the memory limit of its control group (a container's --memory)")
    found = re.search(r"90% of the ([\d.]+) MiB available under the memory limit of its control group "
                      r"\(a container's --memory\): ([\d.]+) MiB less the ([\d.]+) MiB the group uses already, "
                      r"is ([\d.]+) MiB", err)
    assert found, err
    have, lim, used, may = map(float, found.groups())
    assert (lim, used, have) == (800, 84, 716) and may == pytest.approx(0.9 * have, rel=1e-3)


def test_svg_deep_groups(capsys, tmp_path, out):
    svg = tmp_path / "a.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg">' + "<g>" * 20_000
                   + '<rect x="1" y="1" width="5" height="5"/>' + "</g>" * 20_000 + "</svg>")
    code, err = _run(capsys, ["pieces", str(svg)])
    _clean_error(code, err, out, needle="nested")


# --------------------------------------------------------------------------- silently wrong


def test_extreme_k_is_refused(capsys, tmp_path, out):
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    for k in ("1e300", "1e-300"):
        code, err = _run(capsys, _gen(src, out, "--weights", "paper", "--k", k))
        _clean_error(code, err, out, needle="k must be between")


def test_direct_solver_converged_only_when_the_bound_meets_tol():
    import clothgrid

    t = np.linspace(0, 1, 17)
    b = clothgrid.Boundary.from_sides(np.c_[t, 0 * t], np.c_[1 + 0 * t, t], np.c_[t, 1 + 0.3 * np.sin(np.pi * t)],
                                      np.c_[0 * t, t])
    g = clothgrid.generate(b, solver="direct", tol=1e-6)
    assert g.info["converged"] and g.info["error_estimate"] <= 1e-6
    with pytest.raises(clothgrid.NotConvergedError, match="below what float64"):
        clothgrid.generate(b, solver="direct", tol=1e-30)
    g = clothgrid.generate(b, solver="direct", tol=1e-30, allow_unconverged=True)
    assert not g.info["converged"] and g.info["error_estimate"] > 1e-30


def test_non_finite_grid_never_returned(monkeypatch):
    import importlib

    import clothgrid

    gen_mod = importlib.import_module("clothgrid.generate")

    t = np.linspace(0, 1, 9)
    b = clothgrid.Boundary.from_sides(np.c_[t, 0 * t], np.c_[1 + 0 * t, t], np.c_[t, 1 + 0 * t], np.c_[0 * t, t])
    real = gen_mod.solve

    def poisoned(problem, name, **kw):
        name, res = real(problem, name, **kw)
        res.points[3, 3, 0] = np.nan
        return name, res

    monkeypatch.setattr(gen_mod, "solve", poisoned)
    with pytest.raises(clothgrid.InputError, match="non-finite"):
        clothgrid.generate(b, solver="direct")


# --------------------------------------------------------------------------- bad inputs accepted


@pytest.mark.parametrize("outline", [
    [[False, False], [True, False], [True, True], [False, True]],
    [["0", "0"], ["1", "0"], ["1", "1"], ["0", "1"]],
    [[0.0, 0.0], [True, 0.0], [1.0, 1.0], [0.0, 1.0]],
])
def test_booleans_and_strings_are_not_coordinates(capsys, tmp_path, out, outline):
    src = tmp_path / "a.json"
    src.write_text(json.dumps(_boundary(outline, [0, 1, 2, 3])))
    code, err = _run(capsys, _gen(src, out, "--nodes", "9"))
    _clean_error(code, err, out, needle="a coordinate is a")


def test_booleans_in_sides_and_garmentcode_vertices(capsys, tmp_path, out):
    src = tmp_path / "a.json"
    src.write_text(json.dumps({"bottom": [[0, 0], [True, 0]], "right": [[1, 0], [1, 1]],
                               "top": [[0, 1], [1, 1]], "left": [[0, 0], [0, 1]]}))
    code, err = _run(capsys, _gen(src, out, "--nodes", "9"))
    _clean_error(code, err, out, needle="boolean")
    verts = [[False, False], [True, False], [True, True], [False, True]]
    spec = {"pattern": {"panels": {"a": {"vertices": verts, "edges": [{"endpoints": [i, (i + 1) % 4]}
                                                                      for i in range(4)]}}}}
    src = tmp_path / "g.json"
    src.write_text(json.dumps(spec))
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="piece 'a'")


def _svg(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "s.svg"
    p.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" '
                 f'viewBox="0 0 200 200">{body}</svg>')
    return p


@pytest.mark.parametrize("points", [
    "0,0 100,0 100,100 50,0 0,100",                 # self-touching: a vertex on the bottom side
    "0,0 100,0 100,100 60,100 60,-20 40,-20 40,100 0,100",   # crosses itself, area left
])
def test_self_intersecting_outlines_are_failures_in_pieces_and_generate(capsys, tmp_path, out, points):
    svg = _svg(tmp_path, f'<polygon id="front" points="{points}"/><rect id="back" x="150" y="10" '
                         'width="40" height="50"/>')
    code, err = _run(capsys, ["pieces", str(svg)])
    assert code == 4, err
    assert "piece 'front'" in err and "crosses or touches itself" in err
    code, err = _run(capsys, _gen(svg, out, "--nodes", "9", name="{piece}.npz"))
    assert code == 4 and "piece 'front'" in err and "crosses or touches itself" in err
    assert sorted(p.name for p in out.iterdir()) == ["back.npz"]


def test_open_paths_reaching_infinity_join_nothing(capsys, tmp_path, out):
    """Open paths of a group are joined within a tolerance from their extent: two that reach an
    infinite coordinate (1e999) made it infinite, every end met every other, and the panel drawn
    as its edges (with a diagonal: a fork) was lost. They now join nothing and fail on their own
    (not skipped as 'small': an outline reaching infinity is no glyph); the panel is a piece."""
    svg = _svg(tmp_path, '<g id="p"><path d="M 0 0 L 100 0"/><path d="M 100 0 L 100 100"/>'
                         '<path d="M 100 100 L 0 100"/><path d="M 0 100 L 0 0"/><path d="M 0 0 L 100 100"/>'
                         '<path id="far1" d="M 0 0 L 1e999 50"/><path id="far2" d="M 100 100 L 1e999 50"/></g>')
    code, err = _run(capsys, _gen(svg, out, "--nodes", "9", name="{piece}.npz"))
    assert code == 4 and "Traceback" not in err, err
    assert "piece 'far1': a non-finite coordinate" in err and "piece 'far2'" in err
    assert sorted(p.name for p in out.iterdir()) == ["p.npz"]


@pytest.mark.parametrize("d", ["Z", " h 50 a 10 10 0 0 1 10 10 v 40 h -60 z", "L 10 10 L 0 10 z"])
def test_path_data_without_a_moveto_is_a_failed_piece(capsys, tmp_path, out, d):
    """Found by tests/test_fuzz.py: path data must begin with a moveto; svgpathtools made segments
    without a start point from it (an AttributeError traceback)."""
    svg = _svg(tmp_path, f'<path id="front" d="{d}"/><rect id="back" x="150" y="10" width="40" height="50"/>')
    code, err = _run(capsys, ["pieces", str(svg)])
    assert code == 4 and "Traceback" not in err, err
    assert "piece 'front'" in err and "must begin with a moveto" in err, err
    svg = _svg(tmp_path, f'<path id="front" d="{d}"/>')
    code, err = _run(capsys, _gen(svg, out, "--nodes", "9"))
    _clean_error(code, err, out, needle="moveto")


def test_an_error_quoting_a_bad_line_is_one_line(capsys, tmp_path, out):
    """Found by tests/test_fuzz.py: ezdxf's message for a bad group code quotes the line with its
    line break, which made the error two lines."""
    src = _dxf_lines(tmp_path / "a.dxf", 3)
    src.write_text(src.read_text().replace("ENTITIES\n0\n", "ENTITIES\n0.0\n", 1))
    code, err = _run(capsys, ["pieces", str(src)])
    _clean_error(code, err, out, needle="not a valid DXF")
    assert len(err.strip().splitlines()) == 1, err


def test_a_stitch_naming_a_panel_by_a_list_is_refused(capsys, tmp_path, out):
    """Found by tests/test_fuzz.py: an unhashable panel name in a stitch was a TypeError."""
    sq = [[0, 0], [50, 0], [50, 60], [0, 60]]
    panel = {"vertices": sq, "edges": [{"endpoints": [i, (i + 1) % 4]} for i in range(4)]}
    spec = {"pattern": {"panels": {"a": panel, "b": panel},
                        "stitches": [[{"panel": ["a"], "edge": 0}, {"panel": "b", "edge": 2}]]}}
    src = tmp_path / "g.json"
    src.write_text(json.dumps(spec))
    code, err = _run(capsys, ["garment", str(src), "-o", str(out / "g.npz")])
    _clean_error(code, err, out, needle="no panel named ['a']")


def test_self_intersection_search_agrees_with_all_pairs():
    from clothgrid.boundary import _find_self_intersection, _segments_intersect

    def brute(p, tol):                 # every pair at once, the first in outline order
        n = len(p)
        a, b = p, np.roll(p, -1, axis=0)
        i, j = np.triu_indices(n, 2)
        keep = ~((i == 0) & (j == n - 1))
        i, j = i[keep], j[keep]
        hit = _segments_intersect(a[i], b[i], a[j], b[j], tol)[0]
        return (int(i[hit][0]), int(j[hit][0])) if hit.any() else None

    rng = np.random.default_rng(5)
    for t in range(60):
        n = int(rng.integers(130, 200)) if t % 3 == 0 else int(rng.integers(4, 40))
        th = np.sort(rng.random(n)) * 2 * np.pi
        p = np.c_[np.cos(th), np.sin(th)] * (1 + (0.05 if t % 2 else 0.6) * rng.random(n))[:, None]
        got = _find_self_intersection(p, 1e-12)
        want = brute(p, 1e-12)
        assert (got and got[:2]) == want


# --------------------------------------------------------------------------- big but valid


def test_big_inputs_take_near_linear_time(tmp_path):
    from clothgrid.boundary import _find_self_intersection
    from clothgrid.patterns.chains import chain_loops as _chain
    from clothgrid.patterns.garmentcode import _loop
    from clothgrid.patterns.sampling import Bezier

    n = 200_000
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    p = np.c_[np.cos(th), np.sin(th)]
    t0 = time.perf_counter()
    assert _find_self_intersection(p, 1e-9) is None
    assert time.perf_counter() - t0 < 10
    m = 20_000
    q = p[:: n // m] * 100
    segs = [[Bezier(np.array([q[i], q[(i + 1) % m]]))] for i in range(m)]
    random.Random(3).shuffle(segs)
    t0 = time.perf_counter()
    loops, left = _chain(segs, 1e-4)
    assert len(loops) == 1 and left == 0 and len(loops[0]) == m
    assert time.perf_counter() - t0 < 10
    edges = [{"endpoints": [i, (i + 1) % 30_000]} for i in range(30_000)]
    random.Random(4).shuffle(edges)
    t0 = time.perf_counter()
    loop = _loop(edges, 30_000, "panel")
    assert len(loop) == 30_000 and loop[-1][1] == loop[0][0]
    assert time.perf_counter() - t0 < 5


def test_annotation_classification_of_many_outlines_is_near_linear():
    """Sorting 10^5 small outlines (an SVG of 10^5 rectangles) into pieces and marks took minutes: a
    sorted copy of every box's left edge was made again for each outline, and each small outline's
    notch hosts were sought among all others."""
    from clothgrid.patterns.annotations import classify
    from clothgrid.patterns.piece import Piece

    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)

    def squares(n: int) -> list[Piece]:
        return [Piece(f"p{k}", square + [2 * (k % 300), 2 * (k // 300)], np.arange(4), np.zeros(0, np.int64),
                      meta={"element": "rect"}) for k in range(n)]

    ps = squares(40_000)
    t0 = time.process_time()
    got = classify(ps)
    assert len(got) == 40_000 and not got.skipped
    assert time.process_time() - t0 < 11          # 3.5 s of CPU here; 22 s before


def test_svg_polygon_of_many_points_is_read_in_near_linear_time(tmp_path, monkeypatch, capsys):
    """A ``<polygon>`` of 2 x 10^5 points: one array, not a svgpathtools segment per point, and the
    XML in one feed (expat < 2.6 is quadratic in one huge attribute when fed in chunks). The
    corpus's 10^6-point polygon hung; it now takes seconds."""
    import svgpathtools

    from clothgrid.patterns.svg import _parse_xml

    n = 200_000
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = " ".join(f"{100 * math.cos(t):.6f},{100 * math.sin(t):.6f}" for t in th)
    svg = _svg(tmp_path, f'<polygon points="{pts}"/>')
    big = tmp_path / "big.xml"                  # 8 MB in one attribute
    big.write_text('<svg a="' + "1 " * 4_000_000 + '"/>')
    t0 = time.perf_counter()
    assert _parse_xml(big).get("a").count("1") == 4_000_000
    assert time.perf_counter() - t0 < 3
    monkeypatch.setattr(svgpathtools, "parse_path", lambda *a, **k: pytest.fail("parsed a polygon as a path"))
    t0 = time.perf_counter()
    code = main(["pieces", str(svg)])
    out, err = capsys.readouterr()
    assert code == 0 and err == "" and f"{n} outline points" in out, err
    assert time.perf_counter() - t0 < 10


def test_svg_polygon_makes_the_piece_its_path_makes(tmp_path):
    """The polygon fast path (:func:`piece_from_points`) and the path of the same points agree."""
    from clothgrid.patterns.svg import read_svg

    xy = "0,0 80,0 80,0 80,50 40,50 40,30 0,30"         # an L, with a repeated point
    d = "M" + " L".join(xy.split()) + " Z"
    a = read_svg(_svg(tmp_path, f'<g transform="rotate(30)"><polygon points="{xy}"/></g>'))[0]
    b = read_svg(_svg(tmp_path, f'<g transform="rotate(30)"><path d="{d}"/></g>'))[0]
    np.testing.assert_allclose(a.outline, b.outline, rtol=0, atol=1e-12)     # (matrix products: rounding)
    assert np.array_equal(a.vertices, b.vertices)
    assert a.tolerance == pytest.approx(b.tolerance, rel=1e-12) and a.notes == b.notes
    r = read_svg(_svg(tmp_path, '<rect x="3" y="4" width="20" height="10" transform="skewX(10)"/>'))[0]
    q = read_svg(_svg(tmp_path, '<path d="M3,4 H23 V14 H3 Z" transform="skewX(10)"/>'))[0]
    np.testing.assert_allclose(r.outline, q.outline, rtol=0, atol=1e-12)
    assert np.array_equal(r.vertices, q.vertices) and r.meta["element"] == "rect"
    rounded = read_svg(_svg(tmp_path, '<rect width="20" height="10" rx="2"/>'))[0]     # arcs: path data
    assert len(rounded.outline) > 8
    open_line = read_svg(_svg(tmp_path, '<polyline points="0,0 10,0 10,10"/><rect width="5" height="5"/>'))
    assert len(open_line) == 1 and open_line[0].meta["element"] == "rect"


# --------------------------------------------------------------------------- signals


SIGNAL_SCRIPT = r"""
import os, sys, signal, threading
from clothgrid import writers
from clothgrid.cli import main
real = writers._write_rows
def slow(fh, fmt, rows):
    fh.flush()
    print("WRITING", flush=True)
    threading.Event().wait(30)                 # a large .obj: the signal arrives here
    real(fh, fmt, rows)
writers._write_rows = slow
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_signal_during_a_write_leaves_nothing_behind(tmp_path, out, sig):
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    keep = out / "old.obj"
    keep.write_text("finished earlier\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.Popen([sys.executable, "-c", SIGNAL_SCRIPT, "generate", str(src), "-o", str(out / "g.obj"),
                             "-o", str(out / "g.ply"), "--nodes", "9", "-q"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        line = ""
        while time.monotonic() < deadline and "WRITING" not in line:
            line = proc.stdout.readline()
            if not line and proc.poll() is not None:
                break
        assert "WRITING" in line, proc.stderr.read()
        assert any(p.name.endswith(".tmp") for p in out.iterdir())
        proc.send_signal(sig)
        time.sleep(0.2)
        proc.send_signal(sig)                 # a second signal during the clean-up
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err and err.strip().startswith("clothgrid:"), err
    assert [p.name for p in out.iterdir()] == ["old.obj"] and keep.read_text() == "finished earlier\n"


_PAUSE_AT_NUMPY = """
import sys, time
class _PauseAtNumpy:
    done = False
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" and not self.done:
            self.done = True
            sys.stderr.write("PAUSED-IMPORTING-NUMPY\\n")
            sys.stderr.flush()
            time.sleep(30)
        return None
sys.meta_path.insert(0, _PauseAtNumpy())
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_while_the_command_line_imports(tmp_path, sig):
    """A signal during ``import clothgrid`` (NumPy, SciPy) of ``python -m clothgrid``: one line and
    128 + signum, no KeyboardInterrupt traceback. A ``sitecustomize`` import hook holds the import of
    NumPy (the first thing clothgrid's ``__init__`` imports after its start-up guard) for up to 30 s
    and says so, so the signal lands inside the imports however loaded the machine is."""
    src = tmp_path / "sq.json"
    src.write_text(json.dumps(_boundary(_square(16))))
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(_PAUSE_AT_NUMPY)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(hook), str(ROOT / "src")])}
    # SIGINT at its default, as in a terminal: a shell without job control starts background
    # commands with it ignored, and the child would inherit that (the guard leaves an ignored
    # signal ignored, as it should)
    proc = subprocess.Popen([sys.executable, "-m", "clothgrid", "pieces", str(src)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = ""
        while "PAUSED-IMPORTING-NUMPY" not in line:     # clothgrid's __init__ is importing NumPy now
            line = proc.stderr.readline()
            assert line, "the import hook did not run"
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 128 + sig, err[-2000:]
    assert lines == ["clothgrid: interrupted" if sig == signal.SIGINT else "clothgrid: terminated by SIGTERM"], lines


def test_the_start_up_guard_is_for_the_command_line_only():
    from clothgrid._startup import _module_run

    assert _module_run(["python", "-m", "clothgrid", "pieces"]) == "clothgrid"
    assert _module_run(["python", "-X", "importtime", "-u", "-mclothgrid"]) == "clothgrid"
    assert _module_run(["python", "-m", "pytest", "-q"]) == "pytest"
    assert _module_run(["python", "-c", "import clothgrid", "-m", "clothgrid"]) is None
    assert _module_run(["python", "script.py", "-m", "clothgrid"]) is None
    # this process (pytest) imported clothgrid as a library: SIGINT is still Python's own
    assert signal.getsignal(signal.SIGINT) is not __import__("clothgrid._startup")._startup._stop


# --------------------------------------------------------------------------- noise


def test_no_runtime_warning_above_an_error(capsys, tmp_path, out):
    svg = _svg(tmp_path, '<rect x="0" y="0" width="1e308" height="1e308"/>'
                         '<g transform="scale(1e300)"><rect x="0" y="0" width="10" height="10"/></g>')
    code, err = _run(capsys, ["pieces", str(svg)])
    _clean_error(code, err, out, needle="limit")


def test_limits_are_documented():
    from clothgrid import limits

    readme = (ROOT / "README.md").read_text()
    assert "## Limits" in readme
    for name in ("MAX_FILE_BYTES", "MAX_NESTING", "MAX_INT_DIGITS", "MAX_COORDINATE", "MAX_OUTLINE_POINTS",
                 "MAX_ENTITIES", "MAX_DXF_RECORDS", "MAX_NODES_PER_SIDE"):
        assert name in readme, name
        assert getattr(limits, name) > 0
    for code in ("| 129", "| 143", "| 130"):
        assert code in readme


def test_the_convex_shortcut_of_the_self_crossing_search_is_only_taken_when_safe():
    """A strictly convex outline that turns once and is far from degenerate cannot meet itself,
    so the pairwise search is skipped; a pentagram (every turn to the left, but twice round), a
    bow-tie and a sliver thinner than the touching tolerance take the full search, which finds
    their crossings or touches."""
    from clothgrid.patterns.piece import _clearly_convex, _self_crossing

    square = np.array([[0.0, 0], [10, 0], [10, 10], [0, 10]])
    assert _clearly_convex(square, 1e-8) and _self_crossing(square) is None
    star = np.array([[np.cos(a), np.sin(a)] for a in np.pi / 2 + 4 * np.pi / 5 * np.arange(5)]) * 50
    assert not _clearly_convex(star, 1e-7) and _self_crossing(star) is not None
    bow = np.array([[0.0, 0], [10, 10], [10, 0], [0, 10]])
    assert not _clearly_convex(bow, 1e-8) and _self_crossing(bow) is not None
    sliver = np.array([[0.0, 0], [100, 0], [100, 1e-9], [0, 1e-9]])
    assert not _clearly_convex(sliver, 1e-7)
