"""Tests of the command line, :mod:`clothgrid.cli`, run in-process (one via ``python -m``)."""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import clothgrid
from clothgrid import cli
from clothgrid.cli import main, parse_nodes, parse_tol

# roache-horn from the UNAMalla regions (MIT): 76 points, four sides of 20 points.
HORN_OUTLINE = [
    (0.0, -1.0), (0.1579, -1.0), (0.3158, -1.0), (0.4737, -1.0), (0.6316, -1.0),
    (0.7895, -1.0), (0.9474, -1.0), (1.1053, -1.0), (1.2632, -1.0), (1.4211, -1.0),
    (1.5789, -1.0), (1.7368, -1.0), (1.8947, -1.0), (2.0526, -1.0526), (2.2105, -1.2105),
    (2.3684, -1.3684), (2.5263, -1.5263), (2.6842, -1.6842), (2.8421, -1.8421), (3.0, -2.0),
    (3.1994, -1.7895), (3.3767, -1.5789), (3.5319, -1.3684), (3.6648, -1.1579), (3.7756, -0.9474),
    (3.8643, -0.7368), (3.9307, -0.5263), (3.9751, -0.3158), (3.9972, -0.1053), (3.9972, 0.1053),
    (3.9751, 0.3158), (3.9307, 0.5263), (3.8643, 0.7368), (3.7756, 0.9474), (3.6648, 1.1579),
    (3.5319, 1.3684), (3.3767, 1.5789), (3.1994, 1.7895), (3.0, 2.0), (2.8421, 1.8421),
    (2.6842, 1.6842), (2.5263, 1.5263), (2.3684, 1.3684), (2.2105, 1.2105), (2.0526, 1.0526),
    (1.8947, 1.0), (1.7368, 1.0), (1.5789, 1.0), (1.4211, 1.0), (1.2632, 1.0),
    (1.1053, 1.0), (0.9474, 1.0), (0.7895, 1.0), (0.6316, 1.0), (0.4737, 1.0),
    (0.3158, 1.0), (0.1579, 1.0), (0.0, 1.0), (0.0, 0.8947), (0.0, 0.7895),
    (0.0, 0.6842), (0.0, 0.5789), (0.0, 0.4737), (0.0, 0.3684), (0.0, 0.2632),
    (0.0, 0.1579), (0.0, 0.0526), (0.0, -0.0526), (0.0, -0.1579), (0.0, -0.2632),
    (0.0, -0.3684), (0.0, -0.4737), (0.0, -0.5789), (0.0, -0.6842), (0.0, -0.7895),
    (0.0, -0.8947),
]
HORN_CORNERS = [0, 19, 38, 57]


def _square_sides(n: int = 5) -> dict[str, list[list[float]]]:
    t = np.linspace(0.0, 1.0, n)
    return {
        "bottom": [[x, 0.0] for x in t],
        "right": [[1.0, y] for y in t],
        "top": [[x, 1.0] for x in t],
        "left": [[0.0, y] for y in t],
    }


def _write(path: Path, data) -> Path:
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


@pytest.fixture
def horn(tmp_path: Path) -> Path:
    return _write(tmp_path / "roache-horn.json",
                  {"name": "roache-horn", "outline": HORN_OUTLINE, "corners": HORN_CORNERS})


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.is_file())


# --------------------------------------------------------------------------- parsing


@pytest.mark.parametrize("text, expected", [("257x257", (257, 257)), ("33", (33, 33)),
                                            ("2X9", (2, 9)), (" 16 x 8 ", (16, 8))])
def test_parse_nodes(text, expected):
    assert parse_nodes(text) == expected


@pytest.mark.parametrize("text", ["3x", "1x5", "5x1", "x5", "0", "1", "-3x4", "2.5x3", "axb", ""])
def test_parse_nodes_rejects(text):
    with pytest.raises(argparse.ArgumentTypeError, match=">= 2"):
        parse_nodes(text)


@pytest.mark.parametrize("text, expected", [("2**-12", 2.0**-12), ("2^-12", 2.0**-12),
                                            ("1e-4", 1e-4), ("0.001", 1e-3),
                                            (" 10 ** -3 ", 1e-3)])
