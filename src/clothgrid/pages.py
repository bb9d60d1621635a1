"""Which memory pages large arrays get: :func:`small_pages`.

A policy of its own (NumPy's huge-page switch), below everything that allocates large arrays:
:mod:`clothgrid.generate`, :mod:`clothgrid.writers` and the command line use it.
"""

from __future__ import annotations

import contextlib
import os

__all__ = ["small_pages"]


def _hugepage_switch():
    """NumPy's switch for ``madvise(MADV_HUGEPAGE)`` on its large allocations, or None."""
    try:
        from numpy._core import multiarray
    except ImportError:                  # NumPy 1.x
        from numpy.core import multiarray
    return getattr(multiarray, "_set_madvise_hugepage", None)


@contextlib.contextmanager
def small_pages():
    """Allocate with ordinary 4 KB pages inside this block (also a decorator).

    On Linux, NumPy asks for transparent huge pages (``madvise(MADV_HUGEPAGE)``) for every
    array of 4 MB or more. Where the kernel compacts memory to find them on the first touch
    (``defrag`` in ``madvise`` mode, the usual default; measured on this project's 2-core VM),
    that first touch costs about 2 s a GB against 0.4 s with 4 KB pages, far more than the fewer
    TLB misses save in a solve's few passes over its arrays: at 4096^2 the solve's set-up took
    0.43 s against 0.15 s, the whole ``generate`` 3.0 s against 2.35 s, the cycles 5 % less.
    :func:`clothgrid.generate`, :func:`clothgrid.writers.save` (a 4096^2 grid to ``.npz``: 3.9-5.8
    s against 2.1 s) and the command line allocate in this block; NumPy's setting is put back as
    it was on the way out. ``CLOTHGRID_HUGEPAGES=1`` keeps NumPy's huge pages.
    """
    switch = _hugepage_switch()
    if switch is None or os.environ.get("CLOTHGRID_HUGEPAGES") == "1":
        yield
        return
    previous = switch(False)
    try:
        yield
    finally:
        switch(previous)
