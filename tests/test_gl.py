"""The gl backend (OpenGL through headless EGL) against the CPU and the independent reference.

These tests never skip: CI installs Mesa's llvmpipe (``.ci/run``), and a machine
without an EGL driver should fail them loudly rather than pass them silently.
Sizes are small: llvmpipe runs on the CPU.
"""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest
from conftest import in_forked_child, smooth_quad_sides
from reference import exact_solution, max_rel_error, paper_weights, uniform_weights

import clothgrid
from clothgrid.backends import get_backend, gl
from clothgrid.backends.gl import _device
from clothgrid.initial import boundary_grid

TOL = 2.0**-12
F32 = 1e-5   # "float32 accuracy": relative to the piece's size
REF_WEIGHTS = {"paper": paper_weights, "uniform": uniform_weights}


def quad(rng, nu, nv, dim=2, amp=0.08):
    return clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, nu, nv, dim=dim, amp=amp))


def reference(b, weights="paper"):
    nu, nv = b.shape
    wu, wv = REF_WEIGHTS[weights](nu, nv) if isinstance(weights, str) else weights
    return exact_solution(boundary_grid(b), wu, wv)


def random_weights(rng, nu, nv):
    return np.exp(rng.uniform(-3, 3, size=(nu - 1, nv))), np.exp(rng.uniform(-3, 3, size=(nu, nv - 1)))


@pytest.fixture(params=["device", "host"])
def fp64(request, monkeypatch):
    """Run a test with the float64 steps on the device (GL doubles) and on the host (NumPy)."""
    monkeypatch.setattr(gl, "HOST_FP64", request.param == "host")
    return request.param


# --- the device ------------------------------------------------------------------------------------

def test_backend_is_available_and_reports_its_renderer(rng):
    ok, why = gl.available()
    assert ok, why
    b = quad(rng, 9, 7)
    g = clothgrid.generate(b, backend="gl")
    assert g.info["backend"] == "gl" and g.info["solver"] == "multigrid"
    assert g.info["gl_renderer"] and g.info["gl_max_texture_size"] >= 1024
    assert g.info["gl_fp64"] in ("device", "host")
    if os.environ.get("CLOTHGRID_EXPECT_GPU"):   # set where the run must be on a GPU: EGL falls back silently
        assert not any(s in g.info["gl_renderer"].lower() for s in ("llvmpipe", "softpipe", "swrast")), \
            f"CLOTHGRID_EXPECT_GPU is set but the renderer is {g.info['gl_renderer']!r}"


def test_reduction_pyramid_finds_the_max(rng):
    dev = _device.device()
    for w, h in [(1, 1), (3, 2), (17, 5), (64, 64), (65, 130)]:
        data = rng.random((h, w, 4)).astype(np.float32)
        with dev.current():
            tex = dev.texture(w, h, 4, "f4", data.tobytes())
            red = _device.Reducer(dev, w, h)
            try:
                for ch in range(4):
                    assert red.max(tex, ch) == data[..., ch].max()
            finally:
                red.release()
                tex.release()
        dev.release_thread()


# --- Jacobi: the paper's method, against the CPU sweep for sweep -------------------------------------

@pytest.mark.parametrize("weights", ["paper", "uniform", "custom"])
@pytest.mark.parametrize("init", ["tfi", "average"])
@pytest.mark.parametrize("size, dim", [((17, 12), 2), ((30, 41), 3)])
def test_jacobi_matches_cpu_for_the_same_sweeps(rng, fp64, weights, init, size, dim):
    nu, nv = size
    b = quad(rng, nu, nv, dim=dim)
    w = random_weights(rng, nu, nv) if weights == "custom" else weights
    opts = dict(solver="jacobi", init=init, weights=w, stop="paper", tol=1e-9, max_iter=57, allow_unconverged=True)
    c = clothgrid.generate(b, backend="cpu", **opts)
    g = clothgrid.generate(b, backend="gl", **opts)
    assert c.info["iterations"] == g.info["iterations"] == 57
    assert max_rel_error(g.points, c.points, b.size) <= F32
    assert g.info["gl_fp64"] == fp64


@pytest.mark.parametrize("init", ["tfi", "average"])
def test_jacobi_paper_rule_stops_where_the_cpu_stops(rng, init):
    b = quad(rng, 33, 28)
    c = clothgrid.generate(b, solver="jacobi", stop="paper", init=init, backend="cpu")
    g = clothgrid.generate(b, solver="jacobi", stop="paper", init=init, backend="gl")
    # float32 steps against float64 steps: the same sweep, unless one lands within rounding of eps
    assert abs(g.info["iterations"] - c.info["iterations"]) <= 1
    # the cpu's grid after exactly as many sweeps as the gl's (a tolerance no step meets: when the gl
    # took one sweep more, the cpu's own rule would stop it one short, as happened once)
    same = clothgrid.generate(b, solver="jacobi", stop="paper", init=init, backend="cpu", tol=1e-30,
                              max_iter=g.info["iterations"], allow_unconverged=True)
    assert same.info["iterations"] == g.info["iterations"]
    assert max_rel_error(g.points, same.points, b.size) <= F32
    # the reported figure is a guaranteed bound of the grid returned, far above eps here
    ref = reference(b)
    assert max_rel_error(g.points, ref, b.size) <= g.info["error_estimate"]


