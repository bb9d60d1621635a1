"""An independent exact reference for the tests: the functional's normal equations.

Built from edge-difference (incidence) matrices, not from clothgrid's own
assembly: ``F = 1/2 |W_u^1/2 G_u R|^2 + 1/2 |W_v^1/2 G_v R|^2``, so
``A = G_u^T W_u G_u + G_v^T W_v G_v`` over all nodes, then
``A_II x_I = -A_IB x_B`` with SciPy's ``spsolve``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve


def paper_weights(nu: int, nv: int, k: float = 1.0):
    """Eq. (2), 0-based, written out here independently of clothgrid.weights."""
    lu = np.array([0.01 + (0.5 * (nu - 1) - i) ** 2 / nu for i in range(nu)])
    lv = np.array([0.01 + k * (0.5 * (nv - 1) - j) ** 2 / nv for j in range(nv)])
    wu = np.tile(lv**2, (nu - 1, 1))               # u-edge (i,j)-(i+1,j) carries Lv[j]^2
    wv = np.tile((lu**2)[:, None], (1, nv - 1))    # v-edge (i,j)-(i,j+1) carries Lu[i]^2
    return wu, wv


def uniform_weights(nu: int, nv: int):
    return np.ones((nu - 1, nv)), np.ones((nu, nv - 1))


def exact_solution(boundary_grid: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """The exact minimiser with the boundary nodes of ``boundary_grid`` fixed."""
    nu, nv = boundary_grid.shape[:2]
    idx = np.arange(nu * nv).reshape(nu, nv)

    def diff(a, b):
        m = a.size
        rows = np.repeat(np.arange(m), 2)
        cols = np.stack([a.ravel(), b.ravel()], axis=1).ravel()
        vals = np.tile([-1.0, 1.0], m)
        return sp.csr_matrix((vals, (rows, cols)), shape=(m, nu * nv))

    gu = diff(idx[:-1, :], idx[1:, :])
    gv = diff(idx[:, :-1], idx[:, 1:])
    a = (gu.T @ sp.diags(wu.ravel()) @ gu + gv.T @ sp.diags(wv.ravel()) @ gv).tocsr()
    interior = np.zeros((nu, nv), bool)
    interior[1:-1, 1:-1] = True
    fi, fb = np.flatnonzero(interior), np.flatnonzero(~interior)
    x = boundary_grid.reshape(-1, 3).copy()
    rhs = -(a[fi][:, fb] @ x[fb])
    x[fi] = spsolve(a[fi][:, fi].tocsc(), rhs).reshape(-1, 3)
    return x.reshape(nu, nv, 3)


def max_rel_error(points: np.ndarray, reference: np.ndarray, scale: float) -> float:
    return float(np.linalg.norm(points - reference, axis=-1).max() / scale)
