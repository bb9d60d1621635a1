"""clothgrid.heat on the gl and cuda backends, against the cpu, an independent direct solve and exact answers.

- the V-cycle the operations (:class:`~clothgrid.backends.protocol.HeatOps`) drive is a symmetric positive
  definite preconditioner on the cpu (``tests/test_architecture.py`` checks every backend's class defines them);
- gl (OpenGL through EGL; Mesa's llvmpipe without a GPU; skipped with the reason where no context can be
  made): each operation against the cpu's from the same state (float32), then whole solves on fresh random
  fields with 10^4 conductivity jumps (the float64 residual reported is the independent assembly's; the
  field is the cpu's and the direct solve's to the tolerance), the layered wall exactly, stretched cells,
  a transient run, the error bound, the host fallback of a large coarsest level, and the command line.
  Small grids: llvmpipe runs on the CPU;
- cuda: without a GPU the reason (API and command line); the kernels under Numba's CUDA simulator
  (``tests/cuda_heat_simulated.py`` in a subprocess) and compiled to PTX; on a GPU (skipped with the
  reason elsewhere) whole solves against the cpu.
"""

from __future__ import annotations

import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from test_heat import _direct, _relative_residual, _system

from clothgrid.backends import cuda, gl, load_backend
from clothgrid.cli import main
from clothgrid.errors import BackendUnavailableError, SizeError
from clothgrid.heat import HeatProblem, convection, flux, solve_steady, solve_transient
from clothgrid.heat_multigrid import HeatHierarchy, Stencil5, padded, vcycle

HERE = Path(__file__).parent
GL_OK, GL_WHY = gl.available()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL device for backend 'gl': {GL_WHY}")
GPU = cuda.on_gpu()
needs_gpu = pytest.mark.skipif(not GPU, reason=f"no GPU for backend 'cuda': {cuda.available()[1]}")
without_gpu = pytest.mark.skipif(GPU, reason="a GPU is available: the unavailable backend cannot be shown")


