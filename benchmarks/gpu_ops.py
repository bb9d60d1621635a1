"""Where a cuda multigrid solve spends its time: each operation on each level, device-synchronised.

    python benchmarks/gpu_ops.py 4096 16384

For each size (the T-shirt front, paper weights, two coordinates) the
hierarchy is built and uploaded once; then each operation of
:class:`clothgrid.backends.cuda._multigrid.CudaMultigrid` is run ``reps``
times between two device synchronisations, and its median time is printed
per level, with the level's nodes, next to a whole V-cycle, the full-multigrid
start and the time the same number of kernel launches takes on an empty grid
(launch overhead).

Line solves, V-cycle and full-multigrid start are timed both ways in the same
run: the fused line solve (one launch a colour, ``_kernels.line_solve``) and
the three kernels it replaces (``fused=False``), with their ratio. The grid's
upload (strided host view, pinned chunks) and download are timed too, against
CuPy's plain copies of a contiguous array of the same size.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(fn, sync, reps=10):
    fn()
    sync()
    out = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        sync()
        out.append(time.perf_counter() - t)
    return statistics.median(out)


def piece():
    """The T-shirt front, after a warm-up solve on the GPU (every kernel compiled or loaded)."""
    import clothgrid
    from clothgrid import load_boundary
    from clothgrid.backends import cuda

    cuda.require()
    b = load_boundary(ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json")
    clothgrid.generate(b, (300, 300), backend="cuda")   # compile
    return b


def uploaded(b, n):
    """``(x0, ops)``: the piece's ``n x n`` TFI grid (two coordinates) and its cuda multigrid, paper
    weights; the level counts printed."""
    from clothgrid.backends import cuda
    from clothgrid.initial import initial_grid
    from clothgrid.solvers.multigrid import build_hierarchy
    from clothgrid.weights import make_weights

    x0 = initial_grid(b.resampled(n, n), "tfi")[..., :2]
    ops = cuda.multigrid(build_hierarchy(make_weights("paper", n, n)), x0)
    print(f"{n}x{n}: {ops.levels} levels, line block {ops.block}, {ops.nsep} separators a line", flush=True)
    return x0, ops


def main(sizes):
    import clothgrid
    from clothgrid.backends.cuda import _multigrid
    from clothgrid.solvers.multigrid import fmg, vcycle

    b = piece()
    for n in sizes:
        x0, ops = uploaded(b, n)
        sync = ops.synchronize
        transfers(ops, x0)

        def both(fn, reps=10):
            """(fused, three kernels) median seconds of fn(), whatever FUSED_MAX_BLOCK would pick."""
            out = []
            allowed, block = ops.fused, _multigrid.FUSED_MAX_BLOCK   # the thread-block cap still holds
            _multigrid.FUSED_MAX_BLOCK = 1 << 30
            for fused in (True, False):
                ops.fused = fused and allowed
                out.append(timed(fn, sync, reps))
            ops.fused, _multigrid.FUSED_MAX_BLOCK = allowed, block
            return out

        for what, fn, reps in (("V-cycle", lambda: vcycle(ops), 10), ("full-multigrid start", lambda: fmg(ops), 3)):
            one, three = both(fn, reps)
            print(f"  {what}: fused {one * 1e3:.2f} ms, three kernels {three * 1e3:.2f} ms ({three / one:.2f}x)",
                  flush=True)
        print(f"  max_step {timed(ops.max_step, sync) * 1e3:.3f} ms", flush=True)
        for lvl in range(ops.levels):
            rows = ops.nv[lvl]
            one, three = both(lambda: ops.smooth(lvl))
            line = f"  level {lvl:2d} ({n}x{rows}): smooth {one * 1e3:8.3f} ms (three kernels {three * 1e3:8.3f})"
            if lvl + 1 < ops.levels:
                t_r = timed(lambda: ops.restrict(lvl), sync)
                t_p = timed(lambda: ops.prolong(lvl), sync)
                line += f", restrict {t_r * 1e3:7.3f} ms, prolong {t_p * 1e3:7.3f} ms"
            print(line, flush=True)
        # Launch overhead: a prolongation on the coarsest pair of levels moves a few kB.
        lvl = ops.levels - 2
        per = timed(lambda: [ops.prolong(lvl) for _ in range(200)], sync, 3) / 200
        print(f"  one launch on a tiny level (prolong {lvl}): {per * 1e6:.1f} us", flush=True)
        graph_vcycle(ops, vcycle)
        del ops
        from clothgrid.solvers import multigrid
        for start in (True, False):
            multigrid.FULL_MULTIGRID_START = start
            g = clothgrid.generate(b, (n, n), backend="cuda")
            print(f"  generate, full-multigrid start {start}: {g.info['iterations']} V-cycles, cycles "
                  f"{g.info['cycle_seconds'] * 1e3:.1f} ms, bound {g.info['error_estimate']:.2e}", flush=True)
            del g
        multigrid.FULL_MULTIGRID_START = True


def transfers(ops, x0) -> None:
    """The grid's upload and download (pinned chunks, strided host view) against CuPy's own copies of a
    contiguous host array of the same bytes (pageable memory), each the median of 5."""
    import cupy
    import numpy as np

    from clothgrid.backends.cuda import _transfer

    full = np.zeros((*x0.shape[:2], 3))
    full[..., :2] = x0
    view = full[..., :2]
    dense = np.ascontiguousarray(x0)
    dev = cupy.asarray(dense)
    sync = cupy.cuda.Device().synchronize
    mb = dense.nbytes / 1e6
    t_up = timed(lambda: _transfer.upload(view, cupy), sync, 5)
    t_down = timed(lambda: _transfer.download(dev, view), sync, 5)
    t_cup = timed(lambda: cupy.asarray(dense), sync, 5)
    t_cdown = timed(lambda: cupy.asnumpy(dev), sync, 5)
    t_old = timed(lambda: cupy.asarray(np.ascontiguousarray(view)), sync, 5)   # what the upload was
    t_old_down = timed(lambda: view.__setitem__(Ellipsis, cupy.asnumpy(dev)), sync, 5)   # and the download
    print(f"  transfers of {mb:.0f} MB: upload {t_up * 1e3:.1f} ms ({mb / 1e3 / t_up:.1f} GB/s; before: "
          f"contiguous copy + cupy.asarray {t_old * 1e3:.1f} ms), download {t_down * 1e3:.1f} ms "
          f"({mb / 1e3 / t_down:.1f} GB/s; before: cupy.asnumpy + copy {t_old_down * 1e3:.1f} ms); "
          f"cupy.asarray of a contiguous array {t_cup * 1e3:.1f} ms, "
          f"cupy.asnumpy {t_cdown * 1e3:.1f} ms", flush=True)
    assert np.array_equal(cupy.asnumpy(_transfer.upload(view, cupy)), dense)
    del dev


def graph_vcycle(ops, vcycle) -> None:
    """Capture one V-cycle's launches in a CUDA graph (CuPy stream capture, Numba launching on
    that stream) and time its replays: the V-cycle without Python's launch overhead."""
    try:
        import cupy
        from numba import cuda as ncuda

        s = cupy.cuda.Stream(non_blocking=True)
        ops.stream = ncuda.external_stream(s.ptr)
        s.begin_capture()
        try:
            vcycle(ops)
        finally:
            graph = s.end_capture()
        graph.launch(stream=s)
        s.synchronize()
        t = timed(lambda: graph.launch(stream=s), s.synchronize)
        print(f"  V-cycle replayed from a CUDA graph: {t * 1e3:.2f} ms", flush=True)
    except Exception as exc:   # an experiment: say why it did not run
        print(f"  CUDA graph capture failed: {type(exc).__name__}: {exc}", flush=True)
    finally:
        ops.stream = 0


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [4096])
