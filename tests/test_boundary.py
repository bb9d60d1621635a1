"""Tests of clothgrid.boundary and clothgrid.readers."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

from clothgrid.boundary import Boundary, resample_polyline
from clothgrid.errors import BoundaryError, InputError
from clothgrid.readers import READERS, load_boundary, register_reader

REGIONS = Path(__file__).parent / "data" / "regions"
REGION_FILES = sorted(REGIONS.glob("*.json"))
WITH_CORNERS = [p for p in REGION_FILES if "corners" in json.loads(p.read_text())]


def square_sides(n: int = 5, dim: int = 2) -> list[np.ndarray]:
    """bottom, right, top, left of the unit square with n points per side."""
    t = np.linspace(0.0, 1.0, n)
    z, o = np.zeros(n), np.ones(n)
    sides = [np.c_[t, z], np.c_[o, t], np.c_[t, o], np.c_[z, t]]
    if dim == 3:
        sides = [np.c_[s, np.zeros(n)] for s in sides]
    return sides


def square_outline() -> np.ndarray:
    """Counter-clockwise unit square, 2 points per side between corners 0, 2, 4, 6."""
    return np.array([[0, 0], [0.5, 0], [1, 0], [1, 0.5], [1, 1], [0.5, 1], [0, 1], [0, 0.5]], float)


# ------------------------------------------------------------------ from_sides
def test_from_sides_2d():
    b = Boundary.from_sides(*square_sides(5), name="sq")
    assert b.dim == 2 and b.name == "sq"
    for s in (b.bottom, b.right, b.top, b.left):
        assert s.shape == (5, 3) and s.dtype == np.float64 and s.flags.c_contiguous
        assert np.all(s[:, 2] == 0.0)
    assert b.shape == (5, 5)
    assert b.size == pytest.approx(np.sqrt(2))
    assert b.side_lengths == pytest.approx((1, 1, 1, 1))
    assert b.orientation == 1.0
    np.testing.assert_allclose(b.normal, [0, 0, 1])
    out = b.outline()
    assert out.shape == (16, 3)
    assert len(np.unique(out, axis=0)) == 16
    assert "sq" in repr(b) and "5" in repr(b)


def test_from_sides_3d_planar_rotated():
    rot = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))[0]
    if rot[2, 2] < 0:
        rot[:, 2] *= -1
    sides = [s @ rot.T + [1.0, 2.0, 3.0] for s in square_sides(6, dim=3)]
    b = Boundary.from_sides(*sides)
    assert b.dim == 3 and b.shape == (6, 6)
    np.testing.assert_allclose(b.bottom, sides[0])
    assert b.orientation == 1.0
    np.testing.assert_allclose(b.normal, rot[:, 2], atol=1e-12)
    assert np.linalg.norm(b.normal) == pytest.approx(1.0)


def test_from_sides_3d_non_planar():
    t = np.linspace(0, 1, 7)
    z = lambda x, y: 0.5 * (x - 0.5) * (y - 0.5)  # noqa: E731  (a saddle)
    sides = [np.c_[t, 0 * t, z(t, 0)], np.c_[1 + 0 * t, t, z(1, t)],
             np.c_[t, 1 + 0 * t, z(t, 1)], np.c_[0 * t, t, z(0, t)]]
    b = Boundary.from_sides(*sides)
    assert b.dim == 3 and b.shape == (7, 7)
    assert b.orientation == 1.0
    assert b.normal[2] > 0.99


def test_corners_are_snapped_bitwise():
    bottom, right, top, left = square_sides(4)
    left = left.copy()
    right = right.copy()
    left[0] += 1e-13
    right[-1] -= [3e-13, 1e-13]
    b = Boundary.from_sides(bottom, right, top, left)
    assert np.array_equal(b.left[0], b.bottom[0])
    assert np.array_equal(b.right[0], b.bottom[-1])
    assert np.array_equal(b.left[-1], b.top[0])
    assert np.array_equal(b.right[-1], b.top[-1])
    assert np.array_equal(b.right[-1], [1.0, 1.0, 0.0])   # the top's value is kept


def test_consecutive_duplicates_allowed():
    bottom, right, top, left = square_sides(4)
    bottom = np.insert(bottom, 2, bottom[2], axis=0)
    b = Boundary.from_sides(bottom, right, top, left)
    assert len(b.bottom) == 5


def test_mismatched_counts_raise_from_shape():
    bottom, right, top, left = square_sides(5)
    b = Boundary.from_sides(bottom, right, square_sides(7)[2], left)
    with pytest.raises(BoundaryError, match=r"bottom 5 and top 7") as e:
        b.shape
    assert "--nodes 7x5" in str(e.value)
    assert b.resampled(7, 5).shape == (7, 5)


@pytest.mark.parametrize("change, words", [
    ({"bottom": "abc"}, ["bottom", "points"]),
    ({"right": [[1, 0], [1]]}, ["right", "points"]),
    ({"top": np.zeros((4, 4))}, ["top", "shape (4, 4)"]),
    ({"left": 3.0}, ["left", "points"]),
    ({"left": []}, ["left", "no points"]),
    ({"left": [[0, 0]]}, ["left", "at least 2 points", "got 1"]),
    ({"top": np.c_[np.linspace(0, 1, 5), np.ones(5), np.zeros(5)]}, ["same dimension", "top 3D", "bottom 2D"]),
])
def test_from_sides_bad_arrays(change, words):
    sides = dict(zip(("bottom", "right", "top", "left"), square_sides(5)))
    sides.update(change)
    with pytest.raises(BoundaryError) as e:
        Boundary.from_sides(**sides)
    for w in words:
        assert w in str(e.value)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_from_sides_non_finite(value):
    bottom, right, top, left = square_sides(5)
    right = right.copy()
    right[3, 0] = value
    with pytest.raises(BoundaryError, match=r"right side .*non-finite.*point 3"):
        Boundary.from_sides(bottom, right, top, left)


def test_from_sides_open_corner():
    bottom, right, top, left = square_sides(5)
    with pytest.raises(BoundaryError) as e:
        Boundary.from_sides(bottom, right + [0.1, 0.0], top, left)
    msg = str(e.value)
    assert isinstance(e.value, InputError) and isinstance(e.value, ValueError)
    assert "bottom-right corner does not meet" in msg
    assert "bottom[-1] = (1, 0)" in msg and "right[0] = (1.1, 0)" in msg
    assert "0.1 apart" in msg
    assert f"{100 * 0.1 / np.hypot(1.1, 1):.3g}%" in msg
    assert "top-right" in msg   # the other open corner is listed


def test_from_sides_reversed_side_is_diagnosed():
    bottom, right, top, left = square_sides(5)
    with pytest.raises(BoundaryError, match=r"left side seems reversed.*bottom to top"):
        Boundary.from_sides(bottom, right, top, left[::-1])
    with pytest.raises(BoundaryError, match=r"top side seems reversed.*left to right"):
        Boundary.from_sides(bottom, right, top[::-1], left)


def test_from_sides_zero_length_side():
    # a triangle whose right side is a single repeated point
    bottom = [[0, 0], [1, 0]]
    right = [[1, 0], [1, 0], [1, 0]]
    top = [[0, 1], [0.5, 0.5], [1, 0]]
    left = [[0, 0], [0, 1]]
    with pytest.raises(BoundaryError, match=r"right side has zero length"):
        Boundary.from_sides(bottom, right, top, left)


def test_from_sides_self_intersecting():
    # bottom and top cross: a bow tie
    bottom = [[0, 0], [1, 1]]
    right = [[1, 1], [1, 0]]
    top = [[0, 1], [1, 0]]
    left = [[0, 0], [0, 1]]
    with pytest.raises(BoundaryError) as e:
        Boundary.from_sides(bottom, right, top, left)
    msg = str(e.value)
    assert "crosses or touches itself" in msg
    assert "bottom segment 0" in msg and "top segment 0" in msg
    assert "near (0.5, 0.5)" in msg


def test_touching_outline_rejected():
    # a notch in the top reaches down to touch the bottom side at (1, 0)
    pts = [[0, 0], [1, 0], [2, 0], [2, 2], [1.5, 2], [1, 0], [0.5, 2], [0, 2]]
    with pytest.raises(BoundaryError, match=r"bottom segment 0 .* meets .*near \(1, 0\)"):
        Boundary.from_outline(pts, [0, 2, 3, 7])


def test_fold_back_rejected():
    # the right side goes up and comes back down over itself before going on
    pts = [[0, 0], [1, 0], [1, 0.8], [1, 0.5], [1, 1], [0, 1]]
    with pytest.raises(BoundaryError, match=r"folds back"):
        Boundary.from_outline(pts, [0, 1, 4, 5])


def test_non_planar_3d_skips_intersection_check():
    # a bow tie in xy, but lifted out of any plane
    pts = [[0, 0, 0], [1, 1, 0], [1, 0, 1], [0, 1, 1.5]]
    b = Boundary.from_outline(pts, [0, 1, 2, 3])
    assert b.dim == 3


def test_intersection_check_is_fast():
    n = 4000
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.3 * np.sin(9 * t)
    pts = np.c_[r * np.cos(t), r * np.sin(t)]
    t0 = time.perf_counter()
    b = Boundary.from_outline(pts, [0, 1000, 2000, 3000])
    assert time.perf_counter() - t0 < 0.5
    assert b.shape == (1001, 1001)
    bad = pts.copy()
    bad[2500] = [0.0, 0.0]   # a spike to the centre crosses nothing but touches no one...
    bad[500] = [0.0, 0.0]    # ...until a second spike meets it there
    with pytest.raises(BoundaryError, match=r"crosses or touches"):
        Boundary.from_outline(bad, [0, 1000, 2000, 3000])


# ---------------------------------------------------------------- from_outline
@pytest.mark.parametrize("path", WITH_CORNERS, ids=lambda p: p.stem)
def test_regions_with_corners(path):
    data = json.loads(path.read_text())
    pts = np.asarray(data["outline"], float)
    c = data["corners"]
    b = Boundary.from_outline(pts, c, name=data["name"])
    counts = [len(b.bottom), len(b.right), len(b.top), len(b.left)]
    assert sum(counts) - 4 == len(pts)
    expected = [c[1] - c[0], c[2] - c[1], c[3] - c[2], len(pts) - c[3] + c[0]]
    assert [n - 1 for n in counts] == expected
    np.testing.assert_array_equal(b.bottom[0, :2], pts[c[0]])
    np.testing.assert_array_equal(b.right[0, :2], pts[c[1]])
    np.testing.assert_array_equal(b.top[-1, :2], pts[c[2]])
    np.testing.assert_array_equal(b.left[-1, :2], pts[c[3]])
    np.testing.assert_array_equal(b.outline()[:, :2], np.roll(pts, -c[0], axis=0))
    assert b.orientation == 1.0
    assert b.shape == (counts[0], counts[3])


def test_there_are_regions_with_corners():
    assert len(WITH_CORNERS) == 8   # the 76-point Roache regions


@pytest.mark.parametrize("path", sorted(REGIONS.glob("few_sides-cuad*.json")), ids=lambda p: p.stem)
def test_unit_square_regions(path):
    pts = np.asarray(json.loads(path.read_text())["outline"], float)
    corners = [int(np.flatnonzero((pts == q).all(axis=1))[0]) for q in ([0, 0], [1, 0], [1, 1], [0, 1])]
    b = Boundary.from_outline(pts, corners)
    assert b.side_lengths == pytest.approx((1, 1, 1, 1))
    assert b.orientation == 1.0


@pytest.mark.parametrize("name", ["roache-airfoil", "roache-nairfoil", "roache-valley"])
def test_slit_regions_touch_themselves(name):
    """These Roache regions run along a cut and back: their outlines touch themselves."""
    pts = json.loads((REGIONS / f"{name}.json").read_text())["outline"]
    n = len(pts)
    with pytest.raises(BoundaryError, match=r"touches|folds back"):
        Boundary.from_outline(pts, [0, n // 4, n // 2, 3 * n // 4])


def test_from_outline_wraps_and_drops_repeated_point():
    pts = square_outline()
    rolled = np.roll(pts, 3, axis=0)          # corners now at 3, 5, 7, 1 (wrapping)
    b = Boundary.from_outline(np.vstack([rolled, rolled[:1]]), [3, 5, 7, 1], name="x")
    ref = Boundary.from_outline(pts, [0, 2, 4, 6])
    for s in ("bottom", "right", "top", "left"):
        np.testing.assert_array_equal(getattr(b, s), getattr(ref, s))
    np.testing.assert_array_equal(ref.left, [[0, 0, 0], [0, 0.5, 0], [0, 1, 0]])
    np.testing.assert_array_equal(ref.top, [[0, 1, 0], [0.5, 1, 0], [1, 1, 0]])


def test_clockwise_outline():
    pts = square_outline()[::-1]               # clockwise
    b = Boundary.from_outline(pts, [0, 2, 4, 6])
    assert b.orientation == -1.0
    np.testing.assert_allclose(b.normal, [0, 0, -1])
    b3 = Boundary.from_outline(np.c_[pts, np.full(len(pts), 2.0)], [0, 2, 4, 6])
    assert b3.dim == 3 and b3.orientation == -1.0
    np.testing.assert_allclose(b3.normal, [0, 0, -1], atol=1e-12)


def test_bow_tie_outline_rejected():
    with pytest.raises(BoundaryError, match=r"crosses or touches itself"):
        Boundary.from_outline([[0, 0], [1, 1], [1, 0], [0, 1]], [0, 1, 2, 3])


@pytest.mark.parametrize("corners, words", [
    ([0, 2, 4], "4 indices"),
    ("0246", "4 indices"),
    (5, "4 indices"),
    ([0, 2, 4.0, 6], "integer"),
    ([0, 2, True, 6], "integer"),
    ([0, 2, 4, 8], "0..7"),
    ([-1, 2, 4, 6], "0..7"),
    ([0, 2, 2, 6], "distinct"),
    ([0, 4, 2, 6], "order"),
    ([6, 4, 2, 0], "order"),
])
def test_from_outline_bad_corners(corners, words):
    with pytest.raises(BoundaryError, match=words):
        Boundary.from_outline(square_outline(), corners)


def test_from_outline_bad_points():
    with pytest.raises(BoundaryError, match=r"at least 4 points"):
        Boundary.from_outline([[0, 0], [1, 0], [1, 1]], [0, 1, 2, 0])
    with pytest.raises(BoundaryError, match=r"outline .*non-finite.*point 5"):
        pts = square_outline()
        pts[5, 1] = np.nan
        Boundary.from_outline(pts, [0, 2, 4, 6])
    with pytest.raises(BoundaryError, match=r"outline must be a list of 2D or 3D points"):
        Boundary.from_outline([1, 2, 3, 4], [0, 1, 2, 3])


# ------------------------------------------------------------------ resampling
def l_path(k: int) -> np.ndarray:
    """A monotone L path (arc length = x + y), unevenly sampled, ending at (2, 1)."""
    x = np.sort(np.r_[0.0, 2.0, np.random.default_rng(k).uniform(0, 2, 6)])
    y = np.sort(np.r_[0.0, 1.0, np.random.default_rng(k + 1).uniform(0, 1, 3)])
    return np.vstack([np.c_[x, 0 * x], np.c_[2 + 0 * y[1:], y[1:]]])


def test_resample_polyline_uniform_arc_length():
    p = l_path(0)
    q = resample_polyline(p, 13)
    assert q.shape == (13, 3) and np.all(q[:, 2] == 0)
    assert np.array_equal(q[0, :2], p[0]) and np.array_equal(q[-1, :2], p[-1])
    s = q[:, 0] + q[:, 1]                    # arc length along the L path
    np.testing.assert_allclose(np.diff(s), 3.0 / 12, rtol=1e-12)
    assert np.all((np.abs(q[:, 1]) < 1e-15) | (np.abs(q[:, 0] - 2) < 1e-15))  # on the path
    np.testing.assert_allclose(resample_polyline([[0, 0], [1, 0], [1, 0], [3, 0]], 4)[:, 0], [0, 1, 2, 3])


def test_resample_polyline_errors():
    with pytest.raises(InputError, match=r"integer >= 2"):
        resample_polyline(l_path(0), 1)
    with pytest.raises(BoundaryError, match=r"zero length"):
        resample_polyline([[1, 1], [1, 1]], 5)


def test_resampled_boundary():
    bottom = l_path(3)                             # (0,0) ... (2,1)
    top = np.array([[0, 3], [0.3, 3], [2, 3]])
    left = np.array([[0, 0], [0, 1], [0, 2.2], [0, 3]])
    right = np.array([[2, 1], [2, 3]])
    b = Boundary.from_sides(bottom, right, top, left, name="L")
    r = b.resampled(9, 4)
    assert r.shape == (9, 4) and r.name == "L" and r.dim == 2
    assert r.left is b.left                        # already 4 points: unchanged
    for s in ("bottom", "right", "top", "left"):
        assert np.array_equal(getattr(r, s)[[0, -1]], getattr(b, s)[[0, -1]])
    assert np.array_equal(r.left[0], r.bottom[0]) and np.array_equal(r.right[-1], r.top[-1])
    # bottom: 2 long then 1 up, 8 segments split 5 + 3 at the kept corner
    np.testing.assert_allclose(np.diff(r.bottom[:6, 0]), 2.0 / 5, rtol=1e-12)
    np.testing.assert_allclose(np.diff(r.bottom[5:, 1]), 1.0 / 3, rtol=1e-12)
    np.testing.assert_allclose(np.diff(r.top[:, 0]), 2.0 / 8, rtol=1e-12)
    np.testing.assert_allclose(np.diff(r.right[:, 1]), 2.0 / 3, rtol=1e-12)
    # the L's corner (2, 0) turns by 90 degrees: it is kept as a node, so no side is cut short
    assert any(np.array_equal(p[:2], [2.0, 0.0]) for p in r.bottom)
    assert r.side_lengths == pytest.approx(b.side_lengths)


def test_resampled_outline_spaces_nodes_whatever_the_count():
    """A boundary sampled from an outline (a pattern piece's, ``from_outline(..., sampled=True)``) has
    points, not nodes, on its sides: a side with as many points as nodes asked is spaced by arc length
    too (its points 0.5 to 4 apart: kept as nodes they gave Optitex's graded sleeve an edge spread of
    10). Sides given as sides (``from_sides``), or a region file's outline with its corners, with the
    count asked stay as they are (a classic region's own nodes)."""
    xs = np.array([0.0, 0.5, 4.5, 5.0, 9.0, 10.0])               # uneven points on the bottom side
    outline = np.vstack([np.column_stack([xs, np.zeros(6)]), [[10.0, 5.0], [0.0, 5.0]]])
    region = Boundary.from_outline(outline, [0, 5, 6, 7])
    assert not region.sampled and region.resampled(6, 2).bottom is region.bottom
    b = Boundary.from_outline(outline, [0, 5, 6, 7], name="strip", sampled=True)
    assert b.sampled and b.bottom.shape == (6, 3)
    r = b.resampled(6, 2)
    np.testing.assert_allclose(r.bottom[:, 0], np.linspace(0.0, 10.0, 6), rtol=0, atol=1e-12)
    assert not r.sampled
    sides = Boundary.from_sides(b.bottom, b.right, b.top, b.left)
    assert not sides.sampled and sides.resampled(6, 2).bottom is sides.bottom


@pytest.mark.parametrize("nu, nv", [(1, 5), (5, 0), (2.0, 5), ("3", 4), (True, 4)])
def test_resampled_bad_counts(nu, nv):
    b = Boundary.from_sides(*square_sides(5))
    with pytest.raises(InputError, match=r"(nu|nv) must be an integer >= 2"):
        b.resampled(nu, nv)


# --------------------------------------------------------------------- readers
def write(tmp_path: Path, name: str, content) -> Path:
    p = tmp_path / name
    p.write_text(content if isinstance(content, str) else json.dumps(content))
    return p


def test_load_sides_json(tmp_path):
    sides = dict(zip(("bottom", "right", "top", "left"), (s.tolist() for s in square_sides(4, dim=3))))
    b = load_boundary(write(tmp_path, "piece.json", sides))
    assert b.name == "piece" and b.dim == 3 and b.shape == (4, 4)
    b = load_boundary(write(tmp_path, "p2.JSON", {**sides, "name": "front"}))
    assert b.name == "front"


def test_load_region_json(tmp_path):
    p = write(tmp_path, "r.json", {"name": "sq", "outline": square_outline().tolist(),
                                   "corners": [0, 2, 4, 6]})
    b = load_boundary(p)
    assert b.name == "sq" and b.dim == 2 and b.shape == (3, 3)


@pytest.mark.parametrize("path", WITH_CORNERS, ids=lambda p: p.stem)
def test_load_test_regions(path):
    b = load_boundary(path)
    assert b.name == path.stem and b.shape == (20, 20)


@pytest.mark.parametrize("content, error, words", [
    ("{\"bottom\": [[0, 0], [1, 0]],\n \"right\": oops}", InputError, ["invalid JSON", "line 2", "column"]),
    ("[1, 2]", InputError, ["must be an object", "list"]),
    ({"points": []}, InputError, ["expected the keys", "'bottom'", "'outline'", "'points'"]),
    ({"bottom": [[0, 0], [1, 0]], "top": [[0, 1], [1, 1]]}, InputError, ["missing side(s) right, left"]),
    ({"outline": [[0, 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0]]}, BoundaryError, ["z varies", "'corners'"]),
    ({"outline": [[0, 0], [1, 0], [2, 0]]}, BoundaryError, ["encloses no area"]),
    ({"outline": "abc"}, InputError, ["'outline' must be a list", "str"]),
    ({"outline": [[0, 0], [1, "x"], [1, 1]]}, BoundaryError, ["must be a list of 2D or 3D points"]),
    ({"outline": "abc", "corners": [0, 1, 2, 3]}, InputError, ["'outline' must be a list", "str"]),
    ({"outline": [[0, 0], [1, 0], [1, 1], [0, 1]], "corners": 4}, InputError, ["'corners' must be a list"]),
    ({"outline": [[0, 0], [1, 0], [1, 1], [0, 1]], "corners": [0, 1, 2, 3], "name": 5},
     InputError, ["'name' must be a string"]),
    ({"outline": [[0, 0]], "corners": [0, 1, 2, 3], "bottom": []}, InputError, ["not both"]),
    ({"bottom": 1, "right": [], "top": [], "left": []}, InputError, ["'bottom' must be a list"]),
    ({"outline": [[0, 0], [1, 1], [1, 0], [0, 1]], "corners": [0, 1, 2, 3]}, BoundaryError,
     ["crosses or touches itself"]),
    ({"outline": [[0, 0], [1, 0], [1, 1], [0, 1]], "corners": [0, 2, 1, 3]}, BoundaryError, ["order"]),
])
def test_reader_errors(tmp_path, content, error, words):
    p = write(tmp_path, "bad.json", content)
    with pytest.raises(error) as e:
        load_boundary(p)
    assert isinstance(e.value, InputError)
    msg = str(e.value)
    assert str(p) in msg
    for w in words:
        assert w in msg


def test_reader_file_errors(tmp_path):
    with pytest.raises(InputError, match=r"no such file"):
        load_boundary(tmp_path / "missing.json")
    with pytest.raises(InputError, match=r"unknown input file type '\.stl'.*\.json"):
        load_boundary(write(tmp_path, "a.stl", "solid"))
    with pytest.raises(InputError, match=r"no closed path"):     # one registry: an SVG is read as a pattern
        load_boundary(write(tmp_path, "a.svg", "<svg/>"))
    with pytest.raises(InputError, match=r"directory"):
        load_boundary(tmp_path)
    bad = tmp_path / "bin.json"
    bad.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(InputError, match=r"UTF-8"):
        load_boundary(bad)


def test_register_reader(tmp_path, monkeypatch):
    calls = []

    def read_sq(path):
        calls.append(path)
        return Boundary.from_sides(*square_sides(3), name=Path(path).stem)

    monkeypatch.setattr("clothgrid.readers.READERS", dict(READERS))   # restored afterwards
    register_reader("SQ", read_sq)
    b = load_boundary(write(tmp_path, "thing.sq", ""))
    assert b.name == "thing" and calls == [tmp_path / "thing.sq"]
    with pytest.raises(InputError, match=r"known: .*\.json, \.sq"):
        load_boundary(write(tmp_path, "thing.txt", ""))


def test_resample_keeps_sharp_vertices_and_spreads_the_rest_by_length():
    from clothgrid.boundary import sharp_vertices
    # a dart: along, down into the V, up, along (turns of about 100 and 160 degrees)
    p = np.array([[0, 0], [4, 0], [4.2, -3], [4.4, 0], [10, 0]], float)
    keep = sharp_vertices(p)
    assert list(keep) == [1, 2, 3]
    q = resample_polyline(p, 21, keep)
    for k in keep:                                  # every sharp vertex is a node, exactly
        assert any(np.array_equal(x[:2], p[k]) for x in q)
    assert np.all(np.diff(q[:, 0]) >= 0)            # in order along the side
    assert np.array_equal(q[0, :2], p[0]) and np.array_equal(q[-1, :2], p[-1])
    smooth = np.c_[np.linspace(0, 1, 50), np.sin(np.linspace(0, 1, 50))]
    assert len(sharp_vertices(smooth)) == 0       # a sampled smooth curve keeps nothing


SLITS = ("roache-airfoil", "roache-nairfoil", "roache-valley")     # outlines that touch themselves


def _outline_only(path: Path) -> list:
    return json.loads(path.read_text())["outline"]


@pytest.mark.parametrize("path", [p for p in REGION_FILES if p.stem not in SLITS], ids=lambda p: p.stem)
def test_an_outline_without_corners_gets_them_chosen(tmp_path, path):
    """A region file without 'corners' is read with corners chosen as a pattern piece's are: a
    valid four-sided boundary holding every point of the outline bit for bit, whose fold-free grid
    has no folded cell; unit squares get their own four corners."""
    from clothgrid import generate

    outline = _outline_only(path)
    b = load_boundary(write(tmp_path, "r.json", {"name": path.stem, "outline": outline}))
    assert b.name == path.stem and b.orientation == 1.0
    loop = b.outline()[:, :2]
    pts = np.asarray(outline, float)
    assert all((loop == q).all(axis=1).any() for q in pts)       # every point of the outline, exactly
    if path.stem.startswith("few_sides-cuad"):
        assert b.side_lengths == pytest.approx((1, 1, 1, 1))
    g = generate(b, 24, functional="auto")
    assert g.info["folded"] == 0


def test_chosen_corners_do_not_depend_on_units_or_direction(tmp_path):
    """The corners chosen for an outline are the same points whatever its scale (metres or
    micrometres, a power of ten: not exact in binary) and whichever way it runs, and a constant z
    is kept."""
    from clothgrid.patterns import outline_boundary

    rng = np.random.default_rng()
    pts = np.asarray(_outline_only(REGIONS / "roache-tie.json"), float) + rng.normal(scale=1e-4, size=(76, 2))
    ref, choice = outline_boundary(pts)
    corners = np.array([ref.bottom[0], ref.bottom[-1], ref.top[-1], ref.top[0]])
    for scale in (1e-6, 1e3):
        b, _ = outline_boundary(pts * scale)
        got = np.array([b.bottom[0], b.bottom[-1], b.top[-1], b.top[0]])
        np.testing.assert_allclose(got, corners * scale, rtol=1e-12)
    b, _ = outline_boundary(pts[::-1])                  # clockwise: taken in reverse
    assert b.orientation == 1.0
    np.testing.assert_array_equal(np.array([b.bottom[0], b.bottom[-1], b.top[-1], b.top[0]]), corners)
    b, _ = outline_boundary(np.column_stack([pts, np.full(len(pts), 2.5)]))
    assert np.all(b.outline()[:, 2] == 2.5) and b.dim == 3
    np.testing.assert_array_equal(b.outline()[:, :2], ref.outline()[:, :2])


def test_the_command_grids_an_outline_without_corners(tmp_path, capsys):
    from clothgrid.cli import main

    src = write(tmp_path, "circle.json", {"outline": [[np.cos(t), np.sin(t)] for t in np.linspace(0, 2 * np.pi, 41)[:-1]]})
    out = tmp_path / "g.npz"
    assert main(["generate", str(src), "-o", str(out), "-q"]) == 0
    grid = np.load(out)["points"]
    assert grid.shape == (11, 11, 3)
    r = np.hypot(grid[..., 0], grid[..., 1])
    assert np.allclose(np.r_[r[0], r[-1], r[:, 0], r[:, -1]], 1.0)     # the sides on the circle
    # -v says where the corners went: a unit square's, whichever of its points the outline starts at
    src = write(tmp_path, "square.json", {"outline": [[1, 1], [0, 1], [0, 0], [1, 0]]})
    capsys.readouterr()
    assert main(["generate", str(src), "-o", str(tmp_path / "s.npz"), "--nodes", "5x5", "-v"]) == 0
    assert "corners (bottom-left, bottom-right, top-right, top-left) (0, 0) (1, 0) (1, 1) (0, 1); " \
           "sides of 2, 2, 2, 2 points" in capsys.readouterr().err
    # 'clothgrid pieces' is for pattern files: it says what to do with a boundary file instead
    assert main(["pieces", str(src)]) == 2
    err = capsys.readouterr().err
    assert "is a boundary file" in err and "clothgrid generate" in err and "load_boundary()" in err


def test_an_outline_too_dense_to_check_is_refused(tmp_path, monkeypatch, capsys):
    """The self-intersection check counts its pairs of nearby segments before comparing them: an
    outline whose noise is far wider than its point spacing (quadratic in its points) is refused
    over clothgrid.limits.MAX_SEGMENT_PAIRS with a message, by the API and by the command (exit 2,
    no output), while a smooth outline of as many points is checked as before."""
    from clothgrid import limits
    from clothgrid.cli import main

    monkeypatch.setattr(limits, "MAX_SEGMENT_PAIRS", 50_000)     # the smooth outline: 11,400 pairs; the noisy: 155,000
    rng = np.random.default_rng()
    n = 8000
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    smooth = np.c_[np.cos(t), np.sin(t)]
    Boundary.from_outline(smooth, [0, n // 4, n // 2, 3 * n // 4])
    noisy = smooth * (1 + 0.01 * rng.standard_normal(n))[:, None]
    with pytest.raises(BoundaryError, match=r"too dense to check for self-intersection.*MAX_SEGMENT_PAIRS"):
        Boundary.from_outline(noisy, [0, n // 4, n // 2, 3 * n // 4])
    src = write(tmp_path, "noisy.json", {"outline": noisy.tolist()})
    out = tmp_path / "g.npz"
    assert main(["generate", str(src), "-o", str(out), "--nodes", "9", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clothgrid: error:") and "too dense" in err[0]
    assert not out.exists()
