"""What a cloth simulator needs from a grid: rest shape, springs, masses, sides, units.

* :func:`pattern_uv`: node positions in the piece's own flat 2D coordinates, in
  its length unit (the flat rest shape of the cut piece).
* :func:`springs`: Provot's structural, shear and bend springs with their rest
  lengths, as typed index pairs (:class:`Springs`).
* :func:`node_areas` and :func:`node_masses`: lumped areas and masses, a quarter
  of each adjacent cell's flat area per node, times an areal density.
* :func:`sides` and :func:`corners`: flat node indices of the four sides and the
  four corners, for pinning and for sewing pieces together.
* :func:`parse_density` and :func:`length_scale`: areal densities such as
  ``"0.2kg/m2"`` or ``"150gsm"`` and the length units of the coordinates.

Units. clothgrid's coordinates carry no unit of their own: the functions that
need one take ``length_unit`` (one of :data:`LENGTH_UNITS`); when it is not
given, ``grid.info["length_unit"]`` is used if present, else metres
(:data:`DEFAULT_LENGTH_UNIT`). A reader that knows its unit (SVG and DXF
patterns are in millimetres) records it there or passes it on. Masses are in
kilograms and densities in kg/m^2 whatever the length unit.

Rest shape. For a planar piece (2D input, or 3D input whose boundary lies in a
plane) the rest shape is the flat pattern :func:`pattern_uv`; for a curved 3D
piece there is no flat pattern without distortion, so the rest shape is the 3D
grid as it is, and :func:`pattern_uv` falls back to the arc lengths along the
grid lines (see there).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np

from .errors import InputError
from .geometry import PLANAR_TOL, best_fit_plane, boundary_loop
from .units import LENGTH_UNITS, length_scale



class GridLike(Protocol):
    """What the functions here read of a grid (:class:`clothgrid.Grid` is one): no import of it,
    so that the grid module can build on this one."""

    points: Any
    info: dict
    dim: int

    @property
    def uv(self) -> Any: ...

    @property
    def quads(self) -> Any: ...

    @property
    def shape(self) -> tuple[int, int]: ...

    def triangles(self, diagonal: str = "fixed") -> Any: ...

__all__ = [
    "Springs", "SPRING_KINDS", "LENGTH_UNITS", "MASS_UNITS", "DEFAULT_LENGTH_UNIT", "CORNER_NAMES",
    "springs", "pattern_uv", "is_planar", "rest_coordinates", "cell_areas", "node_areas",
    "node_masses", "sides", "corners", "parse_density", "length_scale", "resolve_length_unit",
]

#: Kilograms per mass unit, by name.
MASS_UNITS: dict[str, float] = {"kg": 1.0, "g": 1e-3, "mg": 1e-6, "oz": 0.028349523125,
                                "lb": 0.45359237}
#: The unit assumed for coordinates when none is given or recorded.
DEFAULT_LENGTH_UNIT = "m"
#: Spring kind names; a spring's ``kind`` code is the index into this tuple.
SPRING_KINDS: tuple[str, ...] = ("structural", "shear", "bend")
#: Corner names in the order of :meth:`Boundary.from_outline`'s ``corners``.
CORNER_NAMES: tuple[str, ...] = ("bottom-left", "bottom-right", "top-right", "top-left")

_NUM = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_DENSITY = re.compile(rf"\s*({_NUM})\s*(?:(gsm)|([a-z]+)\s*/\s*([a-z]+)\s*(?:\^|\*\*)?\s*(?:2|²))\s*",
                      re.IGNORECASE)


# --------------------------------------------------------------------------- units


def resolve_length_unit(grid: GridLike, length_unit: str | None = None) -> str:
    """The length unit to use: ``length_unit``, else ``grid.info["length_unit"]``, else metres.

    Raises
    ------
    InputError
        For an unknown unit.
    """
    unit = length_unit if length_unit is not None else (grid.info.get("length_unit") or DEFAULT_LENGTH_UNIT)
    length_scale(unit)
    return str(unit).strip().lower()


def parse_density(value: float | str) -> float:
    """An areal density in kg/m^2 from a number (kg/m^2) or text with a unit.

    Text is a number followed by ``MASS/LENGTH2`` (mass one of :data:`MASS_UNITS`,
    length one of :data:`LENGTH_UNITS`; the square written ``2``, ``^2``,
    ``**2`` or ``²``) or by ``gsm`` (grams per square metre, the textile unit):
    ``"0.2kg/m2"``, ``"150 g/m^2"``, ``"150gsm"``, ``"4.4 oz/yd2"``,
    ``"0.015 g/cm2"``. Text without a unit is refused (``150`` could mean gsm
    or kg/m^2); a plain number is taken as kg/m^2.

    Raises
    ------
    InputError
        Text not of that form, an unknown unit, or a density that is not
        positive and finite.
    """
    if isinstance(value, (bool, np.bool_)):
        raise InputError(f"density must be a number in kg/m2 or text such as '0.2kg/m2', not {value!r}")
    if isinstance(value, (int, float, np.integer, np.floating)):
        density = float(value)
    elif isinstance(value, str):
        m = _DENSITY.fullmatch(value)
        if m is None:
            raise InputError(f"invalid density {value!r}: expected a number and a unit such as "
                             "0.2kg/m2, 150g/m2 or 150gsm")
        number, gsm, mass, length = m.groups()
        if gsm:
            mass, length = "g", "m"
        mass, length = mass.lower(), length.lower()
        if mass not in MASS_UNITS:
            raise InputError(f"invalid density {value!r}: unknown mass unit {mass!r} "
                             f"(use one of {', '.join(MASS_UNITS)})")
        if length not in LENGTH_UNITS:
            raise InputError(f"invalid density {value!r}: unknown length unit {length!r} "
                             f"(use one of {', '.join(LENGTH_UNITS)})")
        density = float(number) * MASS_UNITS[mass] / LENGTH_UNITS[length] ** 2
    else:
        raise InputError(f"density must be a number in kg/m2 or text such as '0.2kg/m2', not {value!r}")
    if not (math.isfinite(density) and density > 0):
        raise InputError(f"density must be positive and finite, not {value!r}")
    return density


# --------------------------------------------------------------------------- rest shape


def is_planar(grid: GridLike) -> bool:
    """True if the piece is planar: 2D input, or a 3D boundary within ``1e-9`` of its size of a plane.

    The boundary decides (its nodes are exact), as in :func:`clothgrid.quality.quality`.
    """
    if grid.dim == 2:
        return True
    loop = boundary_loop(np.asarray(grid.points, dtype=np.float64))
    _, _, dist = best_fit_plane(loop)
    return dist <= PLANAR_TOL * float(np.linalg.norm(np.ptp(loop, axis=0)))


def _rotation_to_xy(normal: np.ndarray) -> np.ndarray:
    """The smallest rotation ``R`` (``(3, 3)``) with ``R @ normal = +z``; ``normal`` a unit vector, not -z."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(normal, z)
    c = float(normal @ z)
    if np.linalg.norm(v) < 1e-15 and c > 0:
        return np.eye(3)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _line_arc_lengths(points: np.ndarray) -> np.ndarray:
    """``(nu, nv, 2)`` arc length from the start of each grid line: along u, then along v."""
    nu, nv = points.shape[:2]
    out = np.zeros((nu, nv, 2))
    du = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    dv = np.linalg.norm(np.diff(points, axis=1), axis=-1)
    np.cumsum(du, axis=0, out=out[1:, :, 0])
    np.cumsum(dv, axis=1, out=out[:, 1:, 1])
    return out


