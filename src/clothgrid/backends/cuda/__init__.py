"""cuda backend: the multigrid and fdm solvers on an NVIDIA GPU (CuPy arrays, numba.cuda kernels).

``pip install 'clothgrid[cuda]'`` (CuPy for CUDA 12 and numba-cuda). The grid
and the multigrid hierarchy live in GPU memory as CuPy arrays; the multigrid's
operations are the CPU multigrid's kernels written for ``numba.cuda``
(:mod:`clothgrid.backends.cuda._kernels`), one thread per node or per line
block; fdm's four dense products are cuBLAS GEMMs on the eigenvectors computed
on the host. The float64 residual and the error bound are computed on the GPU;
one float per V-cycle and the finished grid come back. ``docs/cuda.md`` says
what runs where.

Under Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1`` set before
``numba.cuda`` is imported) the same code runs on the CPU with NumPy arrays,
which is how the tests check the kernels without a GPU; ``backend="auto"``
never picks the simulator.

:func:`require` raises :class:`~clothgrid.errors.BackendUnavailableError`
with the reason when there is no GPU to use: CuPy missing, no GPU or driver
for CuPy, numba.cuda or libNVVM unusable.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from ...errors import InputError, SizeError
from ...memory import format_bytes
from ...multigrid_levels import Level
from ...weights import interior_diagonal
from ..cpu import residual
from ..protocol import ProblemData
from . import _device, _sim

if TYPE_CHECKING:   # annotations only: the operations' modules load on first use (numba.cuda)
    from ...heat_multigrid import HeatHierarchy
    from ._heat import CudaHeatOps
    from ._multigrid import CudaMultigrid

__all__ = ["name", "solvers", "require", "available", "on_gpu", "array_module", "info", "describe", "summary",
           "device_bytes", "check_size", "residual", "max_step", "multigrid", "jacobi_sweeper", "heat_ops"]

name = "cuda"
#: Solvers that run on this backend (``auto`` picks the first).
solvers: tuple[str, ...] = ("multigrid", "fdm")


def require() -> _device.Device:
    """The device; raises BackendUnavailableError (with the reason) when there is none."""
    return _device.require()


def available() -> tuple[bool, str]:
    """``(True, device name)`` or ``(False, why not)``; cheap when CuPy is not installed, remembered."""
    dev = _device.probe()
    return (False, dev) if isinstance(dev, str) else (True, dev.name)


def on_gpu() -> bool:
    """True when the backend has a real GPU (not the simulator): ``get_backend("auto")`` then picks it."""
    dev = _device.probe()
    return not isinstance(dev, str) and not dev.simulated


def array_module() -> ModuleType:
    """The module of the device's arrays: CuPy on a GPU, NumPy under the simulator."""
    require()
    return _sim.array_module()


def describe() -> dict[str, Any]:
    """``cuda_*`` keys of a grid's info: ``cuda_device`` (name), ``cuda_compute_capability``,
    ``cuda_memory`` (bytes), ``cuda_cupy`` (version), ``cuda_simulator``."""
    return require().describe()


info = describe


def summary() -> str:
    """One line: the device, its compute capability and memory, CuPy's version."""
    return require().summary()


def device_bytes(solver: str, nu: int, nv: int, coords: int = 3, separable: bool = False) -> int:
    """Bytes of device memory a solve of an ``nu x nv`` grid allocates, at most.

    ``coords`` is the number of coordinates solved (2 for a planar piece given in
    2D), ``separable`` whether the weights are the paper's or uniform (1D factors).

    ``multigrid``, per node, ``k = coords``: level 0's float64 iterate as parity
    planes (``8 k``) and the grid it is split from and merged back into
    (``8 k``); the coarse levels, about as many nodes again in all: five float32
    stencil arrays, float32 iterate and right-hand side (``20 + 8 k``); the line
    solves' scratch, three float64 arrays over level 0's lines and three float32
    ones over level 1's (15); the float64 temporaries that form the coarse
    stencils (8); and 32 MiB whatever the size (the pool's rounding, the
    kernels' modules). Per-edge weights add level 0's edge weights split by parity
    (16), a second hierarchy for the barrier solve of the error bound, one
    coordinate with a right-hand side (83; the residual solve's operations tried before it share
    the stencils and take less, about 40 + 16 k, returned to CuPy's pool before the barrier solve
    would take it), and conjugate gradients' three float64
    vectors and one array temporary (``32 k``: where V-cycles stall on jumps). Measured on an H100 (NVML, the
    T-shirt front, two coordinates, paper weights): 84-86 bytes a node from
    1024^2 to 16384^2 against the 91 counted here. ``fdm``: the two eigenvector
    matrices, ``8 ((nu-2)^2 + (nv-2)^2)``, and per node the right-hand side, the
    grid and its copy, the weights, the residual and the products' three work
    arrays (192).
    """
    n = nu * nv
    if solver == "multigrid":
        return (24 * coords + 20 + 15 + 8 + (0 if separable else 16 + 83 + 32 * coords)) * n + (32 << 20)
    if solver == "fdm":
        return 8 * ((nu - 2) ** 2 + (nv - 2) ** 2) + 192 * n
    raise InputError(f"solver {solver!r} does not run on backend 'cuda': use one of {', '.join(solvers)}")


