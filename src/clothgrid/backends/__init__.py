"""Backends: where the array operations of the solvers run.

A backend is a module satisfying :class:`~clothgrid.backends.protocol.Backend`
(name, the solvers it runs on a device, require/available, describe/summary,
device_bytes/check_size, array_module, residual/max_step, and the factories
``multigrid`` and ``jacobi_sweeper`` of the operations the solvers drive):
:mod:`clothgrid.backends.cpu` (NumPy and Numba on the host),
:mod:`clothgrid.backends.gl` (OpenGL through headless EGL) and
:mod:`clothgrid.backends.cuda` (CuPy and numba.cuda on an NVIDIA GPU).

:data:`REGISTRY` maps each name to its module, imported only when asked for
(:func:`load_backend`), so that ``import clothgrid`` imports neither moderngl
nor CuPy nor numba.cuda. ``get_backend("auto")`` is the cuda backend where it
finds a GPU (for the solvers it runs, and grids of at least :data:`AUTO_GPU_MIN_NODES`
nodes), else the CPU backend.
"""

from __future__ import annotations

from importlib import import_module

from ..errors import InputError
from .protocol import Backend

__all__ = ["BACKENDS", "REGISTRY", "Backend", "get_backend", "load_backend"]

#: Backend name -> module path (relative to this package, or absolute), imported on demand.
REGISTRY: dict[str, str] = {"cpu": ".cpu", "gl": ".gl", "cuda": ".cuda"}

#: The names ``get_backend`` accepts.
BACKENDS = ("auto", *REGISTRY)


def load_backend(name: str) -> Backend:
    """The module registered as ``name``, imported now if it was not; checks nothing about its device.

    Parameters
    ----------
    name : str
        A key of :data:`REGISTRY`.

    Returns
    -------
    Backend
        The backend module.

    Raises
    ------
    InputError
        ``name`` is not registered.
    """
    try:
        path = REGISTRY[name]
    except KeyError:
        raise InputError(f"unknown backend {name!r}: use one of {', '.join(BACKENDS)}") from None
    return import_module(path, __name__)


#: ``backend="auto"`` runs grids of fewer nodes than this on the cpu even where a GPU is found: a
#: cuda solve's fixed cost (launches, transfers, about 20-30 ms) loses to the host's cores on small
#: grids. Measured on an H200 host with 16 cores (2026-11-27, docs/performance.md "Fourth loan"),
#: paper weights, whole solve: 32^2 cpu 2.2 ms / cuda 31 ms, 256^2 11 / 43 ms, 512^2 37 / 52 ms,
#: 1024^2 97 / 65 ms: the two cross near 700^2.
AUTO_GPU_MIN_NODES = 1 << 19


def get_backend(name: str, solver: str = "auto", nodes: int | None = None) -> Backend:
    """The backend module for ``name`` (``"auto"`` or a key of :data:`REGISTRY`: ``"cpu"``, ``"gl"``, ``"cuda"``).

    ``"auto"`` is ``cuda`` when it has a GPU (not Numba's simulator), runs
    ``solver`` (``"auto"``: any) and the grid has at least :data:`AUTO_GPU_MIN_NODES`
    nodes (or ``nodes`` is not given), else ``cpu``; without CuPy the check
    costs one package lookup, and its answer is remembered.

    Parameters
    ----------
    name : str
        ``"auto"`` or a registered backend's name.
    solver : str, optional
        The solver that will run (for ``"auto"``).
    nodes : int, optional
        The grid's nodes (for ``"auto"``: smaller grids run on the cpu).

    Returns
    -------
    Backend
        The backend module, its device checked (:meth:`~clothgrid.backends.protocol.Backend.require`).

    Raises
    ------
    InputError
        An unknown name.
    BackendUnavailableError
        With the reason, for ``"gl"`` when no OpenGL context can be created and
        for ``"cuda"`` when no GPU can be used.
    """
    if name == "auto":
        cuda = load_backend("cuda")   # on_gpu: the cuda module's own, beyond the protocol
        if (cuda.on_gpu() and (solver == "auto" or solver in cuda.solvers)
                and (nodes is None or nodes >= AUTO_GPU_MIN_NODES)):
            return cuda
        return load_backend("cpu")
    backend = load_backend(name)
    backend.require()
    return backend