def test_parse_tol(text, expected):
    assert parse_tol(text) == pytest.approx(expected)


@pytest.mark.parametrize("text", ["0", "-1e-3", "nan", "inf", "2**", "__import__('os')",
                                  "2*-12", "1e400", "(-2)**0.5", "-2**0.5", "2**2000"])
def test_parse_tol_rejects(text):
    with pytest.raises(argparse.ArgumentTypeError, match="tolerance"):
        parse_tol(text)


def test_version(capsys):
    code, out, _ = run(capsys, "--version")
    assert code == 0
    assert out.startswith("clothgrid ")


def test_no_command_is_usage_error(capsys):
    code, _, err = run(capsys)
    assert code == 2
    assert "generate" in err


# --------------------------------------------------------------------------- generate


def test_generate_writes_all_formats(capsys, horn, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    code, stdout, err = run(capsys, "generate", horn, "-o", out / "g.npz", "-o", out / "g.obj",
                            "-o", out / "g.json", "--nodes", "24x16", "--plot", out / "g.png")
    assert code == 0, err
    assert _files(out) == ["g.json", "g.npz", "g.obj", "g.png"]
    with np.load(out / "g.npz") as z:
        assert z["points"].shape == (24, 16, 3)
        assert z["quads"].shape == (23 * 15, 4)
    obj = (out / "g.obj").read_text().splitlines()
    assert sum(line.startswith("v ") for line in obj) == 24 * 16
    assert sum(line.startswith("f ") for line in obj) == 23 * 15
    json.loads((out / "g.json").read_text())
    assert (out / "g.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "folded" in stdout  # the quality table
    assert "iterations" in stdout and "error estimate" in stdout  # the timing line
    assert "clothgrid:" in err  # progress on stderr


def test_generate_default_nodes_and_quiet(capsys, horn, tmp_path):
    code, stdout, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", "-q",
                            "--solver", "direct", "--tol", "2**-20")
    assert code == 0, err
    assert all("warning" in line for line in err.splitlines())  # no progress, only warnings
    assert "direct" in stdout
    with np.load(tmp_path / "g.npz") as z:
        assert z["points"].shape == (20, 20, 3)


def test_collector_held_off_during_start_up_and_restored(capsys, horn, tmp_path, monkeypatch):
    """The command holds Python's cyclic collector off until its first piece is made (Numba's
    start-up), then collects as usual; afterwards the collector is as it was, on or off."""
    import gc

    import clothgrid.pipeline as pipeline

    seen = []
    real = pipeline.run_job

    def spy(*a, **k):
        seen.append(gc.isenabled())
        return real(*a, **k)

    monkeypatch.setattr(pipeline, "run_job", spy)
    assert gc.isenabled()
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", "-q", "--nodes", "9")
    assert code == 0, err
    assert seen == [False] and gc.isenabled()
    gc.disable()
    try:
        code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "h.npz", "-q", "--nodes", "9")
        assert code == 0, err
        assert not gc.isenabled()       # left off: it was off before
    finally:
        gc.enable()


def test_python_m_clothgrid(horn, tmp_path):
    src = str(Path(clothgrid.__file__).resolve().parent.parent)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]),
               MPLBACKEND="Agg")
    res = subprocess.run([sys.executable, "-m", "clothgrid", "generate", str(horn), "-o",
                          str(tmp_path / "g.ply"), "--nodes", "12"], capture_output=True,
                         text=True, env=env, stdin=subprocess.DEVNULL, timeout=600)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "g.ply").is_file()
    # console_main ends the process with os._exit after flushing: the report arrives whole
    assert "solver " in res.stdout and res.stdout.endswith("\n"), res.stdout
    bad = subprocess.run([sys.executable, "-m", "clothgrid", "generate", str(horn), "-o",
                          str(tmp_path / "g.xyz")], capture_output=True, text=True, env=env,
                         stdin=subprocess.DEVNULL, timeout=600)
    assert bad.returncode == 2
    assert "clothgrid: error:" in bad.stderr


