"""What a backend supplies: the :class:`Backend` protocol and the operations its solvers drive.

A backend is a module (``clothgrid.backends.cpu``, ``.gl``, ``.cuda``) that
satisfies :class:`Backend` structurally: every attribute below is present and,
where it is a function, callable. Solvers never probe a backend with
``hasattr``: where a backend has nothing to do it supplies a no-op (the cpu
backend's ``describe`` returns ``{}``, its ``check_size`` checks nothing on a
device). The objects a backend's factories return satisfy
:class:`MultigridOps` (``multigrid``) and :class:`JacobiSweeper`
(``jacobi_sweeper``) and :class:`HeatOps` (``heat_ops``, the heat solver's), every
operation present.

The backends are found by name through the registry of
:mod:`clothgrid.backends` (:data:`~clothgrid.backends.REGISTRY`), loaded on
demand. ``tests/test_architecture.py`` checks every backend module and every
operations class against these protocols; ``docs/architecture.md``
says how to add a backend or a solver.

This module imports nothing of :mod:`clothgrid.solvers` (the solvers import it):
the multigrid hierarchy that :meth:`Backend.multigrid` takes is plain data from
:mod:`clothgrid.multigrid_levels`, and a problem is read through
:class:`ProblemData`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from ..multigrid_levels import Level
from ..weights import Weights

if TYPE_CHECKING:   # annotations only: heat_multigrid loads Numba
    from ..heat_multigrid import HeatHierarchy

__all__ = ["Backend", "MultigridOps", "NoVectors", "JacobiSweeper", "HeatOps", "ProblemData", "members", "BACKEND_MEMBERS",
           "MULTIGRID_OPERATIONS", "JACOBI_OPERATIONS", "HEAT_OPERATIONS"]


class ProblemData(Protocol):
    """What a backend reads of a problem: :class:`clothgrid.solvers.problem.Problem` is one.

    Backends take the solvers' problem by this shape and never import
    :mod:`clothgrid.solvers` (which imports them).

    Attributes
    ----------
    r0 : numpy.ndarray
        ``(nu, nv, 3)`` initial grid; its boundary nodes are the fixed data.
    weights : Weights
        Edge weights.
    """

    r0: np.ndarray
    weights: Weights


@runtime_checkable
class MultigridOps(Protocol):
    """The operations :func:`~clothgrid.solvers.multigrid.solve_multigrid` drives on a backend.

    The backend holds, per level ``l``, the iterate ``x[l]`` and right-hand side
    ``b[l]``; level 0's iterate is the grid itself (boundary nodes fixed, ``b``
    zero unless given), coarser levels hold corrections with zero boundary.
    :func:`~clothgrid.solvers.multigrid.vcycle` uses ``smooth``, ``restrict``
    and ``prolong``; :func:`~clothgrid.solvers.multigrid.fmg` (the full
    multigrid start) also ``restrict_full`` and ``prolong_full``.

    Attributes
    ----------
    levels : int
        Number of levels, finest (0) first.
    """

    levels: int

    def smooth(self, level: int, reverse: bool = False) -> None:
        """One zebra line sweep on ``level``: even rows then odd rows (odd then even if ``reverse``)."""

    def restrict(self, level: int) -> None:
        """``b[l+1] = P^T (b[l] - A_l x[l])`` and ``x[l+1] = 0``, right after a pre-smoothing sweep.

        A backend may use that the odd rows' residual is then zero.
        """

    def prolong(self, level: int) -> None:
        """``x[l] += P x[l+1]`` where the next (reversed) sweep needs it: at least on the even rows."""

    def restrict_full(self, level: int) -> None:
        """Full-multigrid start: ``b[l+1] = P^T (b[l] - A_l x[l])`` with every row's residual; ``x[l+1] = 0``."""

    def prolong_full(self, level: int) -> None:
        """Full-multigrid start: ``x[l] += P x[l+1]`` on every row (odd rows the mean of their neighbours)."""

    def max_step(self) -> float:
        """``max |D^-1 (b - A x)|`` over level 0's interior nodes (Euclidean per node), in float64.

        Reads one float back from a device: the operations issued before it have finished.
        """

    def band_steps(self, barriers: Any) -> np.ndarray | None:
        """:func:`~clothgrid.solvers.bounds.band_steps`' table of level 0's iterate for a
        :class:`~clothgrid.solvers.bounds.BandBarriers` (unit-stencil or per-edge weights), for the error
        bound by band barriers; None where the backend does not compute it (the solve then
        uses :meth:`max_step` times ``max z``, looser by 5-1000x, and so more V-cycles).
        """

    def residual_solve(self, eps: float) -> "tuple[MultigridOps, float] | None":
        """For the residual solve's error bound (``solvers.multigrid._residual_solve_bound``, per-edge
        weights): new one-coordinate operations on the same hierarchy for ``A y = q``, ``q = |b - A x| +
        eps D`` of this iterate (Euclidean over the coordinates), ``y`` zero, whose
        ``relative_residual()`` returns ``max (q - A y) / q`` over the interior nodes; with this
        iterate's :meth:`max_step`. The new operations may use this solve's dead memory (its coarse
        levels between cycles). None where the backend does not supply it (the solve then takes the
        barrier solve's ``max z``).
        """

    def relative_residual(self) -> float:
        """``max (b - A x) / b`` over level 0's interior nodes, for operations made by
        :meth:`residual_solve` (a positive right-hand side)."""

    def solution(self) -> np.ndarray:
        """Level 0's iterate as a float64 ``(nu, nv, k)`` host array."""

    def solution_into(self, out: np.ndarray) -> None:
        """Write level 0's iterate into the host array ``out`` (``(nu, nv, k)``, any strides)."""

    def solution_max(self) -> float:
        """The largest value of level 0's iterate over the interior nodes, first coordinate (the
        barrier solve's ``max z``), without a host copy of the grid where the backend can; it ends
        the solve where :meth:`solution` does."""

    # Conjugate gradients around the V-cycle (clothgrid.solvers.multigrid.ConjugateGradients) use
    # level-0 vectors of the backend's own (zero on the boundary ring, ``k`` coordinates); scalars
    # are per coordinate, ``(k,)`` float64 arrays.

    def vector(self) -> Any | None:
        """A new level-0 vector, zero; None where the backend has none (then the solve takes
        V-cycles only, and none of the operations below is called)."""

    def residual(self, r: Any) -> None:
        """``r = b - A x`` of level 0's iterate, on the interior nodes."""

    def apply(self, p: Any, q: Any) -> np.ndarray:
        """``q = A p`` on level 0; returns ``p . q`` per coordinate."""

    def dot(self, a: Any, b: Any) -> np.ndarray:
        """``a . b`` per coordinate."""

    def axpy(self, r: Any, p: Any, q: Any, alpha: np.ndarray) -> None:
        """``x += alpha p`` (level 0's iterate; its boundary nodes keep their bits), ``r -= alpha q``."""

    def xpay(self, p: Any, z: Any, beta: np.ndarray) -> None:
        """``p = z + beta p``."""

    def bind(self, r: Any | None, z: Any | None) -> None:
        """Make ``r`` level 0's right-hand side and ``z`` (set to zero) its iterate, so that a V-cycle
        makes ``z = M r``; ``bind(None, None)`` brings back the iterate and right-hand side."""

    def synchronize(self) -> None:
        """Wait until the device has done the work issued so far (a no-op where nothing is queued)."""

    def spare(self) -> np.ndarray | None:
        """Host memory this object holds whose contents are dead until its next full-multigrid start
        or V-cycle (the cpu's coarse levels and line-solve scratch), as one C-contiguous array: another
        solve run in between may take it as its ``spare`` (the barrier solve of per-edge weights does,
        instead of fresh pages). None where there is none (the devices')."""

    def extra(self) -> dict[str, Any]:
        """Keys the solve adds to its result's info (e.g. the gl backend's pass counts); ``{}`` if none."""