def pattern_uv(grid: GridLike) -> np.ndarray:
    """``(nu, nv, 2)`` node positions in the piece's own flat coordinates (the rest shape).

    * 2D input: ``x, y`` as given.
    * Planar 3D input: the nodes rotated into the xy-plane by the smallest
      rotation taking the piece's plane normal to ``+z``, then ``x, y``; the
      normal's sign is that of :attr:`Boundary.normal`'s reference (positive z,
      or for a vertical plane positive y, then x), so a 3D piece lying in the
      xy-plane keeps its ``x, y`` and no piece is mirrored. Distances are kept
      (an isometry); any component off the plane (solver rounding) is dropped.
    * Curved 3D input: no distortion-free flat pattern exists; this returns the
      arc lengths along the grid lines instead, ``[i, j, 0]`` the length of
      u-line ``j`` from ``(0, j)`` to ``(i, j)`` and ``[i, j, 1]`` that of v-line
      ``i`` from ``(i, 0)`` to ``(i, j)`` (the normalised :attr:`Grid.uv` scaled
      by each line's length): texture coordinates in length units, exact along
      each grid line but not a rest shape. Check :func:`is_planar` first.

    Lengths are in the grid's length unit (the coordinates' unit).
    """
    points = np.asarray(grid.points, dtype=np.float64)
    if grid.dim == 2:
        return points[..., :2].copy()
    if not is_planar(grid):
        return _line_arc_lengths(points)
    _, normal, _ = best_fit_plane(boundary_loop(points))
    for k in (2, 1, 0):  # the reference sign of Boundary._plane
        if abs(normal[k]) > 1e-9:
            normal = normal if normal[k] > 0 else -normal
            break
    rot = _rotation_to_xy(normal / np.linalg.norm(normal))
    return np.ascontiguousarray((points @ rot.T)[..., :2])


