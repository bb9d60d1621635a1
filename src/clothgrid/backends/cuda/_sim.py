"""Numba's CUDA simulator: whether it is on, and the arrays its kernels take.

With ``NUMBA_ENABLE_CUDASIM=1`` in the environment before ``numba.cuda`` is
first imported, ``numba.cuda`` runs kernels on the CPU, one Python thread per
GPU thread, over NumPy arrays. The cuda backend then keeps its arrays in NumPy
instead of CuPy (everything else is the same code), which is how the tests
check the kernels without a GPU.
"""

from __future__ import annotations

import os
import sys


def active() -> bool:
    """True when ``numba.cuda`` is, or will be when imported, Numba's CUDA simulator.

    Numba reads ``NUMBA_ENABLE_CUDASIM`` when it is imported: once it is, its
    configuration says; before, the environment does (without importing Numba,
    which costs half a second).
    """
    if "numba" not in sys.modules and os.environ.get("NUMBA_ENABLE_CUDASIM", "0") in ("", "0"):
        return False
    from numba.core import config

    return bool(config.ENABLE_CUDASIM)


def array_module():
    """The array module of the device's arrays: NumPy under the simulator, else CuPy."""
    if active():
        import numpy

        return numpy
    import cupy

    return cupy


def kernel_array(a):
    """What a kernel takes for the array ``a`` of :func:`array_module`, sharing its memory.

    On a GPU a Numba device array made once from the CuPy array's
    ``__cuda_array_interface__`` (passing CuPy arrays to every launch would
    parse the interface, and synchronise its stream, each time); under the
    simulator a simulated device array over the NumPy array (a NumPy argument
    would be copied in and out at every launch).
    """
    if active():
        from numba.cuda.simulator.cudadrv.devicearray import FakeCUDAArray

        return FakeCUDAArray(a)
    from numba import cuda  # GPU only

    return cuda.as_cuda_array(a)  # GPU only
