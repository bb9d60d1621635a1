"""``multigrid``: semi-coarsening multigrid with zebra line relaxation.

The weighted length system (MATH.md) is anisotropic in both directions: with
the paper's weights u-edges dominate next to the bottom and top sides and
v-edges next to the left and right sides, by up to 1e9. A point smoother
cannot damp such errors; this solver uses the classic robust pair instead:

- **smoother**: zebra line Gauss-Seidel along u. Every interior row ``j`` of
  one colour (``j`` even, then ``j`` odd) is solved exactly for all its nodes
  at once, a tridiagonal system in ``i`` (Thomas algorithm). Errors strongly
  coupled along u disappear in one sweep;
- **semi-coarsening along v**: a coarse level keeps every column ``i`` and the
  rows ``j = 0, 2, 4, ...`` plus the last row, so any error the line smoother
  leaves (smooth along v, whatever it does along u) is seen by the coarse grid;
- **Galerkin coarse operators** ``A_c = P^T A P`` with linear interpolation
  along v (odd rows take the mean of the rows above and below). The fine
  5-point stencil becomes a 9-point stencil on coarse levels, and stays 9-point;
  the coarsest level has one interior row, which one line solve solves exactly.

V(1,1) cycles converge by a factor of about 0.08 per cycle with uniform
weights and 0.12-0.16 with the paper's, independent of the size
(``tests/test_multigrid.py``, ``benchmarks/bench_solvers.py``). Any node
counts work, not only ``2^k + 1``. Iteration stops on the guaranteed bound of
:mod:`clothgrid.solvers.bounds` (``stop="error"``).

The hierarchy is plain NumPy data (:class:`Level`, built once on the CPU by
:func:`build_hierarchy`); a backend turns it into a :class:`MultigridOps`
object that owns the level arrays and supplies the array operations, and
:func:`vcycle` drives any backend's operations the same way.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import InputError
from ..weights import Weights
from .bounds import barrier_max
from .problem import Problem, SolveResult

__all__ = ["Level", "Separable", "MultigridOps", "build_hierarchy", "coarse_rows", "vcycle", "fmg", "solve_multigrid",
           "convergence_factor", "DEFAULT_MAX_CYCLES"]


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

    def stencil(self, dtype=np.float32, xp=np, rows: slice = slice(None)) -> tuple:
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
    (``C`` is the sum of the four weights). Coarser levels hold all five as
    ``(nu, nv)`` float32 arrays (zero where a coupling leaves the grid). Level
    ``l+1`` keeps rows :func:`coarse_rows` of level ``l`` and all columns.

    With separable weights every level also carries ``sep``
    (:class:`Separable`); a coarse level then forms its five arrays only when
    asked (the CPU kernels read ``sep`` instead: 335 MB less at 4096^2).
    """

    def __init__(self, E=None, N=None, C=None, NE=None, NW=None, *, sep: Separable | None = None):
        if E is None and sep is None:
            raise ValueError("a Level needs stencil arrays or a separable form")
        self._arrays = None if E is None else (C, E, N, NE, NW)
        self.sep = sep

    def _stencil(self) -> tuple:
        if self._arrays is None:
            self._arrays = self.sep.stencil()
        return self._arrays

    C = property(lambda self: self._stencil()[0], doc="Centre coefficients (None on the finest level).")
    E = property(lambda self: self._stencil()[1], doc="Couplings ``(i, j)-(i+1, j)``.")
    N = property(lambda self: self._stencil()[2], doc="Couplings ``(i, j)-(i, j+1)``.")
    NE = property(lambda self: self._stencil()[3], doc="Couplings ``(i, j)-(i+1, j+1)`` (coarse levels).")
    NW = property(lambda self: self._stencil()[4], doc="Couplings ``(i, j)-(i-1, j+1)`` (coarse levels).")

    @property
    def nine(self) -> bool:
        """True for a 9-point (coarse) level."""
        return self._arrays is None or self._arrays[0] is not None

    @property
    def shape(self) -> tuple[int, int]:
        if self._arrays is None:
            return len(self.sep.du), len(self.sep.md)
        return (self.N.shape[0], self.N.shape[1] + (0 if self.nine else 1))


