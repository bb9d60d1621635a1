"""Compatibility of numba-cuda with the NumPy it runs beside.

numba-cuda up to 0.30.4 (the newest release on 2026-11-23) registers a CUDA
overload of ``np.row_stack`` when it first compiles a kernel. NumPy 2.5
removed that name (a deprecated alias of ``np.vstack`` since NumPy 2.0), so
every kernel compilation fails with ``AttributeError: module 'numpy' has no
attribute 'row_stack'``: seen on an H100 with numba-cuda 0.30.4 and NumPy
2.5.2. :func:`patch_numpy` puts the alias back (the same function object as
``np.vstack``: nothing else changes) before numba.cuda compiles anything.
"""

from __future__ import annotations


def patch_numpy() -> None:
    """Give NumPy back ``row_stack`` (``vstack``) where it lacks it; idempotent."""
    import numpy as np

    if "row_stack" not in np.__dict__:
        np.row_stack = np.vstack
