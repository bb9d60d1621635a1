"""``jacobi``: the paper's per-node update, eq. (3), one sweep at a time.

Two stopping rules:

``stop="paper"``
    the paper's: stop when no node moved more than ``tol * scale`` in the last
    sweep. Cheap, and not an error bound: Jacobi contracts by ``1 - O(1/n^2)``
    per sweep, so a small step can leave nodes far from the solution.
``stop="error"`` (default)
    stop when the a-posteriori bound of :mod:`clothgrid.solvers.bounds`,
    ``last step * max z``, guarantees every node within ``tol * scale`` of the
    exact solution. The bound is computed from the step every sweep makes
    anyway, so checking it costs nothing.
"""

from __future__ import annotations

import math
import time
from typing import Callable

from ..backends.protocol import Backend
from ..errors import InputError
from .bounds import barrier_max
from .problem import Problem, SolveResult

__all__ = ["solve_jacobi", "default_max_iter"]


def default_max_iter(nu: int, nv: int) -> int:
    """Enough sweeps for Jacobi to meet a true tolerance of about 2^-12 (about 8 n^2)."""
    return max(1000, 8 * max(nu, nv) ** 2)


def solve_jacobi(problem: Problem, *, backend: Backend, tol: float, stop: str = "error", max_iter: int | None = None,
                 progress: Callable[[str], None] | None = None, progress_seconds: float = 2.0,
                 **_: object) -> SolveResult:
    """Iterate eq. (3) until the stopping rule holds or ``max_iter`` sweeps are done."""
    if stop not in ("error", "paper"):
        raise InputError(f"unknown stop rule {stop!r}: use 'error' or 'paper'")
    nu, nv = problem.shape
    if max_iter is None:
        max_iter = default_max_iter(nu, nv)
    if max_iter < 1:
        raise InputError(f"max_iter must be at least 1, not {max_iter}")
    # The barrier max turns a step into a guaranteed error bound; without the
    # analytic barrier it costs a direct solve, which only the true rule needs.
    zmax = barrier_max(problem) if (stop == "error" or problem.weights.unit_stencil) else math.nan
    limit = tol * problem.scale / (zmax if stop == "error" else 1.0)
    run = backend.jacobi_sweeper(problem, stop=stop)   # a JacobiSweeper (clothgrid.backends.protocol)
    step = math.inf
    it = 0
    last_report, last_it, last_step = time.perf_counter(), 0, None
    try:
        while it < max_iter:
            done, step = run.sweeps(max_iter - it, limit)
            it += done
            if step <= limit:
                break
            if progress and (now := time.perf_counter()) - last_report >= progress_seconds:
                msg = f"jacobi: {it} sweeps, last step {step / problem.scale:.3g}"
                if stop == "error":
                    msg += f", error bound {step * zmax / problem.scale:.3g} (tol {tol:.3g})"
                if last_step and 0 < step < last_step:
                    rate = math.log(last_step / step) / (it - last_it)
                    msg += f", about {math.log(step / limit) / rate:.3g} sweeps to go"
                progress(msg)
                last_report, last_it, last_step = now, it, step
        converged = step <= limit
        points, bound_step = run.result(step)
        extra = {"last_step": step / problem.scale, **run.extra()}
    finally:
        run.close()
    err = bound_step * zmax / problem.scale if not math.isnan(zmax) else math.nan
    return SolveResult(points, iterations=it, error_estimate=err, converged=converged, bound=not math.isnan(zmax),
                       extra=extra)
