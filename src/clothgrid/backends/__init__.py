"""Backends: where the array operations of the solvers run.

A backend is a module exposing ``name``, ``sweep``, ``max_step`` (see
:mod:`clothgrid.backends.cpu`), or, like :mod:`clothgrid.backends.gl` (OpenGL
through headless EGL), ``solvers`` (the solvers it runs), ``check_size`` and
the solvers' device operations (``jacobi_sweeper``). ``get_backend("auto")``
is the CPU backend.
"""

from __future__ import annotations

from types import ModuleType

from ..errors import InputError

__all__ = ["BACKENDS", "get_backend"]

BACKENDS = ("auto", "cpu", "gl")


def get_backend(name: str) -> ModuleType:
    """The backend module for ``name`` (``"auto"``, ``"cpu"`` or ``"gl"``).

    Raises :class:`~clothgrid.errors.BackendUnavailableError` (with the reason)
    for ``"gl"`` when no OpenGL context can be created.
    """
    if name in ("auto", "cpu"):
        from . import cpu

        return cpu
    if name == "gl":
        from . import gl

        gl.require()
        return gl
    raise InputError(f"unknown backend {name!r}: use one of {', '.join(BACKENDS)}")
