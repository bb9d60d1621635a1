"""The multigrid hierarchy as plain data: levels of stencils, built once on the CPU.

The hierarchy of :mod:`clothgrid.solvers.multigrid` (semi-coarsening along v,
Galerkin coarse operators ``A_c = P^T A P`` with linear interpolation along v)
is data, like PyAMG's: a list of :class:`Level` objects holding NumPy arrays
(or, for separable weights, the 1D factors of :class:`Separable`). Data flows
one way::

    multigrid_levels (this module: build_hierarchy)      plain NumPy data, on the CPU
        -> a backend's ``multigrid(levels, x0, rhs)``      turns it into a MultigridOps
        -> clothgrid.solvers.multigrid (vcycle, fmg)       drives any backend's operations

This module imports neither :mod:`clothgrid.backends` nor
:mod:`clothgrid.solvers`; the one Numba kernel it needs (the Galerkin product
of a per-edge level, :mod:`clothgrid._galerkin`) is loaded on first use.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .weights import Weights

__all__ = ["Level", "Separable", "coarse_rows", "fine_level", "galerkin_1d", "coarsen_separable", "coarsen",
           "build_hierarchy", "hierarchy_bytes", "diagonal_partner"]

#: Most lines the CPU multigrid's line solves take in one block (its per-thread scratch holds the
#: factors of that many lines: :func:`hierarchy_bytes`).
LINE_BLOCK = 512


@dataclass
class Separable:
    """A level's operator ``Ku (x) M + Du (x) K`` for separable weights.

    With ``wu[i, j] = cu[i] dv[j]`` and ``wv[i, j] = du[i] cv[j]`` the fine
    operator is ``Ku (x) diag(dv) + diag(du) (x) Kv`` (``Ku``, ``Kv`` the 1D
    weighted second differences along i and j). Interpolation acts along ``j``
    only, so every Galerkin level keeps the form, with ``Ku`` and ``du``
    unchanged and two symmetric tridiagonal matrices ``M``, ``K`` over the
    level's rows: the whole 9-point stencil is held in six 1D arrays.

    Attributes
    ----------
    cu : (nu-1,) float64
        Edge weights along i (``Ku[i, i+1] = -cu[i]``).
    du : (nu,) float64
    md, mu, kd, ku : (nv,) float64
        Diagonals ``M[J, J]``, ``K[J, J]`` and super-diagonals ``M[J, J+1]``,
        ``K[J, J+1]`` over the level's rows, zero where a row or coupling is
        not interior.
    """

    cu: np.ndarray
    du: np.ndarray
    md: np.ndarray
    mu: np.ndarray
    kd: np.ndarray
    ku: np.ndarray

    def stencil(self, dtype: type = np.float32, xp: Any = np, rows: slice = slice(None)) -> tuple:
        """The level's ``C, E, N, NE, NW`` as ``(nu, nv)`` arrays (see :class:`Level`).

        ``xp`` is the array module that forms them (CuPy forms them on the GPU
        from the 1D factors: nothing of the grid's size crosses the bus);
        ``rows`` picks the rows ``J`` to form (``slice(p, None, 2)``: one parity).
        """
        cu = xp.asarray(np.r_[self.cu, 0.0])[:, None]           # cu[i]: the edge to i+1 (none from the last column)
        cl = xp.asarray(np.r_[0.0, self.cu])[:, None]           # cu[i-1]: the edge from i-1
        du = xp.asarray(self.du)[:, None]
        md, mu, kd, ku = (xp.asarray(a[rows]) for a in (self.md, self.mu, self.kd, self.ku))
        C = (cl + cu) * md + du * kd
        E = cu * md
        N = -((cl + cu) * mu + du * ku)
        NE = cu * mu
        NW = cl * mu
        return tuple(xp.ascontiguousarray(a, dtype=dtype) for a in (C, E, N, NE, NW))


class Level:
    """One level's operator as a stencil over an ``(nu, nv)`` node array.

    Couplings are positive "conductances" (minus the matrix entries); the row
    of interior node ``(i, j)`` reads

        C x[i,j] - E[i-1,j] x[i-1,j] - E[i,j] x[i+1,j] - N[i,j-1] x[i,j-1] - N[i,j] x[i,j+1]
                 - NE[i,j] x[i+1,j+1] - NE[i-1,j-1] x[i-1,j-1]
                 - NW[i,j] x[i-1,j+1] - NW[i+1,j-1] x[i+1,j-1] = b[i,j]

    The finest level is the 5-point stencil of the edge weights: ``E = wu``
    ``(nu-1, nv)``, ``N = wv`` ``(nu, nv-1)``, ``C``, ``NE``, ``NW`` ``None``
    (``C`` is the sum of the four weights). Coarser levels hold ``C``, ``E``,
    ``N``, ``NE`` as ``(nu, nv)`` float32 arrays (zero where a coupling leaves
    the grid). Level ``l+1`` keeps rows :func:`coarse_rows` of level ``l`` and
    all columns.

    A cell's two diagonal couplings are equal: ``NW[i+1, j] = NE[i, j]`` (both
    come from the u-edge between columns ``i`` and ``i+1``, weighted by the
    interpolation along ``j``, which acts on every column alike), and
    ``NW[0, j] = 0``. ``NW`` is therefore not stored: the property forms it from
    ``NE`` on first use (the GPU backends upload it; the cpu kernels read ``NE``
    of the column before instead). An ``NW`` given to the constructor must be
    that array.

    A level 0 may also be given as a 9-point level (``C``, ``E``, ``N`` and a zero ``NE``): the
    5-point stencil with an explicit centre, e.g. plus a mass diagonal (:mod:`clothgrid.heat`'s
    time steps); only the cpu backend's multigrid takes it.

    With separable weights every level also carries ``sep``
    (:class:`Separable`); a coarse level then forms its five arrays only when
    asked (the CPU kernels read ``sep`` instead: 335 MB less at 4096^2).
    """

    def __init__(self, E: np.ndarray | None = None, N: np.ndarray | None = None, C: np.ndarray | None = None,
                 NE: np.ndarray | None = None, NW: np.ndarray | None = None, *, sep: Separable | None = None):
        if E is None and sep is None:
            raise ValueError("a Level needs stencil arrays or a separable form")
        if NW is not None and (NE is None or NW.shape != NE.shape or np.any(NW[0])
                               or not np.array_equal(NW[1:], NE[:-1])):
            raise ValueError("NW must be NE of the column before (NW[i+1, j] = NE[i, j], NW[0] = 0): "
                             "a cell's two diagonal couplings are equal")
        self._arrays = None if E is None else (C, E, N, NE, NW)
        self.sep = sep

    def _stencil(self) -> tuple:
        if self._arrays is None:
            self._arrays = self.sep.stencil()
        return self._arrays

    def _nw(self) -> np.ndarray | None:
        C, E, N, NE, NW = self._stencil()
        if NW is None and NE is not None:
            NW = diagonal_partner(NE)
            self._arrays = (C, E, N, NE, NW)
        return NW

    C = property(lambda self: self._stencil()[0], doc="Centre coefficients (None on the finest level).")
    E = property(lambda self: self._stencil()[1], doc="Couplings ``(i, j)-(i+1, j)``.")
    N = property(lambda self: self._stencil()[2], doc="Couplings ``(i, j)-(i, j+1)``.")
    NE = property(lambda self: self._stencil()[3], doc="Couplings ``(i, j)-(i+1, j+1)`` (coarse levels).")
    NW = property(lambda self: self._nw(),
                  doc="Couplings ``(i, j)-(i-1, j+1)`` (coarse levels): ``NE`` of the column before, formed on "
                      "first use.")

    @property
    def nine(self) -> bool:
        """True for a 9-point (coarse) level."""
        return self._arrays is None or self._arrays[0] is not None

    @property
    def shape(self) -> tuple[int, int]:
        """``(nu, nv)``: the level's columns and rows."""
        if self._arrays is None:
            return len(self.sep.du), len(self.sep.md)
        return (self.N.shape[0], self.N.shape[1] + (0 if self.nine else 1))


