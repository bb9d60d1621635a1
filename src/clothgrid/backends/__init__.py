"""Backends: where the array operations of the solvers run.

A backend is a module exposing ``name``, ``sweep``, ``max_step`` (see
:mod:`clothgrid.backends.cpu`), or, like :mod:`clothgrid.backends.gl` (OpenGL
through headless EGL) and :mod:`clothgrid.backends.cuda` (CuPy and numba.cuda
on an NVIDIA GPU), ``solvers`` (the solvers it runs), ``check_size`` and the
solvers' device operations (``multigrid``, ``jacobi_sweeper``).
``get_backend("auto")`` is the cuda backend where it finds a GPU (for the
solvers it runs), else the CPU backend.
"""

from __future__ import annotations

from types import ModuleType

from ..errors import InputError

__all__ = ["BACKENDS", "get_backend"]

BACKENDS = ("auto", "cpu", "gl", "cuda")


def get_backend(name: str, solver: str = "auto") -> ModuleType:
    """The backend module for ``name`` (``"auto"``, ``"cpu"``, ``"gl"`` or ``"cuda"``).

    ``"auto"`` is ``cuda`` when it has a GPU (not Numba's simulator) and runs
    ``solver`` (``"auto"``: any), else ``cpu``; without CuPy the check costs
    one package lookup, and its answer is remembered. Raises
    :class:`~clothgrid.errors.BackendUnavailableError` (with the reason) for
    ``"gl"`` when no OpenGL context can be created and for ``"cuda"`` when no
    GPU can be used.
    """
    if name == "auto":
        from . import cuda

        if cuda.on_gpu() and (solver == "auto" or solver in cuda.solvers):
            return cuda
    if name in ("auto", "cpu"):
        from . import cpu

        return cpu
    if name == "gl":
        from . import gl

        gl.require()
        return gl
    if name == "cuda":
        from . import cuda

        cuda.require()
        return cuda
    raise InputError(f"unknown backend {name!r}: use one of {', '.join(BACKENDS)}")