def assert_fresh_python_ok(code: str) -> None:
    """Run ``code`` in a fresh interpreter with this clothgrid first on the path; it prints ``ok``."""
    src = str(Path(clothgrid.__file__).resolve().parent.parent)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         stdin=subprocess.DEVNULL, timeout=600)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr


def test_lean_imports_blas_in_a_fresh_interpreter():
    """preload_cython_blas: Numba's kernels and BLAS work without scipy.linalg's package until it is
    imported, and then the package is whole, with the very module as its attribute."""
    code = """
import sys
from clothgrid.lean_imports import preload_cython_blas
assert preload_cython_blas()
assert not preload_cython_blas()          # once
assert "scipy.linalg" not in sys.modules
import numpy as np
from numba import njit
@njit
def dot(a):
    return np.dot(a, a)                   # Numba's BLAS, through cython_blas
assert dot(np.arange(4.0)) == 14.0
assert "scipy.linalg" not in sys.modules
import scipy.linalg
from scipy.linalg import cython_blas
assert scipy.linalg.cython_blas is cython_blas is sys.modules["scipy.linalg.cython_blas"]
assert scipy.linalg.__loader__.__class__.__name__ == "SourceFileLoader"
assert np.allclose(scipy.linalg.solve(2 * np.eye(3), np.ones(3)), 0.5)
print("ok")
"""
    assert_fresh_python_ok(code)


def test_reading_a_dxf_with_turn_points_imports_no_kd_tree():
    """AAMA turn points snap to the outline without SciPy's spatial package (its import, with
    scipy.sparse, cost the command about 0.13 s: patterns.piece.snap_to_outline)."""
    dxf = Path(__file__).resolve().parents[2] / "shared" / "patterns" / "astm_GLX0924S16_NEW.DXF"
    if not dxf.exists():
        pytest.skip(f"{dxf} is not here (../shared/patterns)")
    code = f"""
import sys
from clothgrid.readers import read_pieces
pieces = read_pieces({str(dxf)!r})
assert sum(1 for p in pieces if p.turn_points is not None and len(p.turn_points)) > 0
assert "scipy.spatial" not in sys.modules
print("ok")
"""
    assert_fresh_python_ok(code)


def test_svgpathtools_without_quad_reads_the_same_pieces(tmp_path):
    """lean_imports.svgpathtools_without_quad: in a fresh interpreter svgpathtools imports without
    scipy.integrate (and says so), scipy.integrate imports as usual afterwards, and an SVG pattern
    file reads to the very same outlines as with a plain import."""
    svg = tmp_path / "piece.svg"          # lines, a cubic and an elliptic arc, as svgpathtools parses them
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" viewBox="0 0 300 200">'
                   '<path id="front" d="M 10 10 L 210 10 C 240 60 240 120 210 170 '
                   'A 100 40 0 0 1 10 170 Z" fill="none" stroke="black"/></svg>')
    code = """
import sys, hashlib
hook = sys.argv[1] == "hook"
if hook:
    from clothgrid.lean_imports import svgpathtools_without_quad
    assert svgpathtools_without_quad() and not svgpathtools_without_quad()
from clothgrid.readers import read_input
got = read_input(sys.argv[2])
pieces = got if isinstance(got, list) else [got]
h = hashlib.sha256()
for p in pieces:
    h.update(repr(p.name).encode())
    h.update(p.outline.tobytes())
import svgpathtools.path as P
assert P._quad_available is (not hook), P._quad_available
assert ("scipy.integrate" in sys.modules) is (not hook)
import scipy.integrate
assert abs(scipy.integrate.quad(lambda x: x * x, 0, 1)[0] - 1 / 3) < 1e-12
assert not any(type(f).__name__ == "_WrapOnce" for f in sys.meta_path)
print(h.hexdigest())
"""
    src = str(Path(clothgrid.__file__).resolve().parent.parent)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]))
    out = []
    for mode in ("hook", "plain"):
        res = subprocess.run([sys.executable, "-c", code, mode, str(svg)], capture_output=True, text=True,
                             env=env, stdin=subprocess.DEVNULL, timeout=600)
        assert res.returncode == 0, res.stderr
        out.append(res.stdout.strip())
    assert out[0] == out[1]


