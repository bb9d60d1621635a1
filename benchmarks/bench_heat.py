"""clothgrid.heat against FiPy on the same steady problem, in the same run.

The problem: a fabric cross-section of ``n x n`` cells, 4 mm x 4 mm, layers of
k = 0.04 and 0.4 W/(m K) (contrast 10) plus a random 1e4-contrast inclusion
map in the middle layer (0.025 to 250 W/(m K) blocks), skin 34 C at the
bottom, 20 C at the top, insulated left and right, a uniform source. FiPy
(4.x, SciPy solvers) solves it with its default solver (``DefaultSolver``:
SuperLU at the time of writing) and, with ``--pcg``, also with ``LinearPCGSolver`` (unpreconditioned
conjugate gradients: it did not reach 1e-10 in 20000 iterations at 256^2, 260 s); clothgrid with
``solve_steady`` at ``tol=1e-8`` (relative residual), with Numba's threads (all cores) and with one
thread (FiPy's SuperLU is single-threaded; on a machine shared with other jobs one thread can be
the faster: a parallel kernel waits for its slowest thread). Times are wall seconds
for building the problem and solving it (FiPy: mesh, variables, equation,
solve); Numba's compilation is warmed up first. The largest temperature
difference between the two is printed too.

Usage::

    python benchmarks/bench_heat.py            # 256^2 and 1024^2
    python benchmarks/bench_heat.py 128 512    # other sizes
    python benchmarks/bench_heat.py --pcg 256  # also FiPy's LinearPCGSolver
    python benchmarks/bench_heat.py --layers   # the layers alone (no 1e4 block layer)
    python benchmarks/bench_heat.py --gl       # also the gl backend (float32 shaders, float64 refinement)
    python benchmarks/bench_heat.py --cuda     # also the cuda backend (float64 on an NVIDIA GPU)

``--gl`` adds the gl backend's wall seconds (context, upload and solve; the hierarchy is built on the
CPU as for the cpu backend), its CG iterations and float64 refinements, and the renderer: on a machine
without a GPU that is Mesa's llvmpipe, i.e. the shaders run on the CPU, and its times are no GPU's. ``--cuda`` adds the cuda backend's wall seconds likewise (CuPy arrays, float64
throughout; it needs an NVIDIA GPU) and its device.
"""

from __future__ import annotations

import os
import sys
import time

# as `clothgrid heat` does: Numba's OpenMP threads sleep between kernels (spinning, the default, cost each
# parallel kernel ~15 ms on a loaded machine); before Numba runs its first parallel kernel
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np


CASE = "blocks"   # --layers: the layers alone (contrast 10), without the 1e4 block layer


