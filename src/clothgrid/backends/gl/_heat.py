"""The heat solver's operations (:class:`~clothgrid.backends.protocol.HeatOps`) as GL passes, float32.

:func:`clothgrid.heat_multigrid.vcycle` and :func:`~clothgrid.heat_multigrid.pcg`
drive these exactly as they drive the CPU's Numba kernels. The hierarchy
(interpolation weights, Galerkin coarse operators, the line solves' Thomas
factors, the coarsest level's inverse) is built on the CPU in float64 and
uploaded once as float32 textures (``_shaders``: the layout); vectors are R32F
textures of level 0's padded shape with a framebuffer each.

- ``smooth``: zebra line Gauss-Seidel along ``v``, one compute dispatch per
  colour (an invocation per line, Thomas along it on an image, in place);
- ``restrict``: one fragment pass over the coarse level (the residual of the
  even rows formed in it: the odd rows' is zero after the sweep);
- ``prolong``: one compute pass, in place, on the even rows;
- ``coarse_solve``: one fragment pass, the dense inverse times the right-hand
  side (at most :data:`DENSE_COARSEST` unknowns; a larger coarsest level, a
  long thin grid's single line, is solved on the host by SuperLU: a read-back
  and an upload per cycle);
- ``apply``/``residual``: one fragment pass (flux form); ``axpy``/``xpay``:
  one compute pass each; ``dot``: a sum-reduction pyramid (:class:`Reducer`)
  and one float read back.

The arithmetic is float32 (``precise = False``): the solver wraps the
conjugate gradients in iterative refinement whose residual is recomputed in
float64 on the host (:func:`clothgrid.heat_multigrid.refine`), and that float64
residual is what a solve reports.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ._device import Reducer, device

__all__ = ["GLHeatOps", "DENSE_COARSEST", "heat_texture_bytes"]

#: The coarsest level is solved on the device (a dense inverse) up to this many unknowns.
DENSE_COARSEST = 4096
_LINES = 32    # HEAT_LINES' local_size_x
_TILE = 8      # the 2D compute shaders' local size


class _Vec:
    """A level's vector: an R32F texture of the padded shape and its framebuffer."""

    __slots__ = ("tex", "fbo", "shape")

    def __init__(self, tex, fbo, shape):
        self.tex, self.fbo, self.shape = tex, fbo, shape