def test_lean_imports_blas_leaves_an_imported_scipy_linalg_alone():
    import scipy.linalg  # noqa: F401  (imported in this process: nothing to do)

    from clothgrid.lean_imports import preload_cython_blas

    assert not preload_cython_blas()


# --------------------------------------------------------------------------- bad input -> 2


def _bad_inputs() -> dict[str, tuple[object, tuple[str, ...], tuple[str, ...]]]:
    """name -> (file content, extra args, any of these words in the message)."""
    nan = _square_sides()
    nan["bottom"][2] = [float("nan"), 0.0]
    open_corner = _square_sides()
    open_corner["right"][0] = [1.1, 0.0]
    one_point = _square_sides()
    one_point["left"] = [[0.0, 0.0]]
    mismatch = _square_sides()
    mismatch["top"] = [[x, 1.0] for x in np.linspace(0.0, 1.0, 7)]
    zero = _square_sides()
    zero["right"] = [[1.0, 0.0]] * 5
    zero["top"] = [[x, y] for x, y in zip(np.linspace(0.0, 1.0, 5), np.linspace(1.0, 0.0, 5))]
    t = np.linspace(0.0, 1.0, 6)[:-1]
    bowtie = ([[x, 0.0] for x in t] + [[1.0 - 0.5 * x, y] for x, y in zip(t, t)]
              + [[0.5 - 0.5 * x, 1.0 + x] for x in t]
              + [[0.0 + 2 * x, 2.0 - 2 * x] for x in t])
    return {
        "invalid-json": ('{"outline": [[0, 0], [1, 0]', (), ("json",)),
        "corners-do-not-meet": (open_corner, (), ("corner", "meet", "match")),
        "nan": (nan, (), ("nan", "finite")),
        "one-point-side": (one_point, (), ("point", "left", "side")),
        "mismatched-counts": (mismatch, (), ("--nodes", "count", "match")),
        "zero-length-side": (zero, (), ("zero", "length", "degenerate")),
        "self-intersecting": ({"name": "bowtie", "outline": bowtie, "corners": [0, 5, 10, 15]},
                              (), ("cross", "intersect")),
    }


@pytest.mark.parametrize("case", sorted(_bad_inputs()))
def test_bad_input_exit_2(capsys, tmp_path, case):
    content, extra, words = _bad_inputs()[case]
    src = _write(tmp_path / "in.json", content if isinstance(content, str)
                 else json.dumps(content))
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run(capsys, "generate", src, "-o", out / "g.npz", "--plot", out / "g.png",
                       *extra)
    assert code == 2, err
    assert "clothgrid: error:" in err
    assert any(w in err.lower() for w in words), err
    assert _files(out) == []


@pytest.mark.parametrize("args, words", [
    (["--nodes", "3x"], ("--nodes", "nuxnv")),
    (["--nodes", "1x5"], ("--nodes", ">= 2")),
    (["--solver", "magic"], ("--solver", "invalid choice")),
    (["--tol", "2**x"], ("--tol", "tolerance")),
    (["--max-iter", "0"], ("--max-iter",)),
])
def test_bad_options_exit_2(capsys, horn, tmp_path, args, words):
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", *args)
    assert code == 2
    assert "clothgrid: error:" in err
    assert all(w in err.lower() for w in words), err
    assert not (tmp_path / "g.npz").exists()


def test_missing_input(capsys, tmp_path):
    code, _, err = run(capsys, "generate", tmp_path / "nope.json", "-o", tmp_path / "g.npz")
    assert code == 2
    assert "nope.json" in err and "no such file" in err.lower()
    assert not (tmp_path / "g.npz").exists()


def test_unknown_output_extension(capsys, horn, tmp_path):
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", "-o", tmp_path / "g.stl")
    assert code == 2
    assert ".stl" in err and ".npz" in err
    assert _files(tmp_path) == ["roache-horn.json"]


def test_bad_plot_extension(capsys, horn, tmp_path):
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", "--plot",
                       tmp_path / "g.jpg")
    assert code == 2
    assert "--plot" in err
    assert _files(tmp_path) == ["roache-horn.json"]


