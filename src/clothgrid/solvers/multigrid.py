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

Per-edge weights with jumps (four weights a node: a stiff patch in a soft
piece) defeat linear interpolation: V-cycles slow to 0.5 a cycle at 10:1 and
stall (0.87-0.94) at 100:1 and 10^4:1. Where a solve's V-cycles converge
slower than :data:`KRYLOV_SWITCH` a cycle, it goes on with conjugate gradients
preconditioned by one V-cycle from zero (:class:`ConjugateGradients`, on
backends whose operations supply level-0 vectors), which reaches the bound in
tens of iterations where V-cycles would take hundreds; the stopping rule and
its bound are the same, on the true residual of the iterate.

The hierarchy is plain NumPy data (:class:`~clothgrid.multigrid_levels.Level`,
built once on the CPU by :func:`~clothgrid.multigrid_levels.build_hierarchy`);
a backend turns it into a :class:`~clothgrid.backends.protocol.MultigridOps`
object that owns the level arrays and supplies every operation, and
:func:`vcycle` drives any backend's operations the same way. This module
imports the hierarchy and the protocol, never a backend: the solve receives the
backend as an argument. ``Level``, ``Separable``, ``build_hierarchy``,
``coarse_rows`` and ``MultigridOps`` stay importable from here.
"""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np

from ..backends.protocol import Backend, MultigridOps
from ..errors import InputError
from ..multigrid_levels import Level, Separable, build_hierarchy, coarse_rows
from ..weights import Weights
from .bounds import BandBarriers, _analytic_barrier_max, barrier_max
from .problem import Problem, SolveResult

__all__ = ["Level", "Separable", "MultigridOps", "build_hierarchy", "coarse_rows", "vcycle", "fmg", "solve_multigrid",
           "convergence_factor", "DEFAULT_MAX_CYCLES", "FMG_VCYCLE_LEVELS"]

# Iterations allowed by default. V-cycles take 1-4 on the paper's and uniform weights and 3 on a smooth
# per-edge field; conjugate gradients on jumps 8-45 (10:1 to 10^4:1 blocks), and 268 were seen (10^4:1
# blocks of 25 x 5 cells on a 200 x 40 grid), past the 100 allowed before they came. 400 iterations at
# 1024^2 would take about as long as the direct solve (10-13 s).
DEFAULT_MAX_CYCLES = 400

# Start with a full-multigrid pass (every backend supplies ``restrict_full`` and ``prolong_full``).
FULL_MULTIGRID_START = True

# The full-multigrid start takes a V-cycle on levels 1 .. FMG_VCYCLE_LEVELS and one smoothing sweep on
# coarser ones. A V-cycle on every level cost two V-cycles' time at 1024^2 (the coarse levels keep
# all 1024 columns, so each costs about as much per call as the next finer one). With V-cycles on
# levels 1 and 2 only, the T-shirt front and four classic regions take the same V-cycles at 1024^2
# and 2048^2 and the solve is 8-12 % faster; at 4096^2 the paper's weights take 3 cycles (2.35 s
# against 2.53 s), where V-cycles on level 1 alone left the third cycle's bound at 1.7x the
# tolerance, one cycle more (docs/performance.md).
FMG_VCYCLE_LEVELS = 2


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


#: A solve with per-edge weights whose last V-cycle lowered ``max|D^-1 r|`` by less than this
#: factor (after two or more) goes on with :class:`ConjugateGradients`. The paper's weights times a
#: smooth field converge by 0.05 a cycle and keep V-cycles; 8 x 8 blocks of 10:1 by 0.30 at the
#: second cycle, slowing to 0.5 (19 cycles at 1024^2), 100:1 by 0.87.
KRYLOV_SWITCH = 0.25

#: Conjugate gradients start again from the true residual when the stopping figure has not reached a
#: new low for this many iterations (a safeguard: the float32 coarse levels make the preconditioner
#: only nearly symmetric). The figure, a maximum norm, is not monotone under conjugate gradients:
#: on 10^4:1 blocks at 97 x 81 a restart after 4 iterations without a new low took 109 iterations
#: (19 restarts) where none took 43; with 20, random patchworks of 10^5-10^6:1 on small elongated
#: grids (64 x 21: some 30 stiff blocks, as many small eigenvalues of the preconditioned operator
#: for the Krylov space to find) restarted before it had found them and never met the bound in 400
#: iterations. With 50, 1200 fresh patchworks (5-69 nodes a side, contrasts up to 10^6) all converge,
#: the slowest in 239; the jump rows of ``bench_speed.py`` never restart either way.
KRYLOV_RESTART = 50


class ConjugateGradients:
    """Conjugate gradients on level 0 of ``ops``, preconditioned by one V-cycle from zero.

    Each coordinate is its own system with the same matrix, so the scalars are per coordinate
    (arrays). The iterate is ``ops``' own: :meth:`step` updates it once (``x += alpha p``), after
    which ``ops.max_step`` and ``ops.solution`` read it as after a V-cycle. Three level-0 vectors:
    the residual ``r``, the direction ``p``, and ``w`` holding the preconditioned residual ``z``
    and then ``q = A p``.

    Parameters
    ----------
    ops : MultigridOps
        Operations whose ``vector()`` is not None.
    """

    def __init__(self, ops: MultigridOps, r: object):
        self.ops = ops
        self.r, self.p, self.w = r, ops.vector(), ops.vector()
        self.rz: np.ndarray | None = None
        self.iterations = self.restarts = 0

    @classmethod
    def on(cls, ops: MultigridOps) -> "ConjugateGradients | None":
        """Conjugate gradients on ``ops``, or None where its ``vector()`` is None (the backend has
        no level-0 vectors: the solve keeps V-cycles)."""
        r = ops.vector()
        return None if r is None else cls(ops, r)

    def _precondition(self) -> None:
        self.ops.bind(self.r, self.w)
        vcycle(self.ops)
        self.ops.bind(None, None)

    def restart(self) -> None:
        """Start again from the iterate's true residual (the next :meth:`step`)."""
        self.rz = None

    def step(self) -> None:
        """One iteration: the next direction (from the true residual after a restart), then
        ``x += alpha p``."""
        ops = self.ops
        if self.rz is None:
            ops.residual(self.r)
            self._precondition()
            self.rz = ops.dot(self.r, self.w)
            ops.xpay(self.p, self.w, np.zeros_like(self.rz))         # p = z
            self.restarts += self.iterations > 0
        else:
            self._precondition()
            rz = ops.dot(self.r, self.w)
            beta = np.divide(rz, self.rz, out=np.zeros_like(rz), where=self.rz > 0)
            ops.xpay(self.p, self.w, beta)
            self.rz = rz
        pq = ops.apply(self.p, self.w)                                # w = q = A p
        alpha = np.divide(self.rz, pq, out=np.zeros_like(pq), where=pq > 0)
        ops.axpy(self.r, self.p, self.w, alpha)
        self.iterations += 1


