"""Tests for clothgrid.quality."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clothgrid.errors import InputError
from clothgrid.grid import Grid
from clothgrid.quality import Quality, quality


def plane_grid(nu: int = 9, nv: int = 7, shear: float = 0.0, h: float = 1.0) -> np.ndarray:
    """``(nu, nv, 3)`` nodes ``x = h*(i + shear*j)``, ``y = h*j``, ``z = 0``."""
    i, j = np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij")
    return np.stack([h * (i + shear * j), h * j, np.zeros_like(i)], axis=-1)


def cylinder_grid(nu: int = 40, nv: int = 20, turn: float = 1.5 * np.pi) -> np.ndarray:
    """Part of the unit cylinder about z: ``i`` along the angle, ``j`` along z."""
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    theta = turn * i / (nu - 1)
    return np.stack([np.cos(theta), np.sin(theta), 2.0 * j / (nv - 1)], axis=-1)


def reference_folds(points: np.ndarray, normal: np.ndarray) -> set[tuple[int, int]]:
    """Folded cells by the definition, one corner at a time."""
    nu, nv = points.shape[:2]
    out = set()
    for i in range(nu - 1):
        for j in range(nv - 1):
            c = [points[i, j], points[i + 1, j], points[i + 1, j + 1], points[i, j + 1]]
            for k in range(4):
                cross = np.cross(c[(k + 1) % 4] - c[k], c[k - 1] - c[k])
                if not cross @ normal > 0:
                    out.add((i, j))
    return out


def folds(q: Quality) -> set[tuple[int, int]]:
    return {(int(i), int(j)) for i, j in q.folded_cells}


def random_rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_uniform_square_grid_is_perfect():
    q = quality(Grid.from_points(plane_grid(), dim=2))
    assert q.folded == 0
    assert q.folded_cells.shape == (0, 2)
    assert q.min_scaled_jacobian == pytest.approx(1.0, abs=1e-14)
    assert q.max_aspect_ratio == pytest.approx(1.0, abs=1e-14)
    assert q.max_orthogonality_deviation_deg == pytest.approx(0.0, abs=1e-12)
    assert q.edge_spread_u == pytest.approx(1.0) and q.edge_spread_v == pytest.approx(1.0)


def test_rectangular_cells_aspect_and_spread():
    p = plane_grid(6, 5)
    p[..., 1] *= 3.0                       # v-edges 3 long, u-edges 1
    p[..., 0] = np.array([0, 1, 2, 4, 5, 6], dtype=float)[:, None]   # one u-edge twice as long
    q = quality(Grid.from_points(p, dim=2))
    assert q.folded == 0
    assert q.max_aspect_ratio == pytest.approx(3.0)
    assert q.edge_spread_u == pytest.approx(2.0)
    assert q.edge_spread_v == pytest.approx(1.0)


def test_node_moved_across_its_neighbour_folds_the_right_cells():
    p = plane_grid(8, 8)
    p[3, 3, 0] = 4.5                       # past its neighbour (4, 3)
    q = quality(Grid.from_points(p, dim=2))
    assert q.folded == 2
    assert q.folded_cells.tolist() == [[3, 2], [3, 3]]
    assert q.folded_cells.dtype == np.int64
    assert q.min_scaled_jacobian == pytest.approx(-1.0)
    assert folds(q) == reference_folds(p, np.array([0.0, 0.0, 1.0]))
    assert "folded cells: 2 (first at cells (3, 2), (3, 3))" in q.table()


def test_matches_reference_on_random_perturbations():
    rng = np.random.default_rng(1)
    for _ in range(5):
        p = plane_grid(12, 10)
        p[1:-1, 1:-1, :2] += rng.uniform(-0.8, 0.8, size=(10, 8, 2))
        q = quality(Grid.from_points(p, dim=2))
        expected = reference_folds(p, np.array([0.0, 0.0, 1.0]))
        assert expected, "the perturbation should fold something"
        assert folds(q) == expected and q.folded == len(expected)


def test_clockwise_grid_detects_its_orientation():
    p = plane_grid(9, 7)
    p[..., 0] *= -1.0                      # mirrored: the boundary loop turns clockwise
    g = Grid.from_points(p, dim=2, flip=True)
    q = quality(g)
    assert q.folded == 0
    assert q.min_scaled_jacobian == pytest.approx(1.0)
    forced = quality(g, orientation=+1)
    assert forced.folded == 8 * 6
    assert forced.min_scaled_jacobian == pytest.approx(-1.0)
    p[4, 3, 0] = -5.5                      # fold the mirrored grid: node past (5, 3)
    assert folds(quality(Grid.from_points(p, dim=2))) == {(4, 2), (4, 3)}


def test_explicit_normal_overrides_detection():
    g = Grid.from_points(plane_grid(), dim=2)
    assert quality(g, normal=(0, 0, -1)).folded == 0          # orientation detected about it
    assert quality(g, normal=(0, 0, -1), orientation=1).folded == 8 * 6
    with pytest.raises(InputError):
        quality(g, normal=(0, 0, 0))


def test_degenerate_cell_counts_as_folded():
    p = plane_grid(5, 5)
    p[2, 2] = p[3, 2]                      # zero-length edge
    q = quality(Grid.from_points(p, dim=2))
    assert {(2, 1), (2, 2)} <= folds(q)
    assert q.min_scaled_jacobian <= 0.0
    assert math.isinf(q.max_aspect_ratio) and math.isinf(q.edge_spread_u)


@pytest.mark.parametrize("shear_deg", [30.0, 10.0])
def test_sheared_grid_orthogonality(shear_deg):
    s = math.tan(math.radians(shear_deg))
    q = quality(Grid.from_points(plane_grid(7, 6, shear=s), dim=2))
    assert q.folded == 0
    assert q.max_orthogonality_deviation_deg == pytest.approx(shear_deg, abs=1e-9)
    assert q.min_scaled_jacobian == pytest.approx(math.cos(math.radians(shear_deg)))
    assert q.max_aspect_ratio == pytest.approx(1.0 / math.cos(math.radians(shear_deg)))


def test_planar_grid_rotated_into_3d_gives_the_same_numbers():
    rng = np.random.default_rng(7)
    p = plane_grid(10, 8, shear=0.2, h=0.3)
    p[1:-1, 1:-1, :2] += rng.uniform(-0.05, 0.05, size=(8, 6, 2))
    p[4, 4, 0] = p[5, 4, 0] + 0.1          # one fold
    flat = quality(Grid.from_points(p, dim=2))
    assert flat.folded > 0
    for seed in range(3):
        rot = random_rotation(seed)
        g3 = Grid.from_points(p @ rot.T + np.array([3.0, -2.0, 10.0]), dim=3)
        q = quality(g3)
        assert folds(q) == folds(flat)
        for name in ("min_scaled_jacobian", "max_aspect_ratio", "max_orthogonality_deviation_deg",
                     "edge_spread_u", "edge_spread_v"):
            assert getattr(q, name) == pytest.approx(getattr(flat, name), rel=1e-9, abs=1e-9), name
        # mirrored and rotated: still detected as a fine grid with the same fold
        mirrored = p * np.array([-1.0, 1.0, 1.0])
        qm = quality(Grid.from_points(mirrored @ rot.T, dim=3))
        assert folds(qm) == folds(flat)


def test_curved_grid_without_folds():
    g = Grid.from_points(cylinder_grid())
    q = quality(g)
    assert q.folded == 0                   # 3/4 of a turn: no single plane would do
    assert 0.99 < q.min_scaled_jacobian <= 1.0 + 1e-12
    assert q.max_orthogonality_deviation_deg == pytest.approx(0.0, abs=1e-9)
    assert quality(g, orientation=-1).folded == 39 * 19


def test_curved_grid_with_one_folded_node():
    p = cylinder_grid()
    p[20, 10] += 1.5 * (p[21, 10] - p[20, 10])   # node moved past its neighbour (21, 10)
    q = quality(Grid.from_points(p))
    assert folds(q) == {(20, 9), (20, 10)}
    assert q.min_scaled_jacobian < 0
    p[20, 10, :2] *= 1.05                          # also lifted off the surface a little
    assert folds(quality(Grid.from_points(p))) == {(20, 9), (20, 10)}


def test_curved_grid_folded_near_the_edge():
    p = cylinder_grid()
    p[1, 1] += 1.5 * (p[2, 1] - p[1, 1])
    assert folds(quality(Grid.from_points(p))) == {(1, 0), (1, 1)}


def test_as_dict_and_table():
    p = plane_grid(8, 8)
    p[3, 3, 0] = 4.5
    q = quality(Grid.from_points(p, dim=2))
    d = q.as_dict()
    assert d["folded"] == 2 and d["folded_cells"] == [[3, 2], [3, 3]]
    assert set(d) == {"folded", "folded_cells", "min_scaled_jacobian", "max_aspect_ratio",
                      "max_orthogonality_deviation_deg", "edge_spread_u", "edge_spread_v"}
    lines = quality(Grid.from_points(plane_grid(), dim=2)).table().splitlines()
    assert lines[-1] == "folded cells: 0"
    assert lines[0].startswith("min scaled Jacobian") and lines[0].split()[-1] == "1"
    columns = {len(line) - len(line[line.rindex("  "):].lstrip()) for line in lines[:-1]}
    assert len(columns) == 1               # the values start in one column
    many = plane_grid(8, 8)
    many[..., 0] *= -1
    assert quality(Grid.from_points(many, dim=2), orientation=1).table().splitlines()[-1].endswith(", ...)")


def test_large_grid_is_fast():
    import time

    p = plane_grid(1024, 1024)
    g2 = Grid.from_points(p, dim=2)
    g3 = Grid.from_points(cylinder_grid(1024, 1024))
    quality(g2)
    t = time.perf_counter()
    q2, q3 = quality(g2), quality(g3)
    assert time.perf_counter() - t < 6.0   # generous: shared CI machines
    assert q2.folded == 0 and q3.folded == 0


@pytest.mark.parametrize("curved", [False, True])
def test_blocks_of_rows_give_the_whole_grid_measures(monkeypatch, curved):
    """Quality is measured a few rows of cells at a time: blocks of 1, 2 and 7 rows
    (curved pieces with their halo for local normals) give what one block gives."""
    import importlib

    q = importlib.import_module("clothgrid.quality")   # the package exports the function as quality
    rng = np.random.default_rng(3)
    pts = cylinder_grid(23, 17) if curved else plane_grid(23, 17, shear=0.3)
    pts = pts + rng.normal(scale=0.1 if curved else 0.4, size=pts.shape) * (1.0 if curved else np.array([1.0, 1.0, 0.0]))
    grid = Grid.from_points(pts, dim=3 if curved else 2)
    whole = quality(grid).as_dict()
    assert whole["folded"] > 0
    for rows in (1, 2, 7):
        monkeypatch.setattr(q, "BLOCK_CELLS", rows * 16)
        got = quality(grid).as_dict()
        assert got.pop("folded_cells") == whole["folded_cells"]
        # local normals come from running sums, whose rounding depends on where a block starts
        assert got == pytest.approx({k: v for k, v in whole.items() if k != "folded_cells"}, rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_planar_kernel_gives_the_numpy_measures(monkeypatch, seed):
    """Large planar grids are measured by one Numba pass (quality_kernels.planar_blocks): on fresh
    grids with folds, a zero-length edge, a straight grid corner and a tilted plane it gives the
    NumPy form's figures (to rounding) and the folded cells by the definition."""
    import importlib

    q = importlib.import_module("clothgrid.quality")
    rng = np.random.default_rng([seed, 16])
    nu, nv = rng.integers(3, 40, size=2)
    p = plane_grid(nu, nv, shear=rng.uniform(-0.5, 0.5))
    p[1:-1, 1:-1, :2] += rng.uniform(-0.7, 0.7, size=(nu - 2, nv - 2, 2))
    if seed % 2:
        p[1, 1] = p[1, 2]                       # a zero-length edge: its cells count as folded
    if seed == 2:
        p[0, 0] = 0.5 * (p[1, 0] + p[0, 1])     # a grid corner on a straight side (180 degrees)
    rot = random_rotation(seed)
    grid = Grid.from_points(p @ rot.T, dim=3)
    normal = rot @ np.array([0.0, 0.0, 1.0])
    monkeypatch.setattr(q, "KERNEL_CELLS", 10**12)
    ref = quality(grid, normal=normal).as_dict()
    monkeypatch.setattr(q, "KERNEL_CELLS", 0)
    kernels = importlib.import_module("clothgrid.quality_kernels")
    calls, kernel = [], kernels.planar_blocks
    monkeypatch.setattr(kernels, "planar_blocks", lambda *a: calls.append(1) or kernel(*a))
    got = quality(grid, normal=normal).as_dict()
    assert calls, "the kernel was not used"
    assert got.pop("folded_cells") == ref.pop("folded_cells")
    assert got == pytest.approx(ref, rel=1e-12)
    straight = {(0, 0)} if seed == 2 else set()   # the straight corner's cell: not folded by that corner
    assert folds(quality(grid, normal=normal)) - straight == reference_folds(p, np.array([0.0, 0.0, 1.0])) - straight


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_angle_kernel_gives_every_corners_extremes(monkeypatch, seed):
    """sim_figures' Numba pass (quality_kernels.angle_and_edge_extremes) takes the arctangent
    only of corners that could be a row's new extreme: on fresh curved grids with folds, its
    smallest and largest angle are those of every corner's angle by the same arithmetic, bit for
    bit, and the NumPy form's to rounding."""
    import importlib

    from clothgrid import quality_kernels as kernels

    q = importlib.import_module("clothgrid.quality")
    rng = np.random.default_rng([seed, 21])
    nu, nv = (int(n) for n in rng.integers(4, 60, size=2))
    p = plane_grid(nu, nv, shear=rng.uniform(-0.5, 0.5)) @ random_rotation(seed).T
    p[1:-1, 1:-1] += rng.uniform(-0.6, 0.6, size=(nu - 2, nv - 2, 3)) * [1, 1, seed % 3]
    if seed == 3:       # a nearly uniform grid: every corner near 90 degrees, little to skip
        p = plane_grid(nu, nv) + rng.uniform(-1e-7, 1e-7, size=(nu, nv, 3))
    amin, amax, corners, lo, hi = kernels.angle_and_edge_extremes(np.ascontiguousarray(p))
    angles, ang = [], np.empty(4)
    for i in range(nu - 1):
        for j in range(nv - 1):
            if (i in (0, nu - 2)) and (j in (0, nv - 2)):
                continue                        # the grid-corner cells aside
            kernels._cell_angles(p, i, j, ang)
            angles.extend(ang)
    assert (amin, amax) == (min(angles), max(angles))
    monkeypatch.setattr(q, "KERNEL_CELLS", 10**12)
    ref = q.sim_figures(p)
    monkeypatch.setattr(q, "KERNEL_CELLS", 0)
    got = q.sim_figures(p)
    assert got["min_angle_deg"] == amin and got["max_angle_deg"] == amax
    assert got.pop("corner_cell_angles_deg") == pytest.approx(ref.pop("corner_cell_angles_deg"), rel=1e-12)
    assert got.pop("shortest_vs_target") is ref.pop("shortest_vs_target") is None
    assert got == pytest.approx(ref, rel=1e-12, abs=1e-12)
    if seed in (1, 2):
        assert amin == 0.0          # folded corners count as 0


