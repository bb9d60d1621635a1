"""Every solver against an independent exact reference, on fresh inputs."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import regions_with_corners, smooth_quad_sides
from reference import exact_solution, max_rel_error, paper_weights, uniform_weights

import clothgrid
from clothgrid.initial import boundary_grid

TOL = 2.0**-12
REF_WEIGHTS = {"paper": paper_weights, "uniform": uniform_weights}


def reference(boundary, weights="paper"):
    nu, nv = boundary.shape
    wu, wv = REF_WEIGHTS[weights](nu, nv) if isinstance(weights, str) else weights
    return exact_solution(boundary_grid(boundary), wu, wv)


def check_within_tol(grid, ref, scale, tol=TOL):
    err = max_rel_error(grid.points, ref, scale)
    assert err <= tol, f"max error {err:.3g} > tol {tol:.3g} ({grid.info})"
    # the reported figure is a guaranteed bound: it may not be below the true error
    assert grid.info["error_bound"] and err <= grid.info["error_estimate"] * (1 + 1e-9) + 1e-14
    return err


@pytest.mark.parametrize("weights", ["paper", "uniform"])
@pytest.mark.parametrize("init", ["tfi", "average", "zero"])
@pytest.mark.parametrize("solver", ["direct", "fdm", "jacobi", "multigrid"])
@pytest.mark.parametrize("size", [(5, 5), (17, 12), (30, 41)])
def test_random_quads_within_tol(rng, solver, init, weights, size):
    nu, nv = size
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, nu, nv))
    g = clothgrid.generate(b, init=init, weights=weights, solver=solver)
    assert g.points.shape == (nu, nv, 3) and g.info["solver"] == solver and g.info["converged"]
    check_within_tol(g, reference(b, weights), b.size)


@pytest.mark.parametrize("weights", ["paper", "uniform"])
@pytest.mark.parametrize("solver", ["auto", "direct", "fdm", "multigrid"])
@pytest.mark.parametrize("size", [(64, 64), (100, 73)])
def test_random_quads_larger_exact_solvers(rng, solver, weights, size):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, *size))
    g = clothgrid.generate(b, weights=weights, solver=solver)
    err = check_within_tol(g, reference(b, weights), b.size)
    if g.info["solver"] in ("direct", "fdm"):
        assert err < 1e-8  # exact methods: rounding only


@pytest.mark.parametrize("solver", ["direct", "fdm", "jacobi", "multigrid"])
def test_random_3d_quads(rng, solver):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 21, 15, dim=3))
    g = clothgrid.generate(b, solver=solver)
    ref = reference(b)
    assert np.ptp(ref[..., 2]) > 0.01  # the z coordinate is really solved
    check_within_tol(g, ref, b.size)


REGIONS = regions_with_corners()


@pytest.mark.parametrize("path", REGIONS, ids=[p.stem for p in REGIONS])
@pytest.mark.parametrize("nodes", [None, (33, 27)])
@pytest.mark.parametrize("weights", ["paper", "uniform"])
@pytest.mark.parametrize("solver", ["direct", "fdm", "jacobi", "multigrid"])
def test_regions_within_tol(path, nodes, weights, solver):
    b = clothgrid.load_boundary(path)
    if nodes is not None:
        b = b.resampled(*nodes)
    init = "average" if solver == "jacobi" and nodes else "tfi"
    g = clothgrid.generate(b, init=init, weights=weights, solver=solver)
    check_within_tol(g, reference(b, weights), b.size)


def test_regions_are_the_classic_eight():
    assert {p.stem for p in REGIONS} == {f"roache-{n}" for n in
                                         "annulus dome horn nhorseshoe plow shell swan tie".split()}


@pytest.mark.parametrize("solver", ["direct", "jacobi", "multigrid", "auto"])
def test_per_edge_weights(rng, solver):
    nu, nv = 19, 23
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, nu, nv))
    wu = np.exp(rng.uniform(-3, 3, size=(nu - 1, nv)))
    wv = np.exp(rng.uniform(-3, 3, size=(nu, nv - 1)))
    g = clothgrid.generate(b, weights=(wu, wv), solver=solver)
    assert g.info["weights"] == "custom"
    if solver == "auto":
        assert g.info["solver"] == "direct"
    check_within_tol(g, reference(b, (wu, wv)), b.size)


def test_fdm_refuses_per_edge_weights(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 9, 9))
    with pytest.raises(clothgrid.InputError, match="separable"):
        clothgrid.generate(b, weights=(np.ones((8, 9)), np.ones((9, 8))), solver="fdm")


def test_paper_k_changes_the_solution(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 25, 25))
    g = clothgrid.generate(b, weights="paper", k=4.0)
    wu, wv = paper_weights(25, 25, k=4.0)
    ref = exact_solution(boundary_grid(b), wu, wv)
    check_within_tol(g, ref, b.size)
    assert max_rel_error(ref, reference(b, "paper"), b.size) > 10 * TOL


def test_fdm_refines_to_tol_at_large_size(rng):
    """At 2048 nodes the paper's weights span ~1e10; the fdm products lose accuracy and must refine."""
    from clothgrid.backends import cpu
    from clothgrid.solvers import Problem
    from clothgrid.solvers.fdm import solve_fdm
    from clothgrid.initial import initial_grid
    from clothgrid.weights import make_weights

    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 33, 33)).resampled(2000, 9)
    p = Problem(initial_grid(b), make_weights("paper", 2000, 9), b.size)
    first = solve_fdm(p, backend=cpu, tol=1e-3)       # no refinement needed for a loose tol
    assert first.extra["refinements"] == 0 and first.error_estimate > 1e-7
    res = solve_fdm(p, backend=cpu, tol=1e-7)
    assert res.extra["refinements"] >= 1 and res.error_estimate <= 1e-7 and res.converged
    ref = exact_solution(boundary_grid(b), *paper_weights(2000, 9))
    assert max_rel_error(res.points, ref, b.size) <= res.error_estimate


