"""A-posteriori error bounds for any approximate solution.

``A`` (MATH.md) is an M-matrix, so ``(D^-1 A)^-1 >= 0`` and for any grid ``R``
with the right boundary nodes, ``s = D^-1 (b - A R)`` (the step one Jacobi sweep
would take) bounds the error node by node:

    |R*[i,j] - R[i,j]| <= max|s| * z[i,j],     where D^-1 A z = 1, z >= 0 on the boundary.

For separable weights with constant ``cu``, ``cv`` (the paper's and uniform
weights) ``z[i,j] = i (nu-1-i) + j (nv-1-j)`` solves ``D^-1 A z = 1`` exactly, so
the bound costs one residual evaluation. For other weights ``z`` takes one
extra linear solve (``A z = D 1``), done with whatever factorisation is at hand.
Distances are Euclidean per node (the triangle inequality carries the bound
over from one coordinate to the 3-vector).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..backends.protocol import Backend
from .problem import Problem

__all__ = ["barrier_max", "error_bound"]


def _analytic_barrier_max(nu: int, nv: int) -> float:
    hu, hv = (nu - 1) // 2, (nv - 1) // 2
    return float(hu * (nu - 1 - hu) + hv * (nv - 1 - hv))


def barrier_max(problem: Problem, solve: Callable[[np.ndarray], np.ndarray] | None = None) -> float:
    """``max z`` of the barrier function ``D^-1 A z = 1``.

    Parameters
    ----------
    problem : Problem
    solve : callable, optional
        ``solve(rhs)`` returning ``A^-1 rhs`` for an ``(nu-2)*(nv-2)`` vector;
        needed only for weights without the analytic barrier. Without it a
        sparse direct solve is made.
    """
    nu, nv = problem.shape
    if problem.weights.unit_stencil:
        return _analytic_barrier_max(nu, nv)
    d = problem.diagonal().ravel()
    if solve is None:
        from scipy.sparse.linalg import splu

        lu = splu(problem.interior_matrix(), permc_spec="MMD_AT_PLUS_A")
        solve = lu.solve
    return float(np.max(solve(d)))


def error_bound(points: Any, problem: Problem, backend: Backend, zmax: float, weights: tuple | None = None) -> float:
    """Guaranteed bound on ``max |R* - R|`` (absolute) for the grid ``points``.

    ``weights``: ``(wu, wv)`` as arrays of the backend where ``points`` lives
    (a GPU's); by default the problem's own.
    """
    wu, wv = weights if weights is not None else (problem.weights.wu, problem.weights.wv)
    return backend.max_step(points, wu, wv) * zmax
