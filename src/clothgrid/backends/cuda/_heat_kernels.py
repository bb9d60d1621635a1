"""numba.cuda kernels of the heat solver: :mod:`clothgrid._heat_kernels`' (the CPU's) on a GPU, float64.

Same padded arrays ``(nu + 2, nv + 2)`` (unknowns inside a zero ring), same
stencils (level 0: ``we``, ``wn``, ``c0`` in flux form; coarse levels: the
9-point ``S``), same interpolation ``P`` and line factors ``cp``, ``im``, same
order of operations. The arrays are Fortran-ordered on the device (``i``
fastest): point kernels run one thread per point with ``threadIdx.x`` along
``i``, so neighbouring threads read neighbouring addresses; the line solves
(zebra Gauss-Seidel along ``j``) run one thread per line ``i`` of a colour
(Thomas along ``j``, the forward pass kept in ``x`` itself), whose threads then
read addresses two apart. Dot products and copies are CuPy's (the backend's
array module).

Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) runs these on the CPU: the
tests check them there against the CPU kernels, and compile them to PTX.
"""

from __future__ import annotations

from ._compat import patch_numpy

patch_numpy()   # numba-cuda <= 0.30.4 with NumPy >= 2.5 (see _compat)

from numba import cuda  # noqa: E402


@cuda.jit(device=True)
def _flux5(we, wn, c0, x, i, j):
    """Row ``(i, j)`` of ``A x`` in flux form (the CPU's ``_flux5``)."""
    xc = x[i, j]
    return (c0[i, j] * xc + we[i - 1, j] * (xc - x[i - 1, j]) + we[i, j] * (xc - x[i + 1, j])
            + wn[i, j - 1] * (xc - x[i, j - 1]) + wn[i, j] * (xc - x[i, j + 1]))


@cuda.jit(device=True)
def _ax9(S, x, i, j):
    """Row ``(i, j)`` of a 9-point level times ``x`` (the CPU's ``S4 x + _row9``)."""
    return S[i, j, 4] * x[i, j] + (
        S[i, j, 0] * x[i - 1, j - 1] + S[i, j, 1] * x[i - 1, j] + S[i, j, 2] * x[i - 1, j + 1]
        + S[i, j, 3] * x[i, j - 1] + S[i, j, 5] * x[i, j + 1]
        + S[i, j, 6] * x[i + 1, j - 1] + S[i, j, 7] * x[i + 1, j] + S[i, j, 8] * x[i + 1, j + 1])


@cuda.jit
def apply5(we, wn, c0, x, out):
    """``out = A x`` on the interior."""
    i, j = cuda.grid(2)
    i += 1
    j += 1
    if i <= x.shape[0] - 2 and j <= x.shape[1] - 2:
        out[i, j] = _flux5(we, wn, c0, x, i, j)


@cuda.jit
def residual5(we, wn, c0, b, x, r, i0, step):
    """``r = b - A x`` on the interior rows ``i0, i0 + step, ...``."""
    t, j = cuda.grid(2)
    i = i0 + step * t
    j += 1
    if i <= x.shape[0] - 2 and j <= x.shape[1] - 2:
        r[i, j] = b[i, j] - _flux5(we, wn, c0, x, i, j)


@cuda.jit
def residual9(S, b, x, r, i0, step):
    """``r = b - A x`` on the interior rows ``i0, i0 + step, ...`` of a 9-point level."""
    t, j = cuda.grid(2)
    i = i0 + step * t
    j += 1
    if i <= x.shape[0] - 2 and j <= x.shape[1] - 2:
        r[i, j] = b[i, j] - _ax9(S, x, i, j)


@cuda.jit
def lines5(we, wn, b, x, colour, cp, im, first):
    """Zebra line Gauss-Seidel on level 0: line ``i`` (``i % 2 == colour``) solved along ``j`` (the CPU's
    ``lines5``)."""
    i = 2 - colour + 2 * cuda.grid(1)
    nv = x.shape[1] - 2
    if i > x.shape[0] - 2:
        return
    prev = 0.0
    for j in range(1, nv + 1):
        rhs = b[i, j]
        if not first:
            rhs += we[i - 1, j] * x[i - 1, j] + we[i, j] * x[i + 1, j]
        prev = (rhs + wn[i, j - 1] * prev) * im[i, j]
        x[i, j] = prev
    v = 0.0
    for j in range(nv, 0, -1):
        v = x[i, j] - cp[i, j] * v
        x[i, j] = v


@cuda.jit
def lines9(S, b, x, colour, cp, im, first):
    """Zebra line Gauss-Seidel on a 9-point level (the CPU's ``lines9``)."""
    i = 2 - colour + 2 * cuda.grid(1)
    nv = x.shape[1] - 2
    if i > x.shape[0] - 2:
        return
    prev = 0.0
    for j in range(1, nv + 1):
        rhs = b[i, j]
        if not first:
            rhs -= (S[i, j, 0] * x[i - 1, j - 1] + S[i, j, 1] * x[i - 1, j] + S[i, j, 2] * x[i - 1, j + 1]
                    + S[i, j, 6] * x[i + 1, j - 1] + S[i, j, 7] * x[i + 1, j] + S[i, j, 8] * x[i + 1, j + 1])
        prev = (rhs - S[i, j, 3] * prev) * im[i, j]
        x[i, j] = prev
    v = 0.0
    for j in range(nv, 0, -1):
        v = x[i, j] - cp[i, j] * v
        x[i, j] = v


@cuda.jit
def restrict_even(P, r, bc):
    """``bc = P^T r`` from the even rows (the CPU's ``restrict_even``): one thread per coarse point."""
    I, J = cuda.grid(2)
    I += 1
    J += 1
    if I > bc.shape[0] - 2 or J > bc.shape[1] - 2:
        return
    nv = r.shape[1] - 2
    i = 2 * I
    j = 2 * J
    s = r[i, j] + P[i, j - 1, 2] * r[i, j - 1]
    if j + 1 <= nv:
        s += P[i, j + 1, 0] * r[i, j + 1]
    bc[I, J] = s


@cuda.jit
def prolong_add_even(P, xc, x):
    """``x += P xc`` on the even rows (the CPU's ``prolong_add_even``)."""
    t, j = cuda.grid(2)
    i = 2 * (t + 1)
    j += 1
    if i > x.shape[0] - 2 or j > x.shape[1] - 2:
        return
    I = i // 2
    J = j // 2
    x[i, j] += P[i, j, 0] * xc[I, J] + P[i, j, 2] * xc[I, J + 1]


@cuda.jit
def update_xr(x, r, p, q, alpha):
    """``x += alpha p``, ``r -= alpha q`` (every element: the rings are zero)."""
    i, j = cuda.grid(2)
    if i < x.shape[0] and j < x.shape[1]:
        x[i, j] += alpha * p[i, j]
        r[i, j] = r[i, j] - alpha * q[i, j]


@cuda.jit
def update_p(p, z, beta):
    """``p = z + beta p``."""
    i, j = cuda.grid(2)
    if i < p.shape[0] and j < p.shape[1]:
        p[i, j] = z[i, j] + beta * p[i, j]