# --- the paper's stopping rule ---------------------------------------------------------------

def test_paper_rule_stops_far_from_the_solution(rng):
    """The paper's rule (last step < eps) stops with nodes many eps away from the solution."""
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 64, 64, amp=0.15))
    ref = reference(b)
    g = clothgrid.generate(b, solver="jacobi", stop="paper", init="tfi")
    err = max_rel_error(g.points, ref, b.size)
    assert g.info["converged"] and g.info["last_step"] < TOL
    assert err > 20 * TOL, f"paper rule error {err:.3g} unexpectedly small"
    assert g.info["error_estimate"] >= err  # the reported bound tells the truth about it
    g2 = clothgrid.generate(b, solver="jacobi", stop="error", init="tfi")
    assert max_rel_error(g2.points, ref, b.size) <= TOL
    assert g2.info["iterations"] > 10 * g.info["iterations"]


def test_paper_rule_tfi_needs_fewer_sweeps_than_average(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 32, 32))
    n_avg = clothgrid.generate(b, solver="jacobi", stop="paper", init="average").info["iterations"]
    n_tfi = clothgrid.generate(b, solver="jacobi", stop="paper", init="tfi").info["iterations"]
    assert n_tfi < n_avg


# --- not converged ------------------------------------------------------------------------------

def test_max_iter_raises_with_grid_attached(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 30, 30))
    with pytest.raises(clothgrid.NotConvergedError, match="did not reach") as exc:
        clothgrid.generate(b, solver="jacobi", max_iter=10)
    assert exc.value.grid is not None and exc.value.grid.info["iterations"] == 10
    g = clothgrid.generate(b, solver="jacobi", max_iter=10, allow_unconverged=True)
    assert not g.info["converged"] and g.info["error_estimate"] > TOL
    assert "use solver 'auto'" in str(exc.value)
    # past multigrid's iterations (what 'auto' picks on large grids) the hint is the exact solve
    with pytest.raises(clothgrid.NotConvergedError, match="use solver 'direct'"):
        clothgrid.generate(b, solver="multigrid", max_iter=1, tol=1e-12)


# --- memory ---------------------------------------------------------------------------------------

def test_oversize_refused_before_allocating(rng):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 9, 9))
    with pytest.raises(clothgrid.SizeError, match="needs about .* of memory"):
        clothgrid.generate(b, (300_000, 300_000))


def test_jacobi_true_rule_with_per_edge_weights_checks_the_direct_solve_memory(rng, monkeypatch):
    import clothgrid.memory as memory

    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 9, 9))
    w = (np.ones((8, 9)), np.ones((9, 8)))
    limit = memory.estimate_bytes("direct", 9, 9) - 1            # enough for jacobi, not for direct
    monkeypatch.setattr(memory, "available_bytes", lambda: int(limit / 0.9))
    monkeypatch.setattr(memory, "SMALL_BYTES", 0)                # a 9 x 9 grid is checked too
    with pytest.raises(clothgrid.SizeError, match="solver 'direct'"):
        clothgrid.generate(b, weights=w, solver="jacobi", stop="error")
    clothgrid.generate(b, weights=w, solver="jacobi", stop="paper")  # no barrier solve: fits


