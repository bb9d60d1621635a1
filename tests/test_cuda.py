"""The cuda backend (CuPy and numba.cuda on an NVIDIA GPU).

Three groups:

- the kernels under Numba's CUDA simulator, on every machine: ``tests/cuda_simulated.py``
  run in a subprocess with ``NUMBA_ENABLE_CUDASIM=1`` (the simulator must be chosen before
  ``numba.cuda`` is imported; this process keeps the real one), against the CPU multigrid
  operation by operation and against the independent reference; and every kernel compiled
  to PTX for a Hopper GPU (sm_90) where libNVVM is installed, GPU or not;
- on a machine without a usable GPU: the reasons ``backend="cuda"`` gives, ``auto`` choosing
  the CPU, the CLI's exit code;
- on a GPU (skipped, with the reason, elsewhere): whole solves against the CPU backend and
  the reference at 257x257 and 1025x1025, fdm, the size check.
"""

from __future__ import annotations

import importlib.machinery
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from conftest import in_forked_child, smooth_quad_sides
from reference import exact_solution, max_rel_error, paper_weights

import clothgrid
from clothgrid.backends import cpu, cuda, get_backend
from clothgrid.backends.cuda import _device
from clothgrid.initial import boundary_grid

TOL = 2.0**-12
F32 = 1e-5
HERE = Path(__file__).parent
GPU = cuda.on_gpu()
needs_gpu = pytest.mark.skipif(not GPU, reason=f"no GPU for backend 'cuda': {cuda.available()[1]}")
without_gpu = pytest.mark.skipif(GPU, reason="a GPU is available: the unavailable backend cannot be shown")


def quad(rng, nu, nv, dim=2):
    return clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, nu, nv, dim=dim))


@pytest.fixture
def fresh_probe(monkeypatch):
    """Forget the remembered device for one test (and restore it after)."""
    monkeypatch.setattr(_device, "_PROBE", None)


# --- the kernels, without a GPU ----------------------------------------------------------------------------

def test_kernels_under_the_simulator():
    """``tests/cuda_simulated.py`` in a subprocess with Numba's CUDA simulator (about 20 s), with this
    run's seed (a failure names it: ``CLOTHGRID_TEST_SEED`` replays the same fresh inputs)."""
    from conftest import SEED

    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "CLOTHGRID_TEST_SEED": str(SEED)}
    cmd = [sys.executable, "-m", "pytest", str(HERE / "cuda_simulated.py"), "-q", "-p", "no:cacheprovider"]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=HERE.parent)
    assert p.returncode == 0, f"CLOTHGRID_TEST_SEED={SEED}\n" + p.stdout[-6000:] + p.stderr[-2000:]
    assert " passed" in p.stdout and "skipped" not in p.stdout


def kernel_signatures():
    """Each kernel with the argument types the cuda multigrid launches it with (level 0, coarse levels)."""
    from numba.core import types as nt

    def arr(dt, nd):
        return nt.Array(dt, nd, "C")

    f8, f4, i8, b1 = nt.float64, nt.float32, nt.int64, nt.boolean
    a3, a2 = (lambda dt: arr(dt, 3)), (lambda dt: arr(dt, 2))
    line = {dt: (a3(dt),) * 3 + (a2(dt),) * 11 + (i8,) * 7 + (b1, b1) for dt in (f8, f4)}
    seps = {dt: (a3(dt),) + (a2(dt),) * 4 + (i8,) * 5 for dt in (f8, f4)}
    spread = {dt: (a3(dt),) + (a2(dt),) * 2 + (i8,) * 4 for dt in (f8, f4)}
    coarse4 = (a3(f4),) * 4
    return {
        "line_blocks": [line[f8], line[f4]],
        "line_solve": [line[f8], line[f4]],
        "line_separators": [seps[f8], seps[f4]],
        "line_spread": [spread[f8], spread[f4]],
        "restrict5": [(a3(f8),) * 3 + (a2(f8),) * 3 + (i8, i8, b1) + coarse4],
        "restrict9": [(a3(f4),) * 3 + (a2(f4),) * 8 + coarse4],
        "prolong": [(a3(f8), a3(f4), a3(f4)), (a3(f4),) * 3],
        "restrict5_full": [(a3(f8),) * 4 + (a2(f8),) * 4 + (i8, i8, b1, i8) + coarse4],
        "restrict_rhs": [(a3(f4),) * 2 + (i8,) + coarse4],
        "prolong_full": [(a3(f8),) * 2 + (a3(f4),) * 2 + (i8,), (a3(f4),) * 4 + (i8,)],
        "max_step5": [(a3(f8),) * 4 + (a2(f8),) * 4 + (i8, i8, i8, b1, i8, a2(f8))],
        "split_grid": [(a3(f8),) * 3],
        "residual5": [(a3(f8),) * 4 + (a2(f8),) * 4 + (i8, i8, i8, b1, f8) + (a3(f8),) * 2],
        "merge_grid": [(a3(f8),) * 3],
    }