def diagonal_partner(NE: Any) -> Any:
    """``NW`` of a 9-point level from its ``NE`` (:class:`Level`): ``NW[i + 1] = NE[i]``, ``NW[0] = 0``,
    in ``NE``'s dtype and array module."""
    NW = NE.copy()
    NW[1:] = NE[:-1]
    NW[0] = 0
    return NW


def coarse_rows(nv: int) -> np.ndarray:
    """Rows a coarse level keeps: ``0, 2, 4, ...`` and ``nv - 1``."""
    return np.unique(np.r_[np.arange(0, nv, 2), nv - 1])


def fine_level(weights: Weights) -> Level:
    """Level 0: the 5-point stencil of the weights.

    For separable weights with constant ``cu`` and ``cv`` (the paper's,
    uniform) ``wu`` depends on ``j`` only and ``wv`` on ``i`` only: the level
    holds stride-0 views of their 1D factors, so sweeps stream only the grid.
    Separable weights also give the level its :class:`Separable` form.
    """
    nu, nv = weights.shape
    sep = None
    if weights.factors is not None:
        cu, dv, du, cv = weights.factors
        md, kd, ku = np.zeros(nv), np.zeros(nv), np.zeros(nv)
        md[1:-1] = dv[1:-1]                  # M = diag(dv) over the interior rows
        kd[1:-1] = cv[:-1] + cv[1:]          # K[j, j]: the v-edges below and above row j
        ku[1:-2] = -cv[1:-1]                 # K[j, j+1] between interior rows
        sep = Separable(cu=cu, du=du, md=md, mu=np.zeros(nv), kd=kd, ku=ku)
        if weights.unit_stencil:
            return Level(E=np.broadcast_to(cu[0] * dv, (nu - 1, nv)),
                         N=np.broadcast_to((du * cv[0])[:, None], (nu, nv - 1)), sep=sep)
    return Level(E=np.ascontiguousarray(weights.wu), N=np.ascontiguousarray(weights.wv), sep=sep)


