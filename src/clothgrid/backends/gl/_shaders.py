"""GLSL sources of the gl backend.

Layout shared by every shader: a grid of ``nu x nv`` nodes is a texture of width
``nv`` and height ``nu``, texel ``(x, y) = (j, i)``, so a C-ordered NumPy array
``(nu, nv, channels)`` uploads without a transpose. Neighbours ``i -/+ 1`` (along
u) are ``y -/+ 1``, neighbours ``j -/+ 1`` (along v) are ``x -/+ 1``. Weight
textures hold, per node, the weights of its four edges in the order
``(i-1, i+1, j-1, j+1)`` (the paper's "four weights per node"), zero where a
boundary node has no such edge. Fragment shaders draw one full-screen triangle
(:data:`VERTEX`) into a framebuffer of the grid's size, one fragment per node.
"""

from __future__ import annotations

VERTEX = """
#version 430
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

_HEAD = """
#version 430
#define UM ivec2(0, -1)
#define UP ivec2(0, 1)
#define VM ivec2(-1, 0)
#define VP ivec2(1, 0)
bool on_boundary(ivec2 p, ivec2 n) { return p.x == 0 || p.y == 0 || p.x == n.x - 1 || p.y == n.y - 1; }
"""

# Eq. (3) with per-edge weights and a right-hand side, float32:
#   e'[p] = (sum_k w_k e[p + d_k] + f[p]) / sum_k w_k,   alpha = |e'[p] - e[p]| (the node's step).
# With f = 0 and e the grid itself this is the paper's update verbatim; the solvers run it on
# the correction e of a float64 iterate x with f = b - A x (see _device.Level0).
JACOBI = _HEAD + """
uniform sampler2D e;
uniform sampler2D w;
uniform sampler2D f;
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 n = textureSize(e, 0);
    vec4 c = texelFetch(e, p, 0);
    if (on_boundary(p, n)) { o = vec4(c.xyz, 0.0); return; }
    vec4 k = texelFetch(w, p, 0);
    vec3 s = k.x * texelFetch(e, p + UM, 0).xyz + k.y * texelFetch(e, p + UP, 0).xyz
           + k.z * texelFetch(e, p + VM, 0).xyz + k.w * texelFetch(e, p + VP, 0).xyz
           + texelFetch(f, p, 0).xyz;
    vec3 r = s / (k.x + k.y + k.z + k.w);
    o = vec4(r, length(r - c.xyz));
}
"""

# One level of the max-reduction pyramid: each fragment takes the max of a 4x4 block of one
# channel of the level below (values are non-negative).
REDUCE_MAX = """
#version 430
uniform sampler2D src;
uniform int channel;
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 4;
    ivec2 n = textureSize(src, 0);
    float m = 0.0;
    for (int dy = 0; dy < 4; dy++) {
        for (int dx = 0; dx < 4; dx++) {
            ivec2 q = p + ivec2(dx, dy);
            if (q.x < n.x && q.y < n.y) m = max(m, texelFetch(src, q, 0)[channel]);
        }
    }
    o = vec4(m);
}
"""

# Float64 on the device (GL 4.0 doubles): the iterate x and the level-0 weights are stored as
# exact IEEE doubles, two uints each (packDouble2x32). One pass adds the float32 correction e to
# x (in double) and computes the residual r = b - A x of the new x in double, in the same order
# of operations as the CPU backend (clothgrid.backends.cpu.residual, `precise` keeps the
# compiler from fusing). Outputs: the new x, and f = (float(r), s) where s = |r| / diag is the
# node's Jacobi-scaled residual rounded *up* to float32, so that the max over s is never below
# the float64 value (the error bound's factor, clothgrid.solvers.bounds).
FOLD_RESIDUAL = _HEAD + """
uniform usampler2D xa;     // (x.lo, x.hi, y.lo, y.hi)
uniform usampler2D xb;     // (z.lo, z.hi, -, -)
uniform sampler2D e;       // float32 correction, zero on the boundary
uniform usampler2D wa;     // weights of the edges to i-1 and i+1 as doubles
uniform usampler2D wb;     // weights of the edges to j-1 and j+1 as doubles
uniform bool has_b;        // a right-hand side b (float64, same layout as x), else b = 0
uniform usampler2D ba;
uniform usampler2D bb;
layout(location = 0) out uvec4 oxa;
layout(location = 1) out uvec4 oxb;
layout(location = 2) out vec4 of;

