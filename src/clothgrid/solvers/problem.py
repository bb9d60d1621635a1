"""The linear problem every solver solves (MATH.md).

For interior nodes ``(i, j)`` the weighted length functional's minimum solves

    (wu[i-1,j] + wu[i,j] + wv[i,j-1] + wv[i,j]) R[i,j]
        - wu[i-1,j] R[i-1,j] - wu[i,j] R[i+1,j] - wv[i,j-1] R[i,j-1] - wv[i,j] R[i,j+1] = 0

with the boundary nodes fixed: ``A x = b``, ``A`` symmetric positive definite,
one matrix for x, y and z.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp

from ..weights import Weights, interior_diagonal

__all__ = ["Problem", "SolveResult"]


@dataclass
class Problem:
    """A grid to solve: boundary nodes (and an initial guess) plus weights.

    Attributes
    ----------
    r0 : numpy.ndarray
        ``(nu, nv, 3)`` initial grid; its boundary nodes are the fixed data.
    weights : Weights
        Edge weights.
    scale : float
        Length that tolerances are relative to (the boundary's bounding-box
        diagonal).
    overwrite : bool
        The solver may return its solution in ``r0`` itself (no second grid
        in memory: 400 MB at 4096 x 4096). :func:`clothgrid.generate` sets it
        for the initial grid it builds.
    """

    r0: np.ndarray
    weights: Weights
    scale: float
    overwrite: bool = False

    @property
    def shape(self) -> tuple[int, int]:
        return self.r0.shape[0], self.r0.shape[1]

    @property
    def active_coords(self) -> list[int]:
        """Coordinates with non-zero boundary data; the others solve to zero."""
        r = self.r0
        ring = np.concatenate([r[:, 0], r[:, -1], r[0], r[-1]])
        return [c for c in range(3) if np.any(ring[:, c] != 0.0)]

    def interior_matrix(self) -> sp.csc_matrix:
        """The SPD matrix ``A`` over interior nodes, flat index ``(i-1)(nv-2) + (j-1)``."""
        nu, nv = self.shape
        wu, wv = self.weights.wu, self.weights.wv
        m, n = nu - 2, nv - 2
        east, north = wu[1:, 1:-1], wv[1:-1, 1:]          # edges to (i+1, j) and (i, j+1)
        diag = self.diagonal().ravel()
        idx = np.arange(m * n).reshape(m, n)
        rows = [idx.ravel()]
        cols = [idx.ravel()]
        vals = [diag]
        for w, a, b in ((east[:-1, :], idx[:-1, :], idx[1:, :]), (north[:, :-1], idx[:, :-1], idx[:, 1:])):
            for p, q in ((a, b), (b, a)):
                rows.append(p.ravel())
                cols.append(q.ravel())
                vals.append(-w.ravel())
        import scipy.sparse as sp   # on first use (direct solves, the barrier bound)

        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m * n, m * n))

    def interior_rhs(self) -> np.ndarray:
        """``b`` as an ``(nu-2, nv-2, 3)`` array: the boundary nodes' pull on their neighbours."""
        r = self.r0
        wu, wv = self.weights.wu, self.weights.wv
        b = np.zeros((r.shape[0] - 2, r.shape[1] - 2, 3))
        b[0] += wu[0, 1:-1, None] * r[0, 1:-1]
        b[-1] += wu[-1, 1:-1, None] * r[-1, 1:-1]
        b[:, 0] += wv[1:-1, 0, None] * r[1:-1, 0]
        b[:, -1] += wv[1:-1, -1, None] * r[1:-1, -1]
        return b

    def diagonal(self) -> np.ndarray:
        """The diagonal of ``A`` as ``(nu-2, nv-2)``."""
        return interior_diagonal(self.weights.wu, self.weights.wv)

    def with_interior(self, y: np.ndarray) -> np.ndarray:
        """A full grid: the boundary of ``r0`` and the interior ``y`` ``(nu-2, nv-2, 3)``."""
        r = self.r0.copy()
        r[1:-1, 1:-1] = y
        return r


@dataclass
class SolveResult:
    """What a solver returns.

    ``error_estimate`` is relative to :attr:`Problem.scale`; ``bound`` says
    whether it is a guaranteed bound (``True``) or an estimate.
    """

    points: np.ndarray
    iterations: int
    error_estimate: float
    converged: bool
    bound: bool = True
    extra: dict | None = None
