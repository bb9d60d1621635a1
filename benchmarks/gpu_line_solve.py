"""Which colours of a cuda multigrid the fused line solve should take: timings to choose the rule.

    python benchmarks/gpu_line_solve.py 1024 4096 8192

For each size (the T-shirt front, paper weights, two coordinates) and each
level, one zebra sweep (``smooth``) is timed, device-synchronised, with the
three kernels (``line_blocks``, ``line_separators``, ``line_spread``) and with
the fused ``line_solve`` at several thread-block sizes (``FUSED_THREADS``:
whole lines of ``nsep + 1`` threads, as many as fit). Then the V-cycle and the
full-multigrid start are timed with the fused kernel on colours of at most
``MAX_LINES`` lines (a rule that was tried; the one kept, ``FUSED_MAX_BLOCK``,
fuses every level or none by the line blocks' length), all in the same run,
with the ratio to the three kernels everywhere. The fused kernel's
registers per thread are printed (a thread block needs them all at once).
"""

from __future__ import annotations

import sys

from gpu_ops import piece, timed, uploaded   # benchmarks/, the script's own folder

THREADS = (128, 256, 512, 1024)
MAX_LINES = (0, 16, 32, 64, 128, 1 << 30)


def main(sizes):
    from clothgrid.backends.cuda import _kernels as K
    from clothgrid.backends.cuda import _multigrid as M
    from clothgrid.solvers.multigrid import fmg, vcycle

    b = piece()
    default_threads, default_block = M.FUSED_THREADS, M.FUSED_MAX_BLOCK
    M.FUSED_MAX_BLOCK = 1 << 30          # the fused kernel wherever this script asks for it
    smooth = M.CudaMultigrid.smooth

    def smooth_up_to(self, level, reverse=False):
        """The fused kernel on colours of at most max_lines[0] lines, the three kernels elsewhere."""
        fused = self.fused
        self.fused = fused and (self.nv[level] - 1) // 2 <= max_lines[0]
        try:
            smooth(self, level, reverse)
        finally:
            self.fused = fused

    max_lines = [1 << 30]
    M.CudaMultigrid.smooth = smooth_up_to
    for n in sizes:
        _, ops = uploaded(b, n)
        sync = ops.synchronize
        print("  level  lines  three kernels ms  " + "  ".join(f"fused {t:4d} thr" for t in THREADS), flush=True)
        max_lines[0] = 1 << 30
        for lvl in range(ops.levels):
            ops.fused = False
            three = timed(lambda: ops.smooth(lvl), sync)
            cells = []
            for t in THREADS:
                M.FUSED_THREADS = t
                ops.fused = ops.nsep > 0
                try:
                    one = timed(lambda: ops.smooth(lvl), sync)
                    cells.append(f"{one * 1e3:8.3f} ({three / one:4.2f}x)")
                except Exception as exc:   # too many resources for a launch of this size: say so
                    cells.append(f"{type(exc).__name__[:18]:>18}")
            print(f"  {lvl:5d}  {(ops.nv[lvl] - 1) // 2:5d}  {three * 1e3:16.3f}  " + "  ".join(cells), flush=True)
        M.FUSED_THREADS = default_threads
        ops.fused = False
        v3, f3 = timed(lambda: vcycle(ops), sync), timed(lambda: fmg(ops), sync, 3)
        print(f"  three kernels everywhere: V-cycle {v3 * 1e3:.2f} ms, full-multigrid start {f3 * 1e3:.2f} ms")
        for t in (256, 512):
            M.FUSED_THREADS = t
            for lines in MAX_LINES[1:]:
                max_lines[0] = lines
                ops.fused = ops.nsep > 0
                try:
                    v, f = timed(lambda: vcycle(ops), sync), timed(lambda: fmg(ops), sync, 3)
                    print(f"  fused on colours of <= {lines} lines, {t} threads: V-cycle {v * 1e3:.2f} ms "
                          f"({v3 / v:.2f}x), full-multigrid start {f * 1e3:.2f} ms ({f3 / f:.2f}x)", flush=True)
                except Exception as exc:
                    print(f"  fused on colours of <= {lines} lines, {t} threads: {type(exc).__name__}: {exc}")
        M.FUSED_THREADS = default_threads
        del ops
    M.FUSED_MAX_BLOCK, M.CudaMultigrid.smooth = default_block, smooth
    try:
        print("registers per thread, line_solve:", K.line_solve.get_regs_per_thread())
        print("registers per thread, line_blocks:", K.line_blocks.get_regs_per_thread())
    except Exception as exc:
        print(f"registers: {type(exc).__name__}: {exc}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [4096])