def _iterate(ops: MultigridOps, measure: Callable[[], tuple[float, float]], limit: float, max_iter: int,
             krylov: bool, steps: list[float],
             on_cycle: Callable[[float, ConjugateGradients | None], None] | None = None
             ) -> tuple[float, ConjugateGradients | None]:
    """V-cycles (then, for ``krylov``, conjugate gradients once they are slow: :data:`KRYLOV_SWITCH`)
    until the figure of ``measure()`` (``(step, figure)``, after each iteration) is at most ``limit``,
    or ``max_iter`` iterations in all; appends each step to ``steps``. Returns the last figure and
    the conjugate gradients that ran (None: V-cycles only). ``on_cycle(figure, cg)`` after each
    iteration that goes on."""
    figure = math.inf
    cg: ConjugateGradients | None = None
    switched = not krylov
    best, since = math.inf, 0
    while len(steps) < max_iter:
        if not switched and len(steps) >= 2 and steps[-1] > KRYLOV_SWITCH * steps[-2]:
            switched = True
            cg = ConjugateGradients.on(ops)
        if cg is None:
            vcycle(ops)
        else:
            cg.step()
        step, figure = measure()
        steps.append(step)
        if figure <= limit:
            break
        if cg is not None:
            best, since = (figure, 0) if figure < best else (best, since + 1)
            if since >= KRYLOV_RESTART:
                cg.restart()
                best, since = figure, 0
        if on_cycle is not None:
            on_cycle(figure, cg)
    return figure, cg


