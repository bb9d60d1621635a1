"""The multigrid operations (:class:`~clothgrid.backends.protocol.MultigridOps`) as GL passes.

:func:`~clothgrid.solvers.multigrid.vcycle` drives these operations exactly as
it drives the CPU's. The hierarchy (Galerkin coarse operators, built once on the
CPU) is uploaded as float32 textures; each level's Thomas factors are computed on
the device (the THOMAS compute pass). Per level: the iterate (two RGBA32F
textures, ping-pong for the prolongation), its right-hand side and three stencil
textures (a residual texture only if the general restriction is ever needed).

- ``smooth``: zebra line Gauss-Seidel along u, one compute dispatch per colour
  (one invocation per row ``j``, Thomas algorithm along ``i`` on an image);
- ``restrict``: after a sweep that ended on the odd rows (the V-cycle's
  pre-smoothing), those rows' residual is zero to rounding, so ``P^T r`` is the
  residual of the even rows: one fragment pass over the coarse grid. Otherwise a
  residual pass and a restriction pass;
- ``prolong``: a prolongation pass (fragment shader) into the other texture;
- ``max_step``: the fold of :class:`~clothgrid.backends.gl._device.Level0`:
  level 0's float32 iterate is the correction of a float64 iterate; the fold
  adds it in float64 and recomputes the float64 residual, whose Jacobi-scaled
  max (one float read back) is the guaranteed bound's factor. So every cycle is
  one step of mixed-precision iterative refinement with a float32 V-cycle as the
  inner solver.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ...multigrid_levels import Level
from ..protocol import NoVectors
from ._device import Level0, device

__all__ = ["GLMultigrid", "stencil_textures"]

_LOCAL = 32   # LINE_SOLVE's local_size_x


def full_stencil(level: Level) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``C, E, N`` of a :class:`~clothgrid.multigrid_levels.Level` as float64 ``(nu, nv)`` arrays.

    The finest level holds only its edge weights (``E = wu`` ``(nu-1, nv)``,
    ``N = wv`` ``(nu, nv-1)``, ``C`` None): they are padded with zeros and
    ``C`` is their sum around each node; coarse levels hold all three.
    """
    nu, nv = level.shape
    if level.C is not None and level.E.shape == (nu, nv):
        return (np.asarray(level.C, np.float64), np.asarray(level.E, np.float64),
                np.asarray(level.N, np.float64))
    E = np.zeros((nu, nv))
    N = np.zeros((nu, nv))
    E[:-1] = level.E
    N[:, :-1] = level.N
    C = E.copy()
    C[1:] += E[:-1]
    C += N
    C[:, 1:] += N[:, :-1]
    return C, E, N


