"""A sewn garment as USD: one ``UsdGeom.Mesh``, the rest shape as face-varying ``primvars:st``.

Written through ``usd-core`` (``pip install clothgrid[usd]``; imported only
here, when a ``.usda`` / ``.usd`` / ``.usdc`` output is asked for):

- ``/Garment`` (the default prim, an ``Xform``) holding the mesh ``/Garment/Cloth``:
  ``points`` (placed, mm; every grid node, or the welded vertices with
  ``seams="weld"``), ``faceVertexCounts`` (all 4), ``faceVertexIndices`` (the
  quads, oriented as the spec's edge loops), ``orientation`` right-handed,
  ``subdivisionScheme`` none;
- ``primvars:st`` (``TexCoord2fArray``, interpolation ``faceVarying``): at every
  face corner the flat pattern coordinates (mm) of that corner's grid node, in
  its panel's own frame, so a welded vertex keeps one rest position per panel
  it belongs to (the pattern rest shape a cloth solver takes its rest lengths
  from); seen from the faces' front side (``Garment.face_rest``: a flipped
  panel's ``x`` negated), so every face runs counter-clockwise in ``st`` as
  Newton's Style3D loader needs (it drops faces of negative panel area);
- one ``UsdGeom.Subset`` per panel (family ``panel``, element type ``face``,
  partition), named after the panel (made a valid prim name);
- stage metadata: ``metersPerUnit`` 0.001, ``upAxis`` Y; ``customData`` on the
  mesh: ``clothgrid:seams`` (keep / weld), ``clothgrid:stitched_pairs``.

Seams are not in the USD file: with ``seams="keep"`` they are in the ``.npz``
(``stitches``); ``seams="weld"`` writes the sewn mesh.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["write_garment_usd", "USD_SUFFIXES"]

USD_SUFFIXES = (".usda", ".usd", ".usdc")


def _pxr() -> Any:
    try:
        import pxr.Sdf
        import pxr.Usd
        import pxr.UsdGeom
        import pxr.Vt
    except ImportError:
        raise InputError("USD output needs usd-core: pip install 'clothgrid[usd]' (or pip install usd-core)") from None
    return pxr


def prim_name(name: str, taken: set[str]) -> str:
    """A valid, unused USD prim name for a panel name."""
    base = re.sub(r"[^A-Za-z0-9_]", "_", name) or "panel"
    if base[0].isdigit():
        base = "panel_" + base
    out, k = base, 1
    while out in taken:
        k += 1
        out = f"{base}_{k}"
    taken.add(out)
    return out


def write_garment_usd(g: Any, path: str | Path, *, seams: str = "keep") -> Path:
    """Write a :class:`clothgrid.garment.Garment` as a USD stage (``.usda`` text, ``.usd`` /
    ``.usdc`` crate), atomically. (``g`` is typed ``Any``: ``garment.py`` imports this module, and
    imports run one way, ``tests/test_architecture.py``.)"""
    from .writers import atomic_write

    pxr = _pxr()
    Sdf, Usd, UsdGeom, Vt = pxr.Sdf, pxr.Usd, pxr.UsdGeom, pxr.Vt
    path = Path(path)
    if seams == "weld":
        w = g.welded()
        pts, faces = w["points"], w["quads"]
    else:
        pts, faces = g.points, g.quads
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 0.001)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    root = UsdGeom.Xform.Define(stage, "/Garment")
    stage.SetDefaultPrim(root.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/Garment/Cloth")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(pts, dtype=np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 4, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces.reshape(-1), dtype=np.int32)))
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(np.array([lo, hi], dtype=np.float32)))
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                 UsdGeom.Tokens.faceVarying)
    st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(g.face_rest[g.quads.reshape(-1)], dtype=np.float32)))
    taken: set[str] = set()
    for pi, name in enumerate(g.panel_names):
        sub = UsdGeom.Subset.Define(stage, f"/Garment/Cloth/{prim_name(name, taken)}")
        sub.CreateElementTypeAttr(UsdGeom.Tokens.face)
        sub.CreateFamilyNameAttr("panel")
        sub.CreateIndicesAttr(Vt.IntArray.FromNumpy(np.flatnonzero(g.face_panel == pi).astype(np.int32)))
        sub.GetPrim().SetCustomDataByKey("clothgrid:panel", str(name))
    UsdGeom.Subset.SetFamilyType(mesh, "panel", UsdGeom.Tokens.partition)
    mesh.GetPrim().SetCustomDataByKey("clothgrid:seams", seams)
    mesh.GetPrim().SetCustomDataByKey("clothgrid:stitched_pairs", int(len(g.stitches)))
    layer = stage.GetRootLayer()
    suffix = path.suffix.lower()
    with atomic_write(path) as fh:
        if suffix == ".usda":
            fh.write(layer.ExportToString().encode("utf-8"))
        else:                                   # crate: export next to it, then move the bytes in
            with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
                out = Path(tmp) / "garment.usdc"
                if not layer.Export(str(out)):
                    raise InputError(f"cannot write {str(path)!r}: USD export failed")
                fh.write(out.read_bytes())
    return path