class MultigridOps(Protocol):
    """What a backend supplies to run :func:`vcycle` (see ``backends/cpu.py``).

    The backend holds, per level ``l``, the iterate ``x[l]`` and right-hand side
    ``b[l]``; level 0's iterate is the grid itself (boundary nodes fixed, ``b``
    zero), coarser levels hold corrections with zero boundary.
    """

    levels: int

    def smooth(self, level: int, reverse: bool = False) -> None:
        """One zebra line sweep: even rows then odd rows (odd then even if ``reverse``)."""

    def restrict(self, level: int) -> None:
        """``b[l+1] = P^T (b[l] - A_l x[l])`` and ``x[l+1] = 0``."""

    def prolong(self, level: int) -> None:
        """``x[l] += P x[l+1]``."""

    def max_step(self) -> float:
        """``max |D^-1 (b - A x)|`` over level 0's nodes (Euclidean per node)."""

    def solution(self) -> np.ndarray:
        """Level 0's iterate as a float64 ``(nu, nv, k)`` array."""


# V-cycles allowed by default: far more than the 3-15 a solve needs.
DEFAULT_MAX_CYCLES = 100

# Start with a full-multigrid pass where the backend supplies its operations
# (``restrict_full`` and ``prolong_full``: the cpu, gl and cuda backends do).
FULL_MULTIGRID_START = True


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
    otherwise computed by the CPU backend's kernels and kept in float32.
    """
    from ..backends._cpu_multigrid import coarsen

    levels = [fine_level(weights)]
    while levels[-1].shape[1] > min_rows:
        sep = levels[-1].sep
        levels.append(Level(sep=coarsen_separable(sep)) if sep is not None else coarsen(levels[-1]))
    return levels


def hierarchy_bytes(nu: int, nv: int, ncoords: int = 3) -> int:
    """Memory the CPU multigrid holds for an ``nu x nv`` grid, beyond the problem.

    The level-0 iterate (float64, ``ncoords``) and the coarser levels (about
    ``nu * nv`` nodes in all): 5 float32 stencil arrays plus iterate and
    right-hand side of ``ncoords`` each.
    """
    n = nu * nv
    return 8 * ncoords * n + 4 * (5 + 2 * ncoords) * n


def vcycle(ops: MultigridOps, pre: int = 1, post: int = 1, top: int = 0) -> None:
    """One V(pre, post) cycle over ``ops``' levels ``top`` (0: the finest) to the coarsest."""
    last = ops.levels - 1
    for lvl in range(top, last):
        for _ in range(pre):
            ops.smooth(lvl)
        ops.restrict(lvl)
    ops.smooth(last, reverse=True)   # one interior row: exact
    for lvl in range(last - 1, top - 1, -1):
        ops.prolong(lvl)
        for _ in range(post):
            ops.smooth(lvl, reverse=True)


def fmg(ops) -> None:
    """Full multigrid start: improve level 0's iterate by the coarse levels' solutions.

    The residual of the initial grid is restricted down the hierarchy, the
    coarsest level is solved exactly, and each finer level starts from the
    interpolated coarser solution and takes one V-cycle; level 0 finally adds
    the interpolated correction and takes one smoothing sweep. Costs about one
    V-cycle and saves two to three. Needs the optional ``restrict_full`` and ``prolong_full`` operations.
    """
    last = ops.levels - 1
    if last < 1:
        return
    for lvl in range(last):
        ops.restrict_full(lvl)
    ops.smooth(last, reverse=True)
    for lvl in range(last - 1, 0, -1):
        ops.prolong_full(lvl)
        vcycle(ops, top=lvl)
    ops.prolong_full(0)
    # Interpolated odd rows are rough: one sweep (odd rows re-solved first) cuts the
    # first V-cycle's start by about 4x, which saves a whole cycle at 2048^2 and 4096^2.
    ops.smooth(0, reverse=True)


def convergence_factor(weights: Weights, cycles: int = 10, seed: int = 0, backend=None) -> tuple[float, list[float]]:
    """Measured V(1,1) convergence factor for these weights.

    Starts from a random error (zero boundary and right-hand side) and returns
    the geometric mean of the last three cycles' reduction of ``max|D^-1 r|``,
    and every cycle's reduction.
    """
    if backend is None:
        from ..backends import cpu as backend
    nu, nv = weights.shape
    x = np.random.default_rng(seed).standard_normal((nu, nv, 1))
    x[0] = x[-1] = 0.0
    x[:, 0] = x[:, -1] = 0.0
    ops = backend.multigrid(build_hierarchy(weights), x)
    steps = [ops.max_step()]
    for _ in range(cycles):
        vcycle(ops)
        steps.append(ops.max_step())
    ratios = [b / a for a, b in zip(steps, steps[1:])]
    return float(np.exp(np.mean(np.log(ratios[-3:])))), ratios