def rest_coordinates(grid: GridLike) -> np.ndarray:
    """The rest shape the springs and masses are measured on.

    ``(nu, nv, 2)`` :func:`pattern_uv` for a planar piece, ``(nu, nv, 3)`` points
    of the grid for a curved one.
    """
    if is_planar(grid):
        return pattern_uv(grid)
    return np.asarray(grid.points, dtype=np.float64)


# --------------------------------------------------------------------------- springs


@dataclass(frozen=True, eq=False)
class Springs:
    """Mass-spring springs of a grid (Provot 1995): structural, shear and bend.

    Attributes
    ----------
    pairs : numpy.ndarray
        ``(m, 2)`` int64 flat node indices ``i*nv + j`` of the two ends.
    kind : numpy.ndarray
        ``(m,)`` int8 codes: :attr:`STRUCTURAL` (0), :attr:`SHEAR` (1),
        :attr:`BEND` (2); ``KINDS[code]`` is the name.
    axis : numpy.ndarray
        ``(m,)`` int8: 0 along u (the grid's i direction, warp or weft), 1
        along v, -1 diagonal (shear), for anisotropic stiffness.
    rest_length : numpy.ndarray
        ``(m,)`` float64 rest lengths, measured on the flat pattern (planar
        pieces) or on the 3D grid (curved pieces), in the grid's length unit.

    The order is fixed: structural u then v springs, shear springs (the
    ``(i, j)-(i+1, j+1)`` diagonal of every cell, then ``(i+1, j)-(i, j+1)``),
    bend u then v springs; within each group by ``i`` then ``j``.
    """

    pairs: np.ndarray
    kind: np.ndarray
    axis: np.ndarray
    rest_length: np.ndarray

    STRUCTURAL: ClassVar[int] = 0
    SHEAR: ClassVar[int] = 1
    BEND: ClassVar[int] = 2
    KINDS: ClassVar[tuple[str, ...]] = SPRING_KINDS

    def __len__(self) -> int:
        return int(len(self.pairs))

    @staticmethod
    def code(kind: int | str) -> int:
        """The code of a kind given by name (``"shear"``) or code.

        Raises
        ------
        InputError
            For an unknown kind.
        """
        if isinstance(kind, str) and kind in SPRING_KINDS:
            return SPRING_KINDS.index(kind)
        if isinstance(kind, (int, np.integer)) and not isinstance(kind, bool) and 0 <= kind < len(SPRING_KINDS):
            return int(kind)
        raise InputError(f"unknown spring kind {kind!r}: use one of {', '.join(SPRING_KINDS)}")

    def select(self, kind: int | str) -> Springs:
        """The springs of one kind (name or code), in order."""
        keep = self.kind == self.code(kind)
        return Springs(self.pairs[keep], self.kind[keep], self.axis[keep], self.rest_length[keep])

    def counts(self) -> dict[str, int]:
        """Number of springs of each kind, by name."""
        n = np.bincount(self.kind.astype(np.int64), minlength=len(SPRING_KINDS))
        return {name: int(c) for name, c in zip(SPRING_KINDS, n)}

    def lengths(self, positions: np.ndarray) -> np.ndarray:
        """Current lengths of the springs for ``(N, d)`` (or ``(nu, nv, d)``) node positions."""
        x = np.asarray(positions, dtype=np.float64)
        x = x.reshape(-1, x.shape[-1])
        return np.linalg.norm(x[self.pairs[:, 1]] - x[self.pairs[:, 0]], axis=1)

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v}" for k, v in self.counts().items())
        return f"Springs({len(self)}: {shown})"


#: The spring groups in order: (first-end slices, second-end slices, kind, axis).
_GROUPS = (
    ((slice(None, -1), slice(None)), (slice(1, None), slice(None)), Springs.STRUCTURAL, 0),
    ((slice(None), slice(None, -1)), (slice(None), slice(1, None)), Springs.STRUCTURAL, 1),
    ((slice(None, -1), slice(None, -1)), (slice(1, None), slice(1, None)), Springs.SHEAR, -1),
    ((slice(1, None), slice(None, -1)), (slice(None, -1), slice(1, None)), Springs.SHEAR, -1),
    ((slice(None, -2), slice(None)), (slice(2, None), slice(None)), Springs.BEND, 0),
    ((slice(None), slice(None, -2)), (slice(None), slice(2, None)), Springs.BEND, 1),
)


