"""The cuda backend's :class:`~clothgrid.backends.protocol.MultigridOps`: the CPU multigrid on a GPU.

The hierarchy (:func:`~clothgrid.multigrid_levels.build_hierarchy`, NumPy on
the host) is uploaded once: level 0's iterate and right-hand side as float64
parity planes, its edge weights split by row parity (the paper's and uniform
weights as their 1D factors, read through stride flags: no ``(nu, nv)`` array),
every coarse level's iterate, right-hand side and 9-point stencil in float32.
Each operation is then one to three kernel launches of
:mod:`clothgrid.backends.cuda._kernels` over device arrays; :meth:`max_step`
reads back one float, :meth:`solution_into` the grid, once.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ...multigrid_levels import Level
from . import _kernels as K
from ._sim import array_module, kernel_array
from ._transfer import download, upload

#: Threads per block of the node kernels and of the line kernels.
NODE_THREADS = 256
LINE_THREADS = 128
#: Columns ``i`` per thread of the ``max_step`` partial maxima.
MAX_STEP_ROWS = 32
#: Smallest block of columns per thread of a line solve (see :func:`line_block`).
MIN_LINE_BLOCK = 32
#: Threads per block of the fused line solve (:func:`~._kernels.line_solve`): whole lines of
#: ``nsep + 1`` threads each, as many lines as fit (at least one).
FUSED_THREADS = 256
#: Whether a partitioned line solve may be one launch (:func:`~._kernels.line_solve`) or is three.
FUSED_LINE_SOLVE = True
#: The fused line solve runs where the line blocks have at most this many columns (lines of up to
#: about 1100 nodes). Its threads add the separators to their own block's ``L`` nodes one after
#: another, where ``line_spread`` takes a thread a node: measured on an H200 (docs/performance.md), one
#: launch instead of three wins at ``L = 32`` (a V-cycle at 1024^2 1.55x faster) and loses from ``L = 64``
#: (4096^2: 0.77x) on every level, wide or narrow.
FUSED_MAX_BLOCK = 32

def line_block(nu: int) -> int:
    """Columns per block of the partitioned line solves for lines of ``nu`` nodes.

    A line takes about ``2 L + 2 nu / L`` dependent steps (the blocks, then the
    separators), least near ``L = sqrt(nu)``; lines of at most ``MIN_LINE_BLOCK
    + 3`` nodes are one block, which is the CPU's Thomas solve exactly.
    """
    return max(MIN_LINE_BLOCK, math.isqrt(nu))


def line_range(nv: int, p: int) -> tuple[int, int]:
    """Interior rows of parity ``p`` as a range of plane index ``m``: ``j = 2m + p`` in ``1 .. nv-2``."""
    if p == 1:
        return 0, (nv - 3) // 2 + 1
    return 1, (nv - 2) // 2 + 1


def launch(nx: int, ny: int, threads: int) -> tuple[tuple[int, int], tuple[int, int]]:
    """``(blocks, threads per block)`` covering ``nx x ny`` threads, ``x`` (neighbouring memory) first."""
    bx = min(32, nx)
    by = max(1, min(threads // bx, ny))
    return ((nx + bx - 1) // bx, (ny + by - 1) // by), (bx, by)


def _planes(n_rows: int) -> tuple[int, int]:
    """Lengths of the even and odd parity planes of ``n_rows`` rows."""
    return (n_rows + 1) // 2, n_rows // 2


def _coarse_stencil(level: Level, xp: Any, p: int) -> tuple:
    """Rows ``J`` of parity ``p`` of a coarse level's ``C, E, N, NE, NW``, float32 arrays of ``xp``.

    Separable levels are formed by ``xp`` from their 1D factors (on the GPU with
    CuPy) without keeping them on the level; others are uploaded.
    """
    if level.sep is not None:
        return level.sep.stencil(np.float32, xp=xp, rows=slice(p, None, 2))
    return tuple(xp.asarray(np.ascontiguousarray(a[:, p::2])) for a in (level.C, level.E, level.N, level.NE, level.NW))


class CudaMultigrid:
    """Multigrid operations on a GPU (CuPy arrays), or on Numba's CUDA simulator (NumPy arrays).

    Parameters
    ----------
    levels : list of Level
        The hierarchy, finest first.
    x0 : numpy.ndarray
        ``(nu, nv, k)`` level-0 iterate (boundary nodes hold the data), ``k <= 3``.
    rhs : numpy.ndarray, optional
        ``(nu-2, nv-2, k)`` level-0 right-hand side over interior nodes (zero if omitted).
    block : int, optional
        Columns per block of the line solves (default :func:`line_block`).
    fused : bool, optional
        A partitioned line solve in one launch where its blocks have at most :data:`FUSED_MAX_BLOCK`
        columns (default :data:`FUSED_LINE_SOLVE`): the same bits.
    """

    def __init__(self, levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None,
                 block: int | None = None, fused: bool | None = None, share: "CudaMultigrid | None" = None):
        nu, nv, k = x0.shape
        if k > K.MAX_COORDS:
            raise ValueError(f"the cuda multigrid solves at most {K.MAX_COORDS} coordinates, not {k}")
        self._xp = array_module()
        #: Stream of every kernel launch (0: the default stream; a capture can set its own).
        self.stream = 0
        self.levels = len(levels)
        self._hierarchy = levels
        self._shape = x0.shape
        self._diag: tuple | None = None   # level 0's diagonal as parity planes (residual_solve), on first use
        self._has_b = rhs is not None
        self.nv = [lv.shape[1] for lv in levels]
        self.block = block or line_block(nu)
        self.nsep = max(0, (nu - 3) // (self.block + 1))
        # one launch a colour where a thread block holds a whole line's blocks: at most 512 threads
        # (the kernel's 82-86 registers a thread: 1024 threads do not launch on an H200)
        self.fused = (FUSED_LINE_SOLVE if fused is None else fused) and 0 < self.nsep < 512
        #: seconds of the grid's transfers (extra(): where a solve's set-up and download go)
        self.seconds = {"upload": 0.0, "merge": 0.0, "download": 0.0}
        # share: another solve's operations on the same hierarchy (residual_solve): its stencils and
        # scratch, never in use at the same time; the iterate starts at zero without an upload
        self.x = [self._split(x0) if share is None else tuple(self._zeros((k, nu, n)) for n in _planes(nv))]
        if rhs is not None:
            b0 = np.zeros(x0.shape)
            b0[1:-1, 1:-1] = rhs
            self.b = [self._split(b0)]
        else:
            self.b = [tuple(self._zeros((k, 1, 1)) for _ in range(2))]   # never read (has_b False)
        if share is not None:
            self.st, self.ei, self.nm = share.st, share.ei, share.nm
        else:
            self.st = [self._fine_stencil(levels[0])]
        for n_rows in self.nv[1:]:
            self.x.append(tuple(self._zeros((k, nu, n), np.float32) for n in _planes(n_rows)))
            self.b.append(tuple(self._zeros((k, nu, n), np.float32) for n in _planes(n_rows)))
        if share is None:
            for lv in levels[1:]:   # C, E, N, NE, NW: even and odd rows of each
                even, odd = (_coarse_stencil(lv, self._xp, p) for p in (0, 1))
                self.st.append(tuple(kernel_array(a) for pair in zip(even, odd) for a in pair))
        if share is not None:
            self.scratch, self.unused = share.scratch, share.unused
        else:
            # Thomas scratch per precision, as wide as the widest level's lines; 5-point-only arguments.
            self.scratch = {np.float64: self._scratch(nu, self.nv[0], np.float64)}
            if self.levels > 1:
                self.scratch[np.float32] = self._scratch(nu, self.nv[1], np.float32)
            self.unused = {dt: self._zeros((1, 1), dt) for dt in self.scratch}
        #: the iterate, its right-hand side and has_b while conjugate gradients bind others (bind)
        self._own: tuple | None = None
        self._partial = self._xp.zeros((-(-(nu - 2) // MAX_STEP_ROWS), _planes(nv)[0]))
        self._partial_k = kernel_array(self._partial)

    # --- upload -----------------------------------------------------------------------------------------

    def _zeros(self, shape, dtype=np.float64):
        return kernel_array(self._xp.zeros(shape, dtype=dtype))

    def _split(self, grid: np.ndarray):
        """Upload an ``(nu, nv, k)`` float64 grid as parity planes."""
        nu, nv, k = grid.shape
        t = time.perf_counter()
        full = kernel_array(upload(grid, self._xp))   # any strides: chunks through pinned buffers
        self.seconds["upload"] += time.perf_counter() - t
        planes = tuple(self._zeros((k, nu, n)) for n in _planes(nv))
        blocks, threads = launch(nv, nu, NODE_THREADS)
        K.split_grid[blocks, threads, self.stream](full, *planes)
        return planes

    def _split_rows(self, a: np.ndarray):
        """Upload an ``(n, nv)`` stencil array as its even and odd rows ``j`` (contiguous each)."""
        d = self._xp.asarray(a)
        return tuple(kernel_array(self._xp.ascontiguousarray(d[:, p::2])) for p in (0, 1))

    def _fine_stencil(self, level):
        """Level 0's ``Ee, Eo, Ne, No`` and the flags ``ei``, ``nm`` (1D factors where ``E``, ``N`` are views)."""
        E, N = level.E, level.N
        self.ei = 0 if E.strides[0] == 0 else 1     # E[i, j] = E[0, j]: upload one row
        self.nm = 0 if N.strides[1] == 0 else 1     # N[i, j] = N[i, 0]: upload one column
        Ee, Eo = self._split_rows(E[:1] if self.ei == 0 else E)
        if self.nm:
            Ne, No = self._split_rows(N)
        else:
            Ne = No = kernel_array(self._xp.asarray(np.ascontiguousarray(N[:, :1])))
        return Ee, Eo, Ne, No

    def _scratch(self, nu: int, n_rows: int, dtype):
        """Thomas factors and the two spikes, ``(nu, lines)`` each."""
        lines = max(1, (n_rows - 1) // 2)
        return tuple(self._zeros((nu, lines), dtype) for _ in range(3))

    # --- MultigridOps -----------------------------------------------------------------------------------

    def smooth(self, level: int, reverse: bool = False) -> None:
        """One zebra line sweep: even rows then odd rows (odd then even if ``reverse``)."""
        (xe, xo), (be, bo), st, nv = self.x[level], self.b[level], self.st[level], self.nv[level]
        dt = np.float64 if level == 0 else np.float32
        g, yl, yr = self.scratch[dt]
        for p in ((1, 0) if reverse else (0, 1)):
            m_lo, m_hi = line_range(nv, p)
            lines = m_hi - m_lo
            if lines <= 0:
                continue
            q = 1 - p
            own, other, b = (xe, xo, be) if p == 0 else (xo, xe, bo)
            if level == 0:
                Ee, Eo, Ne, No = st
                no = self.unused[dt]
                E, stencil = (Ee, Eo)[p], (no, (Ee, Eo)[p], (Ne, No)[p], (Ne, No)[q], no, no, no, no)
                flags = (self.ei, self.nm, self._has_b, False)
            else:
                Ce, Co, Ee, Eo, Ne, No, NEe, NEo, NWe, NWo = st
                E = (Ee, Eo)[p]
                stencil = ((Ce, Co)[p], E, (Ne, No)[p], (Ne, No)[q], (NEe, NEo)[p], (NEe, NEo)[q],
                           (NWe, NWo)[p], (NWe, NWo)[q])
                flags = (1, 1, True, True)
            ob = 0 if p == 1 else -1
            args = (own, other, b, *stencil, g, yl, yr, m_lo, lines, self.block, self.nsep, ob, *flags)
            if self.fuses():
                per = min(lines, max(1, FUSED_THREADS // (self.nsep + 1)))   # lines per thread block
                K.line_solve[(lines + per - 1) // per, (per, self.nsep + 1), self.stream](*args)
                continue
            blocks, threads = launch(lines, self.nsep + 1, LINE_THREADS)
            K.line_blocks[blocks, threads, self.stream](*args)
            if self.nsep:
                blocks, threads = launch(lines, 1, LINE_THREADS)
                K.line_separators[blocks, threads, self.stream](own, E, g, yl, yr, m_lo, lines, self.block, self.nsep, flags[0])
                blocks, threads = launch(lines, own.shape[1], NODE_THREADS)
                K.line_spread[blocks, threads, self.stream](own, yl, yr, m_lo, lines, self.block, self.nsep)

    def fuses(self) -> bool:
        """Whether :meth:`smooth` solves its lines in one launch (:func:`~._kernels.line_solve`)."""
        return self.fused and self.block <= FUSED_MAX_BLOCK

    def _coarse_launch(self, level: int):
        """Blocks and threads over level ``level + 1``'s nodes ``(J, i)``."""
        return launch(self.nv[level + 1], self._shape[0], NODE_THREADS)

    def restrict(self, level: int) -> None:
        """``b[l+1] = P^T (b[l] - A_l x[l])`` from the even rows, and ``x[l+1] = 0``."""
        (xe, xo), (be, _), st = self.x[level], self.b[level], self.st[level]
        coarse = (*self.b[level + 1], *self.x[level + 1])
        blocks, threads = self._coarse_launch(level)
        if level == 0:
            Ee, _, Ne, No = st
            K.restrict5[blocks, threads, self.stream](xe, xo, be, Ee, Ne, No, self.ei, self.nm, self._has_b, *coarse)
        else:
            Ce, _, Ee, _, Ne, No, NEe, NEo, NWe, NWo = st
            K.restrict9[blocks, threads, self.stream](xe, xo, be, Ce, Ee, Ne, No, NEe, NEo, NWe, NWo, *coarse)

    def prolong(self, level: int) -> None:
        """``x[l] += P x[l+1]`` on the even rows (the odd rows are re-solved next)."""
        blocks, threads = self._coarse_launch(level)
        K.prolong[blocks, threads, self.stream](self.x[level][0], *self.x[level + 1])

    def restrict_full(self, level: int) -> None:
        """Full-multigrid start: ``b[1] = P^T (b[0] - A x[0])`` with every row's residual
        (level 0), or ``b[l+1] = P^T b[l]`` (coarser levels); ``x[l+1] = 0``."""
        coarse = (*self.b[level + 1], *self.x[level + 1])
        blocks, threads = self._coarse_launch(level)
        if level == 0:
            (xe, xo), (be, bo) = self.x[0], self.b[0]
            K.restrict5_full[blocks, threads, self.stream](xe, xo, be, bo, *self.st[0], self.ei, self.nm, self._has_b, self.nv[0],
                                              *coarse)
        else:
            K.restrict_rhs[blocks, threads, self.stream](*self.b[level], self.nv[level], *coarse)

    def prolong_full(self, level: int) -> None:
        """``x[l] += P x[l+1]`` on every row (full-multigrid start)."""
        xe, xo = self.x[level]
        blocks, threads = launch(xe.shape[2], self._shape[0], NODE_THREADS)
        K.prolong_full[blocks, threads, self.stream](xe, xo, *self.x[level + 1], self.nv[level])

    def synchronize(self) -> None:
        """Wait until the device has done the work queued so far (the simulator has nothing queued)."""
        if self._xp is not np:
            self._xp.cuda.Device().synchronize()   # GPU only

    def spare(self) -> None:
        """None: this backend's levels live on the device (no dead host memory to lend)."""
        return None

    def band_steps(self, barriers: Any) -> None:
        """Not computed on this backend: the solve bounds the error by ``max_step() * max z``."""
        return None

    def _interior(self, planes: tuple) -> list:
        """The interior nodes' parts of parity planes, first coordinate (CuPy or NumPy views: a Numba
        device array has no max())."""
        nu, nv = self._shape[:2]
        return [self._xp.asarray(a)[0, 1:-1, slice(*line_range(nv, p))] for p, a in enumerate(planes)]

    def residual_solve(self, eps: float) -> "tuple[CudaMultigrid, float] | None":
        """Operations for ``A y = q``, ``q = |b - A x| + eps D`` of this iterate (Euclidean over the
        coordinates), ``y`` zero, sharing this solve's stencils and scratch, and this iterate's
        :meth:`max_step`; None for a unit-stencil level 0 (the analytic ``max z`` and its bound). The
        norms and ``D`` are array operations on the device; ``D`` is uploaded once."""
        nu, nv, k = self._shape
        if self.ei == 0 or self.nm == 0 or nu < 3 or nv < 3:
            return None
        xp = self._xp
        if self._diag is None:
            from ...weights import interior_diagonal

            fine = self._hierarchy[0]
            grid = np.zeros((nu, nv, 1))
            grid[1:-1, 1:-1, 0] = interior_diagonal(fine.E, fine.N)
            self._diag = self._split(grid)
        r = self.vector()
        self.residual(r)
        q = tuple(kernel_array(xp.sqrt((xp.asarray(a) ** 2).sum(axis=0, keepdims=True))) for a in r)
        step = max(float((n / d).max()) for n, d in zip(self._interior(q), self._interior(self._diag)) if n.size)
        for q_, d_ in zip(q, self._diag):
            xp.asarray(q_)[...] += eps * xp.asarray(d_)          # the ring stays zero (D is zero there)
        ops = CudaMultigrid(self._hierarchy, np.zeros((nu, nv, 1)), block=self.block, fused=self.fused, share=self)
        ops.stream = self.stream
        ops.b[0], ops._has_b = q, True
        return ops, step

    def relative_residual(self) -> float:
        """``max (b - A x) / b`` over level 0's interior nodes of :meth:`residual_solve`'s operations."""
        s = self.vector()
        self.residual(s)
        return max(float((a / c).max()) for a, c in zip(self._interior(s), self._interior(self.b[0])) if a.size)

    def max_step(self) -> float:
        """``max |D^-1 (b - A x)|`` over level 0's interior nodes (Euclidean per node)."""
        (xe, xo), (be, bo) = self.x[0], self.b[0]
        rows, cols = self._partial.shape
        blocks, threads = launch(cols, rows, NODE_THREADS)
        K.max_step5[blocks, threads, self.stream](xe, xo, be, bo, *self.st[0], self.ei, self.nm, self.nv[0], self._has_b,
                                     MAX_STEP_ROWS, self._partial_k)
        return math.sqrt(float(self._partial.max()))

    def solution(self) -> np.ndarray:
        """Level 0's iterate as a float64 ``(nu, nv, k)`` NumPy array."""
        out = np.empty(self._shape)
        self.solution_into(out)
        return out

    # --- conjugate gradients around the V-cycle (clothgrid.solvers.multigrid.ConjugateGradients) -------
    # Vectors are parity-plane pairs of device arrays like the iterate's, ring zero; the residual and
    # A p are a kernel (the CPU's arithmetic order), the rest array operations of CuPy (NumPy under
    # the simulator) on views of the same memory.

    def vector(self) -> tuple:
        """A new level-0 vector, zero (parity planes of every coordinate)."""
        nu, nv, k = self._shape
        return tuple(self._zeros((k, nu, n)) for n in _planes(nv))

    def _views(self, v: tuple) -> tuple:
        return tuple(self._xp.asarray(a) for a in v)

    def _residual_into(self, xe, xo, be, bo, has_b: bool, sign: float, out: tuple) -> None:
        nu, nv, _ = self._shape
        blocks, threads = launch(_planes(nv)[0], nu, NODE_THREADS)
        K.residual5[blocks, threads, self.stream](xe, xo, be, bo, *self.st[0], self.ei, self.nm, nv, has_b,
                                                  sign, *out)

    def _scalars(self, a) -> Any:
        """A per-coordinate host array as a ``(k, 1, 1)`` array of the device."""
        return self._xp.asarray(np.asarray(a, dtype=np.float64)).reshape(-1, 1, 1)

    def residual(self, r: tuple) -> None:
        """``r = b - A x`` of the iterate on the interior nodes."""
        self._residual_into(*self.x[0], *self.b[0], self._has_b, 1.0, r)

    def apply(self, p: tuple, q: tuple) -> np.ndarray:
        """``q = A p`` (``p`` zero on the ring); returns ``p . q`` per coordinate."""
        self._residual_into(*p, *p, False, -1.0, q)        # no b read
        return self.dot(p, q)

    def dot(self, a: tuple, b: tuple) -> np.ndarray:
        """``a . b`` per coordinate (one small array read back)."""
        s = sum((u * w).sum(axis=(1, 2)) for u, w in zip(self._views(a), self._views(b)))
        return np.asarray(s.get() if hasattr(s, "get") else s, dtype=np.float64)

    def axpy(self, r: tuple, p: tuple, q: tuple, alpha: np.ndarray) -> None:
        """``x += alpha p`` (the iterate; its ring keeps its bits, ``p`` being zero there), ``r -= alpha q``."""
        a = self._scalars(alpha)
        for x_, p_ in zip(self._views(self.x[0]), self._views(p)):
            x_ += a * p_
        for r_, q_ in zip(self._views(r), self._views(q)):
            r_ -= a * q_

    def xpay(self, p: tuple, z: tuple, beta: np.ndarray) -> None:
        """``p = z + beta p``."""
        g = self._scalars(beta)
        for p_, z_ in zip(self._views(p), self._views(z)):
            p_ *= g
            p_ += z_

    def bind(self, r: tuple | None, z: tuple | None) -> None:
        """Until ``bind(None, None)``, level 0's right-hand side is ``r`` and its iterate ``z``, set to
        zero: a V-cycle then makes ``z = M r``. ``bind(None, None)`` brings back the iterate."""
        if r is None:
            if self._own:
                self.x[0], self.b[0], self._has_b = self._own
                self._own = None
            return
        if not self._own:
            self._own = (self.x[0], self.b[0], self._has_b)
        for z_ in self._views(z):
            z_.fill(0.0)
        self.x[0], self.b[0], self._has_b = z, r, True

    def solution_max(self) -> float:
        """The largest interior value of level 0's iterate, first coordinate: a reduction over its
        parity planes on the device (no grid crosses the bus)."""
        nu, nv = self._shape[:2]
        if nu < 3 or nv < 3:
            return -math.inf
        return float(max(float(a.max()) for a in self._interior(self.x[0]) if a.size))

    def solution_into(self, out: np.ndarray) -> None:
        """Write level 0's iterate into the host array ``out`` (``(nu, nv, k)``, any strides).

        The parity planes are merged into a device grid, copied to ``out`` in
        chunks of rows ``i`` through pinned buffers (:mod:`._transfer`).
        """
        nu, nv, k = self._shape
        t = time.perf_counter()
        grid = self._xp.empty(self._shape)
        blocks, threads = launch(nv, nu, NODE_THREADS)
        K.merge_grid[blocks, threads, self.stream](*self.x[0], kernel_array(grid))
        self.synchronize()   # the copies run on a stream of their own
        t1 = time.perf_counter()
        download(grid, out)
        self.seconds["merge"] += t1 - t
        self.seconds["download"] += time.perf_counter() - t1

    def extra(self) -> dict[str, Any]:
        """The grid's transfers for the result's info: ``cuda_upload_seconds`` (host view to device
        grid, in the solve's set-up), ``cuda_merge_seconds`` (parity planes to a device grid) and
        ``cuda_download_seconds`` (device grid to the host view), both in its download; the
        backend's ``describe`` adds the device's ``cuda_*`` keys."""
        return {f"cuda_{k}_seconds": v for k, v in self.seconds.items()}