def check_size(nu: int, nv: int, solver: str, host_bytes: int = 0, coords: int = 3, separable: bool = False) -> int:
    """Raise :class:`~clothgrid.errors.SizeError` before allocating a grid the device cannot hold.

    The solve fits when :func:`device_bytes` is at most 90 % of the device's
    free memory (CuPy's pooled free blocks included). ``host_bytes``, the
    host's share of the solve, counts too under the simulator, whose device
    memory is the host's. Returns the bytes counted.
    """
    dev = require()
    need = device_bytes(solver, nu, nv, coords, separable) + (host_bytes if dev.simulated else 0)
    have = dev.free_memory()
    if need > 0.9 * have:
        raise SizeError(f"a {nu}x{nv} grid with solver '{solver}' needs about {format_bytes(need)} of device "
                        f"memory on backend 'cuda', more than the 90 % of the {format_bytes(have)} free on {dev.name} "
                        "that a solve may take: use fewer nodes or backend 'cpu'")
    return need


def max_step(r: Any, wu: Any, wv: Any) -> float:
    """The largest step a Jacobi sweep would make from the device grid ``r``, in float64 on the device.

    ``max |D^-1 (b - A r)|`` (Euclidean per node) from device arrays ``r``,
    ``wu``, ``wv``: the factor of the error bound of
    :mod:`clothgrid.solvers.bounds`, computed as :func:`clothgrid.backends.cpu.max_step` does.
    """
    xp = array_module()
    res = residual(r, wu, wv)
    return float((xp.sqrt(xp.sum(res * res, axis=-1)) / interior_diagonal(wu, wv)).max())


def multigrid(levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None,
              spare: np.ndarray | None = None) -> CudaMultigrid:
    """The multigrid operations (:class:`~clothgrid.backends.protocol.MultigridOps`) on the device.

    ``levels`` from :func:`~clothgrid.multigrid_levels.build_hierarchy`; ``x0``
    the ``(nu, nv, k)`` level-0 iterate (any strides) and ``rhs`` the optional interior
    right-hand side, both host arrays, uploaded once. ``spare``, the host grid the solution
    comes back into, is left as it is: giving its pages back during the cycles (0.1 s at
    4096^2 on a GPU) would cost as much again when the solution faults them in, and the
    host's peak memory is the same either way (the upload allocates no grid on the host).
    """
    require()
    from ._multigrid import CudaMultigrid

    ops = CudaMultigrid(levels, x0, rhs)
    ops.synchronize()
    return ops


def jacobi_sweeper(problem: ProblemData, *, stop: str = "error") -> NoReturn:
    """Jacobi does not run on this backend: raises :class:`~clothgrid.errors.InputError` saying so."""
    raise InputError(f"solver 'jacobi' does not run on backend 'cuda': use one of {', '.join(solvers)} "
                     "(or backend 'cpu' or 'gl')")


def heat_ops(hierarchy: HeatHierarchy) -> CudaHeatOps:
    """The heat solver's operations (:class:`~clothgrid.backends.protocol.HeatOps`) on the device: the CPU's
    kernels written for ``numba.cuda`` over CuPy arrays, float64, the hierarchy uploaded once."""
    require()
    from ._heat import CudaHeatOps

    return CudaHeatOps(hierarchy)