def test_kernels_compile_for_a_gpu(monkeypatch):
    """Every kernel through Numba's CUDA typing, lowering and libNVVM to PTX: for this machine's GPU,
    or without one for a Hopper GPU (sm_90, the H200's)."""
    from clothgrid.backends.cuda import _sim

    if _sim.active():
        pytest.skip("NUMBA_ENABLE_CUDASIM is set: numba.cuda is the simulator, which compiles nothing")
    from numba import cuda as ncuda
    from numba.cuda import dispatcher
    from numba.cuda.cudadrv import nvvm

    if not nvvm.is_available():
        pytest.skip("libNVVM not found (a CUDA toolkit, or pip install 'clothgrid[cuda]')")
    if ncuda.is_available():
        cc = ncuda.get_current_device().compute_capability
    else:   # device functions are compiled for the current device's capability: say which
        cc = (9, 0)
        monkeypatch.setattr(dispatcher, "get_current_device", lambda: types.SimpleNamespace(compute_capability=cc))
    from clothgrid.backends.cuda import _kernels

    sigs = kernel_signatures()
    launched = {n for n in vars(_kernels) if hasattr(getattr(_kernels, n), "py_func") and not n.startswith("_")}
    assert launched == set(sigs)
    for kernel_name, variants in sigs.items():
        for sig in variants:
            ptx, _ = ncuda.compile_ptx(getattr(_kernels, kernel_name).py_func, sig, cc=cc)
            assert f".target sm_{cc[0]}{cc[1]}" in ptx and ".entry" in ptx, kernel_name


def test_a_process_forked_after_cuda_started_is_told_why(monkeypatch):
    """A CUDA context does not survive fork(): a child forked after the parent found a GPU (and so
    started CUDA) gets the reason instead of CUDA's errors; the simulator, the parent, and a parent
    that found none are left as they were."""
    monkeypatch.setattr(_device, "_PROBE", _device.Device("Test GPU", simulated=False))
    said = in_forked_child(lambda: "|".join(map(str, cuda.available())))
    assert said.startswith("False|backend 'cuda' cannot run in a process forked after its parent used CUDA"), said
    assert cuda.available() == (True, "Test GPU")
    monkeypatch.setattr(_device, "_PROBE", _device.Device(_device.SIMULATOR, simulated=True))
    assert in_forked_child(lambda: "|".join(map(str, cuda.available()))) == f"True|{_device.SIMULATOR}"
    monkeypatch.setattr(_device, "_PROBE", "no GPU (test)")
    assert in_forked_child(lambda: "|".join(map(str, cuda.available()))) == "False|no GPU (test)"