def level_textures(lev: Any, fine: Any = None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``t1, t2, t3`` float32 ``(nu + 2, nv + 2, 4)`` arrays of one level of a
    :class:`~clothgrid.heat_multigrid.HeatHierarchy` (``fine``: level 0's :class:`Stencil5`; ``t2`` is None
    on level 0), in the layout of ``_shaders``' heat section."""
    if lev.S is None:
        we, wn = fine.we, fine.wn
        t1 = np.zeros(we.shape + (4,))
        t1[1:, :, 0] = we[:-1]
        t1[:, :, 1] = we
        t1[:, 1:, 2] = wn[:, :-1]
        t1[:, :, 3] = wn
        c, t2 = fine.c0, None
    else:
        S = lev.S
        t1, t2, c = S[..., 0:4], S[..., 5:9], S[..., 4]
    t3 = np.stack([c, lev.cp, lev.im, np.zeros_like(c)], axis=-1)
    f32 = lambda a: None if a is None else np.ascontiguousarray(a, np.float32)
    return f32(t1), f32(t2), f32(t3)


def heat_texture_bytes(nu: int, nv: int, coarsest: int) -> int:
    """Bytes of textures a solve of ``nu x nv`` cells allocates: per padded point of level 0 two RGBA32F
    stencil textures and the interpolation (48), six R32F vectors (24); the coarse levels a third as much
    again (three stencil textures, the interpolation and two vectors per point: 72 over a quarter, a
    sixteenth, ...); the reduction pyramid; the coarsest level's dense inverse."""
    n = (nu + 2) * (nv + 2)
    return int(n * (48 + 24) + n * 72 // 3 + n * 4 // 15 + 4 * coarsest * coarsest)


class GLHeatOps:
    """:class:`~clothgrid.backends.protocol.HeatOps` on the GL device (float32).

    Parameters
    ----------
    hierarchy : HeatHierarchy
        Built on the CPU; uploaded here.
    """

    precise = False

    def __init__(self, hierarchy: Any):
        self.dev = dev = device()
        t0 = time.perf_counter()
        self.hierarchy = h = hierarchy
        self.levels = len(h.levels)
        nu, nv = h.levels[0].shape
        last = h.levels[-1].shape[0] * h.levels[-1].shape[1]
        dev.check_size(nu + 2, nv + 2, heat_texture_bytes(nu, nv, last if last <= DENSE_COARSEST else 0))
        self.shapes = [(lev.shape[0] + 2, lev.shape[1] + 2) for lev in h.levels]
        self._objects: list = []
        self.counts = {"smooth": 0, "restrict": 0, "prolong": 0, "coarse": 0, "apply": 0, "dot": 0, "axpy": 0}
        self.seconds = {"vcycle": 0.0, "cg": 0.0, "transfer": 0.0}
        with dev.current():
            self.stencils = []
            for lev in h.levels:
                t1, t2, t3 = level_textures(lev, h.fine)
                shape = (lev.shape[0] + 2, lev.shape[1] + 2)
                tex = [self._tex(shape, 4, a) for a in (t1, t2, t3)]
                self.stencils.append({"t1": tex[0], "t2": tex[1] if t2 is not None else tex[0], "t3": tex[2],
                                      "nine": lev.S is not None})
            self.P = [None if lev.P is None else self._tex(self.shapes[l], 4, np.asarray(lev.P, np.float32))
                      for l, lev in enumerate(h.levels)]
            self.x: list[_Vec | None] = [None] + [self._vec(s) for s in self.shapes[1:]]
            self.b: list[_Vec | None] = [None] + [self._vec(s) for s in self.shapes[1:]]
            last = h.levels[-1]
            n = last.shape[0] * last.shape[1]
            self.dense = n <= DENSE_COARSEST
            if self.dense:
                self.inv = self._tex((n, n), 1, np.asarray(h.coarse_inverse(), np.float32))
            self.reducer = Reducer(dev, self.shapes[0][1], self.shapes[0][0])
        self.seconds["upload"] = time.perf_counter() - t0

    # -- allocation (released together)
    def _tex(self, shape: tuple[int, int], comps: int, data: np.ndarray | None = None):
        t = self.dev.texture(shape[1], shape[0], comps, "f4", None if data is None else np.ascontiguousarray(data))
        self._objects.append(t)
        return t

    def _vec(self, shape: tuple[int, int]) -> _Vec:
        tex = self._tex(shape, 1)
        fbo = self.dev.framebuffer(tex)
        self._objects.append(fbo)
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        return _Vec(tex, fbo, shape)

    @staticmethod
    def _groups(width: int, height: int) -> tuple[int, int]:
        return -(-width // _TILE), -(-height // _TILE)

    # -- vectors
    def vector(self) -> _Vec:
        with self.dev.current():
            return self._vec(self.shapes[0])

    def upload(self, a: np.ndarray, out: _Vec) -> _Vec:
        t0 = time.perf_counter()
        with self.dev.current():
            out.tex.write(np.ascontiguousarray(a, np.float32))
        self.seconds["transfer"] += time.perf_counter() - t0
        return out

    def download(self, v: _Vec, out: np.ndarray) -> None:
        t0 = time.perf_counter()
        with self.dev.current():
            out[...] = np.frombuffer(v.tex.read(), np.float32).reshape(v.shape)
        self.seconds["transfer"] += time.perf_counter() - t0

    def copy(self, dst: _Vec, src: _Vec) -> None:
        self._xpay(dst, src, 0.0, True)

    def dot(self, a: _Vec, b: _Vec) -> float:
        t0 = time.perf_counter()
        with self.dev.current():
            s = self.reducer.dot(a.tex, b.tex)
        self.counts["dot"] += 1
        self.seconds["cg"] += time.perf_counter() - t0
        return s

    # -- level 0
    def _ax(self, x: _Vec, b: _Vec | None, out: _Vec) -> None:
        t0 = time.perf_counter()
        with self.dev.current():
            self.dev.draw("HEAT_AX", out.fbo, {"x": x.tex, "b": (b or x).tex, **self._stencil(0)},
                          {"has_b": b is not None, "nine": False})
        self.counts["apply"] += 1
        self.seconds["cg"] += time.perf_counter() - t0

    def apply(self, p: _Vec, q: _Vec) -> float:
        self._ax(p, None, q)
        return self.dot(p, q)

    def residual(self, b: _Vec, x: _Vec, r: _Vec) -> None:
        self._ax(x, b, r)

    def axpy(self, x: _Vec, r: _Vec, p: _Vec, q: _Vec, alpha: float) -> float:
        t0 = time.perf_counter()
        with self.dev.current():
            self.dev.dispatch("HEAT_AXPY", self._groups(self.shapes[0][1], self.shapes[0][0]), {0: x.tex, 1: r.tex},
                              {"p": p.tex, "q": q.tex}, {"alpha": float(alpha)})
        self.counts["axpy"] += 1
        self.seconds["cg"] += time.perf_counter() - t0
        return self.dot(r, r)

    def _xpay(self, p: _Vec, z: _Vec, beta: float, copy: bool) -> None:
        t0 = time.perf_counter()
        with self.dev.current():
            self.dev.dispatch("HEAT_XPAY", self._groups(p.shape[1], p.shape[0]), {0: p.tex}, {"z": z.tex},
                              {"beta": float(beta), "copy": copy})
        self.seconds["cg"] += time.perf_counter() - t0

    def xpay(self, p: _Vec, z: _Vec, beta: float) -> None:
        self._xpay(p, z, beta, False)

    # -- the V-cycle
    def _stencil(self, level: int) -> dict:
        s = self.stencils[level]
        return {"t1": s["t1"], "t2": s["t2"], "t3": s["t3"]}

    def bind(self, r: _Vec, z: _Vec) -> None:
        self.b[0], self.x[0] = r, z

    def smooth(self, level: int, pre: bool) -> None:
        t0 = time.perf_counter()
        nu = self.shapes[level][0] - 2
        x, b = self.x[level], self.b[level]
        with self.dev.current():
            for colour in ((0, 1) if pre else (1, 0)):
                i0 = 2 - colour
                rows = (nu - i0) // 2 + 1 if i0 <= nu else 0
                if rows > 0:
                    self.dev.dispatch("HEAT_LINES", -(-rows // _LINES), {0: x.tex}, {"b": b.tex, **self._stencil(level)},
                                      {"nine": self.stencils[level]["nine"], "first": pre and colour == 0, "i0": i0})
        self.counts["smooth"] += 1
        self.seconds["vcycle"] += time.perf_counter() - t0

    def restrict(self, level: int) -> None:
        t0 = time.perf_counter()
        nc = self.shapes[level + 1]
        with self.dev.current():
            self.dev.draw("HEAT_RESTRICT", self.b[level + 1].fbo,
                          {"x": self.x[level].tex, "b": self.b[level].tex, "P": self.P[level], **self._stencil(level)},
                          {"nine": self.stencils[level]["nine"], "nc": (nc[1], nc[0])})
        self.counts["restrict"] += 1
        self.seconds["vcycle"] += time.perf_counter() - t0

    def coarse_solve(self) -> None:
        t0 = time.perf_counter()
        last = self.levels - 1
        x, b = self.x[last], self.b[last]
        with self.dev.current():
            if self.dense:
                self.dev.draw("HEAT_COARSE", x.fbo, {"b": b.tex, "inv": self.inv})
            else:   # a long thin coarsest level: SuperLU on the host
                nu, nv = self.hierarchy.levels[last].shape
                rhs = np.frombuffer(b.tex.read(), np.float32).reshape(b.shape)[1:-1, 1:-1].astype(np.float64)
                out = np.zeros(b.shape, np.float32)
                out[1:-1, 1:-1] = self.hierarchy.coarse_lu.solve(rhs.reshape(-1)).reshape(nu, nv)
                x.tex.write(out)
        self.counts["coarse"] += 1
        self.seconds["vcycle"] += time.perf_counter() - t0

    def prolong(self, level: int) -> None:
        t0 = time.perf_counter()
        nu, nv = self.shapes[level][0] - 2, self.shapes[level][1] - 2
        if nu >= 2:
            with self.dev.current():
                self.dev.dispatch("HEAT_PROLONG", self._groups(nv, nu // 2), {0: self.x[level].tex},
                                  {"xc": self.x[level + 1].tex, "P": self.P[level]})
        self.counts["prolong"] += 1
        self.seconds["vcycle"] += time.perf_counter() - t0

    # -- the rest
    def extra(self) -> dict[str, Any]:
        """``gl_*`` keys: the device, pass counts and seconds (host-side: the device runs asynchronously,
        so a pass's time shows where its result is read back, in ``cg``'s dot products)."""
        return {**self.dev.describe(), "gl_heat_passes": dict(self.counts),
                "gl_heat_seconds": {k: round(v, 4) for k, v in self.seconds.items()},
                "gl_heat_coarsest": "device (dense inverse)" if self.dense else "host (SuperLU)"}

    def release(self) -> None:
        """Free the textures and unbind the context from this thread."""
        if not self._objects:
            return
        with self.dev.current():
            self.reducer.release()
            for obj in reversed(self._objects):
                obj.release()
            self._objects = []
        self.dev.release_thread()

    def __del__(self):
        try:
            self.release()
        except Exception:   # the context is busy in another thread, or already gone at exit
            pass