def spring_pairs(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Topology of :func:`springs` for an ``nu x nv`` grid: ``(pairs, kind, axis)``."""
    idx = np.arange(nu * nv, dtype=np.int64).reshape(nu, nv)
    pairs = np.concatenate([np.stack([idx[a].ravel(), idx[b].ravel()], axis=1) for a, b, _, _ in _GROUPS])
    kind = np.concatenate([np.full(idx[a].size, k, dtype=np.int8) for a, _, k, _ in _GROUPS])
    axis = np.concatenate([np.full(idx[a].size, x, dtype=np.int8) for a, _, _, x in _GROUPS])
    return pairs, kind, axis


def springs(grid: GridLike) -> Springs:
    """Provot's springs of ``grid`` with rest lengths from the flat pattern.

    Structural springs join neighbours along u and v (the grid edges), shear
    springs the two diagonals of every cell, bend springs every second node
    along u and along v. An ``nu x nv`` grid has ``(nu-1) nv + nu (nv-1)``
    structural, ``2 (nu-1)(nv-1)`` shear and ``(nu-2) nv + nu (nv-2)`` bend
    springs. Rest lengths are measured on :func:`rest_coordinates`: the flat
    pattern of a planar piece, the 3D grid of a curved one.
    """
    nu, nv = grid.shape
    pairs, kind, axis = spring_pairs(nu, nv)
    rest = rest_coordinates(grid)
    length = np.concatenate([np.sqrt(np.einsum("...k,...k->...", d, d)).ravel()
                             for d in (rest[b] - rest[a] for a, b, _, _ in _GROUPS)])
    return Springs(pairs=pairs, kind=kind, axis=axis, rest_length=length)


# --------------------------------------------------------------------------- areas and masses


def cell_areas(grid: GridLike) -> np.ndarray:
    """``(nu-1, nv-1)`` rest areas of the cells, in the length unit squared.

    Half the norm of the cross product of the cell's diagonals, on
    :func:`rest_coordinates`: the exact area of a planar quad (convex or not);
    for a curved piece the area of the cell's vector-area projection. On a grid
    without folded cells the areas sum to the area enclosed by the boundary.
    """
    r = rest_coordinates(grid)
    d1 = r[1:, 1:] - r[:-1, :-1]
    d2 = r[:-1, 1:] - r[1:, :-1]
    if r.shape[-1] == 2:
        return 0.5 * np.abs(d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0])
    return 0.5 * np.linalg.norm(np.cross(d1, d2), axis=-1)


def node_areas(grid: GridLike) -> np.ndarray:
    """``(nu*nv,)`` lumped rest area per node: a quarter of each adjacent cell's area.

    In flat index order ``i*nv + j`` and the length unit squared; the sum is
    the sum of :func:`cell_areas`.
    """
    a = 0.25 * cell_areas(grid)
    nu, nv = grid.shape
    out = np.zeros((nu, nv))
    out[:-1, :-1] += a
    out[1:, :-1] += a
    out[1:, 1:] += a
    out[:-1, 1:] += a
    return out.ravel()


def node_masses(grid: GridLike, density: float | str, length_unit: str | None = None) -> np.ndarray:
    """``(nu*nv,)`` lumped node masses in kg: density times :func:`node_areas`.

    Parameters
    ----------
    grid : Grid
        The grid.
    density : float or str
        Areal density, kg/m^2 as a number or text with a unit (``"150gsm"``,
        ``"0.2kg/m2"``; :func:`parse_density`).
    length_unit : str, optional
        Unit of the grid's coordinates (:data:`LENGTH_UNITS`); default
        ``grid.info["length_unit"]`` if recorded, else metres.

    Returns
    -------
    numpy.ndarray
        Masses in flat index order; their sum is density times the piece's
        flat area.

    Raises
    ------
    InputError
        A bad density or unknown unit.
    """
    rho = parse_density(density)
    scale = length_scale(resolve_length_unit(grid, length_unit))
    return node_areas(grid) * (rho * scale * scale)


# --------------------------------------------------------------------------- sides and corners


def sides(grid: GridLike) -> dict[str, np.ndarray]:
    """Flat node indices of the four sides, each in its side's direction.

    ``bottom`` and ``top`` run left to right (``i`` increasing), ``left`` and
    ``right`` bottom to top (``j`` increasing), as the boundary's sides do; the
    corners belong to two sides each.
    """
    nu, nv = grid.shape
    i = np.arange(nu, dtype=np.int64)
    j = np.arange(nv, dtype=np.int64)
    return {"bottom": i * nv, "right": (nu - 1) * nv + j, "top": i * nv + nv - 1, "left": j.copy()}


def corners(grid: GridLike) -> dict[str, int]:
    """Flat node indices of the corners by name (:data:`CORNER_NAMES`)."""
    nu, nv = grid.shape
    return dict(zip(CORNER_NAMES, (0, (nu - 1) * nv, nu * nv - 1, nv - 1)))
