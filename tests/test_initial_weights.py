"""Initial grids (eq. 4, the contour mean, zeros), the weights of eq. 2, and Grid basics."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import smooth_quad_sides

import clothgrid
from clothgrid.initial import initial_grid
from clothgrid.weights import make_weights, paper_lengths


def test_tfi_is_eq4_node_by_node(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 9, 6, dim=3))
    r = initial_grid(b, "tfi")
    nu, nv = 9, 6
    for i in range(nu):
        for j in range(nv):
            u, v = i / (nu - 1), j / (nv - 1)
            expect = ((1 - u) * r[0, j] + u * r[-1, j] + (1 - v) * r[i, 0] + v * r[i, -1]
                      - ((1 - u) * (1 - v) * r[0, 0] + (1 - u) * v * r[0, -1] + u * (1 - v) * r[-1, 0]
                         + u * v * r[-1, -1]))
            np.testing.assert_allclose(r[i, j], expect, atol=1e-14)


def test_tfi_reproduces_an_affine_grid_and_uniform_solution_is_affine():
    # A parallelogram with uniformly spaced sides: TFI and the uniform-weight solution are both affine.
    e1, e2, o = np.array([2.0, 0.3]), np.array([0.5, 1.5]), np.array([1.0, -1.0])
    nu, nv = 11, 8
    s, t = np.linspace(0, 1, nu), np.linspace(0, 1, nv)
    exact = o + s[:, None, None] * e1 + t[None, :, None] * e2
    b = clothgrid.Boundary.from_sides(exact[:, 0], exact[-1, :], exact[:, -1], exact[0, :])
    np.testing.assert_allclose(initial_grid(b, "tfi")[..., :2], exact, atol=1e-13)
    g = clothgrid.generate(b, weights="uniform")
    np.testing.assert_allclose(g.points[..., :2], exact, atol=1e-12)


def test_average_and_zero(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 8, 7))
    ring = np.concatenate([b.bottom, b.top, b.left[1:-1], b.right[1:-1]])
    avg = initial_grid(b, "average")
    np.testing.assert_allclose(avg[1:-1, 1:-1], np.broadcast_to(ring.mean(axis=0), (6, 5, 3)))
    assert np.all(initial_grid(b, "zero")[1:-1, 1:-1] == 0)
    for r in (avg, initial_grid(b, "zero")):
        np.testing.assert_array_equal(r[:, 0], b.bottom)
        np.testing.assert_array_equal(r[-1, :], b.right)


def test_paper_lengths_eq2_zero_based_and_symmetric():
    n = 1024
    lu = paper_lengths(n)
    assert lu[0] == pytest.approx(0.01 + (0.5 * 1023) ** 2 / 1024)
    np.testing.assert_allclose(lu, lu[::-1])
    assert lu.min() == pytest.approx(0.01 + 0.25 / 1024)
    assert (lu.max() / lu.min()) ** 2 > 1e8   # squared weights span eight orders of magnitude (MATH.md)
    lv = paper_lengths(10, k=3.0)
    assert lv[0] == pytest.approx(0.01 + 3.0 * 4.5**2 / 10)


def test_paper_weights_layout():
    w = make_weights("paper", 6, 9, k=2.0)
    lu, lv = paper_lengths(6), paper_lengths(9, 2.0)
    assert w.wu.shape == (5, 9) and w.wv.shape == (6, 8)
    np.testing.assert_allclose(w.wu, np.tile(lv**2, (5, 1)))          # u-edges in row j: Lv[j]^2
    np.testing.assert_allclose(w.wv, np.tile((lu**2)[:, None], (1, 8)))  # v-edges in column i: Lu[i]^2
    assert w.unit_stencil and not make_weights((w.wu, w.wv), 6, 9).unit_stencil


def test_grid_quads_ccw_and_triangles(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 6, 5))
    g = clothgrid.generate(b, weights="uniform")
    assert g.quads.shape == (20, 4) and g.quads.max() == 29
    p = g.vertices[:, :2]
    q = p[g.quads]
    area = 0.5 * np.sum(q[:, :, 0] * np.roll(q[:, :, 1], -1, axis=1) - np.roll(q[:, :, 0], -1, axis=1) * q[:, :, 1],
                        axis=1)
    assert np.all(area > 0)
    for diag in ("fixed", "alternate"):
        t = g.triangles(diag)
        assert t.shape == (40, 3)
        tp = p[t]
        d = (tp[:, 1, 0] - tp[:, 0, 0]) * (tp[:, 2, 1] - tp[:, 0, 1]) - (tp[:, 1, 1] - tp[:, 0, 1]) * (tp[:, 2, 0] - tp[:, 0, 0])
        assert np.all(d > 0)
        assert 0.5 * d.sum() == pytest.approx(area.sum())
    np.testing.assert_allclose(g.uv[:, 0, 0], np.r_[0, np.cumsum(np.linalg.norm(np.diff(b.bottom, axis=0), axis=1))]
                               / np.linalg.norm(np.diff(b.bottom, axis=0), axis=1).sum())
    assert g.uv.min() == 0 and g.uv.max() == 1


def test_clockwise_piece_gets_ccw_quads(rng):
    """A clockwise piece's quads come out counter-clockwise: the mirror image of the same piece drawn
    counter-clockwise has the very same signed cell areas. (On about 1 random outline in 1500 the
    length functional folds a cell of this 6 x 5 grid, in both: the fold is the functional's, the
    orientation is what is checked.)"""
    sides = smooth_quad_sides(rng, 6, 5)
    mirrored = [s * np.array([-1.0, 1.0]) for s in sides]   # mirror x: the piece turns clockwise
    b = clothgrid.Boundary.from_sides(*mirrored)
    assert b.orientation < 0
    g = clothgrid.generate(b)
    g0 = clothgrid.generate(clothgrid.Boundary.from_sides(*sides))

    def areas(grid):
        q = grid.vertices[grid.quads][:, :, :2]
        return 0.5 * np.sum(q[:, :, 0] * np.roll(q[:, :, 1], -1, axis=1) - np.roll(q[:, :, 0], -1, axis=1) * q[:, :, 1],
                            axis=1)

    area, area0 = areas(g), areas(g0)
    assert area.sum() > 0 and np.count_nonzero(area > 0) >= 0.9 * area.size
    np.testing.assert_allclose(np.sort(area), np.sort(area0), rtol=1e-9, atol=1e-12)
    assert clothgrid.quality(g).folded == clothgrid.quality(g0).folded


@pytest.mark.parametrize("shape", [(520, 510, 3), (700, 400, 2), (400, 700, 1)])
def test_transfinite_kernel_gives_the_numpy_forms_bits(shape, monkeypatch):
    """Large grids are interpolated by one Numba pass (initial_kernels.transfinite_into): on fresh
    boundaries, bit for bit the NumPy form's grid."""
    from clothgrid import initial

    rng = np.random.default_rng()
    r = np.zeros(shape)
    for side in (np.s_[0], np.s_[-1], np.s_[:, 0], np.s_[:, -1]):
        r[side] = rng.normal(size=r[side].shape) * rng.uniform(0.1, 100)
    assert shape[0] * shape[1] >= initial.KERNEL_NODES
    got = initial.transfinite(r.copy())
    monkeypatch.setattr(initial, "KERNEL_NODES", 10**12)
    want = initial.transfinite(r.copy())
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