def test_small_grids_do_not_read_the_systems_memory(monkeypatch):
    """A grid under memory.SMALL_BYTES is not checked against the system (reading /proc and the
    control group's files costs more than its solve); a larger one, or kept grids that bring it
    over, or SMALL_BYTES 0, is; an explicit ``available`` always is."""
    import clothgrid.memory as memory

    def never() -> int:
        raise AssertionError("the system's memory was read")

    monkeypatch.setattr(memory, "available_bytes", never)
    small = memory.estimate_bytes("fdm", 100, 100)
    assert small < memory.SMALL_BYTES
    assert memory.check_memory("fdm", 100, 100) == small
    with pytest.raises(AssertionError, match="was read"):
        memory.check_memory("fdm", 100, 100, kept=memory.SMALL_BYTES)
    with pytest.raises(AssertionError, match="was read"):
        memory.check_memory("fdm", 1000, 1000)
    with pytest.raises(clothgrid.SizeError):
        memory.check_memory("fdm", 100, 100, available=small)
    monkeypatch.setattr(memory, "SMALL_BYTES", 0)
    with pytest.raises(AssertionError, match="was read"):
        memory.check_memory("fdm", 100, 100)


def test_memory_estimate_orders_solvers():
    from clothgrid.memory import check_memory, estimate_bytes

    assert estimate_bytes("direct", 1024, 1024) > 4 * estimate_bytes("fdm", 1024, 1024)
    with pytest.raises(clothgrid.SizeError, match="solver 'fdm'"):
        check_memory("direct", 1024, 1024, available=10**9)
    assert check_memory("fdm", 1024, 1024, available=10**9) < 10**9


@pytest.mark.parametrize("solver, n", [("multigrid", 300), ("fdm", 300), ("direct", 120), ("jacobi", 40)])
def test_memory_estimate_covers_generate_quality_and_save(tmp_path, solver, n):
    """What the CLI says before allocating bounds what generate, quality and an NPZ
    save allocate (NumPy's allocations, traced), for 2D and 3D pieces."""
    import tracemalloc

    from clothgrid.memory import estimate_bytes
    from clothgrid.readers import load_boundary

    piece = load_boundary(Path(clothgrid.__file__).parent / "data" / "tshirt_front.json")
    # imports and kernels (not per node), at the measured size: there the multigrid runs its parallel
    # kernels, which a fresh Numba cache compiles on first use (tens of MB of the compiler's objects)
    clothgrid.quality(clothgrid.generate(piece, n, solver=solver, weights="paper")).table()
    clothgrid.generate(piece, 9, solver=solver).save(tmp_path / "warm.npz")
    tracemalloc.start()
    try:
        grid = clothgrid.generate(piece, n, solver=solver, weights="paper")
        clothgrid.quality(grid)
        grid.save(tmp_path / "g.npz")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert 0.2 * estimate_bytes(solver, n, n) < peak <= estimate_bytes(solver, n, n)


# --- options ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, words", [
    (dict(init="bilinear"), "unknown init"), (dict(solver="cg"), "unknown solver"),
    (dict(stop="never"), "unknown stop"), (dict(tol=0.0), "tol"), (dict(tol=float("nan")), "tol"),
    (dict(weights="random"), "unknown weights"), (dict(k=-1.0), "k must be"), (dict(backend="opencl"), "backend"),
    (dict(max_iter=0), "max_iter"), (dict(weights=(np.ones((3, 3)), np.ones((3, 3)))), "shape"),
    (dict(weights=(-np.ones((8, 9)), np.ones((9, 8)))), "positive"),
])
def test_bad_options(rng, kwargs, words):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 9, 9))
    with pytest.raises(clothgrid.InputError, match=words):
        clothgrid.generate(b, **kwargs)


@pytest.mark.parametrize("nodes", ["3x", "1x5", (2, 2), 1, "axb", (4, 5, 6)])
def test_bad_nodes(rng, nodes):
    b = clothgrid.Boundary.from_sides(*smooth_quad_sides(rng, 9, 9))
    with pytest.raises(clothgrid.InputError):
        clothgrid.generate(b, nodes)