class NoVectors:
    """The conjugate-gradient operations of a :class:`MultigridOps` without level-0 vectors (the gl
    backend's: its level 0 is float32 textures with a float64 fold): :meth:`vector` is None, so the
    solve keeps V-cycles and calls none of the others."""

    def vector(self) -> None:
        """None: no level-0 vectors on this backend."""
        return None

    def _missing(self) -> NotImplementedError:
        return NotImplementedError(f"{type(self).__name__} has no level-0 vectors (vector() is None)")

    def residual(self, r: Any) -> None:
        """Not on this backend."""
        raise self._missing()

    def apply(self, p: Any, q: Any) -> np.ndarray:
        """Not on this backend."""
        raise self._missing()

    def dot(self, a: Any, b: Any) -> np.ndarray:
        """Not on this backend."""
        raise self._missing()

    def axpy(self, r: Any, p: Any, q: Any, alpha: np.ndarray) -> None:
        """Not on this backend."""
        raise self._missing()

    def xpay(self, p: Any, z: Any, beta: np.ndarray) -> None:
        """Not on this backend."""
        raise self._missing()

    def bind(self, r: Any | None, z: Any | None) -> None:
        """Not on this backend."""
        raise self._missing()


@runtime_checkable
class JacobiSweeper(Protocol):
    """The sweep loop :func:`~clothgrid.solvers.jacobi.solve_jacobi` drives on a backend."""

    def sweeps(self, n: int, limit: float) -> tuple[int, float]:
        """At most ``n`` sweeps, stopping after the first whose step is ``<= limit``.

        Returns
        -------
        (int, float)
            Sweeps made and the last sweep's step (absolute).
        """

    def result(self, step: float) -> tuple[np.ndarray, float]:
        """The grid (float64 ``(nu, nv, 3)`` host array) and the step that, times ``max z``, bounds its error."""

    def extra(self) -> dict[str, Any]:
        """Keys the solve adds to its result's info; ``{}`` if none."""

    def close(self) -> None:
        """Free what the sweeper holds (device textures); a no-op where there is nothing."""


