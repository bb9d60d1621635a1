"""The heat solver's multigrid: black-box multigrid (Dendy) as a preconditioner of conjugate gradients.

:mod:`clothgrid.heat` solves ``(A + diag(shift)) T = b`` for the 5-point
finite-volume operator of per-edge conductances. Conductivity jumps of 10^4
defeat linear interpolation (the grid solver's multigrid stalls at 0.93 per
cycle on them); this hierarchy follows the jumps:

- **full coarsening** (coarse point ``I`` is fine point ``2 I`` along both
  axes), down to a coarsest level of at most 256 unknowns (or one row or
  column: a long thin grid) solved directly (SciPy's SuperLU);
- **operator-dependent interpolation** (Dendy 1982, "Black box multigrid"):
  a fine point's weights come from its own row of the operator, collapsed
  across the other axis, so a correction is interpolated in proportion to
  the conductances it flows through: across an interface of 10^4 it is flat
  on the conducting side and carries the jump on the insulating one;
- **Galerkin coarse operators** ``A_c = P^T A P`` (9 points), restriction
  ``P^T``;
- **zebra line Gauss-Seidel along v** (``j``: the lines are contiguous in
  memory, and :mod:`clothgrid.heat` orients the problem so that ``v`` is the
  direction of the stronger coupling), even lines then odd before the
  coarse-grid correction, odd then even after it (the adjoint), so that one
  V(1,1) cycle is a symmetric positive definite preconditioner and plain
  preconditioned CG applies. Lines, not points: with cells 100 times wider
  than tall red-black point Gauss-Seidel took 300 iterations, lines 6; on
  isotropic cells both take the same iterations at about the same cost.

All kernels are Numba (:mod:`clothgrid._heat_kernels`), on padded float64
arrays ``(nu + 2, nv + 2)`` with the unknowns inside a zero ring. This module
imports neither :mod:`clothgrid.backends` nor :mod:`clothgrid.solvers`.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from . import _heat_kernels as K

__all__ = ["Stencil5", "HeatMultigrid", "pcg", "padded", "numba_threads"]

#: A level with at most this many unknowns (or fewer than 2 rows or columns) is solved directly (SuperLU).
COARSEST_POINTS = 256


@contextmanager
def numba_threads(threads: int | None) -> Iterator[None]:
    """Run the block with ``threads`` Numba threads (``None``: leave Numba's setting)."""
    if threads is None:
        yield
        return
    import numba

    from .errors import InputError

    if int(threads) != threads or not 1 <= threads:
        raise InputError(f"threads must be an integer >= 1, not {threads!r}")
    before = numba.get_num_threads()
    numba.set_num_threads(min(int(threads), numba.config.NUMBA_NUM_THREADS))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def padded(a: np.ndarray) -> np.ndarray:
    """An ``(nu, nv)`` array inside a zero ring, ``(nu + 2, nv + 2)`` float64."""
    out = np.zeros((a.shape[0] + 2, a.shape[1] + 2))
    out[1:-1, 1:-1] = a
    return out


@dataclass
class Stencil5:
    """A 5-point operator on padded arrays (see :mod:`clothgrid._heat_kernels`).

    Attributes
    ----------
    we, wn : numpy.ndarray
        ``(nu + 2, nv + 2)`` conductances ``(i, j)-(i+1, j)`` and
        ``(i, j)-(i, j+1)`` between unknowns (zero towards the ring).
    d : numpy.ndarray
        ``(nu + 2, nv + 2)`` the diagonal: every conductance of the cell,
        those to the boundary included, plus the shift.
    c0 : numpy.ndarray
        ``(nu + 2, nv + 2)`` the diagonal less the conductances between
        unknowns: the boundary conductances plus the shift (the products
        ``A x`` are formed as ``c0 x + sum w (x - x_nb)``).
    """

    we: np.ndarray
    wn: np.ndarray
    d: np.ndarray
    c0: np.ndarray

    @classmethod
    def from_weights(cls, wu: np.ndarray, wv: np.ndarray, shift: np.ndarray | None = None) -> "Stencil5":
        """From node-array edge weights ``wu (nu+1, nv+2)``, ``wv (nu+2, nv+1)`` (the ring: boundary
        conductances) and an optional ``(nu, nv)`` diagonal shift."""
        nu, nv = wv.shape[0] - 2, wu.shape[1] - 2
        we, wn, d = (np.zeros((nu + 2, nv + 2)) for _ in range(3))
        we[1:nu, 1:-1] = wu[1:nu, 1:-1]
        wn[1:-1, 1:nv] = wv[1:-1, 1:nv]
        d[1:-1, 1:-1] = wu[:-1, 1:-1] + wu[1:, 1:-1] + wv[1:-1, :-1] + wv[1:-1, 1:]
        if shift is not None:
            d[1:-1, 1:-1] += shift
        c0 = d - we - wn
        c0[1:, :] -= we[:-1, :]
        c0[:, 1:] -= wn[:, :-1]
        c0[0], c0[-1], c0[:, 0], c0[:, -1] = 0.0, 0.0, 0.0, 0.0
        return cls(we, wn, d, c0)

    @property
    def shape(self) -> tuple[int, int]:
        """``(nu, nv)``: the unknowns."""
        return self.d.shape[0] - 2, self.d.shape[1] - 2

    def apply(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``A x`` for a padded ``x`` (ring zero); returns a padded array (ring zero)."""
        if out is None:
            out = np.zeros_like(self.d)
        K.apply5_dot(self.we, self.wn, self.c0, x, out)
        return out

    def nine(self) -> np.ndarray:
        """The 9-point form ``(nu + 2, nv + 2, 9)`` (corners zero)."""
        S = np.empty(self.d.shape + (9,))
        K.five_to_nine(self.we, self.wn, self.d, S)
        return S


@dataclass
class _Level:
    shape: tuple[int, int]
    S: np.ndarray | None                  # 9-point stencil (coarse levels); level 0 uses the Stencil5
    P: np.ndarray | None = None           # interpolation from the next coarser level
    x: np.ndarray = field(init=False, repr=False)
    b: np.ndarray = field(init=False, repr=False)
    r: np.ndarray = field(init=False, repr=False)
    cp: np.ndarray = field(init=False, repr=False)     # the line solves' factors (line_factors)
    im: np.ndarray = field(init=False, repr=False)
    dp: np.ndarray = field(init=False, repr=False)     # and their scratch

    def __post_init__(self) -> None:
        nu, nv = self.shape
        self.x, self.b, self.r, self.cp, self.im, self.dp = (np.zeros((nu + 2, nv + 2)) for _ in range(6))


def _sparse(S: np.ndarray) -> Any:
    """The matrix of a padded 9-point stencil, CSR over the interior (row-major ``(i, j)``)."""
    import scipy.sparse as sp

    nu, nv = S.shape[0] - 2, S.shape[1] - 2
    idx = np.full((nu + 2, nv + 2), -1)
    idx[1:-1, 1:-1] = np.arange(nu * nv).reshape(nu, nv)
    rows, cols, vals = [], [], []
    for k in range(9):
        di, dj = k // 3 - 1, k % 3 - 1
        v = S[1:-1, 1:-1, k]
        c = idx[1 + di:nu + 1 + di, 1 + dj:nv + 1 + dj]
        m = (v != 0) & (c >= 0)
        rows.append(idx[1:-1, 1:-1][m])
        cols.append(c[m])
        vals.append(v[m])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nu * nv,) * 2)


class HeatMultigrid:
    """Black-box multigrid hierarchy of a 5-point operator, and one V(1,1) cycle as a preconditioner.

    Parameters
    ----------
    fine : Stencil5
        The operator (level 0).
    coarsest_points : int
        Coarsen while a level has more unknowns than this (and at least two
        rows and columns).
    """

    def __init__(self, fine: Stencil5, coarsest_points: int = COARSEST_POINTS):
        self.fine = fine
        self.levels: list[_Level] = [_Level(fine.shape, None)]
        S = None
        while True:
            nu, nv = self.levels[-1].shape
            if min(nu, nv) < 2 or nu * nv <= coarsest_points:
                break
            S = fine.nine() if S is None else S
            ncu, ncv = nu // 2, nv // 2
            P = np.empty((nu + 2, nv + 2, 4))
            K.interpolation(S, ncu, ncv, P)
            Sc = np.empty((ncu + 2, ncv + 2, 9))
            K.galerkin(S, P, Sc)
            self.levels[-1].P = P
            self.levels.append(_Level((ncu, ncv), Sc))
            S = Sc
        none = np.zeros((1, 1))
        for lev in self.levels:
            if lev.S is None:
                K.line_factors(np.zeros((1, 1, 9)), fine.we, fine.wn, fine.d, True, lev.cp, lev.im)
            else:
                K.line_factors(lev.S, none, none, none, False, lev.cp, lev.im)
        from scipy.sparse.linalg import splu

        last = self.levels[-1]
        # SuperLU rather than a dense inverse: LAPACK/BLAS calls would start OpenBLAS's threads, which
        # contend with Numba's (docs/heat.md); a banded LU is also right for a long thin coarsest level
        self._lu = splu(_sparse(fine.nine() if last.S is None else last.S).tocsc())

    def __len__(self) -> int:
        return len(self.levels)

    def _smooth(self, l: int, pre: bool) -> None:
        """Zebra line Gauss-Seidel along ``v``: from zero, even lines then odd (pre-smoothing), or odd
        then even (post-smoothing, the adjoint)."""
        lev = self.levels[l]
        for colour in ((0, 1) if pre else (1, 0)):
            first = pre and colour == 0
            if l == 0:
                f = self.fine
                K.lines5(f.we, f.wn, lev.b, lev.x, colour, lev.cp, lev.im, lev.dp, first)
            else:
                K.lines9(lev.S, lev.b, lev.x, colour, lev.cp, lev.im, lev.dp, first)

    def precondition(self, r: np.ndarray, z: np.ndarray) -> None:
        """``z = M r``: one V(1,1) cycle from zero on ``A z = r`` (padded arrays; ``z`` is overwritten).

        The zebra sweeps end (pre-smoothing) with the odd lines solved, so the residual is computed and
        restricted from the even rows only; they start (post-smoothing) with the odd lines, so the
        correction is interpolated to the even rows only.
        """
        top = self.levels[0]
        top.b, top.x = r, z
        last = len(self.levels) - 1
        for l in range(last):
            lev, nxt = self.levels[l], self.levels[l + 1]
            self._smooth(l, True)
            if l == 0:
                f = self.fine
                K.residual5(f.we, f.wn, f.c0, lev.b, lev.x, lev.r, 2, 2)
            else:
                K.residual9(lev.S, lev.b, lev.x, lev.r, 2, 2)
            K.restrict_even(lev.P, lev.r, nxt.b)
        coarse = self.levels[last]
        nu, nv = coarse.shape
        rhs = coarse.b[1:-1, 1:-1].reshape(-1)
        coarse.x.fill(0.0)
        coarse.x[1:-1, 1:-1] = self._lu.solve(rhs).reshape(nu, nv)
        for l in range(last - 1, -1, -1):
            K.prolong_add_even(self.levels[l].P, self.levels[l + 1].x, self.levels[l].x)
            self._smooth(l, False)


def pcg(mg: HeatMultigrid, b: np.ndarray, x: np.ndarray, tol: float, max_iter: int) -> tuple[int, float]:
    """Conjugate gradients on ``A x = b`` preconditioned by ``mg``'s V-cycle, from ``x`` (updated in place).

    ``b`` and ``x`` are padded ``(nu + 2, nv + 2)`` (ring zero). Stops when
    the relative residual ``||b - A x|| / ||b||`` is at most ``tol``: the
    recursion's residual first, then the true one recomputed from ``x``; the
    iteration restarts from ``x`` if they differ.

    Returns
    -------
    iterations : int
    residual : float
        The true relative residual of the returned ``x``.
    """
    f = mg.fine
    nb = math.sqrt(K.dot(b, b))
    if nb == 0.0:
        x.fill(0.0)
        return 0, 0.0
    r, z, p, q = (np.zeros_like(b) for _ in range(4))
    K.residual5(f.we, f.wn, f.c0, b, x, r)
    rel = math.sqrt(K.dot(r, r)) / nb
    it = 0
    while rel > tol and it < max_iter:
        start = it
        mg.precondition(r, z)
        p[...] = z
        rz = K.dot(r, z)
        while it < max_iter:
            pq = K.apply5_dot(f.we, f.wn, f.c0, p, q)
            if not pq > 0:
                break
            alpha = rz / pq
            rr = K.update_xr(x, r, p, q, alpha)
            it += 1
            rel = math.sqrt(rr) / nb
            if rel <= tol:
                break
            mg.precondition(r, z)
            rz_new = K.dot(r, z)
            if not rz_new > 0:
                break
            K.update_p(p, z, rz_new / rz)
            rz = rz_new
        K.residual5(f.we, f.wn, f.c0, b, x, r)      # the true residual: restart if the recursion drifted
        rel = math.sqrt(K.dot(r, r)) / nb
        if it == start:                              # no step possible (breakdown): give up
            break
    return it, rel