def test_generate_runs_blas_on_one_thread_and_gives_the_threads_back(monkeypatch):
    """Inside generate (and the fdm solve of a grid up to 512^2) NumPy's BLAS runs on one thread;
    an fdm solve over 512^2 takes the threads it found back for its products; after generate the
    caller's setting is back (threadpoolctl's own figures)."""
    threadpoolctl = pytest.importorskip("threadpoolctl", reason="threadpoolctl is a dependency")
    import clothgrid.solvers.fdm as fdm_module
    from clothgrid import blas_threads

    def blas():
        return {lib["num_threads"] for lib in threadpoolctl.threadpool_info() if lib["user_api"] == "blas"}

    monkeypatch.delenv("CLOTHGRID_ONE_BLAS_THREAD", raising=False)     # as in a program, not the command
    before = blas()
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        monkeypatch.setattr(blas_threads, "_STATE", {})     # looked up afresh, under the caller's 2 threads
        seen = []
        real = fdm_module._solve_fdm

        def spy(*a, **k):
            seen.append(blas())
            return real(*a, **k)

        monkeypatch.setattr(fdm_module, "_solve_fdm", spy)
        b = clothgrid.load_boundary(Path(clothgrid.__file__).parent / "data" / "tshirt_front.json")
        clothgrid.generate(b, (65, 65), solver="fdm")
        monkeypatch.setattr(fdm_module, "BLAS_ONE_THREAD_NODES", 64 * 64)
        clothgrid.generate(b, (65, 65), solver="fdm")
        assert seen == [{1}, {2}]
        assert blas() == {2}
    assert blas() == before


def test_a_command_line_run_starts_blas_on_one_thread(monkeypatch):
    """_startup.one_blas_thread_from_the_start: before NumPy loads and with no thread variable set,
    the BLAS libraries' variables are set to 1 (and blas_threads then asks no library); a variable
    the user set, or NumPy already loaded, leaves the environment as it is."""
    import sys

    from clothgrid import _startup, blas_threads

    for v in (*_startup.BLAS_THREAD_VARIABLES, "CLOTHGRID_ONE_BLAS_THREAD"):
        monkeypatch.setenv(v, "")       # recorded as it was, so that what the function sets is undone
        monkeypatch.delenv(v)
    _startup.one_blas_thread_from_the_start()           # NumPy is loaded here: nothing
    assert "OPENBLAS_NUM_THREADS" not in os.environ
    monkeypatch.delitem(sys.modules, "numpy")
    monkeypatch.setenv("MKL_NUM_THREADS", "4")           # the user's: kept, nothing else set
    _startup.one_blas_thread_from_the_start()
    assert os.environ["MKL_NUM_THREADS"] == "4" and "OPENBLAS_NUM_THREADS" not in os.environ
    monkeypatch.delenv("MKL_NUM_THREADS")
    _startup.one_blas_thread_from_the_start()
    assert all(os.environ[v] == "1" for v in _startup.BLAS_THREAD_VARIABLES)
    monkeypatch.setattr(blas_threads, "_STATE", {})
    assert blas_threads._controller() is None and "ctl" not in blas_threads._STATE


def test_importing_clothgrid_shortens_the_openmp_spin_unless_the_user_chose():
    """``import clothgrid`` sets ``GOMP_SPINCOUNT`` (libgomp, Numba's threads) to ``OPENMP_SPIN`` in a
    fresh process, before any parallel kernel loads libgomp; a spin count or a wait policy of the
    user's is left as it is. (The speed it buys on a busy machine: ``benchmarks/bench_contention.py``.)"""
    import subprocess
    import sys

    from clothgrid._startup import OPENMP_SPIN

    code = "import os, clothgrid; print(os.environ.get('GOMP_SPINCOUNT'), os.environ.get('OMP_WAIT_POLICY'))"
    base = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    for extra, want in (({}, f"{OPENMP_SPIN} None"), ({"GOMP_SPINCOUNT": "7"}, "7 None"),
                        ({"OMP_WAIT_POLICY": "ACTIVE"}, "None ACTIVE")):
        out = subprocess.run([sys.executable, "-c", code], env={**base, **extra}, capture_output=True, text=True,
                             check=True)
        assert out.stdout.split() == want.split()
    assert int(OPENMP_SPIN) < 300000         # libgomp's own default, which the import replaces