def jumps(rng, nx: int, ny: int) -> np.ndarray:
    """Random blocks (2-8 cells a side) of 0.025 and 250 W/(m K): contrast 10^4."""
    b = int(rng.integers(2, 9))
    k = np.where(rng.random((-(-nx // b), -(-ny // b))) < 0.4, 250.0, 0.025).repeat(b, 0).repeat(b, 1)
    return k[:nx, :ny]


def random_sides(rng) -> dict:
    """Random boundary conditions, at least one side tying the temperature."""
    kinds = [lambda: float(rng.uniform(15, 40)), lambda: convection(rng.uniform(2, 50), rng.uniform(10, 30)),
             lambda: flux(rng.uniform(-200, 200)), lambda: None]
    sides = {s: kinds[int(rng.integers(4))]() for s in ("left", "right", "bottom", "top")}
    sides[str(rng.choice(["left", "right", "bottom", "top"]))] = float(rng.uniform(15, 40))
    return sides


def random_problem(rng, nx: int, ny: int) -> HeatProblem:
    w = 0.01 * rng.uniform(0.5, 2)
    return HeatProblem(jumps(rng, nx, ny), (w, w * ny / nx * rng.uniform(0.5, 2)),
                       source=rng.uniform(0, 5e4, (nx, ny)), **random_sides(rng))


def hierarchy(rng, nu: int, nv: int, coarsest: int = 16) -> HeatHierarchy:
    k = jumps(rng, nu, nv)
    p = HeatProblem(k, (0.01, 0.01 * nv / nu), left=30, right="h=10,T=20", bottom=25)
    w, _, _ = p.system()
    return HeatHierarchy(Stencil5.from_weights(w.wu, w.wv), coarsest_points=coarsest)


# --- the operations ---------------------------------------------------------------------------------------

def test_the_cpu_vcycle_is_a_symmetric_positive_definite_preconditioner(rng):
    """``M`` from the V-cycle applied to unit vectors: symmetric to rounding, positive definite: plain PCG."""
    h = hierarchy(rng, 12, 10, coarsest=4)
    assert len(h) >= 3
    ops = load_backend("cpu").heat_ops(h)
    n = 12 * 10
    M = np.zeros((n, n))
    for c in range(n):
        r = np.zeros((14, 12))
        r[1 + c // 10, 1 + c % 10] = 1.0
        z = ops.vector()
        vcycle(ops, r, z)
        M[:, c] = z[1:-1, 1:-1].ravel()
    assert np.abs(M - M.T).max() < 1e-12 * np.abs(M).max()
    assert np.linalg.eigvalsh(0.5 * (M + M.T)).min() > 0


# --- gl -------------------------------------------------------------------------------------------------------

def _state(rng, h: HeatHierarchy):
    """Random level vectors for every level (ring zero)."""
    return [padded(rng.standard_normal(lev.shape)) for lev in h.levels]


@needs_gl
def test_gl_operations_equal_the_cpus(rng):
    """Each operation from the same state, gl (float32) against cpu (float64): to float32 rounding."""
    h = hierarchy(rng, 37, 30)
    assert len(h) >= 3
    cpu, g = load_backend("cpu").heat_ops(h), gl.heat_ops(h)
    try:
        def both(make):
            a = make()
            return a, g.upload(a, g.vector())

        def back(v):
            out = np.zeros(h.fine.d.shape)
            g.download(v, out)
            return out

        def close(a, b, scale=None, rel=2e-5):
            scale = scale if scale is not None else np.abs(a).max()
            assert np.abs(a - b).max() <= rel * scale, (np.abs(a - b).max(), scale)

        (x, xg), (b, bg) = both(lambda: padded(rng.standard_normal(h.fine.shape))), \
            both(lambda: padded(rng.standard_normal(h.fine.shape)))
        q, qg = np.zeros_like(x), g.vector()
        pq, pqg = cpu.apply(x, q), g.apply(xg, qg)
        close(q, back(qg))
        assert pqg == pytest.approx(pq, rel=1e-5)
        r, rg = np.zeros_like(x), g.vector()
        cpu.residual(b, x, r)
        g.residual(bg, xg, rg)
        close(r, back(rg))
        assert g.dot(xg, bg) == pytest.approx(cpu.dot(x, b), rel=1e-4, abs=1e-4 * x.size ** 0.5)
        # the V-cycle's operations, level by level and one at a time: the gl state is set to the cpu's before
        # each (chained, float32 rounding is amplified by the 10^4 contrasts, as in any float32 solve)
        xs, bs = _state(rng, h), _state(rng, h)
        for level in range(len(h)):
            cpu.x[level][...] = xs[level]
            cpu.b[level][...] = bs[level]
        r0, z0 = g.vector(), g.vector()
        cpu.bind(bs[0].copy(), xs[0].copy())
        g.bind(r0, z0)

        def sync(*levels):
            for level in levels:
                g.upload(cpu.x[level], g.x[level])
                g.upload(cpu.b[level], g.b[level])

        def level_back(level, which):
            out = np.zeros((h.levels[level].shape[0] + 2, h.levels[level].shape[1] + 2))
            g.download((g.x if which == "x" else g.b)[level], out)
            return out

        for level in range(len(h) - 1):         # in the V-cycle's order: the restriction follows a pre-sweep
            sync(level)
            cpu.smooth(level, True)
            g.smooth(level, True)
            close(cpu.x[level], level_back(level, "x"))
            sync(level)
            cpu.restrict(level)
            g.restrict(level)
            # a residual in float32: rounding relative to its terms, |A| |x| (10^4 contrasts: up to 1e3 x b)
            diag = h.fine.d if level == 0 else h.levels[level].S[..., 4]
            close(cpu.b[level + 1], level_back(level + 1, "b"),
                  np.abs(diag).max() * np.abs(cpu.x[level]).max() + np.abs(cpu.b[level]).max())
        sync(len(h) - 1)
        cpu.coarse_solve()
        g.coarse_solve()
        close(cpu.x[-1], level_back(len(h) - 1, "x"))
        for level in range(len(h) - 2, -1, -1):
            sync(level, level + 1)
            cpu.prolong(level)
            g.prolong(level)
            close(cpu.x[level], level_back(level, "x"))
            sync(level)
            cpu.smooth(level, False)
            g.smooth(level, False)
            # after the coarse correction, float32 line solves across 10^4 contrasts: measured over 300
            # seeds (900 sweeps) median 1.4e-7, 99 % 3.3e-6, largest 3.2e-5 of max |x| (2e-5 failed 1 in 150)
            close(cpu.x[level], level_back(level, "x"), rel=1e-4)
        # a whole V-cycle: float32 against float64 through every level (measured: up to 1e-4 of max |z|)
        r = padded(rng.standard_normal(h.fine.shape))
        z = np.zeros_like(r)
        vcycle(cpu, r, z)
        zg = g.vector()
        vcycle(g, g.upload(r, g.vector()), zg)
        assert np.abs(z - back(zg)).max() <= 1e-3 * np.abs(z).max()
    finally:
        g.release()


@needs_gl
@pytest.mark.parametrize("case", range(3))
def test_gl_equals_cpu_on_fresh_fields_with_1e4_jumps(rng, case):
    """Random blocks of 0.025 / 250 W/(m K), random sides and sources, a fresh field each run: the gl solve's
    float64 residual meets the tolerance (the independent assembly's residual of its field is the same), its
    field is within its guaranteed error bound of a direct solve, and it is the cpu's to the tolerance.

    "To the tolerance": a relative residual of 1e-10 leaves 1e-11 to 1e-8 of the largest temperature
    between either solve and the direct one (30 seeds; 3e-7 once, one fixed side and fluxes elsewhere:
    the range was 4 K of 35 C), so the fields are compared to 1e-6 of the largest temperature."""
    nx, ny = (int(n) for n in rng.integers(20, 48, 2))
    p = random_problem(rng, nx, ny)
    tol = 1e-10
    c = solve_steady(p, tol=tol)
    g = solve_steady(p, tol=tol, backend="gl", error_bound=True)
    info = g.info
    assert info["backend"] == "gl" and info["converged"] and info["residual"] <= tol
    assert info["precision"].startswith("float32") and info["refinements"] >= 1 and info["gl_renderer"]
    # the reported residual is the field's: an independent float64 assembly agrees, to 5 % plus the
    # rounding of forming b - A T where A T nearly cancels b (a fixed 5 % failed once: 3.96e-11
    # against 3.65e-11, a difference of 3e-12, on a field where that rounding is about 1e-12)
    A, b = _system(p)
    T = g.temperature.ravel()
    rounding = 32 * np.finfo(np.float64).eps * np.linalg.norm(abs(A) @ np.abs(T) + np.abs(b)) / np.linalg.norm(b)
    assert abs(_relative_residual(p, g.temperature) - info["residual"]) <= 0.05 * info["residual"] + rounding
    assert info["iterations"] <= c.info["iterations"] + 12, (info, c.info)
    ref = _direct(p)
    assert np.abs(g.temperature - ref).max() <= info["error_bound"] < np.inf
    scale = np.abs(ref).max()
    assert np.abs(g.temperature - ref).max() < 1e-6 * scale
    assert np.abs(g.temperature - c.temperature).max() < 1e-6 * scale


@needs_gl
@pytest.mark.parametrize("axis", ["x", "y"])
def test_gl_layered_wall_is_exact(axis):
    """The layered wall (k = 1, 0.01, 5) of test_heat on gl: float32 passes, float64 refinement: exact to 1e-9 K."""
    n = 60
    kx = np.r_[np.full(20, 1.0), np.full(20, 0.01), np.full(20, 5.0)]
    L, W = 0.03, 0.004
    dx = L / n
    if axis == "x":
        p = HeatProblem(np.repeat(kx[:, None], 8, 1), (L, W), left=34, right=20)
    else:
        p = HeatProblem(np.repeat(kx[None, :], 8, 0), (W, L), bottom=34, top=20)
    res = solve_steady(p, tol=1e-13, backend="gl")
    q = 14.0 / np.sum(dx / kx)
    exact = 34.0 - q * (np.cumsum(dx / kx) - dx / (2 * kx))
    T = res.temperature if axis == "x" else res.temperature.T
    assert np.abs(T - exact[:, None]).max() < 1e-9
    assert res.info["converged"] and res.info["residual"] <= 1e-13


@needs_gl
@pytest.mark.parametrize("sides", [dict(left=34, right=20), dict(bottom=34, top=20)])
def test_gl_stretched_cells(rng, sides):
    k = 10 ** rng.uniform(-1, 1, size=(48, 48))
    p = HeatProblem(k, (0.01, 0.0001), source=1e3, **sides)
    res = solve_steady(p, tol=1e-10, backend="gl")
    assert res.info["converged"] and res.info["iterations"] <= 25, res.info
    ref = _direct(p)
    assert np.abs(res.temperature - ref).max() < 1e-6 * np.ptp(ref)


@needs_gl
def test_gl_error_bound_holds(rng):
    p = random_problem(rng, 32, 24)
    res = solve_steady(p, tol=1e-6, backend="gl", error_bound=True)
    err = np.abs(res.temperature - _direct(p)).max()
    assert err <= res.info["error_bound"] < np.inf


@needs_gl
def test_gl_transient_equals_cpu(rng):
    k = jumps(rng, 24, 16)
    p = HeatProblem(k, (0.01, 0.005), left=34, right="h=10,T=20", capacity=1.5e5)
    kw = dict(dt=2.0, steps=5, initial=20.0, scheme="crank-nicolson", tol=1e-10, save_every=5)
    c = solve_transient(p, **kw)
    g = solve_transient(p, backend="gl", **kw)
    assert g.info["backend"] == "gl" and g.info["residual"] <= 1e-10
    assert np.abs(g.temperature - c.temperature).max() < 1e-6 * np.ptp(c.history)   # measured: up to 1.2e-7


@needs_gl
def test_gl_coarsest_level_on_the_host(rng, monkeypatch):
    """A coarsest level over DENSE_COARSEST unknowns (a long thin grid's one line) is solved by SuperLU on the
    host, the rest on the device: the same answer."""
    from clothgrid.backends.gl import _heat

    monkeypatch.setattr(_heat, "DENSE_COARSEST", 4)
    p = random_problem(rng, 30, 22)
    c = solve_steady(p, tol=1e-10)
    g = solve_steady(p, tol=1e-10, backend="gl")
    assert g.info["gl_heat_coarsest"] == "host (SuperLU)" and g.info["converged"]
    assert np.abs(g.temperature - c.temperature).max() < 1e-6 * np.abs(c.temperature).max()   # as above


@needs_gl
def test_gl_size_is_checked_before_allocating(monkeypatch):
    from clothgrid.backends.gl import _device

    monkeypatch.setattr(_device.device(), "max_size", 32)
    with pytest.raises(SizeError, match="at most 32 texels a side"):
        solve_steady(HeatProblem(1.0, (0.01, 0.01), cells=(40, 8), left=34), backend="gl")


def test_cuda_size_is_checked_before_allocating(rng, monkeypatch):
    """Without a GPU too: the check reads only the device's free memory (a fake device here)."""
    pytest.importorskip("numba.cuda")
    from clothgrid.backends.cuda import _device, _heat

    monkeypatch.setattr(_device, "require", lambda: types.SimpleNamespace(name="Test GPU", free_memory=lambda: 10**5))
    with pytest.raises(SizeError, match=r"heat on 40x30 cells needs about .* free on Test GPU"):
        _heat.CudaHeatOps(hierarchy(rng, 40, 30))


@needs_gl
def test_gl_command_line(tmp_path, capsys):
    out = tmp_path / "t.npz"
    assert main(["heat", "--conductivity", "0.04", "--cells", "40x16", "--size", "0.01x0.004", "--left", "34",
                 "--right", "h=10,T=20", "--backend", "gl", "-o", str(out), "-q"]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    assert "on gl (float32," in line and "float64 refinements" in line
    with np.load(out) as f:
        assert f["temperature"].shape == (40, 16)


# --- cuda -----------------------------------------------------------------------------------------------------

@without_gpu
def test_cuda_without_a_gpu_says_why():
    p = HeatProblem(1.0, (1, 1), cells=(4, 4), left=1)
    with pytest.raises(BackendUnavailableError, match="backend 'cuda'") as exc:
        solve_steady(p, backend="cuda")
    assert str(exc.value) == cuda.available()[1]


@without_gpu
def test_cuda_without_a_gpu_exits_2_with_the_reason(tmp_path, capsys):
    out = tmp_path / "t.npz"
    code = main(["heat", "--size", "0.01x0.01", "--conductivity", "1", "--cells", "4x4", "--left", "34",
                 "--backend", "cuda", "-o", str(out), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("clothgrid: error: backend 'cuda'")
    assert not out.exists()


def test_cuda_heat_kernels_under_the_simulator():
    """``tests/cuda_heat_simulated.py`` in a subprocess with Numba's CUDA simulator."""
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    cmd = [sys.executable, "-m", "pytest", str(HERE / "cuda_heat_simulated.py"), "-q", "-p", "no:cacheprovider"]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=HERE.parent)
    assert p.returncode == 0, p.stdout[-6000:] + p.stderr[-2000:]
    assert " passed" in p.stdout and "skipped" not in p.stdout


def test_cuda_heat_kernels_compile_for_a_gpu(monkeypatch):
    """Every heat kernel through Numba's CUDA typing, lowering and libNVVM to PTX, with the argument types
    the operations launch them with (Fortran-ordered float64): for this machine's GPU, or for sm_90."""
    from clothgrid.backends.cuda import _sim

    if _sim.active():
        pytest.skip("NUMBA_ENABLE_CUDASIM is set: numba.cuda is the simulator, which compiles nothing")
    from numba import cuda as ncuda
    from numba.core import types as nt
    from numba.cuda import dispatcher
    from numba.cuda.cudadrv import nvvm

    if not nvvm.is_available():
        pytest.skip("libNVVM not found (a CUDA toolkit, or pip install 'clothgrid[cuda]')")
    if ncuda.is_available():
        cc = ncuda.get_current_device().compute_capability
    else:
        cc = (9, 0)
        monkeypatch.setattr(dispatcher, "get_current_device", lambda: types.SimpleNamespace(compute_capability=cc))
    from clothgrid.backends.cuda import _heat_kernels as K

    a2, a3, f8, i8, b1 = nt.Array(nt.float64, 2, "F"), nt.Array(nt.float64, 3, "F"), nt.float64, nt.int64, nt.boolean
    sigs = {"apply5": (a2,) * 5, "residual5": (a2,) * 6 + (i8, i8), "residual9": (a3,) + (a2,) * 3 + (i8, i8),
            "lines5": (a2,) * 4 + (i8, a2, a2, b1), "lines9": (a3, a2, a2, i8, a2, a2, b1),
            "restrict_even": (a3, a2, a2), "prolong_add_even": (a3, a2, a2), "update_xr": (a2,) * 4 + (f8,),
            "update_p": (a2, a2, f8)}
    launched = {n for n in vars(K) if hasattr(getattr(K, n), "py_func") and not n.startswith("_")}
    assert launched == set(sigs)
    for name, sig in sigs.items():
        ptx, _ = ncuda.compile_ptx(getattr(K, name).py_func, sig, cc=cc)
        assert f".target sm_{cc[0]}{cc[1]}" in ptx and ".entry" in ptx, name


@needs_gpu
@pytest.mark.parametrize("n", [64, 256])
def test_cuda_equals_cpu_on_1e4_jumps(rng, n):
    p = random_problem(rng, n, n)
    c = solve_steady(p, tol=1e-10)
    g = solve_steady(p, tol=1e-10, backend="cuda")
    assert g.info["backend"] == "cuda" and g.info["converged"] and g.info["precision"] == "float64"
    assert g.info["iterations"] == c.info["iterations"]
    assert _relative_residual(p, g.temperature) <= 1.01e-10
    assert np.abs(g.temperature - c.temperature).max() < 1e-8 * np.ptp(c.temperature)


@needs_gpu
def test_cuda_layered_wall_and_transient(rng):
    n = 60
    kx = np.r_[np.full(20, 1.0), np.full(20, 0.01), np.full(20, 5.0)]
    p = HeatProblem(np.repeat(kx[:, None], 8, 1), (0.03, 0.004), left=34, right=20)
    res = solve_steady(p, tol=1e-13, backend="cuda")
    dx = 0.03 / n
    q = 14.0 / np.sum(dx / kx)
    exact = 34.0 - q * (np.cumsum(dx / kx) - dx / (2 * kx))
    assert np.abs(res.temperature - exact[:, None]).max() < 1e-9
    p = HeatProblem(jumps(rng, 48, 32), (0.01, 0.005), left=34, right="h=10,T=20", capacity=1.5e5)
    kw = dict(dt=2.0, steps=4, initial=20.0, tol=1e-10)
    c, g = solve_transient(p, **kw), solve_transient(p, backend="cuda", **kw)
    assert np.abs(g.temperature - c.temperature).max() < 1e-9 * np.ptp(c.temperature)
