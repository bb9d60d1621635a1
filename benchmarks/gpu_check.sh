#!/bin/bash
# The GPU checks of one lent device session, in order of priority, each under its own time limit,
# everything written under $OUT as it goes (docs/performance.md "On a GPU", docs/heat.md "Backends").
#
#   bash benchmarks/gpu_check.sh            # OUT defaults to /tmp/clothgrid-gpu
#   STEPS="tests bench" MAX=4096 METHODS="cpu multigrid;cuda multigrid;gl multigrid" bash benchmarks/gpu_check.sh
#
# STEPS picks the checks and their order (default: tests weights heat ops bench; also residual); METHODS
# (';'-separated) and MAX the solvers and the largest side of the bench step; WEIGHT_SIZES, OPS_SIZES and
# RESIDUAL_SIZES the sides of the weights, ops and residual steps.
#
# On the project's device machines the Python packages the image lacks travel as wheels in .whl/
# and the GL loader libraries as Debian packages in .gl/ (both git-ignored; see the device tool's
# README); elsewhere install clothgrid with its `gl` and `cuda` extras, FiPy, and skip both steps.
set -u
OUT=${OUT:-/tmp/clothgrid-gpu}
mkdir -p "$OUT"
if ls .gl/*.deb >/dev/null 2>&1; then for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
if ls .whl/*.whl >/dev/null 2>&1; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
    export PYTHONPATH=$PWD/src:/tmp/site
else
    export PYTHONPATH=$PWD/src
fi
egl=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f "$egl" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$egl
export CLOTHGRID_EXPECT_GPU=1 PYTHONUNBUFFERED=1 NUMBA_CACHE_DIR=/tmp/numba-cache
log=$OUT/log.txt
{
    date -u; nproc
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
    python3 -c "import numpy, numba, scipy, cupy; print('numpy', numpy.__version__, 'numba', numba.__version__,
'scipy', scipy.__version__, 'cupy', cupy.__version__, 'CUDA runtime', cupy.cuda.runtime.runtimeGetVersion())"
    python3 -c "import numba_cuda; print('numba-cuda', numba_cuda.__version__)" 2>&1 | tail -1
    git log -1 --format='commit %h %s' 2>/dev/null
} >"$log" 2>&1

STEPS=${STEPS:-tests weights heat ops bench}
METHODS=${METHODS:-cpu multigrid;cuda multigrid;cuda multigrid (three kernels);gl multigrid}
MAX=${MAX:-4096}
IFS=';' read -r -a methods <<<"$METHODS"

step() {  # step SECONDS NAME COMMAND...: run COMMAND under a limit, its output to $OUT/NAME
    local limit=$1 name=$2; shift 2
    local t0=$SECONDS
    timeout "$limit" "$@" >"$OUT/$name" 2>&1
    echo "$name: exit $? after $((SECONDS - t0)) s" >>"$log"
}

for s in $STEPS; do   # in the order STEPS names them
    case $s in
    # the GPU tests: cuda and gl multigrid, and heat on gl and cuda
    tests) step 230 tests.txt python3 -m pytest -q -p no:cacheprovider -rs tests/test_cuda.py tests/test_gl.py \
        tests/test_heat_backends.py ;;
    # every weight kind (paper, uniform, per-edge smooth and 10:1 to 10^4:1 jumps) on cuda and on the host's cpu
    weights) step 150 weights.txt python3 benchmarks/gpu_weights.py --sizes ${WEIGHT_SIZES:-1024 2048} --repeat 2 ;;
    # heat: cpu (all host cores, one core), gl and cuda against FiPy's direct solve, in the same run
    heat) step 100 heat.txt python3 benchmarks/bench_heat.py 256 1024 --gl --cuda ;;
    # each cuda multigrid operation per level (the fused line solve against its three kernels), the
    # grid's transfers, and a V-cycle replayed from a CUDA graph
    ops) step 60 ops.txt python3 benchmarks/gpu_ops.py ${OPS_SIZES:-4096} ;;
    # the solvers of METHODS (add "gl jacobi (paper rule)", "gl jacobi (true rule)" and "cpu direct"
    # for the paper's Jacobi and the direct solve) against the bandwidth floor, CPU multigrid as reference
    bench) step 180 bench.txt python3 benchmarks/bench_gpu.py --min 32 --max "$MAX" --ref-max 1024 --timeout 60 \
        --out "$OUT/gpu" --methods "${methods[@]}"
        rm -f "$OUT/gpu/gpu.csv" "$OUT/gpu/gpu_fig5.png" ;;   # made again from rows.jsonl by --render
    # per-edge weights on cuda: the residual solve's bound against the barrier solve, alternating (not in the default STEPS)
    residual) step 120 residual.txt python3 benchmarks/bench_residual_solve.py --backend cuda \
        --sizes ${RESIDUAL_SIZES:-1024 2048 4096} --kinds smooth blocks --repeat 3 ;;
    *) echo "unknown step $s (tests weights heat ops bench residual)" >>"$log" ;;
    esac
done
cat "$log"
