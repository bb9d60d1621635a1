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

__all__ = ["Level", "MultigridOps", "build_hierarchy", "coarse_rows", "vcycle", "fmg", "solve_multigrid",
           "convergence_factor", "DEFAULT_MAX_CYCLES"]


@dataclass
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
    """

    E: np.ndarray
    N: np.ndarray
    C: np.ndarray | None = None
    NE: np.ndarray | None = None
    NW: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return (self.N.shape[0], self.N.shape[1] + (1 if self.C is None else 0))


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
# (the CPU backend does; the gl backend starts its V-cycles from the initial grid).
FULL_MULTIGRID_START = True


def coarse_rows(nv: int) -> np.ndarray:
    """Rows a coarse level keeps: ``0, 2, 4, ...`` and ``nv - 1``."""
    return np.unique(np.r_[np.arange(0, nv, 2), nv - 1])


def fine_level(weights: Weights) -> Level:
    """Level 0: the 5-point stencil of the weights.

    For separable weights with constant ``cu`` and ``cv`` (the paper's,
    uniform) ``wu`` depends on ``j`` only and ``wv`` on ``i`` only: the level
    holds stride-0 views of their 1D factors, so sweeps stream only the grid.
    """
    nu, nv = weights.shape
    if weights.unit_stencil:
        cu, dv, du, cv = weights.factors
        return Level(E=np.broadcast_to(cu[0] * dv, (nu - 1, nv)), N=np.broadcast_to((du * cv[0])[:, None], (nu, nv - 1)))
    return Level(E=np.ascontiguousarray(weights.wu), N=np.ascontiguousarray(weights.wv))


def build_hierarchy(weights: Weights, min_rows: int = 3) -> list[Level]:
    """All levels, finest first, down to one with at most ``min_rows - 2`` interior rows.

    Coarse levels are Galerkin operators ``P^T A P`` (linear interpolation
    along v), computed by the CPU backend's kernels and kept in float32.
    """
    from ..backends._cpu_multigrid import coarsen

    levels = [fine_level(weights)]
    while levels[-1].shape[1] > min_rows:
        levels.append(coarsen(levels[-1]))
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
    setup = time.perf_counter() - t0
    zmax = barrier_max(problem, solve=None if problem.weights.unit_stencil else
                       _barrier_solver(problem, backend, levels))
    limit = tol * problem.scale / (zmax if stop == "error" else 1.0)
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
    # The inactive coordinates (zero) and the boundary nodes are r0's own.
    out = problem.r0 if problem.overwrite else problem.r0.copy()
    contiguous = active == list(range(active[0], active[-1] + 1))
    if contiguous and hasattr(ops, "solution_into"):   # a view: no temporary grid (400 MB at 4096^2)
        ops.solution_into(out[..., active[0]:active[-1] + 1])
    else:
        out[..., active] = ops.solution()
    factors = [b / a for a, b in zip(steps, steps[1:]) if a > 0]
    extra = {"levels": len(levels), "setup_seconds": setup,
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
