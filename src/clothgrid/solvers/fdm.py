"""``fdm``: the fast diagonalisation method for separable weights.

With ``wu = cu dv^T`` and ``wv = du cv^T`` the interior system is the Sylvester
equation ``Ku Y Dv + Du Y Kv = B`` (``Ku``, ``Kv`` weighted second-difference
matrices, ``Du``, ``Dv`` diagonal). With the generalised eigenpairs
``Ku Phi = Du Phi Lambda`` (``Phi^T Du Phi = I``) and ``Kv Psi = Dv Psi M``,

    Y = Phi [ (Phi^T B Psi) / (lambda_a + mu_b) ] Psi^T,

exact up to rounding: two tridiagonal eigenproblems and four dense products.
"""

from __future__ import annotations

import contextlib
from typing import Callable

import numpy as np

from ..backends.protocol import Backend
from ..blas_threads import host_threads
from ..errors import InputError
from .bounds import barrier_max, error_bound
from .problem import Problem, SolveResult

__all__ = ["solve_fdm", "generalized_eig"]

#: Up to this many nodes a solve on the host keeps :func:`~clothgrid.generate`'s one BLAS thread
#: (:mod:`clothgrid.blas_threads`): two threads gained nothing there (74 ms at 512^2 on two
#: cores) and, spinning after the solve, slowed the Numba kernels after it; above it the solve
#: takes the host's BLAS threads back (:func:`~clothgrid.blas_threads.host_threads`: 427 -> 327 ms
#: at 1024^2).
BLAS_ONE_THREAD_NODES = 512 * 512


def generalized_eig(c: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of ``K phi = lam D phi`` for the 1D problem with edge weights ``c``.

    ``c`` holds the ``n+1`` edge weights of a line of ``n`` interior nodes
    (``K`` tridiagonal, ``K[a, a] = c[a] + c[a+1]``, ``K[a, a+1] = -c[a+1]``),
    ``d`` the ``n`` positive diagonal entries of ``D``. Returns ``lam`` and
    ``Phi`` with ``Phi^T D Phi = I``, via the symmetric tridiagonal matrix
    ``D^-1/2 K D^-1/2``.
    """
    from scipy.linalg import eigh_tridiagonal   # on first use: scipy.linalg costs 0.3-1 s to import

    s = 1.0 / np.sqrt(d)
    diag = (c[:-1] + c[1:]) * s * s
    off = -c[1:-1] * s[:-1] * s[1:]
    lam, v = eigh_tridiagonal(diag, off)
    return lam, v * s[:, None]


class FDM:
    """The fast diagonalisation of one separable problem, reusable for many right-hand sides.

    The eigenpairs are computed on the host (SciPy) and kept as arrays of
    ``xp`` (NumPy, or CuPy for the cuda backend: uploaded once, the products
    then run on the GPU as cuBLAS GEMMs).
    """

    def __init__(self, weights, nu: int, nv: int, xp=np):
        if weights.factors is None:
            raise InputError("solver 'fdm' needs separable weights ('paper' or 'uniform'); "
                             "use solver='direct' or 'auto' for per-edge weights")
        cu, dv, du, cv = weights.factors
        self.xp = xp
        lam, phi = generalized_eig(cu, du[1:-1])
        self.lam, self.phi = xp.asarray(lam), xp.asarray(phi)
        if nu == nv and np.array_equal(cv, cu) and np.array_equal(dv, du):
            self.mu, self.psi = self.lam, self.phi
        else:
            mu, psi = generalized_eig(cv, dv[1:-1])
            self.mu, self.psi = xp.asarray(mu), xp.asarray(psi)

    def apply(self, b, coords: list[int]):
        """``A^-1 b`` for an ``(m, n, 3)`` right-hand side of ``xp``, only for ``coords`` (others zero)."""
        xp = self.xp
        y = xp.zeros_like(b)
        q = len(coords)
        if not q:
            return y
        phi, psi = self.phi, self.psi
        # Coordinates side by side (left products) or stacked (right products): one GEMM each.
        t = phi.T @ xp.concatenate([b[:, :, c] for c in coords], axis=1)       # (m, q n)
        t = xp.concatenate(xp.split(t, q, axis=1), axis=0) @ psi               # (q m, n)
        t /= xp.tile(self.lam[:, None] + self.mu[None, :], (q, 1))
        t = t @ psi.T
        t = phi @ xp.concatenate(xp.split(t, q, axis=0), axis=1)               # (m, q n)
        for c, yc in zip(coords, xp.split(t, q, axis=1)):
            y[:, :, c] = yc
        return y


def solve_fdm(problem: Problem, *, backend: Backend, tol: float = 2.0**-12, max_refine: int = 3,
              progress: Callable[[str], None] | None = None, **_: object) -> SolveResult:
    """Solve exactly by fast diagonalisation (separable weights), refined until the bound meets ``tol``.

    The products lose accuracy as the weights' range grows (about 1e-11 of the
    piece's size at 1024 x 1024 with the paper's weights); each refinement
    step solves for the correction from the residual, at the cost of the four
    products again. At most ``max_refine`` steps are made.

    The backend's ``array_module()`` holds the grid, the weights and the
    products (CuPy for cuda: on the GPU; NumPy on the host); the residual and
    the bound are the backend's own.
    """
    nu, nv = problem.shape
    xp = backend.array_module()
    with (host_threads() if xp is np and nu * nv > BLAS_ONE_THREAD_NODES else contextlib.nullcontext()):
        return _solve_fdm(problem, backend, xp, tol, max_refine, progress)


def _solve_fdm(problem: Problem, backend: Backend, xp, tol: float, max_refine: int,
               progress: Callable[[str], None] | None) -> SolveResult:
    nu, nv = problem.shape
    if progress:
        progress(f"fdm: eigenproblems of size {nu - 2} and {nv - 2}")
    fdm = FDM(problem.weights, nu, nv, xp)
    coords = problem.active_coords
    wu, wv = xp.asarray(problem.weights.wu), xp.asarray(problem.weights.wv)
    points = xp.asarray(problem.r0).copy()
    points[1:-1, 1:-1] = fdm.apply(xp.asarray(problem.interior_rhs()), coords)
    zmax = barrier_max(problem)
    err = error_bound(points, problem, backend, zmax, (wu, wv)) / problem.scale
    refinements = 0
    # Refine while the guaranteed bound is not comfortably inside tol.
    while err > 0.5 * tol and refinements < max_refine:
        refinements += 1
        if progress:
            progress(f"fdm: error bound {err:.3g} > tol/2, refinement {refinements}")
        points[1:-1, 1:-1] += fdm.apply(backend.residual(points, wu, wv), coords)
        err = error_bound(points, problem, backend, zmax, (wu, wv)) / problem.scale
    return SolveResult(getattr(xp, "asnumpy", np.asarray)(points), iterations=refinements, error_estimate=err,
                       converged=err <= tol, extra={"refinements": refinements})