def test_jacobi_auto_with_the_paper_rule_is_the_papers_method(rng):
    g = clothgrid.generate(quad(rng, 12, 12), backend="gl", stop="paper")
    assert g.info["solver"] == "jacobi"


@pytest.mark.parametrize("weights", ["paper", "uniform"])
def test_jacobi_true_rule_within_tol(rng, fp64, weights):
    b = quad(rng, 21, 16)
    g = clothgrid.generate(b, solver="jacobi", backend="gl", weights=weights, stop="error")
    err = max_rel_error(g.points, reference(b, weights), b.size)
    assert g.info["converged"] and err <= TOL
    assert g.info["error_bound"] and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


def test_jacobi_not_converged_keeps_the_grid(rng):
    b = quad(rng, 30, 30)
    with pytest.raises(clothgrid.NotConvergedError) as exc:
        clothgrid.generate(b, solver="jacobi", backend="gl", max_iter=10)
    assert exc.value.grid.info["iterations"] == 10 and exc.value.grid.info["error_estimate"] > TOL


# --- the true tolerance: multigrid render passes ------------------------------------------------------

@pytest.mark.parametrize("weights", ["paper", "uniform"])
@pytest.mark.parametrize("size", [(5, 5), (17, 12), (12, 17), (30, 41), (64, 33)])
def test_multigrid_within_tol_of_the_reference(rng, weights, size):
    b = quad(rng, *size)
    g = clothgrid.generate(b, backend="gl", weights=weights)   # auto: multigrid, stop="error"
    err = max_rel_error(g.points, reference(b, weights), b.size)
    assert g.info["solver"] == "multigrid" and g.info["converged"] and err <= TOL
    assert g.info["error_bound"] and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


@pytest.mark.parametrize("fmg", [True, False])
@pytest.mark.parametrize("init", ["tfi", "zero"])
def test_multigrid_3d_and_host_fp64(rng, fp64, init, fmg, monkeypatch):
    """gl runs the CPU's cycles, with and without the full-multigrid start."""
    from clothgrid.backends._cpu_multigrid import CpuMultigrid
    from clothgrid.solvers import multigrid

    monkeypatch.setattr(multigrid, "FULL_MULTIGRID_START", fmg)
    b = quad(rng, 40, 29, dim=3)
    g = clothgrid.generate(b, backend="gl", init=init)
    # The cpu's own stopping figure is the sharper band-barrier bound, which gl does not compute: on
    # about 1 random quad in 40 it stopped a cycle sooner (its bound just under the tolerance after
    # 2 cycles, gl's max|D^-1 r| max z after 3). The cycles are compared under the same bound.
    monkeypatch.setattr(CpuMultigrid, "band_steps", lambda self, barriers: None)
    c = clothgrid.generate(b, backend="cpu", solver="multigrid", init=init)
    assert c.info["bound_method"] == g.info["bound_method"] == "max step"
    ref = reference(b)
    assert np.ptp(ref[..., 2]) > 0.01
    err = max_rel_error(g.points, ref, b.size)
    assert err <= TOL and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14
    assert g.info["gl_fp64"] == fp64
    # the same cycles as the CPU multigrid, to float32 accuracy
    assert g.info["iterations"] == c.info["iterations"]
    assert max_rel_error(g.points, c.points, b.size) <= F32


def test_driver_rejecting_the_float64_shader_falls_back_to_the_host(rng, monkeypatch):
    from clothgrid.backends.gl import _shaders

    dev = _device.device()
    monkeypatch.setattr(_shaders, "FOLD_RESIDUAL", "#version 430\nthis is not GLSL")
    monkeypatch.setattr(dev, "_programs", {k: v for k, v in dev._programs.items() if k != "FOLD_RESIDUAL"})
    monkeypatch.setattr(dev, "fp64", True)
    b = quad(rng, 20, 15)
    g = clothgrid.generate(b, backend="gl")
    assert g.info["gl_fp64"] == "host"
    err = max_rel_error(g.points, reference(b), b.size)
    assert err <= TOL and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


def test_multigrid_per_edge_weights(rng):
    nu, nv = 23, 19
    b = quad(rng, nu, nv)
    w = random_weights(rng, nu, nv)
    g = clothgrid.generate(b, backend="gl", weights=w)
    err = max_rel_error(g.points, reference(b, w), b.size)
    assert g.info["weights"] == "custom" and err <= TOL and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


def test_multigrid_tight_tolerance_needs_float64_folds(rng):
    """Far below float32's resolution: the float64 iterate and residual carry the accuracy."""
    b = quad(rng, 48, 48)
    g = clothgrid.generate(b, backend="gl", tol=1e-10)
    err = max_rel_error(g.points, reference(b), b.size)
    assert err <= 1e-10 and err <= g.info["error_estimate"] * (1 + 1e-9) + 1e-14


# --- sizes and availability ---------------------------------------------------------------------------