def test_device_memory_estimates():
    # 3 coordinates, per-edge weights (conjugate gradients' vectors included)
    assert cuda.device_bytes("multigrid", 100, 100) == (72 + 43 + 99 + 96) * 10_000 + (32 << 20)
    assert cuda.device_bytes("multigrid", 100, 100, coords=2, separable=True) == 91 * 10_000 + (32 << 20)
    assert cuda.device_bytes("fdm", 102, 52) == 8 * (100**2 + 50**2) + 192 * 102 * 52
    with pytest.raises(clothgrid.InputError, match="does not run on backend 'cuda'"):
        cuda.device_bytes("direct", 10, 10)


def test_size_check_compares_with_the_free_memory(monkeypatch, fresh_probe):
    dev = _device.Device("Test GPU", simulated=True)
    monkeypatch.setattr(_device, "_PROBE", dev)
    monkeypatch.setattr(_device, "available_bytes", lambda: 206 * 1000**2)
    cuda.check_size(100, 100, "multigrid")                       # 1 % of it
    with pytest.raises(clothgrid.SizeError, match=r"needs about .* of device memory .* free on Test GPU"):
        cuda.check_size(1000, 1000, "multigrid", host_bytes=1)   # 100 %
    assert dev.describe()["cuda_device"] == "Test GPU" and dev.describe()["cuda_simulator"] is True


def test_auto_picks_cuda_only_on_a_gpu_and_for_its_solvers(monkeypatch):
    monkeypatch.setattr(cuda, "on_gpu", lambda: True)
    assert get_backend("auto") is cuda and get_backend("auto", "multigrid") is cuda
    assert get_backend("auto", "fdm") is cuda
    assert get_backend("auto", "direct") is cpu and get_backend("auto", "jacobi") is cpu
    monkeypatch.setattr(cuda, "on_gpu", lambda: False)
    assert get_backend("auto") is cpu


def test_auto_leaves_small_grids_on_the_cpu(monkeypatch, rng):
    """A cuda solve's fixed cost loses to the host's cores below about 700^2 (an H200 host): auto
    takes the cpu there, and cuda from AUTO_GPU_MIN_NODES nodes on."""
    from clothgrid.backends import AUTO_GPU_MIN_NODES

    monkeypatch.setattr(cuda, "on_gpu", lambda: True)
    assert get_backend("auto", "multigrid", AUTO_GPU_MIN_NODES - 1) is cpu
    assert get_backend("auto", "multigrid", AUTO_GPU_MIN_NODES) is cuda
    assert get_backend("auto", "fdm", 33 * 33) is cpu
    g = clothgrid.generate(quad(rng, 17, 17))           # a small piece with a GPU found: the cpu
    assert g.info["backend"] == "cpu"
    from clothgrid.generate import check_size

    assert check_size((40, 40))[1] > 0                   # planned on the cpu: no device asked


# --- without a GPU: why not -------------------------------------------------------------------------------

@without_gpu
def test_missing_cupy_says_how_to_install(monkeypatch, fresh_probe):
    monkeypatch.setitem(sys.modules, "cupy", None)     # as if not installed
    install = r"CuPy is not installed \(pip install 'clothgrid\[cuda\]'\)"
    with pytest.raises(clothgrid.BackendUnavailableError, match=install):
        get_backend("cuda")
    assert get_backend("auto") is cpu
    ok, why = cuda.available()
    assert not ok and "CuPy is not installed" in why and not cuda.on_gpu()


def fake_cupy(devices):
    """A ``cupy`` module whose CUDA runtime has ``devices`` GPUs, or raises them if an exception."""
    class CUDARuntimeError(RuntimeError):
        pass

    def count():
        if isinstance(devices, str):
            raise CUDARuntimeError(devices)
        return devices

    mod = types.ModuleType("cupy")
    mod.__spec__ = importlib.machinery.ModuleSpec("cupy", None)
    mod.__version__ = "13.9.9"
    mod.cuda = types.SimpleNamespace(runtime=types.SimpleNamespace(getDeviceCount=count))
    return mod