@runtime_checkable
class HeatOps(Protocol):
    """The operations the heat solver's V-cycle and conjugate gradients drive on a backend.

    :func:`clothgrid.heat_multigrid.vcycle` and :func:`~clothgrid.heat_multigrid.pcg` are written once
    against these; ``Backend.heat_ops(hierarchy)`` returns them for a
    :class:`~clothgrid.heat_multigrid.HeatHierarchy` (black-box multigrid, built on the CPU: the backend
    uploads its arrays). Vectors are the backend's own (host arrays, textures, CuPy arrays) of level 0's
    padded shape ``(nu + 2, nv + 2)``, ring zero; the solver only passes them back.

    Attributes
    ----------
    levels : int
        Number of levels, finest (0) first.
    precise : bool
        True where the arithmetic is float64 (cpu, cuda). False on a float32 device (gl): the solver then
        wraps :func:`~clothgrid.heat_multigrid.pcg` in float64 iterative refinement on the host
        (:func:`~clothgrid.heat_multigrid.refine`), whose residual is what it reports.
    """

    levels: int
    precise: bool

    def vector(self) -> Any:
        """A new level-0 vector, zero."""

    def upload(self, a: np.ndarray, out: Any) -> Any:
        """The host float64 padded array ``a`` as a vector: written into ``out`` (a vector of :meth:`vector`)
        and returned; the cpu returns ``a`` itself."""

    def download(self, v: Any, out: np.ndarray) -> None:
        """Vector ``v`` into the host float64 padded array ``out`` (nothing where ``v`` is ``out``)."""

    def copy(self, dst: Any, src: Any) -> None:
        """``dst = src``."""

    def dot(self, a: Any, b: Any) -> float:
        """``a . b``."""

    def apply(self, p: Any, q: Any) -> float:
        """``q = A p`` (level 0, flux form); returns ``p . q``."""

    def residual(self, b: Any, x: Any, r: Any) -> None:
        """``r = b - A x`` (level 0)."""

    def axpy(self, x: Any, r: Any, p: Any, q: Any, alpha: float) -> float:
        """``x += alpha p``, ``r -= alpha q``; returns ``r . r``."""

    def xpay(self, p: Any, z: Any, beta: float) -> None:
        """``p = z + beta p``."""

    def bind(self, r: Any, z: Any) -> None:
        """Make ``r`` level 0's right-hand side and ``z`` its iterate for the next V-cycle."""

    def smooth(self, level: int, pre: bool) -> None:
        """Zebra line Gauss-Seidel along ``v`` on ``level``: from zero, even lines then odd (``pre``), or odd
        then even (post-smoothing)."""

    def restrict(self, level: int) -> None:
        """``b[l+1] = P^T (b[l] - A_l x[l])``, right after a pre-smoothing sweep (the odd rows' residual is
        then zero: a backend may use it)."""

    def coarse_solve(self) -> None:
        """``x = A^-1 b`` on the coarsest level."""

    def prolong(self, level: int) -> None:
        """``x[l] += P x[l+1]`` where the post-smoothing sweep reads it: at least on the even rows."""

    def extra(self) -> dict[str, Any]:
        """Keys the solve adds to its result's info (the device, pass counts); ``{}`` if none."""

    def release(self) -> None:
        """Free what the operations hold on a device (a no-op on the cpu)."""


