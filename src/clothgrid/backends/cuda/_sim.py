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
        return _device_like()(a)
    from numba import cuda  # GPU only

    return cuda.as_cuda_array(a)  # GPU only


# What Numba's DeviceNDArray answers on a GPU (its methods and instance attributes): no NumPy or
# CuPy methods such as max, sum or fill.
_DEVICE_ARRAY = frozenset({
    "T", "alloc_size", "as_cuda_arg", "bind", "copy_to_device", "copy_to_host", "device_ctypes_pointer",
    "dtype", "flags", "get_ipc_handle", "getitem", "gpu_data", "is_c_contiguous", "is_f_contiguous",
    "nbytes", "ndim", "ravel", "reshape", "setitem", "shape", "size", "split", "squeeze", "stream",
    "strides", "transpose", "view"})
_DEVICE_LIKE = None


def _device_like():
    """The simulator's device array, made as strict as a GPU's: Numba's ``FakeCUDAArray`` hands
    every NumPy method through, so a ``kernel_array(a).max()`` passed under the simulator and
    failed on an H200 (2026-11-26). Its attributes are limited to ``_DEVICE_ARRAY`` (and its
    slices are the same kind)."""
    global _DEVICE_LIKE
    if _DEVICE_LIKE is None:
        from numba.cuda.simulator.cudadrv.devicearray import FakeCUDAArray

        class DeviceLikeArray(FakeCUDAArray):
            def __getattr__(self, name):
                if not name.startswith("__") and name not in _DEVICE_ARRAY:
                    raise AttributeError(f"a device array has no attribute {name!r} (on a GPU it is "
                                         "Numba's DeviceNDArray: take the array module's view first)")
                return super().__getattr__(name)

            def __getitem__(self, idx):
                ret = super().__getitem__(idx)
                return DeviceLikeArray(ret._ary, ret.stream) if isinstance(ret, FakeCUDAArray) else ret

        _DEVICE_LIKE = DeviceLikeArray
    return _DEVICE_LIKE
