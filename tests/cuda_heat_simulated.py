"""The cuda backend's heat kernels under Numba's CUDA simulator, against the CPU's operations.

Not collected on its own (the name does not start with ``test_``):
``tests/test_heat_backends.py`` runs it in a subprocess with
``NUMBA_ENABLE_CUDASIM=1`` (the simulator must be chosen before ``numba.cuda``
is first imported). The simulator runs every GPU thread as a Python thread:
the grids are tiny, with a coarsest level of at most 4 unknowns so that every
kind of level is there.
"""

from __future__ import annotations

import numpy as np
import pytest

from clothgrid.backends import load_backend
from clothgrid.backends.cuda import _sim
from clothgrid.heat import HeatProblem
from clothgrid.heat_multigrid import HeatHierarchy, HeatSolver, Stencil5, padded, vcycle


@pytest.fixture(autouse=True, scope="module")
def simulator():
    assert _sim.active(), "run with NUMBA_ENABLE_CUDASIM=1 (tests/test_heat_backends.py does)"


CONTRAST = 1e4
TOL = 64 * np.finfo(float).eps * CONTRAST


def problem(rng, nu, nv):
    k = np.where(rng.random((nu, nv)) < 0.4, 250.0, 250.0 / CONTRAST)
    return HeatProblem(k, (0.01, 0.01 * nv / nu), left=30, right="h=10,T=20", bottom=25, source=1e4)


def hierarchy(p) -> HeatHierarchy:
    w, _, _ = p.system()
    return HeatHierarchy(Stencil5.from_weights(w.wu, w.wv), coarsest_points=4)


def test_every_operation_equals_the_cpus(rng):
    h = hierarchy(problem(rng, 10, 8))
    assert len(h) == 3
    cpu, dev = load_backend("cpu").heat_ops(h), load_backend("cuda").heat_ops(h)
    assert dev.precise

    def up(a):
        return dev.upload(a, dev.vector())

    def back(v):
        out = np.zeros(h.fine.d.shape)
        dev.download(v, out)
        return out

    def same(a, b):
        # the device sums in another order; the conductivities' contrast (1e4) makes the summed terms
        # up to that much larger than their sum, so rounding differs by up to ~ eps * contrast, far
        # below what a wrong index or coefficient gives
        assert np.abs(a - b).max() <= TOL * max(1.0, np.abs(a).max())

    x, b = padded(rng.standard_normal(h.fine.shape)), padded(rng.standard_normal(h.fine.shape))
    xv, bv = up(x), up(b)
    q, qv = np.zeros_like(x), dev.vector()
    assert dev.apply(xv, qv) == pytest.approx(cpu.apply(x, q), rel=1e-13)
    same(q, back(qv))
    r, rv = np.zeros_like(x), dev.vector()
    cpu.residual(b, x, r)
    dev.residual(bv, xv, rv)
    same(r, back(rv))
    assert abs(dev.dot(xv, bv) - cpu.dot(x, b)) <= TOL * np.abs(x * b).sum()    # its terms cancel
    pv, zv = up(x), up(b)
    p2, z2 = x.copy(), b.copy()
    cpu.xpay(p2, z2, 0.7)
    dev.xpay(pv, zv, 0.7)
    same(p2, back(pv))
    x2, r2 = x.copy(), b.copy()
    rr = cpu.axpy(x2, r2, q, r, 0.3)
    xv2, rv2 = up(x), up(b)
    assert dev.axpy(xv2, rv2, qv, rv, 0.3) == pytest.approx(rr, rel=1e-12)
    same(x2, back(xv2))
    same(r2, back(rv2))
    # the V-cycle's operations from the same state on every level
    for level in range(1, len(h)):
        for which in ("x", "b"):
            a = padded(rng.standard_normal(h.levels[level].shape))
            getattr(cpu, which)[level][...] = a
            getattr(dev, which)[level].a[...] = a
    b0, z0 = padded(rng.standard_normal(h.fine.shape)), padded(rng.standard_normal(h.fine.shape))
    cpu.bind(b0, z0.copy())
    dev.bind(up(b0), up(z0))
    for level in range(len(h) - 1):             # in the V-cycle's order: the restriction follows a pre-sweep
        cpu.smooth(level, True)
        dev.smooth(level, True)
        same(cpu.x[level], np.asarray(dev.x[level].a))
        cpu.restrict(level)
        dev.restrict(level)
        same(cpu.b[level + 1], np.asarray(dev.b[level + 1].a))
        cpu.prolong(level)
        dev.prolong(level)
        same(cpu.x[level], np.asarray(dev.x[level].a))
        cpu.smooth(level, False)
        dev.smooth(level, False)
        same(cpu.x[level], np.asarray(dev.x[level].a))
    dev.b[-1].a[...] = cpu.b[-1]         # the same right-hand side (the restrictions' rounding differs)
    cpu.coarse_solve()
    dev.coarse_solve()
    same(cpu.x[-1], np.asarray(dev.x[-1].a))
    r = padded(rng.standard_normal(h.fine.shape))
    z, zv = np.zeros_like(r), dev.vector()
    vcycle(cpu, r, z)
    vcycle(dev, up(r), zv)
    same(z, back(zv))


def test_a_whole_solve_equals_the_cpus(rng):
    p = problem(rng, 8, 6)
    h = hierarchy(p)
    w, ring, rhs = p.system()
    b = padded(rhs + 1.0)
    out = []
    for name in ("cpu", "cuda"):
        solver = HeatSolver(load_backend(name).heat_ops(h), h.fine)
        x = np.zeros_like(b)
        it, rel, steps = solver.solve(b, x, 1e-9, 100)
        solver.close()
        assert rel <= 1e-9 and steps == 0
        out.append((it, x))
    assert out[0][0] == out[1][0]
    assert np.abs(out[0][1] - out[1][1]).max() <= 1e-12 * np.abs(out[0][1]).max()