def galerkin_1d(d: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``P^T T P`` for a symmetric tridiagonal ``T`` over ``nv`` rows (interior rows only).

    ``d[j] = T[j, j]``, ``u[j] = T[j, j+1]``; ``P`` is the linear interpolation
    from rows :func:`coarse_rows` (coarse row ``J`` is fine row ``2J``, odd
    rows take the mean of their neighbours). Returns the coarse ``(d, u)``,
    zero outside the interior.
    """
    nv = len(d)
    nc = len(coarse_rows(nv))
    dc, uc = np.zeros(nc), np.zeros(nc)
    if nc < 3:
        return dc, uc
    dp, up = np.r_[d, 0.0, 0.0], np.r_[u, 0.0, 0.0]   # rows past the last are never interior
    J = np.arange(1, nc - 1)
    f = 2 * J
    below = f + 1 <= nv - 2                            # fine row f+1 is interior
    dc[1:-1] = dp[f] + 0.25 * dp[f - 1] + up[f - 1] + np.where(below, 0.25 * dp[f + 1] + up[f], 0.0)
    uc[1:-1] = np.where(J + 1 <= nc - 2, 0.5 * up[f] + 0.25 * dp[f + 1] + 0.5 * up[f + 1], 0.0)
    return dc, uc


def coarsen_separable(sep: Separable) -> Separable:
    """The Galerkin coarse level of a separable level: only ``M`` and ``K`` change."""
    md, mu = galerkin_1d(sep.md, sep.mu)
    kd, ku = galerkin_1d(sep.kd, sep.ku)
    return Separable(cu=sep.cu, du=sep.du, md=md, mu=mu, kd=kd, ku=ku)


def build_hierarchy(weights: Weights, min_rows: int = 3) -> list[Level]:
    """All levels, finest first, down to one with at most ``min_rows - 2`` interior rows.

    Coarse levels are Galerkin operators ``P^T A P`` (linear interpolation
    along v): for separable weights in their :class:`Separable` form,
    otherwise computed by :func:`coarsen` (a Numba kernel) and kept in float32.

    Parameters
    ----------
    weights : Weights
        The edge weights of the finest level.
    min_rows : int, optional
        The coarsest level has at most this many rows.

    Returns
    -------
    list of Level
        Finest first; every backend's ``multigrid(levels, x0, rhs)`` takes it.
    """
    levels = [fine_level(weights)]
    while levels[-1].shape[1] > min_rows:
        sep = levels[-1].sep
        levels.append(Level(sep=coarsen_separable(sep)) if sep is not None else coarsen(levels[-1]))
    return levels


def hierarchy_bytes(nu: int, nv: int, ncoords: int = 3, separable: bool = False) -> int:
    """Memory the CPU multigrid holds for an ``nu x nv`` grid, beyond the problem's grid and weights.

    The level-0 iterate as parity planes (float64, ``8 ncoords`` bytes a node); the coarser levels
    (about ``nu * nv`` nodes in all) with iterate and right-hand side in float32 (``8 ncoords``);
    for weights without a separable form also the stencils: level 0's edge weights split by row
    parity (16) and four float32 coarse stencil arrays (``NW`` is ``NE`` of the column before),
    formed and split (32); and the line solves' per-thread scratch (``12 LINE_BLOCK`` bytes a
    column and thread).
    """
    n = nu * nv
    scratch = 12 * LINE_BLOCK * numba_threads() * (nu + 1)   # the line solves' factors, float64 and float32
    return 16 * ncoords * n + (0 if separable else 48 * n) + scratch


def numba_threads() -> int:
    """The threads Numba runs its parallel kernels on (the line-solve scratch has one slice each):
    its configuration where Numba is loaded, else what it will read, ``NUMBA_NUM_THREADS`` (which
    ``import clothgrid`` sets under a container's CPU quota) or the processors this process may use,
    without loading Numba for it."""
    import os
    import sys

    numba = sys.modules.get("numba")
    if numba is not None:
        return int(numba.config.NUMBA_NUM_THREADS)
    from .cgroups import processors

    try:
        return max(1, int(os.environ.get("NUMBA_NUM_THREADS", "")))
    except ValueError:
        return processors()


def coarsen(level: Level, dtype: type = np.float32) -> Level:
    """The Galerkin coarse level of ``level`` (semi-coarsening along v), stencils in ``dtype``.

    Parameters
    ----------
    level : Level
        A level with stencil arrays (the finest level's edge weights or a coarse
        level's ``C, E, N, NE``).
    dtype : numpy dtype, optional
        Of the coarse level's four stencil arrays (float32 by default; ``NW`` is formed from
        ``NE`` where a backend asks for it).

    Returns
    -------
    Level
        ``P^T A P`` over rows :func:`coarse_rows` of ``level``, all columns.
    """
    from ._galerkin import _coarsen

    nu, nv = level.shape
    nc = len(coarse_rows(nv))
    out = [np.empty((nu, nc), dtype=dtype) for _ in range(4)]
    nine = level.C is not None
    dummy = np.zeros((1, 1))
    _coarsen(level.C if nine else dummy, level.E, level.N, level.NE if nine else dummy, nine, *out)
    return Level(C=out[0], E=out[1], N=out[2], NE=out[3])
