"""CPU backend: NumPy array operations and fused Numba kernels over ``(nu, nv, 3)`` grids.

Hot loops (the Jacobi sweep) are Numba kernels, parallel over rows ``i`` and
compiled or loaded from cache on first use; one-shot operations (residual,
error bound) are plain NumPy, so a direct or fdm solve never pays Numba's
start-up. Edge weights follow :mod:`clothgrid.weights`: ``wu (nu-1, nv)``,
``wv (nu, nv-1)``; boundary nodes are never written.

It satisfies :class:`~clothgrid.backends.protocol.Backend` like the device
backends do; where it has nothing to do it says so with a no-op: no device
(``require`` returns None, ``describe`` is ``{}``, ``device_bytes`` and
``check_size`` count nothing: host memory is checked by
:func:`clothgrid.memory.check_memory`), and ``solvers`` is empty because every
solver runs here and ``auto`` picks by size.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..multigrid_levels import Level
from ..weights import interior_diagonal
from .protocol import ProblemData

if TYPE_CHECKING:   # annotations only: the operations' modules load on first use (Numba)
    from ..heat_multigrid import HeatHierarchy
    from ._cpu_heat import CpuHeatOps
    from ._cpu_multigrid import CpuMultigrid

__all__ = ["name", "solvers", "require", "available", "describe", "summary", "device_bytes", "check_size",
           "array_module", "sweep", "max_step", "residual", "multigrid", "jacobi_sweeper", "heat_ops",
           "HostJacobi"]

name = "cpu"
#: Solvers that run on a device: none. Every solver runs on the host, and ``auto`` picks by size
#: (:func:`clothgrid.solvers.choose_solver`).
solvers: tuple[str, ...] = ()


def require() -> None:
    """Nothing to check: the host is always there. Returns None (there is no device object)."""
    return None


def available() -> tuple[bool, str]:
    """Always ``(True, summary())``."""
    return True, summary()


def describe() -> dict[str, Any]:
    """No keys for a grid's info: ``{}`` (the device backends add ``gl_*`` and ``cuda_*`` keys)."""
    return {}


def summary() -> str:
    """One line: what runs the solvers."""
    return "the host CPU (NumPy, SciPy and Numba)"


def device_bytes(solver: str, nu: int, nv: int, coords: int = 3, separable: bool = False) -> int:
    """0: nothing is allocated on a device (host memory: :func:`clothgrid.memory.estimate_bytes`)."""
    return 0


def check_size(nu: int, nv: int, solver: str, host_bytes: int = 0, coords: int = 3, separable: bool = False) -> int:
    """Nothing to check on a device; returns 0. Host memory is checked by :func:`clothgrid.memory.check_memory`."""
    return 0


def array_module() -> ModuleType:
    """NumPy: the backend's arrays are host arrays."""
    return np


def sweep(r: np.ndarray, out: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> float:
    """One Jacobi sweep (eq. 3 with per-edge weights) from ``r`` into ``out``.

    ``out`` must already hold the boundary nodes. Returns the largest
    Euclidean node step ``max |out[i, j] - r[i, j]|`` of the sweep.
    """
    from ._cpu_kernels import _sweep

    return float(_sweep(r, out, wu, wv))


def residual(r: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """``b - A r`` over the interior nodes, as an ``(nu-2, nv-2, 3)`` array.

    The unscaled residual of the SPD system of :mod:`clothgrid.solvers.problem`:
    the sum over the four edges of ``w * (R[neighbour] - R[i, j])``.
    """
    c = r[1:-1, 1:-1]
    out = wu[:-1, 1:-1, None] * (r[:-2, 1:-1] - c)
    out += wu[1:, 1:-1, None] * (r[2:, 1:-1] - c)
    out += wv[1:-1, :-1, None] * (r[1:-1, :-2] - c)
    out += wv[1:-1, 1:, None] * (r[1:-1, 2:] - c)
    return out


def max_step(r: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> float:
    """The largest step a Jacobi sweep would make from ``r``, without making it.

    This is ``max |D^-1 (b - A r)|`` (Euclidean per node): the Jacobi-scaled
    residual, used in the a-posteriori error bound of
    :mod:`clothgrid.solvers.bounds`.
    """
    if r.shape[0] < 3 or r.shape[1] < 3:
        return 0.0
    s = np.linalg.norm(residual(r, wu, wv), axis=-1) / interior_diagonal(wu, wv)
    return float(s.max())


def multigrid(levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None,
              spare: np.ndarray | None = None) -> CpuMultigrid:
    """The multigrid operations (:class:`~clothgrid.backends.protocol.MultigridOps`) on this backend.

    ``levels`` from :func:`~clothgrid.multigrid_levels.build_hierarchy`; ``x0``
    the ``(nu, nv, k)`` level-0 iterate, read once; ``rhs`` the optional
    ``(nu-2, nv-2, k)`` interior right-hand side; ``spare`` dead memory that holds the coarse levels
    and scratch as far as they fit (:class:`~clothgrid.backends._cpu_multigrid.CpuMultigrid`). The
    Numba kernels load on first use.
    """
    from ._cpu_multigrid import CpuMultigrid

    return CpuMultigrid(levels, x0, rhs, spare)


def jacobi_sweeper(problem: ProblemData, *, stop: str = "error") -> HostJacobi:
    """The Jacobi sweep loop (:class:`~clothgrid.backends.protocol.JacobiSweeper`) on host arrays.

    Every sweep's step is known at once (:func:`sweep` returns it), so ``stop`` changes nothing here.
    """
    return HostJacobi(problem)


def heat_ops(hierarchy: HeatHierarchy) -> CpuHeatOps:
    """The heat solver's operations (:class:`~clothgrid.backends.protocol.HeatOps`) on host arrays: the
    Numba kernels of :mod:`clothgrid._heat_kernels`, float64."""
    from ._cpu_heat import CpuHeatOps

    return CpuHeatOps(hierarchy)


class HostJacobi:
    """Eq. (3) sweeps on host arrays, one :func:`sweep` at a time, ping-ponging between two grids.

    Parameters
    ----------
    problem : ProblemData
        The grid to solve (its ``r0`` is copied) and its weights.
    """

    def __init__(self, problem: ProblemData):
        self.wu, self.wv = problem.weights.wu, problem.weights.wv
        self.a = problem.r0.copy()
        self.b = self.a.copy()

    def sweeps(self, n: int, limit: float) -> tuple[int, float]:
        """One sweep (the step is checked after each anyway); returns ``(1, its step)``."""
        step = sweep(self.a, self.b, self.wu, self.wv)
        self.a, self.b = self.b, self.a
        return 1, step

    def result(self, step: float) -> tuple[np.ndarray, float]:
        """The last grid and ``step``: the last sweep's step bounds the grid it produced too
        (``J z <= z``, :mod:`clothgrid.solvers.bounds`)."""
        return self.a, step

    def extra(self) -> dict[str, Any]:
        """No keys: ``{}``."""
        return {}

    def close(self) -> None:
        """Nothing to free."""