def fmg(ops: MultigridOps, vcycle_levels: int | None = None) -> None:
    """Full multigrid start: improve level 0's iterate by the coarse levels' solutions.

    The residual of the initial grid is restricted down the hierarchy, the
    coarsest level is solved exactly, and each finer level starts from the
    interpolated coarser solution: levels up to :data:`FMG_VCYCLE_LEVELS` then
    take one V-cycle, coarser ones one smoothing sweep; level 0 finally adds
    the interpolated correction and takes one smoothing sweep. Costs about one
    V-cycle and saves two to three. Uses ``restrict_full`` and ``prolong_full`` (``prolong`` where a
    reversed sweep follows). ``vcycle_levels``: instead of :data:`FMG_VCYCLE_LEVELS`.
    """
    top_v = FMG_VCYCLE_LEVELS if vcycle_levels is None else vcycle_levels
    last = ops.levels - 1
    if last < 1:
        return
    for lvl in range(last):
        ops.restrict_full(lvl)
    ops.smooth(last, reverse=True)
    for lvl in range(last - 1, 0, -1):
        if lvl <= top_v:
            ops.prolong_full(lvl)      # the V-cycle's first sweep reads the odd rows
            vcycle(ops, top=lvl)
        else:
            ops.prolong(lvl)           # a reversed sweep next: the odd rows are solved before any read
            ops.smooth(lvl, reverse=True)
    # The correction on the even rows, then one sweep with the odd rows re-solved first (their
    # interpolated values, rough, would never be read: prolong, not prolong_full). It cuts the
    # first V-cycle's start by about 4x, which saves a whole cycle at 2048^2 and 4096^2.
    ops.prolong(0)
    ops.smooth(0, reverse=True)


def convergence_factor(weights: Weights, cycles: int = 10, seed: int = 0,
                       backend: Backend | None = None) -> tuple[float, list[float]]:
    """Measured V(1,1) convergence factor for these weights.

    Starts from a random error (zero boundary and right-hand side) and returns
    the geometric mean of the last three cycles' reduction of ``max|D^-1 r|``,
    and every cycle's reduction.

    Parameters
    ----------
    weights : Weights
    cycles : int, optional
        V-cycles to run.
    seed : int, optional
        Of the random initial error.
    backend : Backend, optional
        Where the cycles run; the cpu backend (from the registry) if omitted.

    Returns
    -------
    (float, list of float)
    """
    if backend is None:
        from ..backends import get_backend

        backend = get_backend("cpu")
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