def conductivity(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    k = np.full((n, n), 0.04)
    k[:, n // 3: 2 * n // 3] = 0.4
    if CASE == "layers":
        return k
    b = max(n // 32, 1)
    blocks = np.where(rng.random((n // b, n // b)) < 0.3, 250.0, 0.025).repeat(b, 0).repeat(b, 1)
    mid = slice(n // 2 - n // 16, n // 2 + n // 16)
    k[:, mid] = blocks[:, mid]
    return k


L = 0.004
SOURCE = 2e4


def run_clothgrid(k: np.ndarray, threads: int | None = None, backend: str = "cpu") -> tuple[float, np.ndarray, dict]:
    from clothgrid.heat import HeatProblem, solve_steady

    t0 = time.perf_counter()
    p = HeatProblem(k, (L, L), bottom=34, top=20, source=SOURCE)
    res = solve_steady(p, tol=1e-8, threads=threads, backend=backend)
    return time.perf_counter() - t0, res.temperature, res.info


def run_fipy(k: np.ndarray, solver: str) -> tuple[float, np.ndarray]:
    import fipy

    n = k.shape[0]
    t0 = time.perf_counter()
    mesh = fipy.Grid2D(dx=L / n, dy=L / n, nx=n, ny=n)
    T = fipy.CellVariable(mesh=mesh, value=27.0)
    kc = fipy.CellVariable(mesh=mesh, value=k.T.ravel())
    T.constrain(34.0, mesh.facesBottom)
    T.constrain(20.0, mesh.facesTop)
    eq = fipy.DiffusionTerm(coeff=kc.harmonicFaceValue) + SOURCE == 0
    s = fipy.DefaultSolver() if solver == "default" else fipy.LinearPCGSolver(tolerance=1e-10, iterations=20000)
    eq.solve(var=T, solver=s)
    return time.perf_counter() - t0, np.asarray(T.value).reshape(n, n).T


def main(sizes: list[int], pcg: bool = False, gl: bool = False, cuda: bool = False) -> None:
    import fipy
    from clothgrid.heat import HeatProblem, solve_steady

    import numba

    solve_steady(HeatProblem(conductivity(64), (L, L), bottom=34, top=20), tol=1e-8)   # warm up Numba
    renderer = ""
    if gl:
        warm = solve_steady(HeatProblem(conductivity(64), (L, L), bottom=34, top=20), tol=1e-8, backend="gl")
        renderer = f"; gl: {warm.info['gl_renderer']}, OpenGL {warm.info['gl_version']}"
    if cuda:
        warm = solve_steady(HeatProblem(conductivity(64), (L, L), bottom=34, top=20), tol=1e-8, backend="cuda")
        import cupy

        name = cupy.cuda.runtime.getDeviceProperties(0)["name"]
        renderer += f"; cuda: {name.decode() if isinstance(name, bytes) else name}, {warm.info['precision']}"
    extra = [b for b, on in (("gl", gl), ("cuda", cuda)) if on]
    print(f"fipy {fipy.__version__} (default solver {fipy.DefaultSolver.__name__}); numpy {np.__version__}; "
          f"numba {numba.__version__}, {numba.get_num_threads()} threads, OMP_WAIT_POLICY="
          f"{os.environ.get('OMP_WAIT_POLICY')}; load average {os.getloadavg()[0]:.1f}; case {CASE}{renderer}")
    print(f"| cells | clothgrid s ({numba.get_num_threads()} threads) | clothgrid s (1 thread) | CG its | FiPy default s "
          "| FiPy / clothgrid (all threads, 1 thread) | max dT vs FiPy (K) |" + (" FiPy PCG s | ratio |" if pcg else "")
          + "".join(f" {b} s | {b} CG its (refinements) | {b} max dT vs FiPy (K) |" for b in extra))
    print("|---|---|---|---|---|---|---|" + ("---|---|" if pcg else "") + "---|---|---|" * len(extra))
    for n in sizes:
        k = conductivity(n)
        tc, Tc, info = run_clothgrid(k)
        t1, T1, _ = run_clothgrid(k, threads=1)
        tf, Tf = run_fipy(k, "default")
        row = (f"| {n}^2 | {tc:.3f} | {t1:.3f} | {info['iterations']} | {tf:.2f} | {tf / tc:.1f}x, {tf / t1:.1f}x "
               f"| {max(np.abs(Tc - Tf).max(), np.abs(T1 - Tf).max()):.1e} |")
        if pcg:
            tp, _ = run_fipy(k, "pcg")
            row += f" {tp:.2f} | {tp / tc:.1f}x |"
        for b in extra:
            tg, Tg, ginfo = run_clothgrid(k, backend=b)
            row += (f" {tg:.3f} | {ginfo['iterations']} ({ginfo.get('refinements', 0)}) "
                    f"| {np.abs(Tg - Tf).max():.1e} |")
        print(row, flush=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    pcg = "--pcg" in args
    if "--layers" in args:
        CASE = "layers"
    main([int(a) for a in args if not a.startswith("--")] or [256, 1024], pcg, "--gl" in args, "--cuda" in args)