@runtime_checkable
class Backend(Protocol):
    """A backend module: where the solvers' array operations run.

    Attributes
    ----------
    name : str
        The name :func:`~clothgrid.backends.get_backend` knows it by.
    solvers : tuple of str
        The solvers that run on the backend's device, the first being what
        ``solver="auto"`` picks there. Empty for a host backend (cpu), on which
        every solver of :data:`clothgrid.solvers.SOLVERS` runs and ``auto``
        picks by size (:func:`clothgrid.solvers.choose_solver`).
    """

    name: str
    solvers: tuple[str, ...]

    def require(self) -> object:
        """The backend's device; raises :class:`~clothgrid.errors.BackendUnavailableError` (with the reason)
        when it cannot be used. The cpu backend returns None (always usable)."""

    def available(self) -> tuple[bool, str]:
        """``(True, what runs: a device name)`` or ``(False, why not)``, without raising."""

    def describe(self) -> dict[str, Any]:
        """Keys added to every grid's info (``gl_*``, ``cuda_*``); ``{}`` where there is nothing to say."""

    def summary(self) -> str:
        """One line about the device, for progress messages."""

    def device_bytes(self, solver: str, nu: int, nv: int, coords: int = 3, separable: bool = False) -> int:
        """Bytes of device memory a solve of an ``nu x nv`` grid allocates (0 on the host)."""

    def check_size(self, nu: int, nv: int, solver: str, host_bytes: int = 0, coords: int = 3,
                   separable: bool = False) -> int:
        """Raise :class:`~clothgrid.errors.SizeError` before allocating a grid the device cannot hold;
        return the device bytes counted (0 on the host, whose memory :func:`clothgrid.memory.check_memory`
        checks)."""

    def array_module(self) -> Any:
        """The module of the backend's arrays (NumPy on the host, CuPy on a GPU)."""

    def residual(self, r: Any, wu: Any, wv: Any) -> Any:
        """``b - A r`` over the interior nodes, ``(nu-2, nv-2, 3)``, for arrays of :meth:`array_module`."""

    def max_step(self, r: Any, wu: Any, wv: Any) -> float:
        """``max |D^-1 (b - A r)|`` (Euclidean per node): the factor of the guaranteed error bound."""

    def multigrid(self, levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None,
                  spare: np.ndarray | None = None) -> MultigridOps:
        """The multigrid operations on this backend.

        Parameters
        ----------
        levels : list of Level
            The hierarchy (:func:`~clothgrid.multigrid_levels.build_hierarchy`), finest first.
        x0 : numpy.ndarray
            ``(nu, nv, k)`` level-0 iterate, boundary nodes holding the data.
        rhs : numpy.ndarray, optional
            ``(nu-2, nv-2, k)`` level-0 right-hand side over interior nodes (zero if omitted).
        spare : numpy.ndarray, optional
            A C-contiguous host array whose contents are dead once ``x0`` and ``rhs`` have been
            read (``x0`` may view it; e.g. the grid the solution is written into): the backend may
            keep its own host arrays in its memory (the cpu's coarse levels), give its pages
            back (:func:`clothgrid.memory.release`; gl's) or leave it alone (cuda's). Its contents
            are undefined afterwards.
        """

    def jacobi_sweeper(self, problem: ProblemData, *, stop: str = "error") -> JacobiSweeper:
        """The Jacobi sweep loop on this backend; raises :class:`~clothgrid.errors.InputError` where
        ``jacobi`` does not run."""

    def heat_ops(self, hierarchy: HeatHierarchy) -> HeatOps:
        """The heat solver's operations (:class:`HeatOps`) on this backend for a black-box multigrid
        hierarchy built on the CPU (:class:`~clothgrid.heat_multigrid.HeatHierarchy`)."""


def members(protocol: type) -> tuple[str, ...]:
    """The names a protocol asks for: its annotated attributes and its methods, in definition order.

    Parameters
    ----------
    protocol : type
        :class:`Backend`, :class:`MultigridOps` or :class:`JacobiSweeper`.

    Returns
    -------
    tuple of str
    """
    names = list(protocol.__dict__.get("__annotations__", {}))
    names += [k for k, v in protocol.__dict__.items() if callable(v) and not k.startswith("_")]
    return tuple(names)


#: Every name a backend module supplies.
BACKEND_MEMBERS = members(Backend)
#: Every operation of a backend's multigrid operations (``levels`` is an attribute of the instance).
MULTIGRID_OPERATIONS = tuple(n for n in members(MultigridOps) if n != "levels")
#: Every operation of a backend's Jacobi sweeper.
JACOBI_OPERATIONS = members(JacobiSweeper)
#: Every operation of a backend's heat operations (``levels`` and ``precise`` are attributes).
HEAT_OPERATIONS = tuple(n for n in members(HeatOps) if n not in ("levels", "precise"))
