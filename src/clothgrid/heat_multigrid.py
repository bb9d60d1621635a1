"""The heat solver's multigrid: black-box multigrid as a preconditioner of conjugate gradients.

:mod:`clothgrid.heat` solves ``(A + diag(shift)) T = b`` for the 5-point
finite-volume operator of per-edge conductances. Conductivity jumps of 10^4
defeat linear interpolation (the grid solver's multigrid stalls at 0.93 per
cycle on them); this hierarchy follows the jumps:

- **full coarsening** (coarse point ``I`` is fine point ``2 I`` along both
  axes), down to a coarsest level of at most 256 unknowns (or one row or
  column: a long thin grid) solved directly (SciPy's SuperLU on the CPU, a
  dense inverse on a device);
- **operator-dependent interpolation** (Dendy 1982, "Black box multigrid"):
  a fine point's weights come from the operator, so a correction is
  interpolated in proportion to the conductances it flows through: across an
  interface of 10^4 it is flat on the conducting side and carries the jump on
  the insulating one. Points between coarse points along ``u`` take theirs
  from their line's operator (Schaffer's collapse, :func:`clothgrid._heat_kernels.interpolation`),
  which keeps strongly stretched cells with random conductivities at 6-10
  iterations (Dendy's pointwise weights: 44-70);
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

The hierarchy (:class:`HeatHierarchy`: interpolation weights, Galerkin
products, the line solves' factors, the coarsest level's factorisation) is
data, built once on the CPU with the Numba kernels of
:mod:`clothgrid._heat_kernels`. The V-cycle (:func:`vcycle`) and conjugate
gradients (:func:`pcg`; :func:`refine`, mixed-precision iterative refinement
around it, for a float32 device) are written once, against the operations of
:class:`~clothgrid.backends.protocol.HeatOps` that each backend supplies
(``Backend.heat_ops``): the cpu backend's Numba kernels
(:mod:`clothgrid.backends._cpu_heat`), the gl backend's shaders and the cuda
backend's kernels. :class:`HeatSolver` holds the operations and their work
vectors for the solves of one operator. Arrays are padded ``(nu + 2, nv + 2)``
with the unknowns inside a zero ring. This module imports neither
:mod:`clothgrid.backends` nor :mod:`clothgrid.solvers` (the backend's
operations are handed to it).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from . import _heat_kernels as K

__all__ = ["Stencil5", "HeatLevel", "HeatHierarchy", "HeatSolver", "vcycle", "pcg", "refine", "padded",
           "numba_threads", "COARSEST_POINTS", "INNER_TOL"]

#: A level with at most this many unknowns (or fewer than 2 rows or columns) is solved directly (SuperLU).
COARSEST_POINTS = 256
#: Relative residual a float32 inner solve of :func:`refine` is asked for at least (its own float32
#: residual). Measured on the benchmark's cases at 256^2 and 512^2 on llvmpipe (CG iterations in all to
#: 1e-8): 1e-3 12-15, 3e-4 12-14, 1e-4 13-17, 1e-5 15-17; a float32 field stops improving near 1e-6.
INNER_TOL = 3e-4


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
class HeatLevel:
    """One level of the hierarchy (host float64 arrays, padded).

    Attributes
    ----------
    shape : (int, int)
        ``(nu, nv)`` unknowns.
    S : numpy.ndarray or None
        ``(nu + 2, nv + 2, 9)`` 9-point stencil (coarse levels); None on level 0, whose operator is the
        hierarchy's :class:`Stencil5` (flux form).
    P : numpy.ndarray or None
        ``(nu + 2, nv + 2, 4)`` interpolation from the next coarser level (None on the coarsest).
    cp, im : numpy.ndarray
        ``(nu + 2, nv + 2)`` the line solves' Thomas factors (eliminated super-diagonal, inverse pivots).
    """

    shape: tuple[int, int]
    S: np.ndarray | None
    P: np.ndarray | None = None
    cp: np.ndarray = field(init=False, repr=False)
    im: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        nu, nv = self.shape
        self.cp, self.im = np.zeros((nu + 2, nv + 2)), np.zeros((nu + 2, nv + 2))


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


class HeatHierarchy:
    """Black-box multigrid hierarchy of a 5-point operator, built on the CPU (data for any backend).

    Parameters
    ----------
    fine : Stencil5
        The operator (level 0).
    coarsest_points : int
        Coarsen while a level has more unknowns than this (and at least two
        rows and columns).

    Attributes
    ----------
    fine : Stencil5
    levels : list of HeatLevel
        Finest first.
    """

    def __init__(self, fine: Stencil5, coarsest_points: int = COARSEST_POINTS):
        self.fine = fine
        self.levels: list[HeatLevel] = [HeatLevel(fine.shape, None)]
        S = None
        while True:
            nu, nv = self.levels[-1].shape
            if min(nu, nv) < 2 or nu * nv <= coarsest_points:
                break
            S = fine.nine() if S is None else S
            ncu, ncv = nu // 2, nv // 2
            P = np.empty((nu + 2, nv + 2, 4))
            K.interpolation(S, ncu, ncv, P, np.empty((3, nu + 2, nv + 2)))
            Sc = np.empty((ncu + 2, ncv + 2, 9))
            K.galerkin(S, P, Sc)
            self.levels[-1].P = P
            self.levels.append(HeatLevel((ncu, ncv), Sc))
            S = Sc
        none = np.zeros((1, 1))
        for lev in self.levels:
            if lev.S is None:
                K.line_factors(np.zeros((1, 1, 9)), fine.we, fine.wn, fine.d, True, lev.cp, lev.im)
            else:
                K.line_factors(lev.S, none, none, none, False, lev.cp, lev.im)
        self._lu: Any = None

    def __len__(self) -> int:
        return len(self.levels)

    def coarsest_stencil(self) -> np.ndarray:
        """The coarsest level's 9-point stencil (level 0's, in 9-point form, when it is the only level)."""
        last = self.levels[-1]
        return self.fine.nine() if last.S is None else last.S

    @property
    def coarse_lu(self) -> Any:
        """SciPy's SuperLU factorisation of the coarsest level (made on first use).

        SuperLU rather than a dense inverse on the CPU: LAPACK/BLAS calls would start OpenBLAS's threads,
        which contend with Numba's (docs/heat.md); a banded LU is also right for a long thin coarsest level.
        """
        if self._lu is None:
            from scipy.sparse.linalg import splu

            self._lu = splu(_sparse(self.coarsest_stencil()).tocsc())
        return self._lu

    def coarse_inverse(self) -> np.ndarray:
        """The coarsest level's inverse as a dense float64 ``(n, n)`` array (``n = nu * nv``, row-major
        ``(i, j)``), for a device that solves the coarsest level by one matrix-vector product; symmetric."""
        last = self.levels[-1]
        n = last.shape[0] * last.shape[1]
        inv = self.coarse_lu.solve(np.eye(n))
        return 0.5 * (inv + inv.T)


# --------------------------------------------------------------------------- the algorithms, once


def vcycle(ops: Any, r: Any, z: Any) -> None:
    """``z = M r``: one V(1,1) cycle from zero on ``A z = r``, driven through ``ops``
    (:class:`~clothgrid.backends.protocol.HeatOps`; ``z`` is overwritten).

    The zebra sweeps end (pre-smoothing) with the odd lines solved, so a backend's ``restrict`` may form
    and restrict the residual from the even rows only; they start (post-smoothing) with the odd lines, so
    ``prolong`` may interpolate the correction to the even rows only.
    """
    ops.bind(r, z)
    last = ops.levels - 1
    for level in range(last):
        ops.smooth(level, True)
        ops.restrict(level)
    ops.coarse_solve()
    for level in range(last - 1, -1, -1):
        ops.prolong(level)
        ops.smooth(level, False)


def pcg(ops: Any, b: Any, x: Any, tol: float, max_iter: int, work: tuple[Any, Any, Any, Any],
        stall: bool = False) -> tuple[int, float]:
    """Conjugate gradients on ``A x = b`` preconditioned by :func:`vcycle`, from ``x`` (updated in place),
    on the vectors of ``ops`` (:class:`~clothgrid.backends.protocol.HeatOps`).

    Stops when the relative residual ``||b - A x|| / ||b||`` is at most ``tol``: the recursion's residual
    first, then the true one recomputed from ``x`` with ``ops.residual``; the iteration restarts from ``x``
    if they differ, and gives up when a restart did not lower the true residual (the field's rounding
    floor is above ``tol``: before, such a solve restarted until ``max_iter``). ``work`` is four
    level-0 vectors (overwritten). ``stall``: give up unless a restart halves the true residual (float32
    arithmetic, whose floor is high).

    Returns
    -------
    iterations : int
    residual : float
        The true relative residual of the returned ``x`` (in the backend's arithmetic).
    """
    r, z, p, q = work
    nb = math.sqrt(ops.dot(b, b))
    if nb == 0.0:
        ops.copy(x, b)                      # x = b = 0
        return 0, 0.0
    ops.residual(b, x, r)
    rel = math.sqrt(ops.dot(r, r)) / nb
    it = 0
    while rel > tol and it < max_iter:
        start, rel_start = it, rel
        vcycle(ops, r, z)
        ops.copy(p, z)
        rz = ops.dot(r, z)
        while it < max_iter:
            pq = ops.apply(p, q)
            if not pq > 0:
                break
            alpha = rz / pq
            rr = ops.axpy(x, r, p, q, alpha)
            it += 1
            rel = math.sqrt(rr) / nb
            if rel <= tol:
                break
            vcycle(ops, r, z)
            rz_new = ops.dot(r, z)
            if not rz_new > 0:
                break
            ops.xpay(p, z, rz_new / rz)
            rz = rz_new
        ops.residual(b, x, r)                # the true residual: restart if the recursion drifted
        rel = math.sqrt(ops.dot(r, r)) / nb
        # no step possible, or a restart that did not improve the true residual (float64: at all, the
        # rounding floor of the field; float32, ``stall``: by half): more restarts would only repeat it
        if it == start or not rel < (0.5 if stall else 1.0) * rel_start:
            break
    return it, rel


def refine(solver: "HeatSolver", b: np.ndarray, x: np.ndarray, tol: float, max_iter: int) -> tuple[int, float, int]:
    """Mixed-precision iterative refinement: ``x += e`` with ``A e = r`` solved by :func:`pcg` on a
    float32 device, ``r = b - A x`` recomputed in float64 on the host after each solve.

    Each inner solve asks for ``max(tol ||b|| / ||r||, INNER_TOL)`` of its (unit-scaled) right-hand side.
    Stops when the float64 relative residual is at most ``tol``, after ``max_iter`` inner iterations in
    all, or when an inner solve no longer halves it (its float32 arithmetic has reached its floor).

    Returns
    -------
    iterations : int
        Inner PCG iterations, all solves.
    residual : float
        ``||b - A x|| / ||b||`` of the returned ``x``, float64 on the host.
    refinements : int
        Inner solves.
    """
    ops, f = solver.ops, solver.fine
    nb = math.sqrt(K.dot(b, b))
    if nb == 0.0:
        x.fill(0.0)
        return 0, 0.0, 0
    r, e, zero = np.zeros_like(b), np.zeros_like(b), np.zeros_like(b)
    K.residual5(f.we, f.wn, f.c0, b, x, r)
    rel = math.sqrt(K.dot(r, r)) / nb
    it = steps = 0
    vb, vx, *work = solver.vectors()
    while rel > tol and it < max_iter:
        s = rel * nb
        rb = ops.upload(r * (1.0 / s), vb)
        ve = ops.upload(zero, vx)
        k, _ = pcg(ops, rb, ve, min(0.5, max(tol / rel, INNER_TOL)), max_iter - it, tuple(work), stall=True)
        it += k
        steps += 1
        ops.download(ve, e)
        x_old = x.copy()
        x += s * e
        K.residual5(f.we, f.wn, f.c0, b, x, r)
        new = math.sqrt(K.dot(r, r)) / nb
        if not new < rel:                    # worse: keep the previous iterate, and stop
            x[...] = x_old
            K.residual5(f.we, f.wn, f.c0, b, x, r)
            break
        progress, rel = new < 0.5 * rel, new
        if k == 0 or not progress:
            break
    return it, rel, steps


class HeatSolver:
    """A backend's :class:`~clothgrid.backends.protocol.HeatOps` for one operator, with its work vectors.

    Parameters
    ----------
    ops : HeatOps
        From the backend's ``heat_ops(hierarchy)``.
    fine : Stencil5
        The operator on the host (float64): the residual of :func:`refine`.
    """

    def __init__(self, ops: Any, fine: Stencil5):
        self.ops, self.fine = ops, fine
        self._vectors: list[Any] | None = None

    def vectors(self) -> list[Any]:
        """Six level-0 vectors of the backend (right-hand side, iterate and :func:`pcg`'s four), made once."""
        if self._vectors is None:
            self._vectors = [self.ops.vector() for _ in range(6)]
        return self._vectors

    def solve(self, b: np.ndarray, x: np.ndarray, tol: float, max_iter: int) -> tuple[int, float, int]:
        """Solve ``A x = b`` to the relative residual ``tol``, from ``x``; ``b`` and ``x`` are padded host
        float64 arrays, ``x`` is updated in place.

        Where the backend computes in float64 (``ops.precise``: cpu, cuda) this is :func:`pcg` on its
        vectors; on a float32 device (gl) it is :func:`refine`, whose residual is float64 on the host.

        Returns
        -------
        (iterations, relative residual, refinements)
            ``refinements``: float32 inner solves (0 where the backend is float64).
        """
        ops = self.ops
        if not ops.precise:
            return refine(self, b, x, tol, max_iter)
        vb, vx, *work = self.vectors()
        bv = ops.upload(b, vb)
        xv = ops.upload(x, vx)
        it, rel = pcg(ops, bv, xv, tol, max_iter, tuple(work))
        ops.download(xv, x)
        return it, rel, 0

    def close(self) -> None:
        """Free what the operations hold on a device (a no-op on the cpu)."""
        self._vectors = None
        self.ops.release()
