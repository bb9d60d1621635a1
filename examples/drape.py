"""Drape a clothgrid piece under gravity with a plain mass-spring model (Provot 1995).

The bundled T-shirt front (or a square) is gridded, laid out flat and horizontal
in its pattern coordinates, pinned at its two top corners and dropped: it swings
down and hangs from the pins. The model uses only what clothgrid hands a
simulator: :meth:`Grid.springs` (structural, shear and bend springs with their
rest lengths from the flat pattern), :meth:`Grid.node_masses` (lumped masses
from an areal density) and :attr:`Grid.corners` (the pinned nodes). It is
integrated with semi-implicit (symplectic) Euler, a time step inside the
explicit stability limit, stiffness-proportional spring damping and light air
damping, and checks that the run stays finite, that the total energy never
rises above its start, and how far the structural springs stretch::

    python examples/drape.py                              # T-shirt, 13 x 17 nodes, 1 s
    python examples/drape.py --nodes 33x45 --seconds 3 --plot docs/drape.png
    python examples/drape.py --piece square --nodes 21

Exit code 0 when the checks pass, 1 when they fail.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field
from importlib.resources import as_file, files
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from clothgrid import Boundary, Grid, generate, load_boundary
from clothgrid.cloth import Springs

GRAVITY = 9.81  # m/s^2, along -z


@dataclass
class Material:
    """Cloth parameters, per unit width, so that they do not depend on the grid's resolution.

    A spring of stiffness ``k`` across a square cell of side ``h`` carries ``k * strain * h`` at a
    strain ``strain``, and there are ``1/h`` of them per unit width: the sheet's stretch stiffness
    is ``k`` (N/m) whatever ``h``. Shear and bend springs get fractions of it.
    """

    density: str = "150gsm"          # areal density (a light cotton jersey is 120-180 g/m^2)
    stretch: float = 2000.0          # N/m, structural springs (woven cotton: 10^3-10^4 N/m)
    shear: float = 0.5               # shear springs, as a fraction of stretch
    bend: float = 0.02               # bend springs, as a fraction of stretch
    air: float = 2.0                 # 1/s, air drag on every node's velocity
    damping_ratio: float = 0.5       # stiffness-proportional spring damping, at the highest frequency
    safety: float = 0.5              # time step as a fraction of the explicit stability limit


@dataclass
class DrapeResult:
    """What :func:`drape` measured."""

    positions: np.ndarray            # (nu, nv, 3) final node positions, metres
    times: np.ndarray                # sample times, s
    energy: np.ndarray               # total energy (kinetic + gravity + springs) at those times, J
    max_strain: np.ndarray           # largest |length / rest - 1| of a structural spring, at those times
    dt: float
    steps: int
    seconds: float                   # wall-clock time of the integration
    pinned: list[int] = field(default_factory=list)
    snapshots: dict[float, np.ndarray] = field(default_factory=dict)  # time -> (nu, nv, 3) positions

    @property
    def finite(self) -> bool:
        return bool(np.isfinite(self.positions).all() and np.isfinite(self.energy).all())

    @property
    def energy_rise(self) -> float:
        """Largest rise of the total energy between two samples, relative to the energy's range.

        The model only loses energy (damping), so this is 0 up to the integrator's own error.
        """
        scale = max(float(np.ptp(self.energy)), abs(float(self.energy[0])), 1e-30)
        return float(max(np.max(np.diff(self.energy), initial=0.0), 0.0) / scale)


def load_piece(name: str, nodes: tuple[int, int]) -> Grid:
    """Grid the bundled T-shirt front (``tshirt``) or a 0.5 m square (``square``)."""
    if name == "tshirt":
        with as_file(files("clothgrid").joinpath("data", "tshirt_front.json")) as path:
            boundary = load_boundary(Path(path))
        # The paper's weights fold cells under the neckline of this piece: uniform ones do not.
        return generate(boundary, nodes, weights="uniform")
    if name == "square":
        t = np.linspace(0.0, 0.5, 3)
        zero, one = 0 * t, 0 * t + 0.5
        boundary = Boundary.from_sides(np.c_[t, zero], np.c_[one, t], np.c_[t, one], np.c_[zero, t],
                                       name="square")
        return generate(boundary, nodes)
    raise ValueError(f"unknown piece {name!r}: use tshirt or square")


def _incidence(pairs: np.ndarray, n: int) -> sp.csr_matrix:
    """``(n, m)`` matrix adding each spring's force to its second node and subtracting it from its first."""
    m = len(pairs)
    rows = np.concatenate([pairs[:, 1], pairs[:, 0]])
    vals = np.concatenate([np.ones(m), -np.ones(m)])
    return sp.csr_matrix((vals, (rows, np.concatenate([np.arange(m)] * 2))), shape=(n, m))


