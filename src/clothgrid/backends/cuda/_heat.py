"""The heat solver's operations (:class:`~clothgrid.backends.protocol.HeatOps`) on a GPU, float64.

:func:`clothgrid.heat_multigrid.vcycle` and :func:`~clothgrid.heat_multigrid.pcg`
drive these exactly as they drive the CPU's Numba kernels. The hierarchy (built
on the CPU) is uploaded once as Fortran-ordered float64 CuPy arrays; each
stencil operation is one launch of :mod:`clothgrid.backends.cuda._heat_kernels`,
dot products are ``cupy.dot`` (cuBLAS), copies CuPy's, the coarsest level one
product with its dense inverse (at most :data:`DENSE_COARSEST` unknowns; a
larger one, a long thin grid's single line, by SuperLU on the host). Under
Numba's CUDA simulator the arrays are NumPy's and the same code runs on the CPU.
The arithmetic is float64 (``precise = True``): the residual a solve reports is
computed on the device.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ...errors import SizeError
from ...memory import format_bytes
from . import _device
from . import _heat_kernels as K
from ._multigrid import NODE_THREADS, launch
from ._sim import array_module, kernel_array

__all__ = ["CudaHeatOps", "DENSE_COARSEST", "heat_device_bytes"]

#: The coarsest level is solved on the device (a dense inverse) up to this many unknowns.
DENSE_COARSEST = 4096
LINE_THREADS = 64


class _DVec:
    """A device array (``a``: CuPy, or NumPy under the simulator) and the kernels' view of it (``k``)."""

    __slots__ = ("a", "k")

    def __init__(self, a: Any):
        self.a, self.k = a, kernel_array(a)


