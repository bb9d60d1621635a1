"""A parallel Numba kernel's serial twin, cached under its own name; parallel kernels that survive fork().

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

**fork().** Numba runs parallel kernels on GNU OpenMP threads (its ``omp`` threading layer, the one
Linux gets without TBB), and GNU OpenMP does not survive a ``fork()``: in a child forked after the
parent's first parallel kernel, Numba kills the child with SIGTERM at its first parallel loop
("Terminating: fork() called from a process already using GNU OpenMP"), and a
``multiprocessing.Pool`` (whose start method is ``fork`` on Linux up to Python 3.13) then waits
for the lost task for ever. Every parallel kernel of clothgrid is therefore declared with
:func:`fork_safe`: in such a child it runs as its serial twin (the same results; one thread a
process, which is what a pool of processes wants anyway). The parent and every other process run
the parallel kernel itself.
"""

from __future__ import annotations

import os
import sys
import types

import numba

__all__ = ["serial_twin", "by_size", "fork_safe", "ForkSafe", "forked_from_openmp"]

#: Twins made so far, by the kernel's Python function: one twin per kernel (two would share one
#: cache entry under one name).
_TWINS: dict = {}

#: Numba options of a parallel kernel that its serial twin keeps
_KEPT_OPTIONS = ("nogil", "error_model", "fastmath", "boundscheck", "inline")

#: True in a process forked from one whose Numba threads had started on GNU OpenMP (set by
#: :func:`_after_fork`, inherited by the child's own children).
_FORKED = False


def forked_from_openmp() -> bool:
    """Whether this process was forked from one whose Numba threads had started on GNU OpenMP: its
    parallel kernels then run serially (:func:`fork_safe`)."""
    return _FORKED


def _after_fork() -> None:
    """In a child just forked: note whether the parent had started Numba's threads on GNU OpenMP."""
    global _FORKED
    par = sys.modules.get("numba.np.ufunc.parallel")
    if par is None or not getattr(par, "_is_initialized", False) or getattr(par, "_threading_layer", None) != "omp":
        return
    pool = sys.modules.get("numba.np.ufunc.omppool")
    if getattr(pool, "openmp_vendor", "GNU") == "GNU":      # Intel's OpenMP runtime is fork-safe
        _FORKED = True


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)


def serial_twin(kernel, **options):
    """``kernel`` (a Numba dispatcher) compiled without threads, cached as ``<name>_serial``.

    ``options`` are the ``numba.njit`` options of the twin (``cache=True`` always); without them, the
    kernel's own (:data:`_KEPT_OPTIONS`). A kernel has one twin: a second call returns the first.
    """
    kernel = kernel.kernel if isinstance(kernel, ForkSafe) else kernel
    f = getattr(kernel, "py_func", kernel)       # NUMBA_DISABLE_JIT=1: the plain function
    twin = _TWINS.get(f)
    if twin is not None:
        return twin
    if not options:
        own = getattr(kernel, "targetoptions", {})
        options = {k: own[k] for k in _KEPT_OPTIONS if own.get(k) is not None}
    g = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial", f.__defaults__, f.__closure__)
    g.__qualname__, g.__module__, g.__doc__ = f.__qualname__ + "_serial", f.__module__, f.__doc__
    twin = _TWINS[f] = numba.njit(cache=True, **options)(g)
    return twin


class ForkSafe:
    """A parallel kernel that runs as its serial twin in a process forked after the parent's Numba
    threads started on GNU OpenMP (module docstring); elsewhere the kernel itself. Called like the
    kernel; its other attributes are the kernel's (``py_func``, ``signatures``, ...)."""

    __slots__ = ("kernel", "_twin")

    def __init__(self, kernel) -> None:
        self.kernel = kernel
        self._twin = None

    def __call__(self, *args, **kwargs):
        if _FORKED:
            return self.serial(*args, **kwargs)
        return self.kernel(*args, **kwargs)

    @property
    def serial(self):
        """The serial twin (:func:`serial_twin`), made on first use."""
        if self._twin is None:
            self._twin = serial_twin(self.kernel)
        return self._twin

    def __getattr__(self, name: str):
        return getattr(self.kernel, name)

    def __repr__(self) -> str:
        return f"ForkSafe({self.kernel!r})"


def fork_safe(kernel) -> ForkSafe:
    """Declare a parallel kernel (decorator, above ``numba.njit(parallel=True, ...)``): a
    :class:`ForkSafe`."""
    return ForkSafe(kernel)


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