def drape(grid: Grid, material: Material | None = None, *, seconds: float = 1.0, samples: int = 200,
          length_unit: str = "m", snapshots=(), progress=None) -> DrapeResult:
    """Pin the grid's two top corners and let it fall from flat and horizontal under gravity.

    Parameters
    ----------
    grid : Grid
        A planar piece; its pattern coordinates are the rest shape and start position.
    material : Material, optional
        Density, stiffness and damping (default :class:`Material`).
    seconds : float
        Simulated time.
    samples : int
        How many times to measure energy and strain.
    length_unit : str
        Unit of the grid's coordinates (converted to metres).
    snapshots : sequence of float
        Times at which to keep a copy of the positions.

    Returns
    -------
    DrapeResult
    """
    mat = material or Material()
    if not grid.planar:
        raise ValueError("drape needs a planar piece (its flat pattern is the rest shape)")
    from clothgrid.cloth import length_scale

    scale = length_scale(length_unit)
    springs: Springs = grid.springs()
    mass = grid.node_masses(mat.density, length_unit)                    # kg
    n = mass.size
    rest = springs.rest_length * scale                                   # m
    k = np.where(springs.kind == Springs.STRUCTURAL, 1.0,
                 np.where(springs.kind == Springs.SHEAR, mat.shear, mat.bend)) * mat.stretch

    # Explicit stability: omega_max^2 <= max over nodes of 2 * (sum of incident k) / m (Gershgorin).
    ksum = np.bincount(springs.pairs.ravel(), weights=np.repeat(k, 2), minlength=n)
    omega = float(np.sqrt(np.max(2.0 * ksum / mass)))
    beta = 2.0 * mat.damping_ratio / omega                               # c = beta * k
    zeta = mat.damping_ratio
    dt = mat.safety * 2.0 * (np.sqrt(1.0 + zeta ** 2) - zeta) / omega   # damped oscillator limit
    steps = max(int(np.ceil(seconds / dt)), 1)
    dt = seconds / steps

    x = np.zeros((n, 3))
    x[:, :2] = grid.pattern_uv.reshape(-1, 2) * scale                    # flat, horizontal, z = 0
    v = np.zeros((n, 3))
    corners = grid.corners
    pinned = [corners["top-left"], corners["top-right"]]
    free = np.ones(n, dtype=bool)
    free[pinned] = False
    inv_m = np.where(free, 1.0 / mass, 0.0)[:, None]
    gravity = np.zeros((n, 3))
    gravity[:, 2] = -GRAVITY * mass
    a_idx, b_idx = springs.pairs[:, 0], springs.pairs[:, 1]
    structural = springs.kind == Springs.STRUCTURAL
    inc = _incidence(springs.pairs, n)
    ck = beta * k

    def measure(x, v):
        d = x[b_idx] - x[a_idx]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        e = (0.5 * float(np.einsum("i,ij,ij->", mass, v, v)) + GRAVITY * float(mass @ x[:, 2])
             + 0.5 * float(np.sum(k * (length - rest) ** 2)))
        return e, float(np.max(np.abs(length[structural] / rest[structural] - 1.0)))

    every = max(steps // max(samples, 1), 1)
    times, energy, strain = [], [], []
    snap_steps = {min(int(round(t / dt)), steps): t for t in snapshots}
    kept: dict[float, np.ndarray] = {}
    t0 = time.perf_counter()
    for step in range(steps + 1):
        if step % every == 0 or step == steps:
            e, s = measure(x, v)
            times.append(step * dt)
            energy.append(e)
            strain.append(s)
            if not np.isfinite(e):
                break
            if progress and step % (every * max(samples // 10, 1)) == 0:
                progress(f"t = {step * dt:.3f} s: energy {e:.6g} J, max structural strain {100 * s:.2f} %")
        if step in snap_steps:
            kept[snap_steps[step]] = x.reshape(*grid.shape, 3).copy()
        if step == steps:
            break
        d = x[b_idx] - x[a_idx]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        u = d / length[:, None]
        rel = np.einsum("ij,ij->i", v[b_idx] - v[a_idx], u)
        tension = k * (length - rest) + ck * rel                        # pulls the ends together
        force = gravity - inc @ (tension[:, None] * u) - mat.air * mass[:, None] * v
        v += dt * force * inv_m                                          # semi-implicit Euler
        x += dt * v
    seconds_wall = time.perf_counter() - t0
    return DrapeResult(positions=x.reshape(*grid.shape, 3), times=np.array(times), energy=np.array(energy),
                       max_strain=np.array(strain), dt=dt, steps=steps, seconds=seconds_wall, pinned=pinned,
                       snapshots=kept)


def plot(grid: Grid, result: DrapeResult, path: str | Path, *, title: str = "") -> Path:
    """Draw the draped piece (matplotlib 3D, shaded by strain) and the fall seen from the side."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import LightSource
    from matplotlib.figure import Figure

    p = result.positions
    fig = Figure(figsize=(11.0, 5.4), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ls = LightSource(azdeg=300, altdeg=35)
    strain = _cell_strain(grid, p)
    colours = ls.shade(np.clip(strain / 0.02, 0, 1), cmap=_cmap(), blend_mode="soft", vert_exag=1.0)
    ax.plot_surface(p[..., 0], p[..., 1], p[..., 2], facecolors=colours, rstride=1, cstride=1,
                    linewidth=0.2, edgecolor=(0, 0, 0, 0.25), antialiased=True, shade=False)
    pins = p.reshape(-1, 3)[result.pinned]
    ax.scatter(pins[:, 0], pins[:, 1], pins[:, 2], color="k", s=30, depthshade=False)
    lo, hi = p.reshape(-1, 3).min(axis=0), p.reshape(-1, 3).max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=14, azim=-62)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(f"t = {result.times[-1]:.2g} s, colour: structural strain 0 to 2 %", fontsize=9)

    side = fig.add_subplot(1, 2, 2)
    mid = grid.shape[0] // 2
    frames = sorted(result.snapshots.items()) + [(float(result.times[-1]), p)]
    cmap = _cmap()
    for k, (t, q) in enumerate(frames):
        colour = cmap(0.85 * k / max(len(frames) - 1, 1))
        side.plot(q[mid, :, 1], q[mid, :, 2], "-", color=colour, lw=1.6, label=f"t = {t:.2g} s")
    side.plot(pins[:, 1], pins[:, 2], "ko", ms=5, label="pins (top corners)")
    side.set_aspect("equal")
    side.set_xlabel("y (m)")
    side.set_ylabel("z (m)")
    side.grid(True, lw=0.3)
    side.legend(fontsize=8, loc="lower left")
    side.set_title("the fall, seen from the side: the middle grid line (i = nu/2)", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path


def _cmap():
    from matplotlib import colormaps

    return colormaps["viridis"]


def _cell_strain(grid: Grid, p: np.ndarray) -> np.ndarray:
    """``(nu, nv)`` largest structural strain at each node (for colouring)."""
    rest = grid.pattern_uv
    out = np.zeros(grid.shape)
    for axis in (0, 1):
        cur = np.linalg.norm(np.diff(p, axis=axis), axis=-1)
        ref = np.linalg.norm(np.diff(rest, axis=axis), axis=-1)
        s = np.abs(cur / ref - 1.0)
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        out[tuple(lo)] = np.maximum(out[tuple(lo)], s)
        out[tuple(hi)] = np.maximum(out[tuple(hi)], s)
    return out


def _nodes(text: str) -> tuple[int, int]:
    from clothgrid.generate import parse_nodes

    return parse_nodes(text)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--piece", choices=("tshirt", "square"), default="tshirt")
    parser.add_argument("--nodes", type=_nodes, default=(13, 17), help="grid size NUxNV (default 13x17)")
    parser.add_argument("--seconds", type=float, default=1.0, help="simulated time (default 1 s)")
    parser.add_argument("--density", default="150gsm", help="areal density (default 150gsm)")
    parser.add_argument("--stretch", type=float, default=2000.0, help="stretch stiffness, N/m (default 2000)")
    parser.add_argument("--max-strain", type=float, default=0.05,
                        help="fail if a structural spring ever stretches more than this (default 0.05)")
    parser.add_argument("--plot", metavar="PNG", help="draw the final drape to this image")
    parser.add_argument("-q", "--quiet", action="store_true")
    args = parser.parse_args(argv)

    say = None if args.quiet else (lambda msg: print(msg, flush=True))
    grid = load_piece(args.piece, args.nodes)
    mat = Material(density=args.density, stretch=args.stretch)
    snaps = (0.0, 0.1, 0.2, 0.3, 0.4, 0.6) if args.plot else ()
    result = drape(grid, mat, seconds=args.seconds, snapshots=snaps, progress=say)
    nu, nv = grid.shape
    ok = result.finite and result.energy_rise <= 1e-3 and float(result.max_strain.max()) <= args.max_strain
    print(f"{args.piece} {nu}x{nv}: {result.steps} steps of {result.dt * 1e6:.1f} us in "
          f"{result.seconds:.2f} s; finite {result.finite}; energy {result.energy[0]:.4g} -> "
          f"{result.energy[-1]:.4g} J (largest rise {result.energy_rise:.2e} of its scale); "
          f"structural strain max {100 * result.max_strain.max():.2f} %, final "
          f"{100 * result.max_strain[-1]:.2f} %: {'ok' if ok else 'FAILED'}")
    if args.plot:
        title = (f"{args.piece}: {nu}x{nv} nodes, {args.density}, stretch {args.stretch:g} N/m, dropped "
                 f"flat, pinned at the two top corners; max strain {100 * result.max_strain.max():.2g} %")
        print(f"wrote {plot(grid, result, args.plot, title=title)}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
