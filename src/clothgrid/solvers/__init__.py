"""Solvers for the weighted length system, one calling convention for all.

Every solver is ``solve_<name>(problem, *, backend, tol, stop, max_iter,
progress) -> SolveResult`` (:mod:`clothgrid.solvers.problem`); :func:`solve`
dispatches by name and resolves ``"auto"``.

============  ==============================================================
``direct``    sparse LU (SuperLU): the paper's CPU baseline, any weights
``fdm``       fast diagonalisation: exact, separable weights only
``jacobi``    eq. (3) sweeps with the ``paper`` or the true ``error`` rule
``auto``      ``fdm`` for separable weights, else ``direct``
============  ==============================================================
"""

from __future__ import annotations

from ..errors import InputError
from ..weights import Weights
from .direct import solve_direct
from .fdm import solve_fdm
from .jacobi import solve_jacobi
from .problem import Problem, SolveResult

__all__ = ["SOLVERS", "choose_solver", "solve", "Problem", "SolveResult"]

SOLVERS = {"direct": solve_direct, "fdm": solve_fdm, "jacobi": solve_jacobi}


def choose_solver(weights: Weights) -> str:
    """The fastest solver that meets the tolerance for these weights."""
    return "fdm" if weights.factors is not None else "direct"


def solve(problem: Problem, solver: str = "auto", **options) -> tuple[str, SolveResult]:
    """Solve ``problem`` with the named solver; returns ``(name used, result)``."""
    if solver == "auto":
        solver = choose_solver(problem.weights)
    try:
        func = SOLVERS[solver]
    except KeyError:
        raise InputError(f"unknown solver {solver!r}: use one of auto, {', '.join(SOLVERS)}") from None
    return solver, func(problem, **options)
