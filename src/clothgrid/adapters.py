"""Hand a grid to other libraries: trimesh, PyVista, NVIDIA Warp / Newton.

trimesh and PyVista are optional: :func:`to_trimesh` and :func:`to_pyvista`
import them when called and raise :class:`~clothgrid.errors.MissingDependencyError`
(an ``ImportError`` and an ``InputError``) when they are not installed.
:func:`to_warp_arrays` needs only NumPy: it returns the arrays that Warp's and
Newton's ``ModelBuilder.add_cloth_mesh`` take, in SI units.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from . import cloth
from .errors import InputError, MissingDependencyError
from .grid import Grid
from .writers import texture_coordinates

__all__ = ["to_trimesh", "to_pyvista", "to_warp_arrays"]


def _require(module: str, purpose: str, pip_name: str | None = None) -> Any:
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f"{purpose} needs the optional package {pip_name or module!r}, which is not installed "
            f"({exc}); install it with: pip install {pip_name or module}") from None


def to_trimesh(grid: Grid, *, triangles: str = "fixed", uv: str = "normalised"):
    """The grid as a :class:`trimesh.Trimesh` (triangles, texture coordinates, no merging).

    Parameters
    ----------
    grid : Grid
        The grid.
    triangles : {"fixed", "alternate"}
        Diagonal choice of :meth:`Grid.triangles` (trimesh holds triangles only).
    uv : {"normalised", "pattern"}
        The texture coordinates attached (``mesh.visual.uv``).

    Returns
    -------
    trimesh.Trimesh
        Vertices in flat index order ``i*nv + j`` (``process=False``, so
        nothing is merged or reordered); ``mesh.metadata["clothgrid"]`` holds
        the shape, quads and sides.

    Raises
    ------
    MissingDependencyError
        If trimesh is not installed.
    """
    trimesh = _require("trimesh", "to_trimesh")
    if triangles not in ("fixed", "alternate"):
        raise InputError(f"triangles must be 'fixed' or 'alternate', not {triangles!r}")
    from trimesh.visual import TextureVisuals

    mesh = trimesh.Trimesh(vertices=np.array(grid.vertices, dtype=np.float64),
                           faces=grid.triangles(triangles),
                           visual=TextureVisuals(uv=np.array(texture_coordinates(grid, uv))), process=False)
    mesh.metadata["clothgrid"] = {"shape": list(grid.shape), "quads": np.array(grid.quads),
                                  "sides": grid.sides, "corners": grid.corners}
    return mesh


def to_pyvista(grid: Grid, *, density: float | str | None = None, length_unit: str | None = None):
    """The grid as a :class:`pyvista.StructuredGrid` with its point data.

    Dimensions ``(nv, nu, 1)``, so point ids are clothgrid's flat indices
    ``i*nv + j`` (as in the ``.vts`` writer). Point data: ``uv`` (the active
    texture coordinates), ``pattern_uv``, ``node_area`` and, with ``density``,
    ``mass`` in kg (``length_unit`` as in :func:`clothgrid.cloth.node_masses`).

    Raises
    ------
    MissingDependencyError
        If pyvista is not installed.
    InputError
        A bad density or unknown unit.
    """
    mass = None if density is None else cloth.node_masses(grid, density, length_unit)
    pv = _require("pyvista", "to_pyvista")
    nu, nv = grid.shape
    sg = pv.StructuredGrid()
    sg.points = np.array(grid.vertices, dtype=np.float64)
    sg.dimensions = (nv, nu, 1)
    sg.point_data["uv"] = np.array(grid.uv.reshape(-1, 2))
    sg.point_data["pattern_uv"] = np.array(grid.pattern_uv.reshape(-1, 2))
    sg.point_data["node_area"] = cloth.node_areas(grid)
    if mass is not None:
        sg.point_data["mass"] = mass
    try:
        sg.point_data.active_texture_coordinates_name = "uv"
    except AttributeError:  # older pyvista
        sg.point_data.active_t_coords_name = "uv"
    return sg


def to_warp_arrays(grid: Grid, *, density: float | str | None = None, length_unit: str | None = None,
                   triangles: str = "fixed") -> dict[str, Any]:
    """Arrays for NVIDIA Warp / Newton cloth (``ModelBuilder.add_cloth_mesh``), in SI units.

    Coordinates are converted from ``length_unit`` (default
    ``grid.info["length_unit"]``, else metres) to metres. No Warp import: pass
    the arrays on, e.g.
    ``builder.add_cloth_mesh(pos=..., rot=..., scale=1.0, vel=..., vertices=a["vertices"],
    indices=a["indices"], density=a["density"])`` (older ``warp.sim`` wants
    ``vertices`` as a list of ``wp.vec3``).

    Returns
    -------
    dict
        ``vertices`` ``(N, 3)`` float32 metres, in flat index order;
        ``indices`` ``(3T,)`` int32, triangles flattened (counter-clockwise,
        :meth:`Grid.triangles` with ``triangles``); ``uv`` ``(N, 2)`` float32
        normalised; ``spring_indices`` ``(2m,)`` int32 flattened pairs,
        ``spring_rest_lengths`` ``(m,)`` float32 metres and ``spring_kinds``
        ``(m,)`` int8 (:class:`clothgrid.cloth.Springs`); ``corners`` ``(4,)``
        int32 (bottom-left, bottom-right, top-right, top-left) and
        ``side_bottom``/``side_right``/``side_top``/``side_left`` int32, for
        pinning (``builder.particle_mass``/flags) and sewing;
        ``length_scale`` (metres per input unit). For a planar piece also
        ``panel_verts`` ``(N, 2)`` float32 metres (the flat pattern, Newton's
        Style3D name) and ``panel_indices`` (= ``indices``). With ``density``
        also ``density`` (float, kg/m^2, Warp's per-area density) and
        ``masses`` ``(N,)`` float32 kg (quad-lumped; ``add_cloth_mesh``
        lumps triangle areas itself, with the same total).

    Raises
    ------
    InputError
        A bad density, unknown unit or diagonal choice.
    """
    unit = cloth.resolve_length_unit(grid, length_unit)
    scale = cloth.length_scale(unit)
    if triangles not in ("fixed", "alternate"):
        raise InputError(f"triangles must be 'fixed' or 'alternate', not {triangles!r}")
    indices = np.ascontiguousarray(grid.triangles(triangles).ravel(), dtype=np.int32)
    sp = cloth.springs(grid)
    out: dict[str, Any] = {
        "vertices": np.ascontiguousarray(grid.vertices * scale, dtype=np.float32),
        "indices": indices,
        "uv": np.ascontiguousarray(grid.uv.reshape(-1, 2), dtype=np.float32),
        "spring_indices": np.ascontiguousarray(sp.pairs.ravel(), dtype=np.int32),
        "spring_rest_lengths": np.asarray(sp.rest_length * scale, dtype=np.float32),
        "spring_kinds": sp.kind.copy(),
        "corners": np.array([grid.corners[k] for k in cloth.CORNER_NAMES], dtype=np.int32),
        "length_scale": scale,
    }
    out.update({f"side_{k}": v.astype(np.int32) for k, v in grid.sides.items()})
    if grid.planar:
        out["panel_verts"] = np.ascontiguousarray(grid.pattern_uv.reshape(-1, 2) * scale, dtype=np.float32)
        out["panel_indices"] = indices
    if density is not None:
        rho = cloth.parse_density(density)
        out["density"] = rho
        out["masses"] = np.asarray(cloth.node_masses(grid, rho, unit), dtype=np.float32)
    return out
