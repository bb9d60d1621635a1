"""Grids between host memory and the GPU through pinned staging buffers, in chunks of rows.

A grid on the host is an ``(nu, nv, k)`` view of any strides (the solved
coordinates of a ``(nu, nv, 3)`` grid: 16 of every 24 bytes); on the device it
is a contiguous ``(nu, nv, k)`` float64 array. CuPy's own copies of a
pageable host array go through the driver's small staging buffers, and a
strided view first needs a contiguous copy of the whole grid: measured on an
H200 at 4096^2 (268 MB), 0.41 s to upload and 0.28-0.70 s to download.

Here the grid moves in chunks of rows ``i`` through two page-locked
("pinned") buffers of :data:`CHUNK_BYTES` each, allocated once per process:
while the DMA engine copies one chunk between a buffer and the device, host
threads copy the other chunk between the other buffer and the strided view
(NumPy's copy releases the GIL, so the threads run in parallel). Nothing the
size of the grid is allocated on the host.

Under Numba's CUDA simulator the "device" arrays are NumPy arrays: the same
chunked schedule runs with plain copies (which is how the tests check it).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from . import _sim

#: Bytes of each of the two pinned staging buffers.
CHUNK_BYTES = 16 << 20
#: Host threads that copy a chunk between a staging buffer and the grid (at most).
MAX_COPY_THREADS = 8
#: Rows below which a chunk is copied by one thread.
MIN_ROWS_PER_THREAD = 8

_LOCK = threading.Lock()
#: Held for a whole upload or download: the staging buffers are the process's, one transfer at a
#: time (``generate`` may run in several Python threads at once).
_TRANSFER = threading.Lock()
_STAGING: list[np.ndarray] = []
_POOL: ThreadPoolExecutor | None = None
_THREADS = 0


def _forget() -> None:
    """In a forked child: the parent's copy threads, lock and pinned memory are not this process's."""
    global _LOCK, _TRANSFER, _POOL, _THREADS
    _LOCK, _TRANSFER, _POOL, _THREADS = threading.Lock(), threading.Lock(), None, 0
    _STAGING.clear()


os.register_at_fork(after_in_child=_forget)


def _buffers(row_bytes: int) -> list[np.ndarray]:
    """The two staging buffers (flat float64), pinned on a GPU, of :data:`CHUNK_BYTES` or one row of
    ``row_bytes`` if larger; made at the first transfer (and again for a larger row)."""
    with _LOCK:
        n = max(CHUNK_BYTES, row_bytes) // 8
        if _STAGING and _STAGING[0].size < n:
            _STAGING.clear()
        if not _STAGING:
            if _sim.active():
                _STAGING.extend(np.empty(n) for _ in range(2))
            else:
                import cupyx  # GPU only

                _STAGING.extend(cupyx.empty_pinned(n, dtype=np.float64) for _ in range(2))  # GPU only
        return _STAGING


def _pool() -> ThreadPoolExecutor | None:
    """Threads for the host's side of the copies (None with one core)."""
    global _POOL, _THREADS
    with _LOCK:
        if not _THREADS:
            from ...cgroups import usable_processors

            _THREADS = min(MAX_COPY_THREADS, usable_processors())
            if _THREADS > 1:
                _POOL = ThreadPoolExecutor(_THREADS, thread_name_prefix="clothgrid-copy")
        return _POOL


