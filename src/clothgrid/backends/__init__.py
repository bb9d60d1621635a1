"""Backends: where the array operations of the solvers run.

A backend is a module exposing ``name``, ``sweep``, ``max_step`` (see
:mod:`clothgrid.backends.cpu`). ``get_backend("auto")`` picks the best
available one; only the CPU backend exists so far.
"""

from __future__ import annotations

from types import ModuleType

from ..errors import InputError

__all__ = ["BACKENDS", "get_backend"]

BACKENDS = ("auto", "cpu")


def get_backend(name: str) -> ModuleType:
    """The backend module for ``name`` (``"auto"`` or ``"cpu"``)."""
    if name in ("auto", "cpu"):
        from . import cpu

        return cpu
    raise InputError(f"unknown backend {name!r}: use one of {', '.join(BACKENDS)}")