def solve_multigrid(problem: Problem, *, backend, tol: float, stop: str = "error", max_iter: int | None = None,
                    progress=None, progress_seconds: float = 2.0, **_) -> SolveResult:
    """V(1,1) cycles until the stopping rule holds.

    ``stop="error"``: the guaranteed bound ``max|D^-1 r| * max z`` is at most
    ``tol * scale``. ``stop="paper"``: the step a Jacobi sweep would take,
    ``max|D^-1 r|``, is below ``tol * scale`` (the paper's rule, not a bound).
    """
    if stop not in ("error", "paper"):
        raise InputError(f"unknown stop rule {stop!r}: use 'error' or 'paper'")
    if max_iter is None:
        max_iter = DEFAULT_MAX_CYCLES
    if max_iter < 1:
        raise InputError(f"max_iter must be at least 1, not {max_iter}")
    t0 = time.perf_counter()
    nu, nv = problem.shape
    active = problem.active_coords
    if nu < 3 or nv < 3 or not active:
        return SolveResult(problem.r0.copy(), iterations=0, error_estimate=0.0, converged=True)
    levels = build_hierarchy(problem.weights)
    ops = backend.multigrid(levels, problem.r0[..., active])
    if hasattr(ops, "synchronize"):   # a device backend: the upload has finished
        ops.synchronize()
    setup = time.perf_counter() - t0
    zmax = barrier_max(problem, solve=None if problem.weights.unit_stencil else
                       _barrier_solver(problem, backend, levels))
    limit = tol * problem.scale / (zmax if stop == "error" else 1.0)
    t_cycles = time.perf_counter()
    if FULL_MULTIGRID_START and hasattr(ops, "prolong_full"):
        fmg(ops)
    steps = []
    step = math.inf
    last_report = time.perf_counter()
    while len(steps) < max_iter:
        vcycle(ops)
        step = ops.max_step()
        steps.append(step)
        if step <= limit:
            break
        if progress and (now := time.perf_counter()) - last_report >= progress_seconds:
            progress(f"multigrid: {len(steps)} cycles, error bound {step * zmax / problem.scale:.3g} (tol {tol:.3g})")
            last_report = now
    # max_step reads one float back from the device: the cycles have finished on it.
    cycles = time.perf_counter() - t_cycles
    t_download = time.perf_counter()
    # The inactive coordinates (zero) and the boundary nodes are r0's own.
    out = problem.r0 if problem.overwrite else problem.r0.copy()
    contiguous = active == list(range(active[0], active[-1] + 1))
    if contiguous and hasattr(ops, "solution_into"):   # a view: no temporary grid (400 MB at 4096^2)
        ops.solution_into(out[..., active[0]:active[-1] + 1])
    else:
        out[..., active] = ops.solution()
    factors = [b / a for a, b in zip(steps, steps[1:]) if a > 0]
    extra = {"levels": len(levels), "setup_seconds": setup, "cycle_seconds": cycles,
             "download_seconds": time.perf_counter() - t_download,
             "convergence_factor": float(np.exp(np.mean(np.log(factors[-3:])))) if factors else None,
             "steps": [s / problem.scale for s in steps]}
    if hasattr(ops, "extra"):
        extra.update(ops.extra())   # e.g. the gl backend's pass counts and timings
    return SolveResult(out, iterations=len(steps), error_estimate=step * zmax / problem.scale,
                       converged=step <= limit, extra=extra)


def _barrier_solver(problem: Problem, backend, levels: list[Level]):
    """``solve(rhs)`` for :func:`barrier_max` by multigrid, with a rigorous correction.

    ``max z`` only needs an upper bound: for an approximation ``y`` of
    ``z = A^-1 D 1`` with ``delta = max |D^-1 (D 1 - A y)| < 1``, ``z <= y + delta z``
    node by node, so ``max z <= max y / (1 - delta)``. Cycles run until
    ``delta <= 0.01``; the returned vector is scaled by ``1 / (1 - delta)``.
    """
    nu, nv = problem.shape

    def solve(rhs: np.ndarray) -> np.ndarray:
        ops = backend.multigrid(levels, np.zeros((nu, nv, 1)), rhs=rhs.reshape(nu - 2, nv - 2, 1))
        delta = math.inf
        for _ in range(200):
            vcycle(ops)
            delta = ops.max_step()   # relative to |D^-1 D 1| = 1
            if delta <= 0.01:
                break
        if not delta < 1:
            raise InputError("multigrid could not bound the error for these weights: use solver 'direct'")
        return ops.solution()[1:-1, 1:-1, 0].ravel() / (1.0 - delta)

    return solve
