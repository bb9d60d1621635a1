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
finds a GPU (for the solvers it runs), else the CPU backend.
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


def get_backend(name: str, solver: str = "auto") -> Backend:
    """The backend module for ``name`` (``"auto"`` or a key of :data:`REGISTRY`: ``"cpu"``, ``"gl"``, ``"cuda"``).

    ``"auto"`` is ``cuda`` when it has a GPU (not Numba's simulator) and runs
    ``solver`` (``"auto"``: any), else ``cpu``; without CuPy the check costs
    one package lookup, and its answer is remembered.

    Parameters
    ----------
    name : str
        ``"auto"`` or a registered backend's name.
    solver : str, optional
        The solver that will run (for ``"auto"``).

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
        if cuda.on_gpu() and (solver == "auto" or solver in cuda.solvers):
            return cuda
        return load_backend("cpu")
    backend = load_backend(name)
    backend.require()
    return backend
