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
