"""CPU backend: NumPy array operations and fused Numba kernels over ``(nu, nv, 3)`` grids.

Hot loops (the Jacobi sweep) are Numba kernels, parallel over rows ``i`` and
compiled or loaded from cache on first use; one-shot operations (residual,
error bound) are plain NumPy, so a direct or fdm solve never pays Numba's
start-up. Edge weights follow :mod:`clothgrid.weights`: ``wu (nu-1, nv)``,
``wv (nu, nv-1)``; boundary nodes are never written.
"""

from __future__ import annotations

import numpy as np

from ..weights import interior_diagonal

__all__ = ["name", "sweep", "max_step", "residual", "multigrid"]

name = "cpu"


def sweep(r: np.ndarray, out: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> float:
    """One Jacobi sweep (eq. 3 with per-edge weights) from ``r`` into ``out``.

    ``out`` must already hold the boundary nodes. Returns the largest
    Euclidean node step ``max |out[i, j] - r[i, j]|`` of the sweep.
    """
    from ._cpu_kernels import _sweep

    return float(_sweep(r, out, wu, wv))


def residual(r: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """``b - A r`` over the interior nodes, as an ``(nu-2, nv-2, 3)`` array.

    The unscaled residual of the SPD system of :mod:`clothgrid.solvers.problem`:
    the sum over the four edges of ``w * (R[neighbour] - R[i, j])``.
    """
    c = r[1:-1, 1:-1]
    out = wu[:-1, 1:-1, None] * (r[:-2, 1:-1] - c)
    out += wu[1:, 1:-1, None] * (r[2:, 1:-1] - c)
    out += wv[1:-1, :-1, None] * (r[1:-1, :-2] - c)
    out += wv[1:-1, 1:, None] * (r[1:-1, 2:] - c)
    return out


def max_step(r: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> float:
    """The largest step a Jacobi sweep would make from ``r``, without making it.

    This is ``max |D^-1 (b - A r)|`` (Euclidean per node): the Jacobi-scaled
    residual, used in the a-posteriori error bound of
    :mod:`clothgrid.solvers.bounds`.
    """
    if r.shape[0] < 3 or r.shape[1] < 3:
        return 0.0
    s = np.linalg.norm(residual(r, wu, wv), axis=-1) / interior_diagonal(wu, wv)
    return float(s.max())


def multigrid(levels, x0: np.ndarray, rhs: np.ndarray | None = None):
    """The multigrid operations (:class:`~clothgrid.solvers.multigrid.MultigridOps`) on this backend.

    ``levels`` from :func:`~clothgrid.solvers.multigrid.build_hierarchy`; ``x0``
    the ``(nu, nv, k)`` level-0 iterate, updated in place.
    """
    from ._cpu_multigrid import CpuMultigrid

    return CpuMultigrid(levels, x0, rhs)