def test_edge_spread_is_sim_figures_spread(rng):
    """quality.edge_spread (the corner choice's score) is sim_figures' edge spread exactly, 2D and 3D
    fresh grids, and inf where an edge has no length."""
    from clothgrid.quality import edge_spread, sim_figures

    for _ in range(10):
        nu, nv = (int(x) for x in rng.integers(2, 30, size=2))
        p = rng.normal(size=(nu, nv, 3))
        assert edge_spread(p) == sim_figures(p)["edge_spread"]
        assert edge_spread(p[..., :2]) == sim_figures(p[..., :2])["edge_spread"]
    p[0, 1] = p[0, 0]
    assert edge_spread(p) == math.inf == sim_figures(p)["edge_spread"]


def test_geometry_cross_is_numpys_cross_bit_for_bit():
    """``geometry.cross`` (the plane frames', vector areas' and quality's cross product without
    NumPy's dispatch) gives ``np.cross``'s bits on fresh vectors of several shapes and scales."""
    from clothgrid.geometry import cross

    rng = np.random.default_rng()
    for shape in [(3,), (7, 3), (60, 3), (4, 9, 3)]:
        for _ in range(20):
            a = rng.normal(size=shape) * 10.0 ** rng.integers(-8, 8)
            b = rng.normal(size=shape) * 10.0 ** rng.integers(-8, 8)
            assert np.array_equal(cross(a, b), np.cross(a, b))
    assert np.array_equal(cross([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_record_remeasures_only_the_moved_nodes_blocks(monkeypatch, seed):
    """A large planar grid's CellRecord measures a copy with some nodes moved again only in the blocks
    of cells at those nodes: on fresh tilted grids, with moves that fold cells, unfold them, make a
    zero-length edge and set new extremes of the edge lengths (at the grid's last row and column as
    well), the same Quality bit for bit as measuring the moved grid whole, and fewer blocks measured."""
    import importlib

    from clothgrid import quality_kernels as kernels
    from clothgrid.quality import quality_record

    q = importlib.import_module("clothgrid.quality")
    monkeypatch.setattr(q, "KERNEL_CELLS", 0)
    rng = np.random.default_rng([seed, 77])
    nu, nv = (int(n) for n in rng.integers(3 * kernels.BLOCK // 2, 3 * kernels.BLOCK, size=2))
    base = plane_grid(nu, nv, shear=rng.uniform(-0.5, 0.5))
    p = base.copy()
    p[1:-1, 1:-1, :2] += rng.uniform(-0.3, 0.3, size=(nu - 2, nv - 2, 2))
    if seed == 1:
        p[5:9, 5:9, :2] += rng.uniform(-1.5, 1.5, size=(4, 4, 2))        # folds to be undone
    rot = random_rotation(seed)
    normal = rot @ np.array([0.0, 0.0, 1.0])
    grid = Grid.from_points(p @ rot.T, dim=3)
    before, record = quality_record(grid, normal=normal)
    assert record is not None and before.as_dict() == quality(grid, normal=normal).as_dict()
    assert before.folded > 0 if seed == 1 else True
    for step in range(4):
        k = int(rng.integers(1, 12))
        nodes = np.stack([rng.integers(1, nu - 1, k), rng.integers(1, nv - 1, k)], -1)
        if step == 1:
            nodes[0] = (nu - 2, nv - 2)                   # next to the last row and column of cells
        q2 = p.copy()
        q2[nodes[:, 0], nodes[:, 1], :2] += rng.normal(scale=[1.0, 0.2, 2.0, 0.05][step], size=(k, 2))
        if step == 2:
            q2[nodes[0, 0], nodes[0, 1]] = q2[nodes[0, 0] + 1, nodes[0, 1]]     # a zero-length edge
        if seed == 1 and step == 3:                       # the folds undone
            q2 = p.copy()
            q2[5:9, 5:9] = base[5:9, 5:9]
            nodes = np.argwhere(q2[..., 0] != p[..., 0])
        calls, kernel = [], kernels.planar_blocks
        monkeypatch.setattr(kernels, "planar_blocks", lambda *a: calls.append(int(a[-1].sum())) or kernel(*a))
        got = record.remeasure(q2 @ rot.T, nodes).as_dict()
        monkeypatch.setattr(kernels, "planar_blocks", kernel)
        want = quality(Grid.from_points(q2 @ rot.T, dim=3), normal=normal).as_dict()
        assert got == want
        assert calls and calls[0] < record.blocks.shape[0] * record.blocks.shape[1]
        p = q2