def test_the_cpu_quota_of_a_control_group_sets_numbas_threads(tmp_path):
    """A container's CPU limit (a cgroup's CFS quota over its period, v1 or v2, the least of the
    group's and its ancestors') caps Numba's threads, rounded up, where it is below the processors
    the process may run on and the user set no count."""
    from clothgrid._startup import threads_for_cpu_quota
    from clothgrid.cgroups import cpu_quota

    from conftest import fake_cgroup

    def tree(files: dict[str, str], proc: str) -> tuple[str, str]:
        return fake_cgroup(tmp_path, files, proc)

    # v2 (pure): the group's cpu.max and its parent's; the least wins
    assert cpu_quota(*tree({"fs/cgroup.controllers": "cpu", "fs/a/cpu.max": "max 100000\n",
                            "fs/a/b/cpu.max": "250000 100000\n"}, "0::/a/b\n")) == 2.5
    assert cpu_quota(*tree({"fs/cgroup.controllers": "cpu", "fs/a/cpu.max": "50000 100000",
                            "fs/a/b/cpu.max": "250000 100000"}, "0::/a/b\n")) == 0.5
    assert cpu_quota(*tree({"fs/cgroup.controllers": "cpu", "fs/a/cpu.max": "max 100000"}, "0::/a\n")) is None
    # v1: the cpu controller's files (a comma-joined mount too); -1 is no limit
    assert cpu_quota(*tree({"fs/cpu/g/cpu.cfs_quota_us": "100000", "fs/cpu/g/cpu.cfs_period_us": "100000"},
                           "4:memory:/x\n1:cpu:/g\n0::/\n")) == 1.0
    assert cpu_quota(*tree({"fs/cpu,cpuacct/g/cpu.cfs_quota_us": "-1", "fs/cpu,cpuacct/g/cpu.cfs_period_us": "100000",
                            "fs/cpu,cpuacct/cpu.cfs_quota_us": "300000",
                            "fs/cpu,cpuacct/cpu.cfs_period_us": "100000"}, "2:cpu,cpuacct:/g\n")) == 3.0
    # nothing to read: no limit known
    assert cpu_quota(str(tmp_path / "none"), str(tmp_path / "none" / "proc")) is None
    assert cpu_quota(*tree({"fs/cpu/cpu.cfs_quota_us": "x"}, "1:cpu:/\n")) is None
    env: dict[str, str] = {}
    assert threads_for_cpu_quota(env, quota=1.0, cpus=4) == 1 and env["NUMBA_NUM_THREADS"] == "1"
    env = {}
    assert threads_for_cpu_quota(env, quota=2.5, cpus=4) == 3 and env["NUMBA_NUM_THREADS"] == "3"
    assert threads_for_cpu_quota(env := {}, quota=0.2, cpus=4) == 1
    for quota, cpus in ((4.0, 4), (8.0, 4), (3.5, 4)):
        env = {}
        assert threads_for_cpu_quota(env, quota=quota, cpus=cpus) is None and env == {}
    env = {"NUMBA_NUM_THREADS": "4"}                      # the user's: kept
    assert threads_for_cpu_quota(env, quota=1.0, cpus=8) is None and env["NUMBA_NUM_THREADS"] == "4"
    # Numba's threads started before clothgrid was imported: their count stays (a changed
    # NUMBA_NUM_THREADS would make Numba's next compile raise), and compiling still works
    import subprocess
    import sys

    code = ("import numba, numpy as np\n"
            "@numba.njit(parallel=True)\n"
            "def f(a):\n"
            "    for i in numba.prange(a.size): a[i] = i\n"
            "f(np.zeros(4))\n"
            "from clothgrid._startup import threads_for_cpu_quota\n"
            "import os\n"
            "got = threads_for_cpu_quota(None, quota=0.5, cpus=numba.config.NUMBA_NUM_THREADS + 1)\n"
            "numba.njit(lambda x: x + 1)(1)\n"
            "print(got, os.environ.get('NUMBA_NUM_THREADS'))\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["None", "None"]


def test_blas_blocks_of_two_threads_count_together(monkeypatch):
    """one_blas_thread entered by two Python threads, left in the other order: the BLAS libraries
    stay on one thread until the last block leaves, then have the caller's setting back (the
    first block's limit is the only one set; the count is shared)."""
    import threading

    threadpoolctl = pytest.importorskip("threadpoolctl", reason="threadpoolctl is a dependency")
    from clothgrid import blas_threads

    monkeypatch.delenv("CLOTHGRID_ONE_BLAS_THREAD", raising=False)
    monkeypatch.setattr(blas_threads, "_STATE", {})

    def blas():
        return {lib["num_threads"] for lib in threadpoolctl.threadpool_info() if lib["user_api"] == "blas"}

    before = blas()
    entered, leave_a, left_a, seen = threading.Event(), threading.Event(), threading.Event(), []

    def a():
        with blas_threads.one_blas_thread():
            entered.set()
            leave_a.wait(10)
        left_a.set()

    t = threading.Thread(target=a)
    t.start()
    assert entered.wait(10)
    with blas_threads.one_blas_thread():
        seen.append((blas(), blas_threads._STATE["depth"]))
        leave_a.set()
        assert left_a.wait(10)
        seen.append((blas(), blas_threads._STATE["depth"]))     # a has left; this block holds the limit
    t.join(10)
    seen.append((blas(), blas_threads._STATE["depth"]))
    assert seen == [({1}, 2), ({1}, 1), (before, 0)] and "limiter" not in blas_threads._STATE
