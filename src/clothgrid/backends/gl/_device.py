"""The OpenGL device of the gl backend: one headless EGL context per process.

:func:`device` creates it on first use (``moderngl`` with ``backend="egl"``:
Mesa's llvmpipe without a GPU, the vendor's driver with one; EGL picks silently,
so the renderer is reported). :class:`Device` compiles and caches the shader
programs, creates textures and framebuffers, draws full-screen passes and
answers the size questions asked before a grid is allocated.
"""

from __future__ import annotations

import ctypes
import os
import re
import threading
import time
from contextlib import contextmanager

import numpy as np

from ...errors import BackendUnavailableError, SizeError
from ...memory import available_bytes, format_bytes
from . import _shaders

__all__ = ["device", "Device", "Level0", "Reducer"]

_LOCK = threading.RLock()
_DEVICE: "Device | None" = None
_FAILURE: str | None = None

#: What a process forked after its parent had made a GL context is told (:func:`_forked`).
FORKED = ("backend 'gl' cannot run in a process forked after its parent used OpenGL: the driver's "
          "context and threads do not survive fork() (a compute dispatch would wait for ever). Start "
          "worker processes with multiprocessing's 'spawn' or 'forkserver' method, or use backend 'cpu'")


def _forked() -> None:
    """In a forked child: where the parent had a context, the driver's state is the parent's (Mesa's
    llvmpipe waits for ever on its worker threads, which the child does not have; a GPU's context
    is the parent's), so the backend is unavailable, with the reason; else the child may make its own."""
    global _LOCK, _DEVICE, _FAILURE
    _LOCK = threading.RLock()
    if _DEVICE is not None:
        _DEVICE, _FAILURE = None, FORKED


os.register_at_fork(after_in_child=_forked)

#: GL version the backend needs: 4.3 for compute shaders (the line solves of the multigrid).
REQUIRED_GL = 430
#: Software renderers keep textures in the host's memory.
_SOFTWARE = ("llvmpipe", "softpipe", "swrast", "lavapipe")
#: Largest texture probed before a solve is allocated (the driver may refuse a texture smaller
#: than GL_MAX_TEXTURE_SIZE squared: llvmpipe refuses one of 1.5 GiB or more).
_PROBE_BYTES = 64 << 20


def device() -> "Device":
    """The process's GL device, created on first use.

    Raises
    ------
    BackendUnavailableError
        moderngl is missing, or no OpenGL 4.3 context could be created through EGL;
        the message says why. The failure is remembered for the process.
    """
    global _DEVICE, _FAILURE
    with _LOCK:
        if _DEVICE is not None:
            return _DEVICE
        if _FAILURE is not None:
            raise BackendUnavailableError(_FAILURE)
        try:
            _DEVICE = Device(_create_context())
        except BackendUnavailableError as exc:
            _FAILURE = str(exc)
            raise
        return _DEVICE


def _create_context():
    """A standalone OpenGL 4.3 context through EGL, on a hardware device when there is one.

    EGL lists its devices in no particular order and Mesa's software device may come
    first, so a software renderer at index 0 is kept only if no later device has a
    hardware one. ``CLOTHGRID_GL_DEVICE=N`` picks EGL device ``N`` instead.
    """
    try:
        import moderngl
    except ImportError as exc:
        raise BackendUnavailableError(
            f"backend 'gl' needs the moderngl package ({exc}): pip install 'clothgrid[gl]'") from None

    def create(index: int):
        return moderngl.create_context(standalone=True, backend="egl", require=REQUIRED_GL, device_index=index)

    wanted = os.environ.get("CLOTHGRID_GL_DEVICE", "").strip()
    try:
        ctx = create(int(wanted) if wanted else 0)
    except Exception as exc:  # moderngl/glcontext raise plain Exceptions with the EGL reason
        raise BackendUnavailableError(
            f"backend 'gl' could not create a headless OpenGL {REQUIRED_GL // 100}.{REQUIRED_GL % 100 // 10} "
            f"context through EGL ({type(exc).__name__}: {exc}). Without a GPU, install Mesa's llvmpipe "
            "(Debian/Ubuntu: apt-get install libegl1 libgl1 libgl1-mesa-dri); with one, its driver's EGL "
            "library") from None
    if not wanted and _is_software(ctx):
        for index in range(1, 8):
            try:
                other = create(index)
            except Exception:
                break
            if _is_software(other):
                other.release()
            else:
                ctx.release()
                ctx = other
                break
    return ctx