def heat_device_bytes(nu: int, nv: int, coarsest: int) -> int:
    """Bytes of device memory a solve of ``nu x nv`` cells allocates: per padded point of level 0 the
    stencil (``we``, ``wn``, ``c0``), the line factors, the interpolation and a residual (8 * 10) and six
    vectors (48); the coarse levels a third as much again (9-point stencil, factors, interpolation,
    three vectors: 8 * 18 over a quarter, a sixteenth, ...); the coarsest level's dense inverse."""
    n = (nu + 2) * (nv + 2)
    return int(n * (80 + 48) + n * 144 // 3 + 8 * coarsest * coarsest)


class CudaHeatOps:
    """:class:`~clothgrid.backends.protocol.HeatOps` on the GPU (float64).

    Parameters
    ----------
    hierarchy : HeatHierarchy
        Built on the CPU; uploaded here.
    """

    precise = True

    def __init__(self, hierarchy: Any):
        t0 = time.perf_counter()
        self.hierarchy = h = hierarchy
        self.levels = len(h.levels)
        nu, nv = h.levels[0].shape
        last = h.levels[-1].shape[0] * h.levels[-1].shape[1]
        dev = _device.require()
        need, have = heat_device_bytes(nu, nv, last if last <= DENSE_COARSEST else 0), dev.free_memory()
        if need > 0.9 * have:
            raise SizeError(f"heat on {nu}x{nv} cells needs about {format_bytes(need)} of device memory on backend "
                            f"'cuda', more than the 90 % of the {format_bytes(have)} free on {dev.name} that a "
                            "solve may take: use fewer cells or backend 'cpu'")
        self.xp = xp = array_module()
        self.shapes = [(lev.shape[0] + 2, lev.shape[1] + 2) for lev in h.levels]
        up = lambda a: kernel_array(xp.asfortranarray(xp.asarray(np.asarray(a, np.float64))))
        f = h.fine
        self.we, self.wn, self.c0 = up(f.we), up(f.wn), up(f.c0)
        self.S = [None if lev.S is None else up(lev.S) for lev in h.levels]
        self.P = [None if lev.P is None else up(lev.P) for lev in h.levels]
        self.cp = [up(lev.cp) for lev in h.levels]
        self.im = [up(lev.im) for lev in h.levels]
        self.x: list[_DVec | None] = [None] + [self._zeros(s) for s in self.shapes[1:]]
        self.b: list[_DVec | None] = [None] + [self._zeros(s) for s in self.shapes[1:]]
        self.r = [self._zeros(s) for s in self.shapes]
        last = h.levels[-1]
        self.dense = last.shape[0] * last.shape[1] <= DENSE_COARSEST
        self.inv = xp.asarray(h.coarse_inverse()) if self.dense else None
        self.seconds = {"upload": time.perf_counter() - t0}

    def _zeros(self, shape: tuple[int, int]) -> _DVec:
        return _DVec(self.xp.zeros(shape, order="F"))

    @staticmethod
    def _flat(v: _DVec) -> Any:
        return v.a.ravel(order="K")

    def _grid(self, ni: int, nj: int):
        return launch(ni, nj, NODE_THREADS)

    # -- vectors
    def vector(self) -> _DVec:
        return self._zeros(self.shapes[0])

    def upload(self, a: np.ndarray, out: _DVec) -> _DVec:
        out.a[...] = self.xp.asarray(a)
        return out

    def download(self, v: _DVec, out: np.ndarray) -> None:
        a = v.a
        out[...] = a.get() if hasattr(a, "get") else a

    def copy(self, dst: _DVec, src: _DVec) -> None:
        dst.a[...] = src.a

    def dot(self, a: _DVec, b: _DVec) -> float:
        return float(self.xp.dot(self._flat(a), self._flat(b)))

    # -- level 0
    def apply(self, p: _DVec, q: _DVec) -> float:
        nu, nv = self.shapes[0][0] - 2, self.shapes[0][1] - 2
        blocks, threads = self._grid(nu, nv)
        K.apply5[blocks, threads](self.we, self.wn, self.c0, p.k, q.k)
        return self.dot(p, q)

    def residual(self, b: _DVec, x: _DVec, r: _DVec) -> None:
        nu, nv = self.shapes[0][0] - 2, self.shapes[0][1] - 2
        blocks, threads = self._grid(nu, nv)
        K.residual5[blocks, threads](self.we, self.wn, self.c0, b.k, x.k, r.k, 1, 1)

    def axpy(self, x: _DVec, r: _DVec, p: _DVec, q: _DVec, alpha: float) -> float:
        blocks, threads = self._grid(*self.shapes[0])
        K.update_xr[blocks, threads](x.k, r.k, p.k, q.k, float(alpha))
        return self.dot(r, r)

    def xpay(self, p: _DVec, z: _DVec, beta: float) -> None:
        blocks, threads = self._grid(*self.shapes[0])
        K.update_p[blocks, threads](p.k, z.k, float(beta))

    # -- the V-cycle
    def bind(self, r: _DVec, z: _DVec) -> None:
        self.b[0], self.x[0] = r, z

    def smooth(self, level: int, pre: bool) -> None:
        nu = self.shapes[level][0] - 2
        x, b = self.x[level], self.b[level]
        for colour in ((0, 1) if pre else (1, 0)):
            i0 = 2 - colour
            rows = (nu - i0) // 2 + 1 if i0 <= nu else 0
            if rows <= 0:
                continue
            blocks = -(-rows // LINE_THREADS)
            first = pre and colour == 0
            if level == 0:
                K.lines5[blocks, LINE_THREADS](self.we, self.wn, b.k, x.k, colour, self.cp[0], self.im[0], first)
            else:
                K.lines9[blocks, LINE_THREADS](self.S[level], b.k, x.k, colour, self.cp[level], self.im[level], first)

    def restrict(self, level: int) -> None:
        nu, nv = self.shapes[level][0] - 2, self.shapes[level][1] - 2
        x, b, r = self.x[level], self.b[level], self.r[level]
        blocks, threads = self._grid(nu // 2, nv)
        if level == 0:
            K.residual5[blocks, threads](self.we, self.wn, self.c0, b.k, x.k, r.k, 2, 2)
        else:
            K.residual9[blocks, threads](self.S[level], b.k, x.k, r.k, 2, 2)
        ncu, ncv = self.shapes[level + 1][0] - 2, self.shapes[level + 1][1] - 2
        blocks, threads = self._grid(ncu, ncv)
        K.restrict_even[blocks, threads](self.P[level], r.k, self.b[level + 1].k)

    def coarse_solve(self) -> None:
        last = self.levels - 1
        x, b = self.x[last], self.b[last]
        nu, nv = self.shapes[last][0] - 2, self.shapes[last][1] - 2
        rhs = b.a[1:-1, 1:-1].reshape(-1)                     # row-major (i, j), as the inverse's rows
        if self.dense:
            sol = self.xp.dot(self.inv, rhs)
        else:   # a long thin coarsest level: SuperLU on the host
            host = rhs.get() if hasattr(rhs, "get") else rhs
            sol = self.xp.asarray(self.hierarchy.coarse_lu.solve(np.asarray(host, np.float64)))
        x.a[1:-1, 1:-1] = sol.reshape(nu, nv)

    def prolong(self, level: int) -> None:
        nu, nv = self.shapes[level][0] - 2, self.shapes[level][1] - 2
        if nu < 2:
            return
        blocks, threads = self._grid(nu // 2, nv)
        K.prolong_add_even[blocks, threads](self.P[level], self.x[level + 1].k, self.x[level].k)

    def extra(self) -> dict[str, Any]:
        """``cuda_heat_coarsest``: where the coarsest level is solved."""
        return {"cuda_heat_coarsest": "device (dense inverse)" if self.dense else "host (SuperLU)"}

    def release(self) -> None:
        """Drop the device arrays (CuPy's pool keeps the memory for the next solve)."""
        self.S = self.P = self.cp = self.im = self.x = self.b = self.r = []
        self.inv = None