uniform bool has_z;        // false for planar grids (z = 0 throughout): xb is not read

dvec3 node(ivec2 q) {
    uvec4 a = texelFetch(xa, q, 0);
    double z = has_z ? packDouble2x32(texelFetch(xb, q, 0).xy) : 0.0lf;
    dvec3 x = dvec3(packDouble2x32(a.xy), packDouble2x32(a.zw), z);
    return x + dvec3(texelFetch(e, q, 0).xyz);
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 n = textureSize(xa, 0);
    dvec3 c = node(p);
    oxa = uvec4(unpackDouble2x32(c.x), unpackDouble2x32(c.y));
    oxb = uvec4(unpackDouble2x32(c.z), 0u, 0u);
    if (on_boundary(p, n)) { of = vec4(0.0); return; }
    uvec4 a = texelFetch(wa, p, 0);
    uvec4 b = texelFetch(wb, p, 0);
    double w0 = packDouble2x32(a.xy), w1 = packDouble2x32(a.zw);
    double w2 = packDouble2x32(b.xy), w3 = packDouble2x32(b.zw);
    precise dvec3 r = w0 * (node(p + UM) - c);
    r = r + w1 * (node(p + UP) - c);
    r = r + w2 * (node(p + VM) - c);
    r = r + w3 * (node(p + VP) - c);
    if (has_b) {
        uvec4 u = texelFetch(ba, p, 0);
        uvec2 v = texelFetch(bb, p, 0).xy;
        r = r + dvec3(packDouble2x32(u.xy), packDouble2x32(u.zw), packDouble2x32(v));
    }
    precise double d = ((w0 + w1) + w2) + w3;
    precise double s = sqrt((r.x * r.x + r.y * r.y) + r.z * r.z) / d;
    s = s * (1.0lf + 1.0e-12lf);   // covers the few-ulp error GLSL allows double sqrt
    float sf = float(s);
    if (double(sf) < s) sf = uintBitsToFloat(floatBitsToUint(sf) + 1u);
    of = vec4(vec3(r), sf);
}
"""

# ---------------------------------------------------------------------------------- multigrid
# The operators of clothgrid.solvers.multigrid on one level, float32, in textures per node:
#   t1 = (E[i-1,j], E[i,j], N[i,j-1], N[i,j])                couplings to i-1, i+1, j-1, j+1
#   t2 = (NE[i,j], NE[i-1,j-1], NW[i,j], NW[i+1,j-1])        to (i+1,j+1), (i-1,j-1), (i-1,j+1), (i+1,j-1)
#   t3 = (C, inv, g, 0)                                        diagonal and the Thomas factors of the
#                                                              rows' tridiagonal systems in i (CPU)
# Level 0 has a 5-point stencil (nine = false); coarse levels are 9-point.

_STENCIL = """
uniform sampler2D t1;
uniform sampler2D t2;
uniform sampler2D t3;
uniform sampler2D b;
uniform bool nine;
"""

# Zebra line Gauss-Seidel along u: one invocation per row j of one colour solves that row's
# tridiagonal system in i exactly (Thomas algorithm, factors precomputed), reading and writing
# the iterate as an image in place. The rows j -/+ 1 belong to the other colour and stay fixed.
LINE_SOLVE = _HEAD.replace("#version 430", """#version 430
layout(local_size_x = 32) in;
layout(rgba32f, binding = 0) uniform image2D x;""") + _STENCIL + """
uniform int first;
void main() {
    ivec2 n = imageSize(x);
    int j = first + 2 * int(gl_GlobalInvocationID.x);
    if (j > n.x - 2) return;
    vec3 prev = imageLoad(x, ivec2(j, 0)).xyz;             // the boundary node i = 0
    for (int i = 1; i < n.y - 1; i++) {                    // forward elimination
        ivec2 p = ivec2(j, i);
        vec4 k = texelFetch(t1, p, 0);
        vec3 r = k.z * imageLoad(x, p + VM).xyz + k.w * imageLoad(x, p + VP).xyz + texelFetch(b, p, 0).xyz;
        if (nine) {
            vec4 q = texelFetch(t2, p, 0);
            r += q.x * imageLoad(x, p + ivec2(1, 1)).xyz + q.y * imageLoad(x, p + ivec2(-1, -1)).xyz
               + q.z * imageLoad(x, p + ivec2(1, -1)).xyz + q.w * imageLoad(x, p + ivec2(-1, 1)).xyz;
        }
        prev = (r + k.x * prev) * texelFetch(t3, p, 0).y;
        imageStore(x, p, vec4(prev, 0.0));
    }
    vec3 next = imageLoad(x, ivec2(j, n.y - 1)).xyz;       // the boundary node i = nu - 1
    for (int i = n.y - 2; i >= 1; i--) {                   // back substitution
        ivec2 p = ivec2(j, i);
        next = imageLoad(x, p).xyz + texelFetch(t3, p, 0).z * next;
        imageStore(x, p, vec4(next, 0.0));
    }
}
"""

# The Thomas factors of every row's tridiagonal system in i, on the device: one invocation per
# row j, forward elimination along i. t3 holds C in .x on entry (coarse levels; on a 5-point level
# C is the sum of the four weights) and (C, inv, g, 0) on exit, with den = C[i] - E[i-1] g[i-1],
# inv = 1 / den, g[i] = E[i] inv.
THOMAS = """
#version 430
layout(local_size_x = 32) in;
layout(rgba32f, binding = 0) uniform image2D t3;
uniform sampler2D t1;
uniform bool nine;
void main() {
    ivec2 n = imageSize(t3);
    int j = int(gl_GlobalInvocationID.x);
    if (j < 1 || j > n.x - 2) return;
    float g = 0.0;
    for (int i = 1; i < n.y - 1; i++) {
        ivec2 p = ivec2(j, i);
        vec4 k = texelFetch(t1, p, 0);
        float c = nine ? imageLoad(t3, p).x : (k.x + k.y) + (k.z + k.w);
        float inv = 1.0 / (c - k.x * g);
        g = k.y * inv;
        imageStore(t3, p, vec4(c, inv, g, 0.0));
    }
}
"""

# r = b - A x at node p of one level (a 5-point level's diagonal is the sum of its four weights).
_RESIDUAL_AT = """
uniform sampler2D x;
vec3 at(ivec2 q) { return texelFetch(x, q, 0).xyz; }
vec3 residual(ivec2 p) {
    vec4 k = texelFetch(t1, p, 0);
    float c = nine ? texelFetch(t3, p, 0).x : (k.x + k.y) + (k.z + k.w);
    vec3 r = texelFetch(b, p, 0).xyz - c * at(p)
           + k.x * at(p + UM) + k.y * at(p + UP) + k.z * at(p + VM) + k.w * at(p + VP);
    if (nine) {
        vec4 q = texelFetch(t2, p, 0);
        r += q.x * at(p + ivec2(1, 1)) + q.y * at(p + ivec2(-1, -1))
           + q.z * at(p + ivec2(1, -1)) + q.w * at(p + ivec2(-1, 1));
    }
    return r;
}
"""

# r = b - A x on one level (zero on the boundary).
RESIDUAL = _HEAD + _STENCIL + _RESIDUAL_AT + """
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    o = on_boundary(p, textureSize(x, 0)) ? vec4(0.0) : vec4(residual(p), 0.0);
}
"""

# Restriction right after a zebra sweep that ended with the odd rows (drawn over the coarse grid):
# those rows were just solved exactly, so their residual is zero (to rounding) and P^T r is the
# residual of the even rows alone: one residual per coarse node, no fine residual pass.
RESTRICT_SMOOTHED = _HEAD + _STENCIL + _RESIDUAL_AT + """
uniform int nc;
layout(location = 0) out vec4 o;
void main() {
    ivec2 P = ivec2(gl_FragCoord.xy);
    if (P.x == 0 || P.y == 0 || P.x >= nc - 1 || P.y == textureSize(x, 0).y - 1) { o = vec4(0.0); return; }
    o = vec4(residual(ivec2(2 * P.x, P.y)), 0.0);
}
"""

# Restriction P^T (drawn over the coarse grid): coarse row J takes fine row 2J and half of the
# rows 2J -/+ 1 (the fine residual is zero on its boundary rows).
RESTRICT = _HEAD + """
uniform sampler2D r;
layout(location = 0) out vec4 o;
void main() {
    ivec2 P = ivec2(gl_FragCoord.xy);
    ivec2 n = ivec2(textureSize(r, 0).x, textureSize(r, 0).y);
    int nc = (n.x + 1) / 2 + ((n.x - 1) % 2);
    if (P.x == 0 || P.y == 0 || P.x >= nc - 1 || P.y == n.y - 1) { o = vec4(0.0); return; }
    ivec2 q = ivec2(2 * P.x, P.y);
    o = vec4(texelFetch(r, q, 0).xyz + 0.5 * (texelFetch(r, q + VM, 0).xyz + texelFetch(r, q + VP, 0).xyz), 0.0);
}
"""

# Prolongation x += P xc (drawn over the fine grid): even rows take coarse row j/2, odd rows
# the mean of coarse rows (j-1)/2 and (j+1)/2.
PROLONG = _HEAD + """
uniform sampler2D x;
uniform sampler2D xc;
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(x, p, 0);
    if (on_boundary(p, textureSize(x, 0))) { o = c; return; }
    vec3 d = (p.x % 2 == 0) ? texelFetch(xc, ivec2(p.x / 2, p.y), 0).xyz
           : 0.5 * (texelFetch(xc, ivec2((p.x - 1) / 2, p.y), 0).xyz + texelFetch(xc, ivec2((p.x + 1) / 2, p.y), 0).xyz);
    o = vec4(c.xyz + d, 0.0);
}
"""

# ---------------------------------------------------------------------------------- sums

# One level of the sum-reduction pyramid: each fragment sums a 4x4 block of one channel.
REDUCE_SUM = """
#version 430
uniform sampler2D src;
uniform int channel;
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 4;
    ivec2 n = textureSize(src, 0);
    float s = 0.0;
    for (int dy = 0; dy < 4; dy++) {
        for (int dx = 0; dx < 4; dx++) {
            ivec2 q = p + ivec2(dx, dy);
            if (q.x < n.x && q.y < n.y) s += texelFetch(src, q, 0)[channel];
        }
    }
    o = vec4(s);
}
"""

# The first level of a dot product's pyramid: each fragment sums a * b over a 4x4 block (channel 0).
REDUCE_DOT = """
#version 430
uniform sampler2D a;
uniform sampler2D b;
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 4;
    ivec2 n = textureSize(a, 0);
    float s = 0.0;
    for (int dy = 0; dy < 4; dy++) {
        for (int dx = 0; dx < 4; dx++) {
            ivec2 q = p + ivec2(dx, dy);
            if (q.x < n.x && q.y < n.y) s += texelFetch(a, q, 0).x * texelFetch(b, q, 0).x;
        }
    }
    o = vec4(s);
}
"""

# ---------------------------------------------------------------------------------- heat
# The heat solver's black-box multigrid and conjugate gradients (clothgrid.heat_multigrid, the CPU
# kernels in clothgrid._heat_kernels), float32. Arrays are padded: a level of nu x nv unknowns is a
# texture of (nv + 2) x (nu + 2) texels, texel (x, y) = (j, i), the unknowns inside a ring that is
# zero in every vector. Vectors are R32F. Stencils, per texel:
#   level 0 (5 points, flux form):  t1 = (we[i-1,j], we[i,j], wn[i,j-1], wn[i,j])   conductances to
#                                   i-1, i+1, j-1, j+1;  t3 = (c0, cp, im, 0)
#   coarse levels (9 points S[k], k = 3 (di + 1) + (dj + 1) for the neighbour (i + di, j + dj)):
#                                   t1 = (S0, S1, S2, S3), t2 = (S5, S6, S7, S8), t3 = (S4, cp, im, 0)
# c0 is the diagonal less the couplings between unknowns; cp, im the line solves' Thomas factors
# (the eliminated super-diagonal and the inverse pivots, computed on the CPU in float64).
# Interpolation P (RGBA): the weights of fine point (i, j)'s parents (i/2 + a, j/2 + b), slot a + 2b.

_HEAT_STENCIL = """
uniform sampler2D t1;
uniform sampler2D t2;
uniform sampler2D t3;
uniform bool nine;
float X(ivec2 q) { return texelFetch(x, q, 0).x; }
// A x at an unknown p: the 5-point level in flux form (c0 x + sum w (x - x_nb): the differences first,
// as the CPU does), a 9-point level row by row
float ax_at(ivec2 p) {
    vec4 a = texelFetch(t1, p, 0);
    float xc = X(p);
    float c = texelFetch(t3, p, 0).x;
    if (nine) {
        vec4 e = texelFetch(t2, p, 0);
        float s = a.x * X(p + ivec2(-1, -1)) + a.y * X(p + UM) + a.z * X(p + ivec2(1, -1)) + a.w * X(p + VM)
                + e.x * X(p + VP) + e.y * X(p + ivec2(-1, 1)) + e.z * X(p + UP) + e.w * X(p + ivec2(1, 1));
        return c * xc + s;
    }
    precise float v = c * xc;
    v = v + a.x * (xc - X(p + UM));
    v = v + a.y * (xc - X(p + UP));
    v = v + a.z * (xc - X(p + VM));
    v = v + a.w * (xc - X(p + VP));
    return v;
}
float residual_at(ivec2 p) { return texelFetch(b, p, 0).x - ax_at(p); }
"""

# q = A p (has_b false, b unused) or r = b - A x (has_b) on level 0; zero on the ring.
HEAT_AX = _HEAD + """
uniform sampler2D x;
uniform sampler2D b;
uniform bool has_b;
""" + _HEAT_STENCIL + """
layout(location = 0) out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    if (on_boundary(p, textureSize(x, 0))) { o = vec4(0.0); return; }
    o = vec4(has_b ? residual_at(p) : ax_at(p));
}
"""

# Zebra line Gauss-Seidel along v (j): one invocation per line i = i0, i0 + 2, ... solves it exactly
# (Thomas, precomputed factors) with the neighbour lines i -/+ 1 held (first: taken as zero, the first
# half sweep from zero), in place on the image x (the forward pass keeps its values there).
HEAT_LINES = _HEAD.replace("#version 430", """#version 430
layout(local_size_x = 32) in;
layout(r32f, binding = 0) uniform image2D x;""") + """
uniform sampler2D b;
uniform sampler2D t1;
uniform sampler2D t2;
uniform sampler2D t3;
uniform bool nine;
uniform bool first;
uniform int i0;
float X(int i, int j) { return imageLoad(x, ivec2(j, i)).x; }
void main() {
    ivec2 n = imageSize(x);
    int i = i0 + 2 * int(gl_GlobalInvocationID.x);
    if (i > n.y - 2) return;
    int nv = n.x - 2;
    float prev = 0.0;
    for (int j = 1; j <= nv; j++) {
        ivec2 p = ivec2(j, i);
        vec4 a = texelFetch(t1, p, 0);
        float rhs = texelFetch(b, p, 0).x;
        float lower;
        if (nine) {
            if (!first) {
                vec4 e = texelFetch(t2, p, 0);
                rhs -= a.x * X(i - 1, j - 1) + a.y * X(i - 1, j) + a.z * X(i - 1, j + 1)
                     + e.y * X(i + 1, j - 1) + e.z * X(i + 1, j) + e.w * X(i + 1, j + 1);
            }
            lower = a.w;
        } else {
            if (!first) rhs += a.x * X(i - 1, j) + a.y * X(i + 1, j);
            lower = -a.z;
        }
        prev = (rhs - lower * prev) * texelFetch(t3, p, 0).z;
        imageStore(x, p, vec4(prev));
    }
    float v = 0.0;
    for (int j = nv; j >= 1; j--) {
        ivec2 p = ivec2(j, i);
        v = imageLoad(x, p).x - texelFetch(t3, p, 0).y * v;
        imageStore(x, p, vec4(v));
    }
}
"""

# Restriction right after a pre-smoothing sweep that ended with the odd lines (drawn over the coarse
# level): their residual is zero, so P^T r reads the even rows only; the residual of the three fine
# points (2I, 2J - 1 .. 2J + 1) is formed here (no fine residual pass).
HEAT_RESTRICT = _HEAD + """
uniform sampler2D x;
uniform sampler2D b;
uniform sampler2D P;
uniform ivec2 nc;
""" + _HEAT_STENCIL + """
layout(location = 0) out vec4 o;
void main() {
    ivec2 c = ivec2(gl_FragCoord.xy);
    if (c.x < 1 || c.y < 1 || c.x > nc.x - 2 || c.y > nc.y - 2) { o = vec4(0.0); return; }
    ivec2 p = 2 * c;
    float s = residual_at(p) + texelFetch(P, p + VM, 0).z * residual_at(p + VM);
    if (p.x + 1 <= textureSize(x, 0).x - 2) s += texelFetch(P, p + VP, 0).x * residual_at(p + VP);
    o = vec4(s);
}
"""

# x += P xc on the even rows i (the post-smoothing sweep starts with the odd lines, which overwrite
# theirs), in place: one invocation per (j, even i).
HEAT_PROLONG = """
#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(r32f, binding = 0) uniform image2D x;
uniform sampler2D xc;
uniform sampler2D P;
void main() {
    ivec2 n = imageSize(x);
    int j = int(gl_GlobalInvocationID.x) + 1;
    int i = 2 * (int(gl_GlobalInvocationID.y) + 1);
    if (j > n.x - 2 || i > n.y - 2) return;
    ivec2 p = ivec2(j, i);
    vec4 w = texelFetch(P, p, 0);
    float v = imageLoad(x, p).x + w.x * texelFetch(xc, ivec2(j / 2, i / 2), 0).x
            + w.z * texelFetch(xc, ivec2(j / 2 + 1, i / 2), 0).x;
    imageStore(x, p, vec4(v));
}
"""

# The coarsest level: x = A^-1 b with the dense inverse (a texture of n x n texels, row k = unknown
# (i - 1) ncv + (j - 1), computed on the CPU in float64).
HEAT_COARSE = _HEAD + """
uniform sampler2D b;
uniform sampler2D inv;
layout(location = 0) out vec4 o;
void main() {
    ivec2 c = ivec2(gl_FragCoord.xy);
    ivec2 s = textureSize(b, 0);
    if (on_boundary(c, s)) { o = vec4(0.0); return; }
    int ncv = s.x - 2;
    int n = textureSize(inv, 0).x;
    int k = (c.y - 1) * ncv + (c.x - 1);
    float acc = 0.0;
    for (int m = 0; m < n; m++) {
        acc += texelFetch(inv, ivec2(m, k), 0).x * texelFetch(b, ivec2(m % ncv + 1, m / ncv + 1), 0).x;
    }
    o = vec4(acc);
}
"""

# Conjugate gradients' vector updates, in place, one invocation per texel (the ring stays zero):
# x += alpha p and r -= alpha q; p = z + beta p (copy: p = z).
HEAT_AXPY = """
#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(r32f, binding = 0) uniform image2D x;
layout(r32f, binding = 1) uniform image2D r;
uniform sampler2D p;
uniform sampler2D q;
uniform float alpha;
void main() {
    ivec2 c = ivec2(gl_GlobalInvocationID.xy);
    ivec2 n = imageSize(x);
    if (c.x >= n.x || c.y >= n.y) return;
    imageStore(x, c, vec4(imageLoad(x, c).x + alpha * texelFetch(p, c, 0).x));
    imageStore(r, c, vec4(imageLoad(r, c).x - alpha * texelFetch(q, c, 0).x));
}
"""

HEAT_XPAY = """
#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(r32f, binding = 0) uniform image2D p;
uniform sampler2D z;
uniform float beta;
uniform bool copy;
void main() {
    ivec2 c = ivec2(gl_GlobalInvocationID.xy);
    ivec2 n = imageSize(p);
    if (c.x >= n.x || c.y >= n.y) return;
    float v = texelFetch(z, c, 0).x;
    imageStore(p, c, vec4(copy ? v : v + beta * imageLoad(p, c).x));
}
"""