def solve_multigrid(problem: Problem, *, backend: Backend, tol: float, stop: str = "error",
                    max_iter: int | None = None, progress: Callable[[str], None] | None = None,
                    progress_seconds: float = 2.0, **_: object) -> SolveResult:
    """V(1,1) cycles until the stopping rule holds.

    ``stop="error"``: a guaranteed error bound is at most ``tol * scale``: on a backend whose
    ``band_steps`` computes it (the cpu's, for any 5-point level 0) the band barriers' bound, else
    ``max|D^-1 r| * max z`` (:mod:`clothgrid.solvers.bounds`).
    ``stop="paper"``: the step a Jacobi sweep would take,
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
    contiguous = active == list(range(active[0], active[-1] + 1))
    # a view where the active coordinates are contiguous: no copy of the grid (16-24 MB at 1024^2)
    x0 = problem.r0[..., active[0]:active[-1] + 1] if contiguous else problem.r0[..., active]
    # Once the iterate lives in ops, r0's contents are dead until the solution comes back into it
    # (its boundary ring aside, kept here): the backend may use its memory (the cpu keeps its coarse
    # levels there, already resident) or give its pages back (400 MB at 4096^2).
    spare = problem.r0 if problem.overwrite and problem.r0.flags.c_contiguous else None
    ring = _ring(problem.r0) if spare is not None else None
    # the boundary's largest coordinate (the residual solve's rounding allowance), read while r0 holds it
    r0 = problem.r0
    xmax = float(np.abs(np.concatenate([r0[0], r0[-1], r0[:, 0], r0[:, -1]])).max())
    ops = backend.multigrid(levels, x0, spare=spare)
    ops.synchronize()   # on a device: the upload has finished (a no-op on the cpu)
    setup = time.perf_counter() - t0
    unit = problem.weights.unit_stencil
    limit = tol * problem.scale
    # Per-edge weights under the error rule try the residual solve's bound after the first iteration
    # (_residual_solve_bound), which needs no barrier solve; the barrier solve (max z) is made only
    # where that bound does not meet the tolerance.
    residual_try = stop == "error" and not unit and RESIDUAL_SOLVE_BOUND
    zmax: float | None = None
    bands: BandBarriers | None = None

    def barriers() -> None:
        """``max z`` and the band barriers' table (solvers.bounds) where the rule needs them."""
        nonlocal zmax, bands
        zmax = barrier_max(problem) if unit else _barrier_max(problem, backend, levels, ops.spare())
        bands = BandBarriers.for_grid(nu, nv, limit / zmax, zmax) if stop == "error" else None

    if not residual_try:
        barriers()
    method = "max step"

    def measure() -> tuple[float, float]:
        """(max|D^-1 r|, the stopping rule's figure: the error bound, or the step for "paper")."""
        nonlocal method, bands, residual_try
        if residual_try:
            residual_try = False        # once, after the first iteration
            got = _residual_solve_bound(ops, limit, _analytic_barrier_max(nu, nv), xmax)
            if got is not None and got[1] <= limit:
                method = "residual solve"
                return got
            barriers()
        assert zmax is not None
        # The float64 residual's rounding, at most 16 u |A| |x| <= 32 u D max|x| a node (the iterate within
        # twice the boundary's range): a floor of |s| that z takes. 1e-5 of the tolerance at 1024^2 and
        # 3e-3 at 16384^2 (a piece within its own size of the origin); it shows only at the rounding floor.
        rounding = 64 * 2.0 ** -53 * xmax * zmax if stop == "error" else 0.0
        if bands is not None:
            got = ops.band_steps(bands)
            if got is not None:
                step, figure = math.sqrt(got[0]), bands.bound(got) + rounding
                if not unit and not figure < step * zmax + rounding:
                    # Per-edge weights whose residual is not at the boundary (coefficient jumps: it sits
                    # at the jumps, 10:1 to 10^4:1 blocks never gained): the plain bound from here on,
                    # half the pass (the table costs 1.5-2 ms more than max_step at 1024^2).
                    bands = None
                method = "band barriers"
                return step, figure
        step = ops.max_step()
        method = "max step"
        return step, step * zmax + rounding if stop == "error" else step

    t_cycles = time.perf_counter()
    if FULL_MULTIGRID_START:
        fmg(ops)
    steps: list[float] = []
    last_report = time.perf_counter()

    def report(figure: float, cg: ConjugateGradients | None) -> None:
        nonlocal last_report
        if progress and (now := time.perf_counter()) - last_report >= progress_seconds:
            what = "cycles" if cg is None else f"iterations ({cg.iterations} conjugate gradients)"
            progress(f"multigrid: {len(steps)} {what}, error bound {figure / problem.scale:.3g} (tol {tol:.3g})")
            last_report = now

    # conjugate gradients where V-cycles are slow: per-edge weights (unit stencils converge by 0.05-0.16)
    figure, cg = _iterate(ops, measure, limit, max_iter, not problem.weights.unit_stencil, steps, report)
    # max_step reads one float back from the device: the cycles have finished on it.
    cycles = time.perf_counter() - t_cycles
    t_download = time.perf_counter()
    # The inactive coordinates (zero) and the boundary nodes are r0's own.
    out = problem.r0 if problem.overwrite else problem.r0.copy()
    if contiguous:   # a view: no temporary grid on the cpu and cuda backends (400 MB at 4096^2)
        ops.solution_into(out[..., active[0]:active[-1] + 1])
    else:
        out[..., active] = ops.solution()
    if ring is not None:
        for c in set(range(out.shape[2])) - set(active):
            out[1:-1, 1:-1, c] = 0.0     # what an inactive coordinate solves to (zero on the ring)
        _ring(out, ring)
    factors = [b / a for a, b in zip(steps, steps[1:]) if a > 0]
    extra = {"levels": len(levels), "setup_seconds": setup, "cycle_seconds": cycles,
             "download_seconds": time.perf_counter() - t_download,
             "convergence_factor": float(np.exp(np.mean(np.log(factors[-3:])))) if factors else None,
             "steps": [s / problem.scale for s in steps]}
    if cg is not None:          # the iterations after the first V-cycles were conjugate gradients'
        extra.update(cg_iterations=cg.iterations, cg_restarts=cg.restarts)
    extra.update(ops.extra())   # e.g. the gl backend's pass counts and timings ({} on the cpu)
    extra["bound_method"] = method      # "residual solve", "band barriers" or "max step" (max|D^-1 r| max z)
    if zmax is None and stop != "error":
        barriers()
    estimate = figure if stop == "error" else (steps[-1] * zmax if steps else math.inf)
    return SolveResult(out, iterations=len(steps), error_estimate=estimate / problem.scale,
                       converged=figure <= limit, extra=extra)