def test_output_dir_missing_is_created(capsys, horn, tmp_path):
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz",
                       "-o", tmp_path / "missing" / "deeper" / "g.obj", "--nodes", "9")
    assert code == 0, err
    assert (tmp_path / "missing" / "deeper" / "g.obj").is_file()


def test_output_dir_under_a_file_is_refused(capsys, horn, tmp_path):
    (tmp_path / "afile").write_text("x")
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz",
                       "-o", tmp_path / "afile" / "sub" / "g.obj")
    assert code == 2
    assert "afile" in err and "is not a folder" in err
    assert _files(tmp_path) == ["afile", "roache-horn.json"]


def test_failed_run_removes_the_folders_it_made(capsys, horn, tmp_path, monkeypatch):
    import clothgrid.writers as writers

    def broken(grid, path, **kw):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(writers, "save", broken)
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "new" / "g.npz", "--nodes", "9")
    assert code == 2 and "permission denied" in err.lower()
    assert _files(tmp_path) == ["roache-horn.json"] and not (tmp_path / "new").exists()


def test_failed_second_output_removes_first(capsys, horn, tmp_path, monkeypatch):
    import clothgrid.writers as writers

    real_save = writers.save
    calls = []

    def flaky_save(grid, path):
        calls.append(path)
        if len(calls) == 2:
            raise PermissionError(13, "Permission denied", str(path))
        return real_save(grid, path)

    monkeypatch.setattr(writers, "save", flaky_save)
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "a.npz", "-o", tmp_path / "b.obj",
                       "--nodes", "8")
    assert code == 2
    assert "b.obj" in err and "permission denied" in err.lower()
    assert _files(tmp_path) == ["roache-horn.json"]


def test_keyboard_interrupt_exit_130(capsys, horn, tmp_path, monkeypatch):
    pipeline = importlib.import_module("clothgrid.pipeline")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "generate", interrupted)
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz")
    assert code == 130
    assert "interrupted" in err
    assert not (tmp_path / "g.npz").exists()


# --------------------------------------------------------------------------- not converged -> 3


def test_not_converged_exit_3(capsys, horn, tmp_path):
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", "--plot",
                       tmp_path / "g.png", "--solver", "jacobi", "--init", "zero",
                       "--max-iter", "5")
    assert code == 3
    assert "clothgrid: error:" in err and "--allow-unconverged" in err
    assert _files(tmp_path) == ["roache-horn.json"]


def test_allow_unconverged_writes(capsys, horn, tmp_path):
    code, _, err = run(capsys, "generate", horn, "-o", tmp_path / "g.npz", "--solver", "jacobi",
                       "--init", "zero", "--max-iter", "5", "--allow-unconverged")
    assert code == 0, err
    assert "warning" in err and "not converged" in err and "--allow-unconverged" in err
    with np.load(tmp_path / "g.npz") as z:
        assert z["points"].shape == (20, 20, 3)


# --------------------------------------------------------------------------- demo


def test_demo(capsys, tmp_path):
    folder = tmp_path / "demo" / "nested"
    code, out, err = run(capsys, "demo", "-o", folder, "--nodes", "17x13")
    assert code == 0, err
    assert _files(folder) == ["tshirt_front.npz", "tshirt_front.obj", "tshirt_front.png"]
    with np.load(folder / "tshirt_front.npz") as z:
        assert z["points"].shape == (17, 13, 3)
    assert "folded" in out and "solve" in out and str(folder) in out


