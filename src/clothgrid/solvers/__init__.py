"""Solvers for the weighted length system, one calling convention for all.

Every solver is ``solve_<name>(problem, *, backend, tol, stop, max_iter,
progress) -> SolveResult`` (:mod:`clothgrid.solvers.problem`); :func:`solve`
dispatches by name and resolves ``"auto"``.

============  ==============================================================
``direct``    sparse LU (SuperLU): the paper's CPU baseline, any weights
``fdm``       fast diagonalisation: exact, separable weights only
``jacobi``    eq. (3) sweeps with the ``paper`` or the true ``error`` rule
``multigrid`` semi-coarsening multigrid with line relaxation, any weights
``auto``      by size: ``fdm`` (separable) or ``direct`` when small, else ``multigrid``
============  ==============================================================
"""

from __future__ import annotations

from typing import Callable

from ..errors import InputError
from ..weights import edge_contrast
from .direct import solve_direct
from .fdm import solve_fdm
from .jacobi import solve_jacobi
from .multigrid import solve_multigrid
from .problem import Problem, SolveResult

__all__ = ["SOLVERS", "choose_solver", "solve", "Problem", "SolveResult"]

SOLVERS = {"direct": solve_direct, "fdm": solve_fdm, "jacobi": solve_jacobi, "multigrid": solve_multigrid}


# Largest grids (nodes) where the exact solvers are the default on the CPU. fdm's solve is slower
# than multigrid's from about 200x200 on (warm, 2 cores, T-shirt front, paper weights: 16 against
# 6.5 ms at 257x257, 72 against 20 ms at 513x513, 302 against 70 ms at 1024x1024; 2026-11-26,
# docs/performance.md), but multigrid's first
# use in a process loads Numba and its kernels (about 0.35 s), which a length grid of up to
# 512x512 does not otherwise need; larger grids load Numba anyway (the quality kernel), and every
# real pattern piece at its default edge length stays on the exact solve.
FDM_MAX_NODES = 512 * 512
DIRECT_MAX_NODES = 128 * 128
# Per-edge weights whose neighbouring edges differ by at most SMOOTH_CONTRAST (a smooth field times the
# paper's weights: 5-9; 8 x 8 blocks of 10:1 at 65^2: 64): multigrid stops after one V-cycle on the
# residual solve's bound and beats the direct solve from about 64 x 64 nodes (warm, 2 cores, T-shirt
# front, smooth field: 2.0 against 6.7 ms at 65^2, 4.1 against 36.5 ms at 128^2). Coefficient jumps take
# conjugate gradients (30-40 iterations at 10^4:1), and the direct solve stays faster up to 128^2.
SMOOTH_CONTRAST = 20.0
DIRECT_MAX_NODES_SMOOTH = 64 * 64


def choose_solver(separable: bool, nu: int, nv: int,
                  contrast: float | Callable[[], float] | None = None) -> str:
    """The fastest CPU solver that meets the tolerance, by size and weights.

    Fast diagonalisation (separable weights) and the sparse direct solve win
    on small grids; multigrid's O(n) cycles win above ``FDM_MAX_NODES`` and
    ``DIRECT_MAX_NODES`` nodes, and for per-edge weights whose ``contrast``
    (:func:`clothgrid.weights.edge_contrast`) is at most ``SMOOTH_CONTRAST``
    above ``DIRECT_MAX_NODES_SMOOTH``. ``contrast`` may be a function giving it:
    it is then called only on grids where it changes the answer (a pass over
    the weights that larger grids would pay for nothing).
    """
    if separable:
        return "fdm" if nu * nv <= FDM_MAX_NODES else "multigrid"
    if nu * nv <= DIRECT_MAX_NODES_SMOOTH:
        return "direct"
    if nu * nv > DIRECT_MAX_NODES:
        return "multigrid"
    c = contrast() if callable(contrast) else contrast
    return "multigrid" if c is not None and c <= SMOOTH_CONTRAST else "direct"


def solve(problem: Problem, solver: str = "auto", **options) -> tuple[str, SolveResult]:
    """Solve ``problem`` with the named solver; returns ``(name used, result)``."""
    if solver == "auto":
        w = problem.weights
        solver = choose_solver(w.factors is not None, *problem.shape, lambda: edge_contrast(w.wu, w.wv))
    try:
        func = SOLVERS[solver]
    except KeyError:
        raise InputError(f"unknown solver {solver!r}: use one of auto, {', '.join(SOLVERS)}") from None
    return solver, func(problem, **options)