@without_gpu
@pytest.mark.parametrize("devices, said", [
    ("cudaErrorNoDevice: no CUDA-capable device is detected", "CUDARuntimeError: cudaErrorNoDevice"),
    (0, "RuntimeError: no CUDA device"),
])
def test_cupy_without_a_gpu_says_what_cuda_says(monkeypatch, fresh_probe, devices, said):
    monkeypatch.setitem(sys.modules, "cupy", fake_cupy(devices))
    with pytest.raises(clothgrid.BackendUnavailableError, match="CuPy 13.9.9 is installed, but CUDA says " + said):
        get_backend("cuda")


@without_gpu
def test_real_cupy_without_a_gpu(fresh_probe):
    """An installed CuPy (not in the test extra: skipped without it) on a GPU-less machine."""
    cupy = pytest.importorskip("cupy")
    ok, why = cuda.available()
    assert not ok and f"CuPy {cupy.__version__} is installed, but CUDA says CUDARuntimeError: cudaError" in why


@without_gpu
def test_numba_cuda_without_a_driver_says_so(monkeypatch, fresh_probe):
    from numba import cuda as ncuda

    if ncuda.is_available():
        pytest.skip("numba.cuda finds a driver here")
    monkeypatch.setitem(sys.modules, "cupy", fake_cupy(1))
    with pytest.raises(clothgrid.BackendUnavailableError, match="numba.cuda cannot use it"):
        get_backend("cuda")