def test_oversize_refused_before_allocating(rng, monkeypatch):
    dev = _device.device()
    b = quad(rng, 9, 9)
    with pytest.raises(clothgrid.SizeError, match="GL_MAX_TEXTURE_SIZE"):
        clothgrid.generate(b, (dev.max_size + 1, 5), backend="gl")
    monkeypatch.setattr(dev, "max_size", 32)
    with pytest.raises(clothgrid.SizeError, match="at most 32 texels"):
        clothgrid.generate(b, (20, 33), backend="gl")
    monkeypatch.setattr(dev, "free_memory", lambda: (10**4, "test"))
    with pytest.raises(clothgrid.SizeError, match="of textures"):
        clothgrid.generate(b, (20, 30), backend="gl")


def test_size_check_passes_a_large_grid_after_a_solve(rng):
    clothgrid.generate(quad(rng, 9, 9), backend="gl")
    gl.check_size(2048, 2048, "multigrid")      # probes a 64 MiB texture; allocates nothing else


def test_oversize_cli_exit_2(capsys, tmp_path):
    from clothgrid.cli import main

    piece = clothgrid.__file__.replace("__init__.py", "data/tshirt_front.json")
    n = _device.device().max_size + 1
    code = main(["generate", piece, "--nodes", f"{n}x{n}", "--backend", "gl", "-o", str(tmp_path / "g.npz")])
    err = capsys.readouterr().err
    assert code == 2 and "GL_MAX_TEXTURE_SIZE" in err and not list(tmp_path.iterdir())


def test_solver_that_does_not_run_on_gl_is_refused(rng):
    with pytest.raises(clothgrid.InputError, match="does not run on backend 'gl'"):
        clothgrid.generate(quad(rng, 9, 9), backend="gl", solver="fdm")


def test_unavailable_backend_says_why(rng, monkeypatch):
    def no_context():
        raise clothgrid.BackendUnavailableError("backend 'gl' could not create ... (test)")

    monkeypatch.setattr(_device, "_DEVICE", None)
    monkeypatch.setattr(_device, "_FAILURE", None)
    monkeypatch.setattr(_device, "_create_context", no_context)
    with pytest.raises(clothgrid.BackendUnavailableError, match=r"\(test\)"):
        get_backend("gl")
    with pytest.raises(clothgrid.BackendUnavailableError, match=r"\(test\)"):   # remembered
        clothgrid.generate(quad(rng, 9, 9), backend="gl")
    assert gl.available() == (False, "backend 'gl' could not create ... (test)")


def test_a_process_forked_after_a_gl_solve_is_told_why_instead_of_waiting(rng):
    """A driver's context does not survive fork(): in a child forked after the parent's first gl
    solve, llvmpipe's first compute dispatch waited for ever (a multiprocessing Pool on fork hung).
    The child is now refused with the reason, and backend 'auto' still grids there (the cpu)."""
    b = quad(rng, 9, 9)
    clothgrid.generate(b, backend="gl")         # the parent has a context

    def child():
        g = clothgrid.generate(b)                # auto: the cpu, unaffected
        try:
            clothgrid.generate(b, backend="gl")
        except clothgrid.BackendUnavailableError as exc:
            return f"{g.info['backend']}|{exc}"
        return "gl ran"

    said = in_forked_child(child)
    assert said.startswith("cpu|backend 'gl' cannot run in a process forked"), said
    assert "'spawn' or 'forkserver'" in said
    assert clothgrid.generate(b, backend="gl").info["backend"] == "gl"    # the parent's context still works


def test_missing_moderngl_says_how_to_install(monkeypatch):
    import builtins

    real = builtins.__import__

    def fake(name, *args, **kwargs):
        if name == "moderngl":
            raise ImportError("No module named 'moderngl'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake)
    with pytest.raises(clothgrid.BackendUnavailableError, match=r"clothgrid\[gl\]"):
        _device._create_context()


def test_another_thread_can_use_the_device_after_a_solve(rng):
    b = quad(rng, 10, 10)
    first = clothgrid.generate(b, backend="gl")
    out = {}

    def work():
        try:
            out["grid"] = clothgrid.generate(b, backend="gl")
        except Exception as exc:  # reported below
            out["error"] = exc

    t = threading.Thread(target=work)
    t.start()
    t.join()
    assert "error" not in out, out.get("error")
    assert np.array_equal(out["grid"].points, first.points)


def test_stalled_jumps_point_to_the_cpu_backend(rng):
    """The gl backend keeps V-cycles (no level-0 vectors for conjugate gradients): where they stall
    on jumps of per-edge weights the error names the cpu backend, which goes on with them."""
    from test_multigrid import jump_weights

    nu, nv = 49, 41
    b = quad(rng, nu, nv)
    wu, wv = jump_weights(rng, nu, nv, 100.0)
    with pytest.raises(clothgrid.NotConvergedError, match="backend 'cpu'"):
        clothgrid.generate(b, weights=(wu, wv), solver="multigrid", backend="gl", max_iter=2)
    g = clothgrid.generate(b, weights=(wu, wv), solver="multigrid", backend="cpu")
    assert g.info["converged"]
