"""The cuda backend's device: a CUDA GPU through CuPy and numba.cuda, or Numba's CUDA simulator.

:func:`probe` looks once per process and remembers the answer: a
:class:`Device`, or the reason there is none. Without CuPy it only asks
``importlib`` whether the package exists (no import, no traceback).
"""

from __future__ import annotations

import importlib.util
import os
import sys
from dataclasses import dataclass

from ...errors import BackendUnavailableError
from ...memory import available_bytes, format_bytes
from . import _compat, _sim

SIMULATOR = "Numba CUDA simulator"
_INSTALL = "pip install 'clothgrid[cuda]'"

_PROBE: Device | str | None = None   # the answer of probe(), once asked

#: What a process forked after its parent had started CUDA is told (:func:`_forked`).
FORKED = ("backend 'cuda' cannot run in a process forked after its parent used CUDA: a CUDA context "
          "does not survive fork(). Start worker processes with multiprocessing's 'spawn' or "
          "'forkserver' method, or use backend 'cpu'")


def _forked() -> None:
    """In a forked child of a parent that found a GPU (and so started CUDA): the backend is
    unavailable, with the reason. The simulator's NumPy arrays survive a fork: it stays."""
    global _PROBE
    if isinstance(_PROBE, Device) and not _PROBE.simulated:
        _PROBE = FORKED


os.register_at_fork(after_in_child=_forked)


@dataclass(frozen=True)
class Device:
    """What the backend runs on.

    Attributes
    ----------
    name : str
        The GPU's name, or ``"Numba CUDA simulator"``.
    simulated : bool
        True under Numba's CUDA simulator (arrays in NumPy, memory the host's).
    compute_capability, total_memory, cupy_version
        The GPU's, ``None`` under the simulator.
    """

    name: str
    simulated: bool
    compute_capability: str | None = None
    total_memory: int | None = None
    cupy_version: str | None = None

    def free_memory(self) -> int:
        """Bytes a solve may allocate now: the GPU's free memory plus CuPy's pooled free blocks,
        or the host's available memory under the simulator."""
        if self.simulated:
            return available_bytes()
        import cupy  # GPU only

        return cupy.cuda.runtime.memGetInfo()[0] + cupy.get_default_memory_pool().free_bytes()  # GPU only

    def describe(self) -> dict:
        """``cuda_*`` keys of a grid's info."""
        return {"cuda_device": self.name, "cuda_simulator": self.simulated,
                "cuda_compute_capability": self.compute_capability, "cuda_memory": self.total_memory,
                "cuda_cupy": self.cupy_version}

    def summary(self) -> str:
        """One line: the device, its compute capability and memory, CuPy's version."""
        if self.simulated:
            return f"{SIMULATOR} (NumPy arrays, kernels run on the CPU)"
        return (f"{self.name}, compute capability {self.compute_capability}, "  # GPU only
                f"{format_bytes(self.total_memory)}, CuPy {self.cupy_version}")


def probe() -> Device | str:
    """The device, or why there is none (remembered for the process)."""
    global _PROBE
    if _PROBE is None:
        _PROBE = Device(SIMULATOR, simulated=True) if _sim.active() else _gpu()
    return _PROBE


def require() -> Device:
    """The device; raises :class:`BackendUnavailableError` with the reason when there is none."""
    dev = probe()
    if isinstance(dev, str):
        raise BackendUnavailableError(dev)
    return dev


def _driver_present() -> bool:
    """False only on Linux with none of the NVIDIA driver's device files (elsewhere: cannot tell, True)."""
    if not sys.platform.startswith("linux"):
        return True
    return any(os.path.exists(p) for p in ("/dev/nvidiactl", "/dev/nvidia0", "/dev/dxg", "/proc/driver/nvidia"))


def _gpu() -> Device | str:
    """The first CUDA GPU, or the first thing missing: CuPy, a GPU CuPy can use, numba.cuda, libNVVM."""
    if importlib.util.find_spec("cupy") is None:
        return f"backend 'cuda' needs CuPy and an NVIDIA GPU: CuPy is not installed ({_INSTALL})"
    # CuPy's import alone costs ~0.5 s: not where no NVIDIA driver is installed (an already
    # imported CuPy costs nothing to ask, and says more)
    if sys.modules.get("cupy") is None and not _driver_present():
        return ("backend 'cuda' finds no usable GPU: no NVIDIA driver on this machine "
                "(no /dev/nvidiactl, /dev/nvidia0, /dev/dxg or /proc/driver/nvidia)")
    try:
        import cupy
    except Exception as exc:   # a broken install: CUDA libraries missing, wrong wheel, ...
        return f"backend 'cuda': CuPy is installed but does not import ({type(exc).__name__}: {exc})"
    try:
        if cupy.cuda.runtime.getDeviceCount() < 1:
            raise RuntimeError("no CUDA device")
    except Exception as exc:   # CUDARuntimeError: no driver, driver too old, no device, ...
        return (f"backend 'cuda' finds no usable GPU: CuPy {cupy.__version__} is installed, but CUDA says "
                f"{type(exc).__name__}: {exc}")
    _compat.patch_numpy()   # before numba.cuda compiles anything
    from numba import cuda

    if not cuda.is_available():
        return f"backend 'cuda': CuPy finds a GPU but numba.cuda cannot use it ({cuda.cuda_error()})"
    from numba.cuda.cudadrv import nvvm  # GPU only from here

    if not nvvm.is_available():
        return f"backend 'cuda': numba.cuda finds no libNVVM to compile its kernels ({_INSTALL} installs it)"
    props = cupy.cuda.runtime.getDeviceProperties(cupy.cuda.Device().id)
    return Device(props["name"].decode(), simulated=False, compute_capability=f"{props['major']}.{props['minor']}",
                  total_memory=cupy.cuda.runtime.memGetInfo()[1], cupy_version=cupy.__version__)