def _is_software(ctx) -> bool:
    return any(s in str(ctx.info.get("GL_RENDERER", "")).lower() for s in _SOFTWARE)


def _gl_get_integers(pname: int, count: int) -> list[int] | None:
    """``glGetIntegerv`` on the current context through the GL dispatch library, or None."""
    for name in ("libOpenGL.so.0", "libGL.so.1"):
        try:
            lib = ctypes.CDLL(name)
            out = (ctypes.c_int * count)()
            lib.glGetIntegerv(ctypes.c_uint(pname), out)
            return list(out)
        except (OSError, AttributeError):
            continue
    return None


class Device:
    """A moderngl context with the backend's programs, and its limits."""

    def __init__(self, ctx):
        import moderngl

        self.mgl = moderngl
        self.ctx = ctx
        info = ctx.info
        self.renderer = str(info.get("GL_RENDERER", "unknown"))
        self.vendor = str(info.get("GL_VENDOR", "unknown"))
        self.version = str(info.get("GL_VERSION", "unknown"))
        dims = [int(info.get("GL_MAX_TEXTURE_SIZE", 0))]
        for key in ("GL_MAX_VIEWPORT_DIMS", "GL_MAX_FRAMEBUFFER_WIDTH", "GL_MAX_FRAMEBUFFER_HEIGHT"):
            v = info.get(key)
            if v:
                dims.extend(int(x) for x in (v if isinstance(v, (tuple, list)) else (v,)))
        self.max_texture_size = int(info.get("GL_MAX_TEXTURE_SIZE", 0))
        self.max_size = min(d for d in dims if d > 0)
        ext = ctx.extensions
        self.fp64 = ctx.version_code >= 400 or "GL_ARB_gpu_shader_fp64" in ext
        self.software = _is_software(ctx)
        self._programs: dict[str, tuple] = {}
        self._compute: dict[str, object] = {}
        self.lock = threading.Lock()
        self._thread: int | None = threading.get_ident()   # the context is current where it was made

    # ------------------------------------------------------------------ the current thread

    @contextmanager
    def current(self):
        """Make the context current in this thread (if it is not already) for a block.

        The context stays current afterwards: unbinding it flushes the pipeline, so
        it is unbound only at the end of a solve (:meth:`release_thread`). A context
        current in another thread cannot be taken: that is an error, not a wait.
        """
        me = threading.get_ident()
        if self._thread != me:
            with self.lock:
                if self._thread is not None:
                    raise BackendUnavailableError(
                        "backend 'gl' is in use by another thread (one OpenGL context per process; "
                        "run gl solves from one thread at a time)")
                self.ctx.mglo.__enter__()
                self._thread = me
        yield

    def release_thread(self) -> None:
        """Unbind the context from this thread, so that another thread may use it."""
        with self.lock:
            if self._thread == threading.get_ident():
                self.ctx.mglo.__exit__(None, None, None)
                self._thread = None

    # ------------------------------------------------------------------ facts

    def describe(self) -> dict:
        """What a grid's ``info`` records about the device."""
        return {"gl_renderer": self.renderer, "gl_vendor": self.vendor, "gl_version": self.version,
                "gl_max_texture_size": self.max_texture_size}

    def free_memory(self) -> tuple[int | None, str]:
        """Memory textures can use now, in bytes, and where the figure comes from."""
        if self.software:
            return available_bytes(), "host memory (software renderer)"
        ext = self.ctx.extensions
        with self.current():
            if "GL_NVX_gpu_memory_info" in ext:
                v = _gl_get_integers(0x9049, 1)          # GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX, KiB
                if v and v[0] > 0:
                    return v[0] * 1024, "GL_NVX_gpu_memory_info"
            if "GL_ATI_meminfo" in ext:
                v = _gl_get_integers(0x87FC, 4)          # TEXTURE_FREE_MEMORY_ATI, KiB
                if v and v[0] > 0:
                    return v[0] * 1024, "GL_ATI_meminfo"
        return None, "unknown (the driver does not say)"

    def check_size(self, nu: int, nv: int, device_bytes: int, host_bytes: int = 0) -> None:
        """Raise :class:`SizeError` unless an ``nu x nv`` grid fits this device.

        ``device_bytes`` is what the solve's textures take; on a software renderer
        textures live in host memory, so ``host_bytes`` (the rest of the pipeline)
        counts too. Nothing is allocated but, for large grids, one probe texture.
        """
        name = f"this OpenGL device ({self.renderer})"
        if max(nu, nv) > self.max_size:
            raise SizeError(
                f"a {nu}x{nv} grid needs {nv}x{nu}-texel textures, but {name} allows at most "
                f"{self.max_size} texels a side (GL_MAX_TEXTURE_SIZE {self.max_texture_size}): use at most "
                f"{self.max_size} nodes a side, or backend 'cpu'")
        have, source = self.free_memory()
        need = device_bytes + (host_bytes if self.software else 0)
        if have is not None and need > 0.9 * have:
            raise SizeError(
                f"a {nu}x{nv} grid with backend 'gl' needs about {format_bytes(need)} of textures"
                + (" and host arrays" if self.software else "")
                + f", more than the 90 % of the {format_bytes(have)} available ({source}) on {name} that a solve "
                "may take: use fewer nodes")
        if 16 * nu * nv >= _PROBE_BYTES and not self.probe(nv, nu):
            raise SizeError(
                f"{name} refused a {nv}x{nu} RGBA32F texture ({format_bytes(16 * nu * nv)}), which a "
                f"{nu}x{nv} grid needs" + (" (llvmpipe takes textures under 1.5 GiB)" if self.software else "")
                + ": use fewer nodes")

    def probe(self, width: int, height: int) -> bool:
        """Whether the driver accepts (and can render to) a ``width x height`` RGBA32F texture."""
        with self.current():
            self.ctx.error  # clear
            tex = fbo = None
            try:
                tex = self.ctx.texture((width, height), 4, dtype="f4")
                if self.ctx.error != "GL_NO_ERROR":     # GL_OUT_OF_MEMORY, GL_INVALID_VALUE
                    return False
                fbo = self.ctx.framebuffer([tex])       # raises if the attachment is incomplete
                return True
            except Exception:
                return False
            finally:
                for obj in (fbo, tex):
                    if obj is not None:
                        obj.release()

    # ------------------------------------------------------------------ programs

    def _build(self, name: str, make):
        try:
            return make()
        except self.mgl.Error as exc:
            raise BackendUnavailableError(
                f"backend 'gl': the OpenGL driver ({self.renderer}, {self.version}) rejected shader "
                f"{name}: {exc}") from None

    def program(self, name: str):
        """``(program, vertex array, {sampler: unit})`` of the fragment shader ``_shaders.<name>``."""
        got = self._programs.get(name)
        if got is None:
            source = getattr(_shaders, name)
            prog = self._build(name, lambda: self.ctx.program(vertex_shader=_shaders.VERTEX, fragment_shader=source))
            got = (prog, self.ctx.vertex_array(prog, []), _assign_units(prog, source))
            self._programs[name] = got
        return got

    def compute(self, name: str):
        """The compute shader ``_shaders.<name>``."""
        got = self._compute.get(name)
        if got is None:
            source = getattr(_shaders, name)
            cs = self._build(name, lambda: self.ctx.compute_shader(source))
            got = self._compute[name] = (cs, _assign_units(cs, source))
        return got

    def dispatch(self, name: str, groups: int | tuple[int, ...], images: dict, inputs: dict,
                 uniforms: dict | None = None) -> None:
        """Run compute shader ``name`` on ``groups`` work groups (a count, or counts along x, y), then a
        memory barrier."""
        cs, units = self.compute(name)
        for unit, tex in images.items():
            tex.bind_to_image(unit, read=True, write=True)
        for key, tex in inputs.items():
            tex.use(units[key])
        _set_uniforms(cs, uniforms)
        cs.run(*groups) if isinstance(groups, tuple) else cs.run(groups)
        self.ctx.memory_barrier()

    # ------------------------------------------------------------------ objects and passes

    def texture(self, width: int, height: int, components: int = 4, dtype: str = "f4", data=None):
        tex = self.ctx.texture((width, height), components, data=data, dtype=dtype)
        tex.filter = (self.mgl.NEAREST, self.mgl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex

    def framebuffer(self, *textures):
        return self.ctx.framebuffer(color_attachments=list(textures))

    def draw(self, name: str, target, inputs: dict, uniforms: dict | None = None) -> None:
        """One full-screen pass of fragment shader ``name`` into framebuffer ``target``."""
        prog, vao, units = self.program(name)
        for key, tex in inputs.items():
            tex.use(units[key])
        _set_uniforms(prog, uniforms)
        target.use()
        vao.render(self.mgl.TRIANGLES, vertices=3)


def _set_uniforms(program, uniforms: dict | None) -> None:
    """Set the uniforms ``program`` declares (the compiler drops unused ones)."""
    for key, value in (uniforms or {}).items():
        if key in program:
            program[key].value = value


_SAMPLER = re.compile(r"uniform\s+[iu]?sampler2D\s+(\w+)\s*;")


def _assign_units(program, source: str) -> dict[str, int]:
    """Give each sampler the shader declares its own texture unit: ``{name: unit}``.

    Every declared sampler gets a unit, so that binding a texture to one the
    compiler dropped (unused in this shader) is harmless.
    """
    units = {}
    for uname in _SAMPLER.findall(source):
        units[uname] = len(units)
        if uname in program:
            program[uname].value = units[uname]
    return units


class Reducer:
    """Reductions of ``width x height`` textures to one float by a pyramid of 4x4 passes: the max of one
    channel (non-negative values), a sum, or the dot product of two one-channel textures (float32)."""

    def __init__(self, dev: Device, width: int, height: int):
        self.dev = dev
        self.levels = []
        w, h = width, height
        while w > 1 or h > 1:
            w, h = -(-w // 4), -(-h // 4)
            tex = dev.texture(w, h, 1, "f4")
            self.levels.append((tex, dev.framebuffer(tex)))

    def _pyramid(self, first: str, inputs: dict, channel: int, rest: str) -> float:
        name, src, ch = first, None, channel
        for out, fbo in self.levels:
            self.dev.draw(name, fbo, inputs if src is None else {"src": src}, {"channel": ch})
            name, src, ch = rest, out, 0
        return float(np.frombuffer(src.read(), np.float32)[0])

    def max(self, tex, channel: int) -> float:
        if not self.levels:  # a 1x1 source
            return float(np.frombuffer(tex.read(), np.float32)[channel])
        return self._pyramid("REDUCE_MAX", {"src": tex}, channel, "REDUCE_MAX")

    def sum(self, tex, channel: int = 0) -> float:
        if not self.levels:
            return float(np.frombuffer(tex.read(), np.float32)[channel])
        return self._pyramid("REDUCE_SUM", {"src": tex}, channel, "REDUCE_SUM")

    def dot(self, a, b) -> float:
        """``sum(a * b)`` of two one-channel textures of this reducer's size."""
        if not self.levels:
            return float(np.frombuffer(a.read(), np.float32)[0] * np.frombuffer(b.read(), np.float32)[0])
        return self._pyramid("REDUCE_DOT", {"a": a, "b": b}, 0, "REDUCE_SUM")

    def release(self) -> None:
        for tex, fbo in self.levels:
            fbo.release()
            tex.release()
        self.levels = []


def _edge_weights(wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """``(nu, nv, 4)`` float64: each node's weights to ``i-1, i+1, j-1, j+1`` (0 where no edge)."""
    nu, nv = wv.shape[0], wu.shape[1]
    w = np.zeros((nu, nv, 4))
    w[1:, :, 0] = wu
    w[:-1, :, 1] = wu
    w[:, 1:, 2] = wv
    w[:, :-1, 3] = wv
    return w


class Level0:
    """The fine grid on the device: the float64 iterate, the weights, a float32 correction.

    The solve works on the correction ``e`` (RGBA32F, xyz + a spare channel) of a
    float64 iterate ``x`` for the right-hand side ``f = b - A x`` (float32), and
    :meth:`fold` adds ``e`` to ``x`` in float64 and recomputes ``f`` from the
    new ``x`` in float64 (mixed-precision iterative refinement). Where the device
    has float64 shader arithmetic, ``x`` and the float64 weights live in textures
    (two uints per double) and the fold is one fragment pass; otherwise ``x``
    stays on the host and the fold runs in NumPy (``host_fp64``).
    """

    def __init__(self, dev: Device, r0: np.ndarray, wu: np.ndarray, wv: np.ndarray, *, host_fp64: bool = False,
                 rhs: np.ndarray | None = None):
        self.dev = dev
        self.nu, self.nv = nu, nv = r0.shape[:2]
        self.k = r0.shape[2]
        if self.k < 3:                       # fewer coordinates (the multigrid's active ones): pad
            r0 = np.concatenate([r0, np.zeros((nu, nv, 3 - self.k))], axis=2)
        self.b = None
        if rhs is not None:                  # interior right-hand side (nu-2, nv-2, k), float64
            self.b = np.zeros((nu, nv, 3))
            self.b[1:-1, 1:-1, :self.k] = rhs
        self.wu, self.wv = wu, wv
        self.device_fp64 = dev.fp64 and not host_fp64
        if self.device_fp64:
            try:
                dev.program("FOLD_RESIDUAL")
            except BackendUnavailableError:   # a driver that rejects the float64 shader: fold on the host
                dev.fp64 = self.device_fp64 = False
        self.timings = {"upload": 0.0, "fold": 0.0, "download": 0.0}
        self._objects: list = []
        t0 = time.perf_counter()
        w = _edge_weights(wu, wv)
        self.w32 = self._tex(4, "f4", w.astype(np.float32))
        self.e = [self._tex(4, "f4", None), self._tex(4, "f4", None)]
        self.e_fbo = [self._fbo(t) for t in self.e]
        self.f = self._tex(4, "f4", None)
        self.f_fbo = self._fbo(self.f)
        for fbo in self.e_fbo + [self.f_fbo]:     # new textures are undefined: zero them on the device
            fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.reducer = Reducer(dev, nv, nu)
        if self.device_fp64:
            wbits = w.view(np.uint32)                                  # (nu, nv, 8): lo, hi per double
            self.wa = self._tex(4, "u4", wbits[..., :4])
            self.wb = self._tex(4, "u4", wbits[..., 4:])
            if self.b is not None:
                ba, bb = self._split(self.b)
                self.ba, self.bb = self._tex(4, "u4", ba), self._tex(4, "u4", bb)
            else:
                self.ba = self.bb = self.wa       # bound but unused (has_b false)
            self.xa, self.xb, self.x_fbo = [], [], []
            xa, xb = self._split(np.ascontiguousarray(r0, np.float64))
            for data in ((xa, xb), (None, None)):
                ta, tb = self._tex(4, "u4", data[0]), self._tex(4, "u4", data[1])
                self.xa.append(ta)
                self.xb.append(tb)
                self.x_fbo.append(self._fbo(ta, tb, self.f))
            self.x = None
        else:
            self.x = np.array(r0, np.float64)
        self.timings["upload"] += time.perf_counter() - t0

    # -- helpers
    def _tex(self, comps: int, dtype: str, data: np.ndarray | None):
        tex = self.dev.texture(self.nv, self.nu, comps, dtype, None if data is None else np.ascontiguousarray(data))
        self._objects.append(tex)
        return tex

    def _fbo(self, *textures):
        fbo = self.dev.framebuffer(*textures)
        self._objects.append(fbo)
        return fbo

    @staticmethod
    def _split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        bits = x.view(np.uint32)                                       # (nu, nv, 6)
        xb = np.zeros(x.shape[:2] + (4,), np.uint32)
        xb[..., :2] = bits[..., 4:6]
        return np.ascontiguousarray(bits[..., :4]), xb

    # -- the float32 correction
    def swap_correction(self) -> None:
        """Make the second correction texture (just drawn into) the current one."""
        self.e.reverse()
        self.e_fbo.reverse()

    def clear_correction(self) -> None:
        self.e_fbo[0].clear(0.0, 0.0, 0.0, 0.0)

    def fold(self) -> float:
        """``x += e``, ``f = b - A x`` (float64), ``e = 0``; returns ``max |D^-1 (b - A x)|`` (float64, rounded up)."""
        t0 = time.perf_counter()
        if self.device_fp64:
            self.dev.draw("FOLD_RESIDUAL", self.x_fbo[1],
                          {"xa": self.xa[0], "xb": self.xb[0], "e": self.e[0], "wa": self.wa, "wb": self.wb,
                           "ba": self.ba, "bb": self.bb}, {"has_b": self.b is not None, "has_z": self.k == 3})
            for pair in (self.xa, self.xb, self.x_fbo):
                pair.reverse()
            self.clear_correction()
            s = self.reducer.max(self.f, 3)
        else:
            from .. import cpu
            from ...weights import interior_diagonal

            e = np.frombuffer(self.e[0].read(), np.float32).reshape(self.nu, self.nv, 4)
            self.x[1:-1, 1:-1] += e[1:-1, 1:-1, :3]
            r = cpu.residual(self.x, self.wu, self.wv)
            if self.b is not None:
                r += self.b[1:-1, 1:-1]
            s = np.linalg.norm(r, axis=-1) / interior_diagonal(self.wu, self.wv)
            f = np.zeros((self.nu, self.nv, 4), np.float32)
            f[1:-1, 1:-1, :3] = r
            f[1:-1, 1:-1, 3] = s
            self.f.write(f)
            self.clear_correction()
            s = float(s.max()) if s.size else 0.0
        self.timings["fold"] += time.perf_counter() - t0
        return s

    def points(self) -> np.ndarray:
        """The float64 iterate ``x`` (without ``e``: fold first)."""
        t0 = time.perf_counter()
        if self.device_fp64:
            a = np.frombuffer(self.xa[0].read(), np.uint32).reshape(self.nu, self.nv, 4)
            if self.k == 3:
                b = np.frombuffer(self.xb[0].read(), np.uint32).reshape(self.nu, self.nv, 4)
                a = np.concatenate([a, b[..., :2]], axis=-1)
            out = np.ascontiguousarray(a).view(np.float64).reshape(self.nu, self.nv, -1)
        else:
            out = self.x
        out = np.ascontiguousarray(out[..., :self.k])
        self.timings["download"] += time.perf_counter() - t0
        return out

    def release(self) -> None:
        self.reducer.release()
        for obj in reversed(self._objects):
            obj.release()
        self._objects = []
