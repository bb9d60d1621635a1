"""The heat solver's operations on the CPU: :class:`~clothgrid.backends.protocol.HeatOps` over Numba.

The kernels are :mod:`clothgrid._heat_kernels` (parallel over rows, float64,
padded arrays); the V-cycle and conjugate gradients that drive them are
:func:`clothgrid.heat_multigrid.vcycle` and :func:`~clothgrid.heat_multigrid.pcg`,
the same functions that drive the gl and cuda backends' operations. Vectors are
the host's padded ``(nu + 2, nv + 2)`` float64 arrays themselves: ``upload``
and ``download`` copy nothing.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import _heat_kernels as K
from ..heat_multigrid import HeatHierarchy

__all__ = ["CpuHeatOps"]


class CpuHeatOps:
    """:class:`~clothgrid.backends.protocol.HeatOps` on the host (Numba kernels, float64).

    Parameters
    ----------
    hierarchy : HeatHierarchy
        The multigrid hierarchy (its arrays are used in place).
    """

    precise = True

    def __init__(self, hierarchy: HeatHierarchy):
        self.hierarchy = h = hierarchy
        self.fine = h.fine
        self.levels = len(h.levels)
        shapes = [(lev.shape[0] + 2, lev.shape[1] + 2) for lev in h.levels]
        # per level: iterate, right-hand side, residual, the line solves' scratch (level 0's x and b are
        # bound to the conjugate-gradient vectors by `bind`)
        self.x = [np.zeros(s) for s in shapes]
        self.b = [np.zeros(s) for s in shapes]
        self.r = [np.zeros(s) for s in shapes]
        self.dp = [np.zeros(s) for s in shapes]

    # -- vectors
    def vector(self) -> np.ndarray:
        return np.zeros_like(self.fine.d)

    def upload(self, a: np.ndarray, out: Any) -> np.ndarray:
        """The host array itself (no copy)."""
        return a

    def download(self, v: np.ndarray, out: np.ndarray) -> None:
        if v is not out:
            out[...] = v

    def copy(self, dst: np.ndarray, src: np.ndarray) -> None:
        dst[...] = src

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        return K.dot(a, b)

    # -- level 0, the conjugate-gradient operations
    def apply(self, p: np.ndarray, q: np.ndarray) -> float:
        f = self.fine
        return K.apply5_dot(f.we, f.wn, f.c0, p, q)

    def residual(self, b: np.ndarray, x: np.ndarray, r: np.ndarray) -> None:
        f = self.fine
        K.residual5(f.we, f.wn, f.c0, b, x, r)

    def axpy(self, x: np.ndarray, r: np.ndarray, p: np.ndarray, q: np.ndarray, alpha: float) -> float:
        return K.update_xr(x, r, p, q, alpha)

    def xpay(self, p: np.ndarray, z: np.ndarray, beta: float) -> None:
        K.update_p(p, z, beta)

    # -- the V-cycle
    def bind(self, r: np.ndarray, z: np.ndarray) -> None:
        self.b[0], self.x[0] = r, z

    def smooth(self, level: int, pre: bool) -> None:
        """Zebra line Gauss-Seidel along ``v``: from zero, even lines then odd (``pre``), or odd then even
        (post-smoothing, the adjoint)."""
        lev = self.hierarchy.levels[level]
        x, b, dp = self.x[level], self.b[level], self.dp[level]
        for colour in ((0, 1) if pre else (1, 0)):
            first = pre and colour == 0
            if level == 0:
                f = self.fine
                K.lines5(f.we, f.wn, b, x, colour, lev.cp, lev.im, dp, first)
            else:
                K.lines9(lev.S, b, x, colour, lev.cp, lev.im, dp, first)

    def restrict(self, level: int) -> None:
        """The next level's right-hand side ``P^T (b - A x)`` from the even rows (the odd rows' residual is
        zero after the pre-smoothing sweep)."""
        lev = self.hierarchy.levels[level]
        x, b, r = self.x[level], self.b[level], self.r[level]
        if level == 0:
            f = self.fine
            K.residual5(f.we, f.wn, f.c0, b, x, r, 2, 2)
        else:
            K.residual9(lev.S, b, x, r, 2, 2)
        K.restrict_even(lev.P, r, self.b[level + 1])

    def coarse_solve(self) -> None:
        """The coarsest level exactly (SuperLU)."""
        last = self.levels - 1
        nu, nv = self.hierarchy.levels[last].shape
        x = self.x[last]
        rhs = self.b[last][1:-1, 1:-1].reshape(-1)
        x.fill(0.0)
        x[1:-1, 1:-1] = self.hierarchy.coarse_lu.solve(rhs).reshape(nu, nv)

    def prolong(self, level: int) -> None:
        """``x += P x_coarse`` on the even rows (the odd lines are solved next)."""
        K.prolong_add_even(self.hierarchy.levels[level].P, self.x[level + 1], self.x[level])

    def extra(self) -> dict[str, Any]:
        return {}

    def release(self) -> None:
        pass