def stencil_textures(level: Level) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``t1, t2, t3`` float32 ``(nu, nv, 4)`` arrays of one coarse :class:`~clothgrid.multigrid_levels.Level`.

    ``t3`` holds only ``C``; the THOMAS pass adds the factors on the device. ``t2`` is
    None on a 5-point level.
    """
    C, E, N = full_stencil(level)
    nu, nv = C.shape
    t1 = np.zeros((nu, nv, 4), np.float32)
    t1[1:, :, 0] = E[:-1]
    t1[:, :, 1] = E
    t1[:, 1:, 2] = N[:, :-1]
    t1[:, :, 3] = N
    t2 = None
    if level.NE is not None:
        t2 = np.zeros((nu, nv, 4), np.float32)
        t2[:, :, 0] = level.NE
        t2[1:, 1:, 1] = level.NE[:-1, :-1]
        t2[:, :, 2] = level.NW
        t2[:-1, 1:, 3] = level.NW[1:, :-1]
    t3 = np.zeros((nu, nv, 4), np.float32)
    t3[..., 0] = C
    return t1, t2, t3


class _Level:
    """Textures of one coarse level (or level 0's extra ones)."""

    def __init__(self, owner, shape, t1, t2, t3, x=None, x_fbo=None, b=None):
        self.nu, self.nv = shape
        self.owner = owner
        tex, fbo = owner._tex, owner._fbo
        self.t1 = t1 if not isinstance(t1, np.ndarray) else tex(shape, t1)
        self.nine = t2 is not None
        self.t2 = tex(shape, t2) if self.nine else self.t1
        self.t3 = tex(shape, t3)
        owner.dev.dispatch("THOMAS", -(-self.nv // _LOCAL), {0: self.t3}, {"t1": self.t1}, {"nine": self.nine})
        if x is None:
            x = [tex(shape), tex(shape)]
            x_fbo = [fbo(t) for t in x]
            x_fbo[0].clear(0.0, 0.0, 0.0, 0.0)
        self.x, self.x_fbo = x, x_fbo
        self.b = b if b is not None else tex(shape)
        self.b_fbo = None if b is not None else fbo(self.b)
        self._r = None

    @property
    def r_fbo(self):
        """A residual texture's framebuffer (made on first use: the V-cycle's restriction after a
        sweep ending on odd rows does without)."""
        if self._r is None:
            self._r = self.owner._tex((self.nu, self.nv))
            self._r_fbo = self.owner._fbo(self._r)
        return self._r_fbo

    @property
    def r(self):
        self.r_fbo
        return self._r

    def stencil(self) -> dict:
        return {"t1": self.t1, "t2": self.t2, "t3": self.t3, "b": self.b}


class GLMultigrid(NoVectors):
    """:class:`~clothgrid.backends.protocol.MultigridOps` on the GL device.

    Parameters
    ----------
    levels : list of Level
        The hierarchy from :func:`~clothgrid.multigrid_levels.build_hierarchy`.
    x0 : numpy.ndarray
        ``(nu, nv, k)`` level-0 iterate, boundary nodes holding the data (``k <= 3``).
    rhs : numpy.ndarray, optional
        ``(nu-2, nv-2, k)`` level-0 right-hand side (zero if omitted).
    host_fp64 : bool
        Run the float64 fold and residual in NumPy instead of on the device.
    """

    def __init__(self, levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None, *,
                 host_fp64: bool = False):
        self.dev = dev = device()
        t0 = time.perf_counter()
        self.levels = len(levels)
        fine = levels[0]
        _, E, N = full_stencil(fine)
        wu, wv = E[:-1], N[:, :-1]
        self._objects: list = []
        self.counts = {"smooth": 0, "restrict": 0, "prolong": 0, "fold": 0}
        self.odd_last = [False] * len(levels)   # was the level's last operation a sweep ending on odd rows?
        self.seconds = {"smooth": 0.0, "restrict": 0.0, "prolong": 0.0, "fold": 0.0}
        with dev.current():
            self.l0 = Level0(dev, np.asarray(x0, np.float64), wu, wv, host_fp64=host_fp64, rhs=rhs)
            self.lv = [_Level(self, fine.shape, self.l0.w32, None, None, x=self.l0.e, x_fbo=self.l0.e_fbo,
                              b=self.l0.f)]
            for level in levels[1:]:
                self.lv.append(_Level(self, level.shape, *stencil_textures(level)))
            self.cert = self.l0.fold()
            self.clean = True
        self.seconds["setup"] = time.perf_counter() - t0

    # -- allocation helpers (released with the level 0 objects)
    def _tex(self, shape, data: np.ndarray | None = None):
        nu, nv = shape
        t = self.dev.texture(nv, nu, 4, "f4", None if data is None else np.ascontiguousarray(data, np.float32))
        self._objects.append(t)
        return t

    def _fbo(self, *textures):
        f = self.dev.framebuffer(*textures)
        self._objects.append(f)
        return f

    # -- MultigridOps
    def smooth(self, level: int, reverse: bool = False) -> None:
        t0 = time.perf_counter()
        lv = self.lv[level]
        dev = self.dev
        with dev.current():
            for first in ((1, 2) if reverse else (2, 1)):
                rows = (lv.nv - 2 - first) // 2 + 1 if first <= lv.nv - 2 else 0
                if rows > 0:
                    dev.dispatch("LINE_SOLVE", -(-rows // _LOCAL), {0: lv.x[0]}, lv.stencil(),
                                 {"first": first, "nine": lv.nine})
        self.odd_last[level] = not reverse
        self.clean = False
        self.counts["smooth"] += 1
        self.seconds["smooth"] += time.perf_counter() - t0

    def restrict(self, level: int) -> None:
        t0 = time.perf_counter()
        lv, lc = self.lv[level], self.lv[level + 1]
        dev = self.dev
        with dev.current():
            if self.odd_last[level]:
                dev.draw("RESTRICT_SMOOTHED", lc.b_fbo, {"x": lv.x[0], **lv.stencil()},
                         {"nine": lv.nine, "nc": lc.nv})
            else:
                dev.draw("RESIDUAL", lv.r_fbo, {"x": lv.x[0], **lv.stencil()}, {"nine": lv.nine})
                dev.draw("RESTRICT", lc.b_fbo, {"r": lv.r})
            lc.x_fbo[0].clear(0.0, 0.0, 0.0, 0.0)
        self.counts["restrict"] += 1
        self.seconds["restrict"] += time.perf_counter() - t0

    def prolong(self, level: int) -> None:
        t0 = time.perf_counter()
        lv, lc = self.lv[level], self.lv[level + 1]
        dev = self.dev
        with dev.current():
            dev.draw("PROLONG", lv.x_fbo[1], {"x": lv.x[0], "xc": lc.x[0]})
            lv.x.reverse()
            lv.x_fbo.reverse()
        self.odd_last[level] = False
        self.counts["prolong"] += 1
        self.seconds["prolong"] += time.perf_counter() - t0

    def restrict_full(self, level: int) -> None:
        """Full-multigrid start: ``P^T`` of every row's residual. Level 0's correction is zero
        after a fold and coarser ones were just cleared, so this is ``P^T b[l]``."""
        self.odd_last[level] = False
        self.restrict(level)

    # PROLONG interpolates every row (odd rows the mean of their neighbours): in a V-cycle the
    # odd rows are re-solved next anyway, and the full-multigrid start needs all of them.
    prolong_full = prolong

    def synchronize(self) -> None:
        """Wait until the device has done the passes issued so far (``glFinish``)."""
        with self.dev.current():
            self.dev.ctx.finish()

    def spare(self) -> None:
        """None: this backend's levels live on the device (no dead host memory to lend)."""
        return None

    def band_steps(self, barriers: Any) -> None:
        """Not computed on this backend: the solve bounds the error by ``max_step() * max z``."""
        return None

    def residual_solve(self, eps: float) -> None:
        """Not on this backend: per-edge weights take the barrier solve and ``max_step() * max z``."""
        return None

    def relative_residual(self) -> float:
        """Not on this backend (no :meth:`residual_solve`)."""
        raise NotImplementedError("relative_residual: this backend has no residual_solve")

    def max_step(self) -> float:
        """Fold level 0's correction into the float64 iterate; ``max |D^-1 (b - A x)|`` in float64."""
        t0 = time.perf_counter()
        if not self.clean:
            with self.dev.current():
                self.cert = self.l0.fold()
            self.clean = True
            self.odd_last[0] = False      # x and b of level 0 changed
            self.counts["fold"] += 1
        self.seconds["fold"] += time.perf_counter() - t0
        return self.cert

    def solution(self) -> np.ndarray:
        """Level 0's float64 iterate (after a fold). This ends the solve: the textures are freed
        and the context is unbound from this thread (so that another thread may use the device)."""
        self.max_step()
        with self.dev.current():
            x = self.l0.points()
        self.release()
        self.dev.release_thread()
        return x

    def solution_max(self) -> float:
        """The largest interior value of :meth:`solution`'s first coordinate (ends the solve likewise)."""
        return float(self.solution()[1:-1, 1:-1, 0].max())

    def solution_into(self, out: np.ndarray) -> None:
        """:meth:`solution` written into the host array ``out`` (``(nu, nv, k)``, any strides); ends the
        solve likewise. The texture read-back is a whole grid anyway: no saving over :meth:`solution`."""
        out[...] = self.solution()

    def extra(self) -> dict[str, Any]:
        """``gl_*`` keys: the device, where the float64 steps ran, pass counts and seconds."""
        return {**self.dev.describe(), "gl_fp64": "device" if self.l0.device_fp64 else "host",
                "gl_passes": dict(self.counts), "gl_seconds": {**self.seconds, **self.l0.timings}}

    def release(self) -> None:
        """Free the textures (done by :meth:`solution`, or when a solve that stopped early is
        garbage collected)."""
        if not self._objects and not self.l0._objects:
            return
        with self.dev.current():
            for obj in reversed(self._objects):
                obj.release()
            self._objects = []
            self.l0.release()

    def __del__(self):
        try:
            self.release()
        except Exception:   # the context is busy in another thread, or already gone at exit
            pass
