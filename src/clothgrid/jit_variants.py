"""A parallel Numba kernel's serial twin, cached under its own name.

Kernels that run ``prange`` loops pay for waking their threads, which small
inputs do not repay; such a kernel gets a serial twin, the same Python code
compiled without ``parallel`` (``prange`` then runs as ``range``), and the
caller picks one by size. The twin is compiled from a copy of the Python
function named ``<name>_serial``: Numba's on-disk cache names its files by a
function's qualified name and line and keys them by the argument types, not
by the ``parallel`` flag, so a twin of the very same function shared the
parallel kernel's cache entry, and whichever was saved last was loaded for
both (until 2026-11-25 the CPU multigrid's parallel kernels ran on one thread
that way: ``tests/test_multigrid.py`` checks that each loads its own).
"""

from __future__ import annotations

import types

import numba

__all__ = ["serial_twin", "by_size"]


def serial_twin(kernel, **options):
    """``kernel`` (a Numba dispatcher) compiled without threads, cached as ``<name>_serial``.

    ``options`` are the ``numba.njit`` options of the twin (``cache=True`` always).
    """
    f = getattr(kernel, "py_func", kernel)       # NUMBA_DISABLE_JIT=1: the plain function
    g = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial", f.__defaults__, f.__closure__)
    g.__qualname__, g.__module__, g.__doc__ = f.__qualname__ + "_serial", f.__module__, f.__doc__
    return numba.njit(cache=True, **options)(g)


def by_size(kernel, least: int, **options):
    """``kernel`` and its serial twin (:func:`serial_twin`, ``options`` the twin's), picked by the
    work's size: ``pick(n)`` is the parallel kernel where ``n >= least``, else the twin.

    ``pick.parallel`` and ``pick.serial`` are the two dispatchers.
    """
    twin = serial_twin(kernel, **options)

    def pick(n: int):
        return kernel if n >= least else twin

    pick.parallel, pick.serial = kernel, twin
    return pick
