"""gl backend: the paper's method on the graphics pipeline (OpenGL 4.3 through headless EGL).

The grid lives in textures on the GL device: the float32 correction in RGBA32F
(x, y, z and a spare channel for each node's step), the per-edge weights as
RGBA32F "four weights per node", and the float64 iterate and weights as pairs of
uints where the device has float64 shader arithmetic. Eq. (3) is a fragment
shader drawn into ping-pong framebuffers; boundary nodes are never written; the
largest step is found by a max-reduction pyramid, read back one float at a time.
The error bound every solver reports is computed from a float64 residual (on
the device, or on the host where the device lacks float64). ``docs/gl.md`` says
what runs where.

It runs on Mesa's llvmpipe (no GPU: Debian packages ``libegl1 libgl1
libgl1-mesa-dri``) and on vendor drivers with EGL. :func:`require` raises
:class:`~clothgrid.errors.BackendUnavailableError` with the reason when no
context can be made.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import InputError
from ...multigrid_levels import Level
from ..cpu import max_step, residual
from ..protocol import ProblemData

if TYPE_CHECKING:   # annotations only: the device's modules load on first use (moderngl)
    from ...heat_multigrid import HeatHierarchy
    from ._device import Device
    from ._heat import GLHeatOps
    from ._jacobi import GLJacobi
    from ._multigrid import GLMultigrid

__all__ = ["name", "solvers", "require", "available", "info", "describe", "summary", "check_size", "device_bytes",
           "array_module", "residual", "max_step", "jacobi_sweeper", "multigrid", "heat_ops"]

name = "gl"
#: Solvers that run on this backend (``auto`` picks the first).
solvers = ("multigrid", "jacobi")
#: Run the float64 steps (fold, residual, bound) in NumPy even where the device has doubles.
HOST_FP64 = False


def require() -> Device:
    """The GL device; raises BackendUnavailableError (with the reason) when there is none."""
    from ._device import device

    return device()


def available() -> tuple[bool, str]:
    """``(True, renderer)`` or ``(False, why not)``."""
    from ...errors import BackendUnavailableError

    try:
        return True, require().renderer
    except BackendUnavailableError as exc:
        return False, str(exc)


def describe() -> dict[str, Any]:
    """``gl_*`` keys of a grid's info: renderer, vendor, version, texture size limit, and where
    the float64 steps run (``gl_fp64``: ``device`` with GL doubles, else ``host``)."""
    dev = require()
    return {**dev.describe(), "gl_fp64": "device" if dev.fp64 and not HOST_FP64 else "host"}


info = describe


def summary() -> str:
    """One line: renderer and GL version."""
    d = require()
    return f"{d.renderer}, OpenGL {d.version}"


def device_bytes(solver: str, nu: int, nv: int, coords: int = 3, separable: bool = False) -> int:
    """Bytes of textures a solve of an ``nu x nv`` grid allocates on the device.

    Textures hold four channels whatever ``coords`` and ``separable`` are (taken
    for the cuda backend's signature). Measured on an H100 (NVML): the multigrid
    took 295 bytes a node at 4096^2 and 326 at 8192^2.
    """
    n = nu * nv
    base = 16 * 4 * n + 16 * n // 15 + 2          # RGBA32F weights, correction (2), right-hand side; reduction
    base += (32 + 2 * 32) * n                      # float64 weights, float64 iterate (2 x 2 RGBA32UI)
    if solver == "jacobi":
        return base + 16 * n                        # the chunk's snapshot
    if solver == "multigrid":
        # level 0: Thomas factors and a residual; coarse levels (about nu * nv nodes in all):
        # iterate (2), right-hand side, residual and three stencil textures (the residual
        # textures are made only if needed: an upper estimate); the driver's own share,
        # measured: two textures' worth
        return base + 2 * 16 * n + 7 * 16 * n + 2 * 16 * n
    raise InputError(f"solver {solver!r} does not run on backend 'gl': use one of {', '.join(solvers)}")


def check_size(nu: int, nv: int, solver: str, host_bytes: int = 0, coords: int = 3, separable: bool = False) -> int:
    """Raise :class:`~clothgrid.errors.SizeError` before allocating a grid the device cannot hold.

    The limits come from the driver: GL_MAX_TEXTURE_SIZE (and the viewport and
    framebuffer limits) for the side, the free memory where the driver says it
    (host memory for a software renderer), and a probe texture for large grids.
    Returns the bytes of textures counted.
    """
    need = device_bytes(solver, nu, nv)
    require().check_size(nu, nv, need, host_bytes)
    return need


def array_module() -> ModuleType:
    """NumPy: the grids a solver hands over and gets back are host arrays (the device holds textures).

    :func:`residual` and :func:`max_step` are the CPU backend's, in float64 on the
    host: the error bound of a solve whose grid is on the host (the device's
    own solvers compute it on the device, see ``docs/gl.md``).
    """
    return np


def jacobi_sweeper(problem: ProblemData, *, stop: str = "error") -> GLJacobi:
    """Jacobi sweeps on the device for :func:`clothgrid.solvers.jacobi.solve_jacobi`."""
    from ._jacobi import GLJacobi

    return GLJacobi(problem, stop=stop, host_fp64=HOST_FP64)


def multigrid(levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None,
              spare: np.ndarray | None = None) -> GLMultigrid:
    """The multigrid operations (:class:`~clothgrid.backends.protocol.MultigridOps`) on the device;
    ``spare``'s pages go back to the system once ``x0`` is uploaded (:func:`clothgrid.memory.release`)."""
    from ...memory import release
    from ._multigrid import GLMultigrid

    ops = GLMultigrid(levels, x0, rhs, host_fp64=HOST_FP64)
    ops.synchronize()
    release(spare)
    return ops


def heat_ops(hierarchy: HeatHierarchy) -> GLHeatOps:
    """The heat solver's operations (:class:`~clothgrid.backends.protocol.HeatOps`) on the device: float32
    shaders, the hierarchy uploaded once; the solver refines in float64 on the host (docs/heat.md)."""
    from ._heat import GLHeatOps

    return GLHeatOps(hierarchy)