def test_demo_piece_is_valid():
    from importlib.resources import files

    data = json.loads(files("clothgrid").joinpath("data", "tshirt_front.json").read_text())
    pts = np.asarray(data["outline"], dtype=float)
    corners = data["corners"]
    assert pts.ndim == 2 and pts.shape[1] == 2 and 90 <= len(pts) <= 160
    assert corners == sorted(corners) and len(corners) == 4 and corners[0] == 0
    x, y = pts.T
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert area > 0  # counter-clockwise
    assert 0.4 < np.ptp(x) < 0.6 and 0.6 < np.ptp(y) < 0.8
    # no two non-adjacent segments cross
    a, b = pts, np.roll(pts, -1, axis=0)

    def side(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    A, B, C, D = a[:, None], b[:, None], a[None], b[None]
    cross = (side(A, B, C) * side(A, B, D) < 0) & (side(C, D, A) * side(C, D, B) < 0)
    assert not cross.any()


def test_closed_pipe_ends_quietly(tmp_path):
    """``clothgrid pieces FILE | head -1``: no traceback, exit 141 (128 + SIGPIPE)."""
    import subprocess
    import sys

    rects = "".join(f'<rect id="p{k}" x="{k % 50 * 30}" y="{k // 50 * 30}" width="20" height="10"/>'
                    for k in range(1500))
    svg = tmp_path / "many.svg"
    svg.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="2000mm" height="2000mm" '
                   f'viewBox="0 0 2000 2000">{rects}</svg>')
    p = subprocess.Popen([sys.executable, "-m", "clothgrid", "pieces", str(svg)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    first = p.stdout.readline()
    p.stdout.close()           # the reader goes away, like `head -1`
    err = p.stderr.read().decode()
    p.wait(timeout=120)
    assert b"1500 pieces" in first
    assert p.returncode == 141 and "Traceback" not in err and "BrokenPipe" not in err, err


# --------------------------------------------------------------------------- one bad piece, the others go on

_MIXED_SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="100mm" viewBox="0 0 200 100">'
              '<rect id="good" x="10" y="10" width="60" height="40"/>'
              '<path id="line" d="M 100 10 L 150 10 Z"/>'                 # two distinct points
              '<polygon id="flat" points="100,60 150,60 180,60"/>'        # three points, no area
              '</svg>')


@pytest.fixture
def mixed_svg(tmp_path: Path) -> Path:
    path = tmp_path / "mixed.svg"
    path.write_text(_MIXED_SVG)
    return path


def test_generate_writes_the_good_pieces_and_names_the_bad_ones(capsys, tmp_path, mixed_svg):
    out = tmp_path / "out"
    code, stdout, err = run(capsys, "generate", mixed_svg, "-o", out / "{piece}.npz", "--edge-length", "10mm")
    assert code == cli.EXIT_PARTIAL == 4
    assert sorted(p.name for p in out.iterdir()) == ["good.npz"]
    assert "piece good:" in stdout
    lines = [ln for ln in err.splitlines() if ln.startswith("clothgrid: error:")]
    assert lines == [f"clothgrid: error: {mixed_svg}: piece 'line': only 2 distinct points; a piece needs "
                     "at least 3 and must enclose an area",
                     f"clothgrid: error: {mixed_svg}: piece 'flat': encloses no area (its outline runs "
                     "back over itself)"]
    assert "2 of 3 pieces failed" in err and "the other 1 was written" in err


def test_pieces_lists_the_good_and_the_failed_pieces(capsys, mixed_svg):
    code, out, err = run(capsys, "pieces", mixed_svg)
    assert code == cli.EXIT_PARTIAL
    assert out.splitlines()[0] == f"{mixed_svg}: 1 piece, 2 failed (coordinates in mm)"
    assert out.splitlines()[1].startswith("good: 60 x 40 mm")
    assert "line: FAILED (cannot be read): only 2 distinct points" in out
    assert "flat: FAILED (cannot be read): encloses no area" in out
    assert f"clothgrid: error: {mixed_svg}: piece 'line': only 2 distinct points" in err
    code, out, _ = run(capsys, "pieces", mixed_svg, "--json")
    assert code == cli.EXIT_PARTIAL
    listing = json.loads(out)
    assert [p["name"] for p in listing["pieces"]] == ["good"]
    assert [(f["name"], f["stage"]) for f in listing["failed"]] == [("line", "read"), ("flat", "read")]
    assert "only 2 distinct points" in listing["failed"][0]["reason"]


def test_piece_good_works_beside_a_bad_piece_and_piece_bad_is_an_error(capsys, tmp_path, mixed_svg):
    code, _, err = run(capsys, "generate", mixed_svg, "--piece", "good", "-o", tmp_path / "g.npz", "-q")
    assert code == 0 and (tmp_path / "g.npz").exists() and "error" not in err
    code, out, _ = run(capsys, "pieces", mixed_svg, "--piece", "good")
    assert code == 0 and "FAILED" not in out
    code, _, err = run(capsys, "generate", mixed_svg, "--piece", "line", "-o", tmp_path / "h.npz")
    assert code == 2 and f"{mixed_svg}: piece 'line': only 2 distinct points" in err
    assert not (tmp_path / "h.npz").exists()
    code, _, err = run(capsys, "pieces", mixed_svg, "--piece", "flat")
    assert code == 2 and "encloses no area" in err


def test_a_file_with_no_good_piece_still_fails(capsys, tmp_path):
    path = tmp_path / "bad.svg"
    path.write_text(_MIXED_SVG.replace('<rect id="good" x="10" y="10" width="60" height="40"/>', ""))
    code, _, err = run(capsys, "generate", path, "-o", tmp_path / "out" / "{piece}.npz")
    assert code == 2 and not (tmp_path / "out").exists()
    assert f"{path}: piece 'line': only 2" in err and f"{path}: piece 'flat': encloses no area" in err
    assert "none of its 2 pieces could be used" in err
    code, out, err = run(capsys, "pieces", path)
    assert code == 2 and out == "" and "piece 'line'" in err


def test_a_piece_that_fails_in_generate_does_not_block_the_others(capsys, tmp_path, monkeypatch):
    """Gridding errors (InputError, BoundaryError, NotConvergedError) are per piece too."""
    from clothgrid import pipeline

    path = tmp_path / "two.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">'
                    '<rect id="a" x="0" y="0" width="40" height="40"/>'
                    '<rect id="b" x="50" y="0" width="40" height="40"/></svg>')
    real = pipeline.generate

    def generate(boundary, nodes, **kw):
        if boundary.name == "b":
            raise clothgrid.NotConvergedError("solver 'multigrid' did not reach error <= 0.000244 (test)")
        return real(boundary, nodes, **kw)

    monkeypatch.setattr(pipeline, "generate", generate)
    code, _, err = run(capsys, "generate", path, "-o", tmp_path / "o" / "{piece}.npz", "-q")
    assert code == cli.EXIT_PARTIAL and sorted(p.name for p in (tmp_path / "o").iterdir()) == ["a.npz"]
    assert f"clothgrid: error: {path}: piece 'b': solver 'multigrid' did not reach" in err
    # the only piece asked for fails: its own error and exit code (3: not converged), nothing written
    code, _, err = run(capsys, "generate", path, "--piece", "b", "-o", tmp_path / "b.npz")
    assert code == 3 and "raise --max-iter" in err and not (tmp_path / "b.npz").exists()