#: The residual solve's full-multigrid start smooths every coarse level once (no V-cycles on levels 1
#: and 2): its ``y`` needs ``delta < 1``, not the solve's accuracy. At 1024^2 and 2048^2 on the smooth
#: field the bound is then 1.03-1.09x higher and the solve 3-9 % faster.
RESIDUAL_SOLVE_FMG_LEVELS = 0
#: The residual solve's most V-cycles after its start. One meets ``delta < 1`` on the smooth field at
#: 1024^2 and 2048^2 (0.1-0.2); at 4096^2 ``delta`` is 3.5 after one, and three meet the bound, which
#: saves the solve's second and third V-cycles and the barrier solve. The loop ends sooner where the
#: bound is met, where ``max y`` alone is above the limit, or where ``delta`` falls by less than half a
#: cycle (coefficient jumps: the barrier solve and conjugate gradients take over).
RESIDUAL_SOLVE_MAX_CYCLES = 4
#: Per-edge weights: bound the error by the residual solve (:func:`_residual_solve_bound`) after the
#: first iteration before making the barrier solve.
RESIDUAL_SOLVE_BOUND = True
#: The share of the tolerance the residual solve's floor ``eps D`` may take (through ``eps max z``,
#: ``max z`` guessed as the unit stencils' analytic value).
RESIDUAL_SOLVE_FLOOR = 0.1


def _residual_solve_bound(ops: MultigridOps, limit: float, zguess: float,
                          xmax: float = 0.0) -> tuple[float, float] | None:
    """An error bound of ``ops``' iterate by one more (scalar) solve: ``(max|D^-1 r|, bound)``, or None
    where the backend does not supply it (``ops.residual_solve``).

    ``A`` is an M-matrix, so the error ``e = A^-1 r`` of the iterate has ``|e| <= A^-1 |r|`` node by
    node (Euclidean over the coordinates: Minkowski's inequality, ``A^-1 >= 0``). For ``q = |r| + eps D``
    (``eps > 0``: ``q > 0``) and any ``y`` zero on the boundary with ``delta = max (q - A y) / q < 1``,
    ``A (y / (1 - delta)) >= q >= |r|``, so ``|e| <= y / (1 - delta)`` and ``max|e| <= max y / (1 -
    delta)``. Where the residual sits in a few places (after a V-cycle: near the boundary, on
    alternate rows), ``A^-1 |r|`` is near the true error while ``max|D^-1 r| max z`` and the band
    barriers are 20-100x above it: per-edge weights then stop one or two V-cycles sooner, without the
    barrier solve. ``y``: a full-multigrid start, then V-cycles until the bound is met (at most
    :data:`RESIDUAL_SOLVE_MAX_CYCLES`; fewer where it cannot be). ``eps`` (``RESIDUAL_SOLVE_FLOOR *
    limit / zguess``) keeps ``q`` positive and costs about ``eps max z``; it is at least
    ``64 u xmax`` (``xmax`` the boundary's largest coordinate), so that ``eps D`` also covers the
    float64 rounding of ``r`` (at most ``16 u |A| |x| <= 32 u D max|x|``, the iterate within twice the
    boundary's range), which keeps the bound rigorous where ``|r|`` is at its rounding floor. Where the
    bound is not met, the one returned is above ``limit`` (``inf`` where no ``y`` had ``delta < 1``); it
    holds still.
    """
    got = ops.residual_solve(max(RESIDUAL_SOLVE_FLOOR * limit / zguess, 64 * 2.0 ** -53 * xmax))
    if got is None:
        return None
    qops, step = got
    fmg(qops, RESIDUAL_SOLVE_FMG_LEVELS)
    if not qops.solution_max() <= 2.0 * limit:   # y well above the limit already: the bound cannot pass
        return step, math.inf
    bound, last = math.inf, math.inf
    for _ in range(RESIDUAL_SOLVE_MAX_CYCLES):
        vcycle(qops)
        delta, ymax = max(qops.relative_residual(), 0.0), qops.solution_max()
        if delta < 1.0:
            bound = ymax / (1.0 - delta)
        # met; or cannot be (max y is about max A^-1 q already); or y's residual no longer falls fast
        if bound <= limit or not ymax <= limit or not delta <= 0.5 * last:
            break
        last = delta
    return step, bound