def _host_copy(dst: np.ndarray, src: np.ndarray) -> None:
    """``dst[...] = src`` over rows, split between the copy threads."""
    pool = _pool()
    rows = dst.shape[0]
    parts = 1 if pool is None else min(_THREADS, rows // MIN_ROWS_PER_THREAD)
    if parts <= 1:
        np.copyto(dst, src)
        return
    cuts = np.linspace(0, rows, parts + 1).astype(int)
    list(pool.map(lambda a, b: np.copyto(dst[a:b], src[a:b]), cuts[:-1], cuts[1:]))


def _rows(shape: tuple[int, ...]) -> int:
    """Rows ``i`` of an ``(nu, nv, k)`` float64 grid per chunk (at least one)."""
    return max(1, CHUNK_BYTES // (8 * int(np.prod(shape[1:]))))


def _staged(buf: np.ndarray, rows: int, shape: tuple[int, ...]) -> np.ndarray:
    """The first ``rows`` rows of an ``(nu, *shape[1:])`` grid in staging buffer ``buf``."""
    return buf[:rows * int(np.prod(shape[1:]))].reshape((rows, *shape[1:]))


class _Stream:
    """A CUDA stream and one event per staging buffer (the simulator's copies are synchronous)."""

    def __init__(self):
        self.gpu = not _sim.active()
        if self.gpu:
            import cupy  # GPU only

            self.stream = cupy.cuda.Stream(non_blocking=True)  # GPU only
            # after the work queued so far on the current stream (which may still use the memory
            # that CuPy's pool hands out for the device grid)
            self.stream.wait_event(cupy.cuda.get_current_stream().record())  # GPU only
            self.events = [cupy.cuda.Event(), cupy.cuda.Event()]  # GPU only

    def to_device(self, dst: Any, src: np.ndarray, slot: int) -> None:
        if self.gpu:
            dst.set(src, stream=self.stream)  # GPU only: asynchronous from pinned memory
            self.events[slot].record(self.stream)
        else:
            dst[...] = src

    def to_host(self, dst: np.ndarray, src: Any, slot: int) -> None:
        if self.gpu:
            src.get(stream=self.stream, out=dst, blocking=False)  # GPU only
            self.events[slot].record(self.stream)
        else:
            dst[...] = src

    def wait(self, slot: int) -> None:
        """Until the copy last queued through staging buffer ``slot`` has finished."""
        if self.gpu:
            self.events[slot].synchronize()

    def finish(self) -> None:
        if self.gpu:
            self.stream.synchronize()


def upload(host: np.ndarray, xp: Any) -> Any:
    """A contiguous float64 device copy (module ``xp``) of the ``(nu, nv, k)`` host grid ``host``.

    The caller's kernels may read it at once: every copy has finished when this returns.
    """
    nu = host.shape[0]
    dev = xp.empty(host.shape, dtype=np.float64)
    rows = _rows(host.shape)
    with _TRANSFER:
        bufs, s = _buffers(8 * host[0].size), _Stream()
        for n, i in enumerate(range(0, nu, rows)):
            r = min(rows, nu - i)
            slot = n % 2
            s.wait(slot)                      # the buffer's previous chunk is on the device
            buf = _staged(bufs[slot], r, host.shape)
            _host_copy(buf, host[i:i + r])
            s.to_device(dev[i:i + r], buf, slot)
        s.finish()
    return dev


def download(dev: Any, host: np.ndarray) -> None:
    """Copy the contiguous ``(nu, nv, k)`` device grid ``dev`` into the host view ``host`` (any strides).

    The kernels that wrote ``dev`` must have finished (the caller synchronises).
    """
    nu = host.shape[0]
    rows = _rows(host.shape)
    chunks = [(i, min(rows, nu - i)) for i in range(0, nu, rows)]
    with _TRANSFER:
        bufs, s = _buffers(8 * host[0].size), _Stream()

        def staged(n: int) -> np.ndarray:
            return _staged(bufs[n % 2], chunks[n][1], host.shape)

        s.to_host(staged(0), dev[0:chunks[0][1]], 0)
        for n in range(len(chunks)):
            if n + 1 < len(chunks):           # the next chunk's DMA runs while this one is copied out
                i, r = chunks[n + 1]
                s.to_host(staged(n + 1), dev[i:i + r], (n + 1) % 2)
            s.wait(n % 2)
            i, r = chunks[n]
            _host_copy(host[i:i + r], staged(n))
        s.finish()