def test_a_failed_write_still_removes_every_output_when_a_piece_failed(capsys, tmp_path, monkeypatch):
    """A failure while writing (not gridding) is the run's: every file written is removed, exit 2."""
    from clothgrid import writers

    path = tmp_path / "two.svg"
    path.write_text(_MIXED_SVG.replace('<polygon', '<rect id="second" x="100" y="10" width="30" height="30"/>'
                                       '<polygon'))
    real = writers.save

    def save(grid, out, **kw):
        if Path(out).name == "second.obj":
            raise OSError(28, "No space left on device", str(out))
        return real(grid, out, **kw)

    monkeypatch.setattr(writers, "save", save)
    code, _, err = run(capsys, "generate", path, "-o", tmp_path / "o" / "{piece}.obj", "-q")
    assert code == 2 and "cannot write" in err and "second.obj" in err
    assert not (tmp_path / "o").exists()            # good.obj and the folder made for it are gone


def test_verbose_prints_where_the_time_goes(tmp_path, capsys):
    src = _write(tmp_path / "square.json", _square_sides(9))
    assert main(["generate", str(src), "-o", str(tmp_path / "g.npz"), "-v", "--functional", "auto"]) == 0
    err = capsys.readouterr().err
    for stage in ("time: start-up", "imports for generate", "time: read", "time: generate", "(solve ",
                  "fold-free ", "quality ", "time: write", "time: whole command"):
        assert stage in err, stage
    assert main(["generate", str(src), "-o", str(tmp_path / "h.npz"), "-q"]) == 0
    assert "time:" not in capsys.readouterr().err
    # multigrid's set-up (where a fresh process loads Numba) is its own figure within the solve
    assert main(["generate", str(src), "-o", str(tmp_path / "m.npz"), "-v", "--solver", "multigrid"]) == 0
    err = capsys.readouterr().err
    assert " of which set-up " in err
    # and the threads the kernels ran on (the multigrid solve's kernels are parallel)
    import numba

    threads = next(s for s in err.splitlines() if s.startswith("clothgrid: threads: "))
    assert f"threads: {numba.config.NUMBA_NUM_THREADS} Numba thread" in threads
    assert f"threading layer {numba.threading_layer()}" in threads