@without_gpu
def test_the_check_without_cupy_is_cheap():
    """No CuPy: ``auto`` looks the package up, imports neither it nor Numba, and remembers the answer."""
    code = ("import sys, importlib.util; sys.modules['cupy'] = None\n"
            "from clothgrid.backends import get_backend, cuda\n"
            "assert get_backend('auto').name == 'cpu' and 'numba' not in sys.modules\n"
            "importlib.util.find_spec = None\n"              # a second look would fail
            "assert get_backend('auto').name == 'cpu' and cuda.available()[0] is False\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr


@without_gpu
def test_cli_backend_cuda_exits_2_and_writes_nothing(capsys, tmp_path, monkeypatch, fresh_probe):
    from clothgrid.cli import main

    monkeypatch.setitem(sys.modules, "cupy", None)
    piece = clothgrid.__file__.replace("__init__.py", "data/tshirt_front.json")
    code = main(["generate", piece, "--nodes", "17x17", "--backend", "cuda", "-o", str(tmp_path / "g.npz")])
    err = capsys.readouterr().err
    assert code == 2 and "CuPy is not installed" in err and not list(tmp_path.iterdir())


# --- on a GPU --------------------------------------------------------------------------------------------

@pytest.mark.skipif(not os.environ.get("CLOTHGRID_EXPECT_GPU"), reason="CLOTHGRID_EXPECT_GPU is not set: "
                    "a GPU is not required on this machine")
def test_the_expected_gpu_is_used():
    """Where the run must be on a GPU (``CLOTHGRID_EXPECT_GPU=1``), the GPU tests must not skip."""
    assert GPU, cuda.available()[1]


@needs_gpu
def test_gpu_reports_itself(rng):
    g = clothgrid.generate(quad(rng, 17, 17), backend="cuda")
    assert g.info["backend"] == "cuda" and g.info["solver"] == "multigrid"
    assert g.info["cuda_device"] and g.info["cuda_simulator"] is False and g.info["cuda_memory"] > 0
    assert get_backend("auto") is cuda


@needs_gpu
@pytest.mark.parametrize("n", [257, 1025])
def test_gpu_multigrid_matches_cpu_and_the_reference(rng, n):
    b = quad(rng, n, n, dim=3)
    g = clothgrid.generate(b, backend="cuda", solver="multigrid")
    c = clothgrid.generate(b, backend="cpu", solver="multigrid")
    ref = exact_solution(boundary_grid(b), *paper_weights(n, n))
    err = max_rel_error(g.points, ref, b.size)
    assert g.info["converged"] and err <= TOL and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14
    assert max_rel_error(g.points, c.points, b.size) <= F32


@needs_gpu
def test_gpu_per_edge_weights(rng):
    n = 129
    b = quad(rng, n, n)
    w = (np.exp(rng.uniform(-2, 2, (n - 1, n))), np.exp(rng.uniform(-2, 2, (n, n - 1))))
    g = clothgrid.generate(b, backend="cuda", weights=w)
    err = max_rel_error(g.points, exact_solution(boundary_grid(b), *w), b.size)
    assert err <= TOL and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


@needs_gpu
@pytest.mark.parametrize("contrast", [100.0, 1e4])
def test_gpu_jumps_go_on_with_conjugate_gradients(rng, contrast):
    """Blocks of 100:1 and 10^4:1 stall V-cycles: on the GPU the solve goes on with conjugate
    gradients (CuPy operations, the residual kernel) and meets the tolerance of the exact solution."""
    n = 129
    b = quad(rng, n, n)
    wu, wv = paper_weights(n, n)
    f = np.where((np.arange(n)[:, None] * 8 // n + np.arange(n)[None, :] * 8 // n) % 2 == 0, contrast, 1.0)
    w = (wu * 0.5 * (f[:-1] + f[1:]), wv * 0.5 * (f[:, :-1] + f[:, 1:]))
    g = clothgrid.generate(b, backend="cuda", solver="multigrid", weights=w)
    err = max_rel_error(g.points, exact_solution(boundary_grid(b), *w), b.size)
    assert g.info["converged"] and g.info.get("cg_iterations", 0) > 0
    assert err <= TOL and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


@needs_gpu
def test_gpu_fdm_matches_cpu(rng):
    b = quad(rng, 257, 200, dim=3)
    g = clothgrid.generate(b, backend="cuda", solver="fdm")
    c = clothgrid.generate(b, backend="cpu", solver="fdm")
    assert g.info["converged"] and max_rel_error(g.points, c.points, b.size) <= 1e-10


@needs_gpu
def test_gpu_refuses_an_absurd_size_before_allocating(rng):
    with pytest.raises(clothgrid.SizeError, match="of device memory on backend 'cuda'"):
        clothgrid.generate(quad(rng, 9, 9), (300_000, 300_000), backend="cuda")


def test_numpy_without_row_stack_is_given_the_alias(monkeypatch):
    """numba-cuda <= 0.30.4 overloads ``np.row_stack``, which NumPy 2.5 removed (seen on an H100)."""
    from clothgrid.backends.cuda import _compat

    monkeypatch.delitem(np.__dict__, "row_stack", raising=False)
    assert "row_stack" not in np.__dict__
    _compat.patch_numpy()
    assert np.row_stack is np.vstack
    _compat.patch_numpy()   # idempotent
    assert np.row_stack is np.vstack


def test_no_driver_files_means_no_cupy_import(monkeypatch, fresh_probe):
    """On Linux without NVIDIA driver files the probe answers without importing CuPy (~0.5 s)."""
    import importlib.util

    monkeypatch.delitem(sys.modules, "cupy", raising=False)
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: importlib.machinery.ModuleSpec("cupy", None) if name == "cupy"
                        else real(name, *a))
    monkeypatch.setattr(_device, "_driver_present", lambda: False)
    with pytest.raises(clothgrid.BackendUnavailableError, match="no NVIDIA driver on this machine"):
        get_backend("cuda")
    assert "cupy" not in sys.modules
    # an already imported CuPy is asked instead (it costs nothing and says more)
    monkeypatch.setattr(_device, "_PROBE", None)
    monkeypatch.setitem(sys.modules, "cupy", fake_cupy(0))
    with pytest.raises(clothgrid.BackendUnavailableError, match="CuPy 13.9.9 is installed"):
        get_backend("cuda")
