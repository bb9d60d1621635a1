"""Jacobi sweeps (eq. 3) as fragment passes, for :func:`clothgrid.solvers.jacobi.solve_jacobi`.

The sweeps run in float32 on the correction ``e`` of a float64 iterate
(:class:`~clothgrid.backends.gl._device.Level0`), ping-ponging between two
framebuffers; each writes every node's step into the spare alpha channel. The
largest step is read back (a max-reduction pyramid, one float) only at the end of
a chunk of sweeps whose length doubles from 1 to :data:`MAX_CHUNK`, not every
sweep. When a chunk ends at or below the limit, the chunk is replayed from a copy
of its start one sweep at a time, so the count of sweeps is exactly where the
rule first holds, as on the CPU (Jacobi's largest step never grows).

With ``stop="error"`` a float32 step at or below the limit is only a hint: the
correction is folded into the float64 iterate and the float64 residual decides
(the guaranteed bound); a fold also happens whenever the step fell 8-fold since
the last one, so that float32 never has to resolve steps far below the
correction it accumulates.
"""

from __future__ import annotations

import time

import numpy as np

from ..protocol import ProblemData
from ._device import Level0, device

__all__ = ["GLJacobi", "MAX_CHUNK"]

MAX_CHUNK = 64
FOLD_EVERY = 8.0


class GLJacobi:
    """The sweep loop's operations (:class:`~clothgrid.backends.protocol.JacobiSweeper`) on the GL device."""

    def __init__(self, problem: ProblemData, *, stop: str = "error", host_fp64: bool = False):
        self.dev = dev = device()
        self.stop = stop
        t0 = time.perf_counter()
        with dev.current():
            self.level = Level0(dev, problem.r0, problem.weights.wu, problem.weights.wv, host_fp64=host_fp64)
            lv = self.level
            self.snap = lv._tex(4, "f4", None)
            self.snap_fbo = lv._fbo(self.snap)
            self.cert = lv.fold()            # f = b - A x0, e = 0
        self.fold_step = self.cert
        self.clean = True                    # e == 0: x is the current iterate and cert its bound
        self.chunk = 1
        self.passes = {"sweeps": 0, "replayed": 0, "reductions": 0, "folds": 1}
        self.t_setup = time.perf_counter() - t0
        self.t_sweeps = 0.0

    # -- passes
    def _sweep(self) -> None:
        lv = self.level
        self.dev.draw("JACOBI", lv.e_fbo[1], {"e": lv.e[0], "w": lv.w32, "f": lv.f})
        lv.swap_correction()
        self.passes["sweeps"] += 1

    def _step(self) -> float:
        self.passes["reductions"] += 1
        return self.level.reducer.max(self.level.e[0], 3)

    def _fold(self) -> float:
        self.passes["folds"] += 1
        self.cert = self.level.fold()
        self.clean = True
        self.fold_step = self.cert
        return self.cert

    # -- the protocol
    def sweeps(self, n: int, limit: float) -> tuple[int, float]:
        """At most ``n`` sweeps, stopping after the first whose step is ``<= limit``; ``(sweeps, step)``."""
        t0 = time.perf_counter()
        dev, lv = self.dev, self.level
        k = max(1, min(self.chunk, n))
        with dev.current():
            if k > 1:
                dev.ctx.copy_framebuffer(self.snap_fbo, lv.e_fbo[0])
            for _ in range(k):
                self._sweep()
            self.clean = False
            step = self._step()
            done = k
            if step <= limit and k > 1:      # find the first sweep of the chunk that met the limit
                dev.ctx.copy_framebuffer(lv.e_fbo[0], self.snap_fbo)
                for done in range(1, k + 1):
                    self._sweep()
                    self.passes["replayed"] += 1
                    step = self._step()
                    if step <= limit:
                        break
            self.chunk = min(2 * self.chunk, MAX_CHUNK)
            if self.stop == "error":
                if step <= limit or step * FOLD_EVERY <= self.fold_step:
                    step = min(step, self._fold()) if step > limit else self._fold()
        self.t_sweeps += time.perf_counter() - t0
        return done, step

    def result(self, step: float) -> tuple[np.ndarray, float]:
        """The grid reached (float64) and the step its guaranteed bound is made of."""
        with self.dev.current():
            cert = self.cert if self.clean else self._fold()
            points = self.level.points()
        return points, cert

    def extra(self) -> dict:
        lv = self.level
        return {**self.dev.describe(), "gl_fp64": "device" if lv.device_fp64 else "host",
                "gl_passes": dict(self.passes),
                "gl_seconds": {"setup": self.t_setup, "sweeps": self.t_sweeps, **lv.timings}}

    def close(self) -> None:
        with self.dev.current():
            self.level.release()
        self.dev.release_thread()