def test_a_first_compile_is_said_once(tmp_path, monkeypatch):
    """A run whose kernels compile (Numba's disk cache holds none: a fresh installation) says so once,
    at the first compile, through its progress; nothing with -q (no progress). The listener waits for
    Numba's import (``lean_imports.after_import``): a module imported later gets its callback right
    after it has run, and a failing callback leaves the import alone."""
    import numba

    from clothgrid.lean_imports import after_import

    said: list[str] = []

    def fresh():
        @numba.njit(cache=False)
        def f(x):
            return x + 1
        return f

    with cli._first_compile_said(None):                 # -q: nothing said
        assert fresh()(1) == 2
    with cli._first_compile_said(said.append):          # numba is imported here: in place at once
        assert said == []
        assert fresh()(1) == 2 and fresh()(2) == 3 and fresh()(1.5) == 2.5     # three compiles
    assert len(said) == 1 and said[0].startswith("compiling numerical kernels")
    assert fresh()(1) == 2 and len(said) == 1          # after the command: nothing said to it
    with cli._first_compile_said(said.append):          # the next command: said once again
        assert fresh()(1) == 2
    from numba.core import event

    assert len(said) == 2 and sum(type(x).__name__ == "FirstCompile" for x in event._registered["numba:compile"]) == 1
    # after_import: a module not imported yet
    (tmp_path / "cg_later_mod.py").write_text("VALUE = 7\n")
    (tmp_path / "cg_later_bad.py").write_text("VALUE = 8\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    seen = []
    assert after_import("cg_later_mod", lambda m: seen.append(m.VALUE))
    assert not after_import("cg_later_mod", seen.append)             # one hook a module
    assert seen == []
    import cg_later_mod                                                  # noqa: F401

    assert seen == [7]
    assert after_import("cg_later_mod", lambda m: seen.append(-m.VALUE)) and seen == [7, -7]   # imported: now
    assert after_import("cg_later_bad", lambda m: 1 / 0)
    import cg_later_bad                                                  # the callback failed: imported still

    assert cg_later_bad.VALUE == 8


def test_timing_lines_without_proc():
    lines = cli.timing_lines(None, 0.01, 0.02, [], 0.03, None)
    assert lines[0].startswith("time: start-up") and "n/a" in lines[0] and lines[-1] == "time: whole command n/a s"


def test_pieces_lists_an_automatic_choices_runners_up(tmp_path, capsys):
    """A piece with six convex corners: its corners are scored, and `clothgrid pieces` lists the
    three runners-up `generate` would try (and --json holds them), each distinct from the choice."""
    svg = tmp_path / "hex.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="600mm" viewBox="0 0 400 600">'
                   '<path id="hex" d="M 20,580 L 320,580 L 340,200 L 240,60 L 80,80 L 0,220 Z"/></svg>')
    code, out, err = run(capsys, "pieces", svg)
    assert code == 0, err
    line = next(s for s in out.splitlines() if s.startswith("  runners-up: "))
    sets = [tuple(map(int, a.split(","))) for a in line.removeprefix("  runners-up: ").split("; ")]
    code, out, _ = run(capsys, "pieces", svg, "--json")
    corners = json.loads(out)["pieces"][0]["corners"]
    assert corners["method"] == "scored" and [list(a) for a in sets] == corners["alternatives"]
    assert len(sets) == 3 and len({tuple(sorted(a)) for a in sets} | {tuple(sorted(corners["indices"]))}) == 4