def _ring(r: np.ndarray, put: tuple | None = None) -> tuple | None:
    """The boundary nodes of ``r`` (copies of its four sides), or, with ``put``, write them back."""
    sides = (np.s_[0], np.s_[-1], np.s_[:, 0], np.s_[:, -1])
    if put is None:
        return tuple(r[s].copy() for s in sides)
    for s, v in zip(sides, put):
        r[s] = v
    return None


#: The barrier solve for per-edge weights stops once ``delta`` (its Jacobi-scaled residual) is at
#: most this: ``max z`` is then bounded within ``1 / (1 - delta)``, at most 11 % above it. At 0.01
#: it took a V-cycle more after the full-multigrid start (delta 0.08 there on a smooth field at
#: 1024^2: 17 ms of a 200 ms solve), and the looser ``max z`` did not change a solve's cycles.
BARRIER_DELTA = 0.1
#: Most iterations of the barrier solve (V-cycles, then conjugate gradients where they are slow).
BARRIER_MAX_ITER = 200
#: Where the barrier solve's iterations cannot bound ``max z`` (extreme coefficient jumps: a
#: 59 x 19 grid of the paper's weights times 8 x 8 blocks of 10^6:1 stalled after 200 conjugate
#: gradients), grids of up to this many interior nodes take the exact barrier from a sparse
#: direct solve instead (128^2: well under a second, ``solvers.DIRECT_MAX_NODES``).
BARRIER_DIRECT_MAX_NODES = 128 * 128


def _barrier_max(problem: Problem, backend: Backend, levels: list[Level], spare: np.ndarray | None = None) -> float:
    """An upper bound of ``max z`` (:func:`~clothgrid.solvers.bounds.barrier_max`) by multigrid, with
    a rigorous correction.

    ``max z`` only needs an upper bound: for an approximation ``y`` of
    ``z = A^-1 D 1`` with ``delta = max |D^-1 (D 1 - A y)| < 1``, ``z <= y + delta z``
    node by node, so ``max z <= max y / (1 - delta)``. Iterations (V-cycles, then conjugate
    gradients where they are slow) run until ``delta <= BARRIER_DELTA``. ``spare``: dead memory the
    barrier solve's arrays may take (the solve's own coarse levels, :meth:`MultigridOps.spare`).
    """
    nu, nv = problem.shape
    rhs = problem.diagonal().reshape(nu - 2, nv - 2, 1)
    ops = backend.multigrid(levels, np.zeros((nu, nv, 1)), rhs=rhs, spare=spare)
    delta = math.inf
    if FULL_MULTIGRID_START:
        fmg(ops)        # from zero, plain V-cycles took 4 to reach delta <= 0.01 at 1024^2; after it, 1-2
        delta = ops.max_step()   # relative to |D^-1 D 1| = 1
    if not delta <= BARRIER_DELTA:
        def measure() -> tuple[float, float]:
            step = ops.max_step()
            return step, step
        delta, _ = _iterate(ops, measure, BARRIER_DELTA, BARRIER_MAX_ITER, True, [])
    if not delta < 1:
        if (nu - 2) * (nv - 2) <= BARRIER_DIRECT_MAX_NODES:   # small: the exact barrier, a direct solve
            return barrier_max(problem)
        raise InputError("multigrid could not bound the error for these weights: use solver 'direct'")
    # max(y) / (1 - delta): the same bits as max(y / (1 - delta)), division being monotone
    return ops.solution_max() / (1.0 - delta)
