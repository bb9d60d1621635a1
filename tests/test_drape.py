"""Draping a sewn garment with NVIDIA Newton (issue 13, item 6): ``clothgrid.drape``.

- the arrays handed to Newton's Style3D cloth (no Newton needed): the rest shape is the flat
  pattern seen from the front side, so every triangle has positive panel area (a mirrored panel
  included) and the edge lengths are the pattern's;
- the body proxy's signed distance;
- with Newton installed (``clothgrid[sim]``, in the test extra): a few frames of a real drape on
  the CPU: Newton keeps every triangle with the pattern's rest area (not the placed one), the
  garment falls onto the body and is caught, nothing goes non-finite; and Newton's own USD loader
  reads the ``.usda`` clothgrid writes with the rest shape as its panel coordinates.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from clothgrid.drape import BODY_FRAMES, Capsule, body_proxy, guess_frame, style3d_arrays
from clothgrid.errors import InputError

SHARED = Path(__file__).resolve().parents[2] / "shared" / "patterns"
SKIRT = SHARED / "gpg_skirt_4_panels_specification.json"
needs_shared = pytest.mark.skipif(not SKIRT.exists(), reason="../shared/patterns is not there")


@lru_cache(maxsize=None)
def _skirt(edge: str = "8cm"):
    from clothgrid.garment import garment

    return garment(SKIRT, edge_length=edge)


def _newton():
    return pytest.importorskip("newton", reason="NVIDIA Newton is not installed (optional extra clothgrid[sim])")


@needs_shared
def test_style3d_arrays_are_the_pattern_seen_from_the_front():
    g = _skirt()
    assert any(p["flipped"] for p in g.info["panels"])          # the back is GarmentCode's mirrored copy
    a = style3d_arrays(g)
    tri, uv = a["panel_indices"], a["panel_verts"]
    np.testing.assert_array_equal(a["indices"], a["weld_map"][tri])
    np.testing.assert_allclose(a["vertices"], g.welded()["points"] / 1000.0)
    assert (a["triangle_area"] > 0).all()
    # in rest coordinates the mirrored panel's triangles run clockwise: that is what face_rest fixes
    r = g.rest[tri] / 1000.0
    signed = 0.5 * ((r[:, 1] - r[:, 0])[:, 0] * (r[:, 2] - r[:, 0])[:, 1]
                    - (r[:, 1] - r[:, 0])[:, 1] * (r[:, 2] - r[:, 0])[:, 0])
    assert (signed < 0).any() and (signed > 0).any()
    np.testing.assert_allclose(np.abs(signed), a["triangle_area"], rtol=1e-12)
    for i, j in ((0, 1), (1, 2), (2, 0)):                       # a mirror image: every length kept
        np.testing.assert_allclose(np.linalg.norm(uv[tri[:, i]] - uv[tri[:, j]], axis=1),
                                   np.linalg.norm(r[:, i] - r[:, j], axis=1), rtol=1e-12)
    # the pattern's area: every panel's quads by the shoelace formula
    q = g.rest[g.quads] / 1000.0
    x, y = q[..., 0], q[..., 1]
    area = 0.5 * np.abs((x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)).sum()
    assert float(a["panel_area"]) == pytest.approx(area, rel=1e-12)


def test_body_proxy_distance_and_frames():
    cap = Capsule("c", (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.1)
    d = cap.distance(np.array([[0.0, 0.5, 0.0], [0.3, 0.5, 0.0], [0.0, 1.3, 0.0], [0.0, -0.1, 0.0]]))
    np.testing.assert_allclose(d, [-0.1, 0.2, 0.2, 0.0], atol=1e-15)
    gc, gpg = body_proxy("garmentcode"), body_proxy("gpg")
    assert {gc.frame, gpg.frame} == set(BODY_FRAMES) and gc.floor == 0.0 and gpg.floor < -1.0
    assert gc.distance([[0.0, 1.0, 0.02]])[0] == pytest.approx(-0.085 + 0.04)   # inside the waist capsules
    assert gc.distance([[0.0, 1.0, 0.5]])[0] > 0.3               # well in front of it
    assert gc.distance([[0.0, -0.5, 0.0]])[0] > 0.3              # below the feet
    assert guess_frame(np.array([[0.0, 1.1, 0.0]])) == "garmentcode"
    assert guess_frame(np.array([[0.0, 0.3, 0.0]])) == "gpg"
    with pytest.raises(InputError, match="body frame"):
        body_proxy("smpl")


@needs_shared
def test_drape_a_few_frames_on_the_cpu():
    """A real Newton run: rest from the pattern, gravity, contacts with the capsules."""
    _newton()
    from clothgrid.drape import drape

    g = _skirt()
    a = style3d_arrays(g)
    res = drape(g, seconds=0.3, fps=30, substeps=10, device="cpu")
    rep = res.report()
    assert rep["frames"] == 9 and rep["finite"]
    assert rep["model_triangles"] == len(a["indices"])          # Newton dropped no triangle as inverted
    assert rep["rest_area_m2"] == pytest.approx(rep["pattern_area_m2"], rel=1e-6)
    # ... and that is the pattern's area, not the placed (welded, gapped) mesh's
    v = a["vertices"][a["indices"]]
    placed = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
    assert abs(placed - rep["pattern_area_m2"]) > 0.02 * rep["pattern_area_m2"]
    assert rep["final_mean_y"] < rep["start_mean_y"]             # it fell ...
    assert rep["final_mean_y"] > res.body.floor + 0.5            # ... onto the body, not to the floor
    assert rep["deepest_in_body_m"] < 0.02
    assert rep["strain_median"] < 0.05                           # the seams pulled the welded start to size
    assert rep["seconds"]["first_frame"] > 0 and len(res.history) == 9


@needs_shared
def test_newtons_usd_loader_reads_the_rest_shape(tmp_path):
    """Newton's Style3D path loads a USD mesh with face-varying st as the panel coordinates."""
    pytest.importorskip("pxr", reason="usd-core is not installed (optional extra clothgrid[usd])")
    _newton()
    import newton.usd
    from pxr import Usd

    g = _skirt()
    out = g.save(tmp_path / "skirt.usda", seams="weld")
    stage = Usd.Stage.Open(str(out))
    mesh, uv_idx = newton.usd.get_mesh(stage.GetPrimAtPath("/Garment/Cloth"), load_uvs=True,
                                       preserve_facevarying_uvs=True, return_uv_indices=True)
    uv, ti = np.asarray(mesh.uvs, dtype=np.float64), np.asarray(uv_idx).reshape(-1, 3)
    assert len(ti) == 2 * len(g.quads)
    e1, e2 = uv[ti[:, 1]] - uv[ti[:, 0]], uv[ti[:, 2]] - uv[ti[:, 0]]
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert (area > 0).all()                                       # Style3D would drop the others
    assert area.sum() / 1e6 == pytest.approx(float(style3d_arrays(g)["panel_area"]), rel=1e-5)
    assert len(mesh.vertices) == int(g.weld_map().max()) + 1
