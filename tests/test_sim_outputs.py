"""Simulation outputs: pattern coordinates, springs, masses, sides, files and adapters (issue 5)."""

from __future__ import annotations

import base64
import importlib.util
import json
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import parse_obj

from clothgrid import Boundary, Grid, InputError, generate, load_boundary
from clothgrid.adapters import to_pyvista, to_trimesh, to_warp_arrays
from clothgrid.cli import main
from clothgrid.cloth import CORNER_NAMES, SPRING_KINDS, Springs, length_scale, node_masses, parse_density
from clothgrid.errors import MissingDependencyError
from clothgrid.writers import save, writer_options

ROOT = Path(__file__).resolve().parents[1]
TSHIRT = ROOT / "src" / "clothgrid" / "data" / "tshirt_front.json"


@pytest.fixture(scope="module")
def tshirt() -> Grid:
    return generate(load_boundary(TSHIRT), (9, 12), weights="uniform")


def shoelace(grid: Grid) -> float:
    """Area enclosed by the grid's boundary nodes, from the 2D coordinates."""
    p = grid.points
    loop = np.concatenate([p[:-1, 0], p[-1, :-1], p[:0:-1, -1], p[0, :0:-1]])[:, :2]
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def rotated(boundary: Boundary, angle: float = 0.7, shift=(0.1, -0.2, 0.3)) -> Boundary:
    """The 2D boundary placed in 3D: rotated about x and shifted (a tilted plane)."""
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])
    sides = [np.c_[p[:, :2], 0 * p[:, 0]] @ rot.T + shift
             for p in (boundary.bottom, boundary.right, boundary.top, boundary.left)]
    return Boundary.from_sides(*sides)


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


# --------------------------------------------------------------------------- pattern coordinates


def test_pattern_uv_2d_is_xy(tshirt):
    assert tshirt.dim == 2 and tshirt.planar
    np.testing.assert_array_equal(tshirt.pattern_uv, tshirt.points[..., :2])


def test_pattern_uv_of_a_tilted_planar_piece_is_an_isometry(tshirt):
    g3 = generate(rotated(load_boundary(TSHIRT)), (9, 12), weights="uniform")
    assert g3.dim == 3 and g3.planar
    flat, ref = g3.pattern_uv.reshape(-1, 2), tshirt.points[..., :2].reshape(-1, 2)
    # a rotation about x followed by the smallest rotation back: the same shape, same handedness
    d = flat - flat[0] - (ref - ref[0])
    assert np.abs(d).max() < 1e-12
    np.testing.assert_allclose(g3.springs().rest_length, tshirt.springs().rest_length, rtol=0, atol=1e-13)


def test_pattern_uv_of_a_3d_piece_in_the_xy_plane_keeps_xy(tshirt):
    g3 = Grid.from_points(tshirt.points + [0.0, 0.0, 2.5], dim=3)
    assert g3.planar
    np.testing.assert_allclose(g3.pattern_uv, tshirt.points[..., :2], rtol=0, atol=1e-15)


def test_curved_piece_uses_arc_lengths_and_3d_rest_shape():
    i, j = np.meshgrid(np.linspace(0, 1, 7), np.linspace(0, 1, 5), indexing="ij")
    p = np.stack([i, j, 0.3 * np.sin(np.pi * i) * np.cos(j)], axis=-1)
    g = Grid.from_points(p, dim=3)
    assert not g.planar
    lengths_u = np.linalg.norm(np.diff(p, axis=0), axis=-1).sum(axis=0)
    lengths_v = np.linalg.norm(np.diff(p, axis=1), axis=-1).sum(axis=1)
    np.testing.assert_allclose(g.pattern_uv[..., 0], g.uv[..., 0] * lengths_u[None, :], atol=1e-14)
    np.testing.assert_allclose(g.pattern_uv[..., 1], g.uv[..., 1] * lengths_v[:, None], atol=1e-14)
    sp = g.springs()
    flat = p.reshape(-1, 3)
    np.testing.assert_allclose(sp.rest_length, np.linalg.norm(flat[sp.pairs[:, 1]] - flat[sp.pairs[:, 0]], axis=1))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_uv_kernel_gives_the_numpy_parameters(monkeypatch, seed):
    """Large grids get their uv from one Numba pass (grid_kernels.arc_length_uv_into): on fresh
    curved grids, with lines of coincident nodes (uniform parameters) and widths that do not fill
    the kernel's column blocks, it gives the NumPy form's numbers bit for bit."""
    import clothgrid.grid as grid_module
    from clothgrid import grid_kernels

    rng = np.random.default_rng([seed, 5])
    nu, nv = (int(n) for n in rng.integers(2, 600, size=2))
    p = np.cumsum(rng.normal(size=(nu, nv, 3)) * 10.0 ** rng.uniform(-3, 3), axis=int(rng.integers(2)))
    if seed == 1:
        p[:, int(rng.integers(nv))] = p[0, 0]     # a u-line of coincident nodes
        p[int(rng.integers(nu))] = p[0, 0]        # a v-line likewise
    monkeypatch.setattr(grid_module, "KERNEL_NODES", 10**12)
    ref = grid_module.arc_length_uv(p)
    monkeypatch.setattr(grid_module, "KERNEL_NODES", 0)
    calls, kernel = [], grid_kernels.arc_length_uv_into
    monkeypatch.setattr(grid_kernels, "arc_length_uv_into", lambda *a: calls.append(1) or kernel(*a))
    got = grid_module.arc_length_uv(p)
    assert calls, "the kernel was not used"
    np.testing.assert_array_equal(got, ref)
    assert np.all(ref[0, :, 0] == 0) and np.all(ref[:, 0, 1] == 0) and np.all(ref[-1, :, 0] == 1) and np.all(ref[:, -1, 1] == 1)



def test_mask_places_is_argwhere(monkeypatch, rng):
    """grid_kernels.mask_places lists a mask's true entries as numpy.argwhere does, in the same
    order, by NumPy under _PARALLEL_ENTRIES and by the parallel kernels above: fresh masks of
    every density (none, all, a few), widths of one, empty rows and non-contiguous views."""
    from clothgrid import grid_kernels

    for threshold in (10**12, 0):
        monkeypatch.setattr(grid_kernels, "_PARALLEL_ENTRIES", threshold)
        for trial in range(30):
            nu, nv = (int(n) for n in rng.integers(1, 300, size=2))
            density = (0.0, 1.0, 1e-3, 0.5)[trial % 4]
            mask = rng.random((nu, nv)) < density
            if trial % 5 == 0:
                mask[rng.integers(nu)] = False        # an empty row
            if trial % 7 == 0:
                mask = mask[::2, ::-1]                # a view, not contiguous
            got = grid_kernels.mask_places(mask)
            assert got.dtype == np.int64 and got.shape[1] == 2
            np.testing.assert_array_equal(got, np.argwhere(mask))
    with pytest.raises(ValueError):
        grid_kernels.mask_places(np.zeros(5, bool))


# --------------------------------------------------------------------------- springs


def test_springs_topology_kinds_and_rest_lengths(tshirt):
    nu, nv = tshirt.shape
    sp = tshirt.springs()
    assert isinstance(sp, Springs) and sp.pairs.dtype == np.int64 and sp.kind.dtype == np.int8
    assert sp.counts() == {"structural": (nu - 1) * nv + nu * (nv - 1), "shear": 2 * (nu - 1) * (nv - 1),
                           "bend": (nu - 2) * nv + nu * (nv - 2)}
    assert Springs.KINDS == SPRING_KINDS == ("structural", "shear", "bend")
    ia, ja = np.divmod(sp.pairs[:, 0], nv)
    ib, jb = np.divmod(sp.pairs[:, 1], nv)
    di, dj = np.abs(ib - ia), np.abs(jb - ja)
    step = {tuple(x) for x in np.c_[sp.kind, di, dj]}
    assert step == {(0, 1, 0), (0, 0, 1), (1, 1, 1), (2, 2, 0), (2, 0, 2)}
    assert ((sp.axis == 0) == (dj == 0) & (sp.kind != 1)).all() and ((sp.axis == -1) == (sp.kind == 1)).all()
    assert len({tuple(sorted(p)) for p in sp.pairs.tolist()}) == len(sp)         # no duplicates
    # rest lengths from the flat coordinates, independently: loop over the pairs
    flat = tshirt.points[..., :2]
    for (a, b), length in zip(sp.pairs.tolist(), sp.rest_length.tolist()):
        (i1, j1), (i2, j2) = divmod(a, nv), divmod(b, nv)
        assert length == pytest.approx(np.hypot(*(flat[i2, j2] - flat[i1, j1])), rel=1e-14)
    shear = sp.select("shear")
    assert len(shear) == sp.counts()["shear"] and (shear.kind == Springs.SHEAR).all()
    np.testing.assert_allclose(sp.lengths(tshirt.points), sp.rest_length, rtol=1e-14)
    with pytest.raises(InputError, match="unknown spring kind"):
        sp.select("diagonal")


# --------------------------------------------------------------------------- masses and units


@pytest.mark.parametrize("text, kg_m2", [
    ("0.2kg/m2", 0.2), ("150gsm", 0.15), ("150 g/m^2", 0.15), ("150 GSM", 0.15), ("0.015g/cm2", 0.15),
    ("1.5e-4 g/mm**2", 0.15), ("0.2 kg/m²", 0.2), ("1 oz/yd2", 0.028349523125 / 0.9144 ** 2),
])
def test_parse_density(text, kg_m2):
    assert parse_density(text) == pytest.approx(kg_m2, rel=1e-12)


@pytest.mark.parametrize("bad", ["", "0.2", "0.2 kg", "kg/m2", "0.2kg/furlong2", "0.2 stone/m2", "-1kg/m2",
                                 "0kg/m2", "nan kg/m2", "1e999 kg/m2", "0.2 kg/m3", None, True, -3.0, float("inf")])
def test_parse_density_rejects(bad):
    with pytest.raises(InputError):
        parse_density(bad)      # text needs a unit; a number (kg/m2) must be positive and finite


def test_parse_density_plain_number_is_kg_per_m2():
    assert parse_density(0.2) == 0.2 and parse_density(np.float32(0.5)) == 0.5


def test_length_units():
    assert length_scale("mm") == 1e-3 and length_scale("M") == 1.0 and length_scale("in") == 0.0254
    with pytest.raises(InputError, match="unknown length unit 'furlong'"):
        length_scale("furlong")


def test_node_masses_sum_to_density_times_flat_area(tshirt):
    area = shoelace(tshirt)
    masses = tshirt.node_masses("150gsm")
    assert masses.shape == (tshirt.points.shape[0] * tshirt.points.shape[1],) and (masses > 0).all()
    assert masses.sum() == pytest.approx(0.15 * area, rel=1e-12)
    # a quarter of each adjacent cell: a corner node gets a quarter of its one cell
    p = tshirt.points[..., :2]
    d1, d2 = p[1, 1] - p[0, 0], p[0, 1] - p[1, 0]
    assert masses[0] == pytest.approx(0.15 * 0.25 * 0.5 * abs(d1[0] * d2[1] - d1[1] * d2[0]), rel=1e-12)
    # the same piece in millimetres has the same masses
    mm = Grid.from_points(tshirt.points * 1000.0, dim=2)
    np.testing.assert_allclose(mm.node_masses("150gsm", "mm"), masses, rtol=1e-12)
    np.testing.assert_allclose(node_masses(Grid.from_points(mm.points, dim=2, info={"length_unit": "mm"}), 0.15),
                               masses, rtol=1e-12)
    # a tilted 3D copy has the same flat area
    g3 = generate(rotated(load_boundary(TSHIRT)), (9, 12), weights="uniform")
    assert g3.node_masses(0.15).sum() == pytest.approx(0.15 * area, rel=1e-12)
    with pytest.raises(InputError):
        tshirt.node_masses("150gsm", "furlong")


def test_sides_and_corners(tshirt):
    nu, nv = tshirt.shape
    v = tshirt.vertices
    s = tshirt.sides
    np.testing.assert_array_equal(v[s["bottom"]], tshirt.points[:, 0])
    np.testing.assert_array_equal(v[s["top"]], tshirt.points[:, -1])
    np.testing.assert_array_equal(v[s["left"]], tshirt.points[0, :])
    np.testing.assert_array_equal(v[s["right"]], tshirt.points[-1, :])
    b = load_boundary(TSHIRT).resampled(nu, nv)
    for name in ("bottom", "right", "top", "left"):
        np.testing.assert_allclose(v[s[name]], getattr(b, name), atol=1e-15)
    c = tshirt.corners
    assert tuple(c) == CORNER_NAMES
    assert c == {"bottom-left": s["bottom"][0], "bottom-right": s["bottom"][-1], "top-right": s["top"][-1],
                 "top-left": s["top"][0]}
    assert v[c["top-left"]].tolist() == [0.06, 0.66, 0.0] and v[c["top-right"]].tolist() == [0.44, 0.66, 0.0]


# --------------------------------------------------------------------------- files


def test_obj_reimports_with_trimesh_and_parser(tshirt, tmp_path):
    trimesh = pytest.importorskip("trimesh", reason="trimesh is in the test extras: pip install -e .[test]")
    path = save(tshirt, tmp_path / "t.obj")
    v, vt, f = parse_obj(path.read_text())
    np.testing.assert_array_equal(v, tshirt.vertices)
    np.testing.assert_array_equal(vt, tshirt.uv.reshape(-1, 2))
    np.testing.assert_array_equal(f, tshirt.quads)
    mesh = trimesh.load(path, process=False)
    np.testing.assert_array_equal(mesh.vertices, tshirt.vertices)          # order and values kept
    np.testing.assert_array_equal(mesh.visual.uv, tshirt.uv.reshape(-1, 2))
    # trimesh splits each quad a b c d along a-c: the "fixed" triangles
    assert sorted(map(tuple, np.sort(mesh.faces, axis=1))) == \
        sorted(map(tuple, np.sort(tshirt.triangles("fixed"), axis=1)))
    assert mesh.area == pytest.approx(shoelace(tshirt), rel=1e-12)


@pytest.mark.parametrize("diagonal", ["fixed", "alternate"])
def test_obj_triangles_and_pattern_uv(tshirt, tmp_path, diagonal):
    trimesh = pytest.importorskip("trimesh", reason="trimesh is in the test extras: pip install -e .[test]")
    path = save(tshirt, tmp_path / "t.obj", triangles=diagonal, uv="pattern")
    v, vt, f = parse_obj(path.read_text())
    np.testing.assert_array_equal(vt, tshirt.pattern_uv.reshape(-1, 2))
    np.testing.assert_array_equal(f, tshirt.triangles(diagonal))
    mesh = trimesh.load(path, process=False)
    np.testing.assert_array_equal(mesh.faces, tshirt.triangles(diagonal))
    np.testing.assert_array_equal(mesh.visual.uv, tshirt.pattern_uv.reshape(-1, 2))


def test_ply_triangles_with_pattern_uv(tshirt, tmp_path):
    lines = save(tshirt, tmp_path / "t.ply", triangles="alternate", uv="pattern").read_text().splitlines()
    end = lines.index("end_header")
    n = tshirt.vertices.shape[0]
    tris = tshirt.triangles("alternate")
    assert f"element face {len(tris)}" in lines[:end]
    body = lines[end + 1:]
    vert = np.array([[float(x) for x in line.split()] for line in body[:n]])
    np.testing.assert_array_equal(vert[:, 3:], tshirt.pattern_uv.reshape(-1, 2))
    faces = np.array([[int(x) for x in line.split()] for line in body[n:]])
    assert (faces[:, 0] == 3).all()
    np.testing.assert_array_equal(faces[:, 1:], tris)


def test_npz_cloth_contents(tshirt, tmp_path):
    path = save(tshirt, tmp_path / "t.npz", density="150gsm", triangles="alternate")
    nu, nv = tshirt.shape
    with np.load(path, allow_pickle=False) as z:
        np.testing.assert_array_equal(z["points"], tshirt.points)
        np.testing.assert_array_equal(z["pattern_uv"], tshirt.points[..., :2])
        np.testing.assert_array_equal(z["triangles"], tshirt.triangles("alternate"))
        assert str(z["triangle_diagonal"]) == "alternate" and str(z["length_unit"]) == "m" and bool(z["planar"])
        pairs, kind, rest = z["spring_pairs"], z["spring_kind"], z["spring_rest_length"]
        assert list(z["spring_kind_names"]) == ["structural", "shear", "bend"]
        # rest lengths recomputed from the flat coordinates, independently of clothgrid.cloth
        flat = z["pattern_uv"].reshape(-1, 2)
        np.testing.assert_allclose(rest, np.hypot(*(flat[pairs[:, 1]] - flat[pairs[:, 0]]).T), rtol=1e-14)
        assert np.bincount(kind).tolist() == list(tshirt.springs().counts().values())
        assert float(z["density"]) == pytest.approx(0.15)
        assert z["masses"].sum() == pytest.approx(0.15 * shoelace(tshirt), rel=1e-12)
        assert z["node_area"].sum() == pytest.approx(shoelace(tshirt), rel=1e-12)
        np.testing.assert_array_equal(z["side_top"], np.arange(nu) * nv + nv - 1)
        np.testing.assert_array_equal(z["corners"], [0, (nu - 1) * nv, nu * nv - 1, nv - 1])
        assert list(z["corner_names"]) == list(CORNER_NAMES)


def test_npz_default_stays_lean(tshirt, tmp_path):
    with np.load(save(tshirt, tmp_path / "t.npz"), allow_pickle=False) as z:
        assert "spring_pairs" not in z.files and "masses" not in z.files
        assert {"points", "uv", "quads", "info", "side_left", "corners", "length_unit"} <= set(z.files)
    with np.load(save(tshirt, tmp_path / "c.npz", cloth=True), allow_pickle=False) as z:
        assert "spring_pairs" in z.files and "node_area" in z.files and "masses" not in z.files


def _vts_arrays(path: Path) -> tuple[ET.Element, dict[str, np.ndarray]]:
    root = ET.parse(path).getroot()
    assert root.get("type") == "StructuredGrid" and root.get("header_type") == "UInt64"
    out = {}
    for da in root.iter("DataArray"):
        raw = base64.b64decode(da.text)
        nbytes = int(np.frombuffer(raw[:8], "<u8")[0])
        assert nbytes == len(raw) - 8
        out[da.get("Name")] = np.frombuffer(raw[8:], "<f8").reshape(-1, int(da.get("NumberOfComponents")))
    return root, out


def test_vts_structure(tshirt, tmp_path):
    path = save(tshirt, tmp_path / "t.vts", density="150gsm")
    root, arrays = _vts_arrays(path)
    nu, nv = tshirt.shape
    assert root.find("StructuredGrid").get("WholeExtent") == f"0 {nv - 1} 0 {nu - 1} 0 0"
    np.testing.assert_array_equal(arrays["Points"], tshirt.vertices)
    np.testing.assert_array_equal(arrays["uv"], tshirt.uv.reshape(-1, 2))
    np.testing.assert_array_equal(arrays["pattern_uv"], tshirt.pattern_uv.reshape(-1, 2))
    assert arrays["mass"].sum() == pytest.approx(0.15 * shoelace(tshirt), rel=1e-12)
    assert root.find(".//PointData").get("TCoords") == "uv"


def test_writer_options_are_checked(tshirt, tmp_path):
    assert writer_options(".obj") == {"triangles", "uv"}
    assert writer_options("vts") == {"density", "length_unit"}
    with pytest.raises(InputError, match="takes no option density"):
        save(tshirt, tmp_path / "t.json", density="150gsm")
    with pytest.raises(InputError, match="triangles must be"):
        save(tshirt, tmp_path / "t.obj", triangles="diagonal")
    with pytest.raises(InputError, match="invalid density"):
        save(tshirt, tmp_path / "t.npz", density="heavy")
    with pytest.raises(InputError, match="unknown length unit"):
        save(tshirt, tmp_path / "t.vts", length_unit="parsec")
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- adapters


def test_to_trimesh(tshirt):
    pytest.importorskip("trimesh", reason="trimesh is in the test extras: pip install -e .[test]")
    mesh = to_trimesh(tshirt, triangles="alternate", uv="pattern")
    np.testing.assert_array_equal(mesh.vertices, tshirt.vertices)
    np.testing.assert_array_equal(mesh.faces, tshirt.triangles("alternate"))
    np.testing.assert_array_equal(mesh.visual.uv, tshirt.pattern_uv.reshape(-1, 2))
    assert mesh.area == pytest.approx(shoelace(tshirt), rel=1e-12)


def test_to_pyvista(tshirt):
    pytest.importorskip("pyvista", reason="pyvista is optional and not installed")
    sg = to_pyvista(tshirt, density="150gsm")
    nu, nv = tshirt.shape
    assert tuple(sg.dimensions) == (nv, nu, 1)
    np.testing.assert_array_equal(np.asarray(sg.points), tshirt.vertices)
    assert float(np.sum(sg.point_data["mass"])) == pytest.approx(0.15 * shoelace(tshirt), rel=1e-12)


def test_missing_optional_packages_raise_clearly(tshirt, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyvista", None)
    monkeypatch.setitem(sys.modules, "trimesh", None)
    for func in (to_pyvista, to_trimesh):
        with pytest.raises(MissingDependencyError, match="pip install") as info:
            func(tshirt)
        assert isinstance(info.value, ImportError) and isinstance(info.value, InputError)


def test_to_warp_arrays_in_metres(tshirt):
    mm = Grid.from_points(tshirt.points * 1000.0, dim=2)
    a = to_warp_arrays(mm, density="150gsm", length_unit="mm")
    n = tshirt.vertices.shape[0]
    assert a["vertices"].dtype == np.float32 and a["vertices"].shape == (n, 3)
    np.testing.assert_allclose(a["vertices"], tshirt.vertices, atol=1e-6)
    assert a["indices"].dtype == np.int32 and a["indices"].shape == (3 * 2 * len(tshirt.quads),)
    np.testing.assert_array_equal(a["indices"].reshape(-1, 3), tshirt.triangles())
    assert a["density"] == pytest.approx(0.15) and a["masses"].sum() == pytest.approx(0.15 * shoelace(tshirt))
    np.testing.assert_allclose(a["spring_rest_lengths"], tshirt.springs().rest_length, rtol=1e-6)
    assert a["spring_indices"].dtype == np.int32 and a["spring_indices"].size == 2 * a["spring_kinds"].size
    np.testing.assert_allclose(a["panel_verts"], tshirt.points[..., :2].reshape(-1, 2), atol=1e-6)
    assert a["corners"].tolist() == [tshirt.corners[k] for k in CORNER_NAMES]
    assert "density" not in to_warp_arrays(tshirt)


# --------------------------------------------------------------------------- command line


def test_cli_cloth_outputs(capsys, tmp_path):
    obj, npz, vts = tmp_path / "t.obj", tmp_path / "t.npz", tmp_path / "t.vts"
    code, _, err = run(capsys, "generate", TSHIRT, "--nodes", "9x12", "--weights", "uniform", "-q",
                       "-o", obj, "-o", npz, "-o", vts, "--density", "150gsm", "--triangles", "alternate",
                       "--uv", "pattern")
    assert code == 0, err
    _, vt, f = parse_obj(obj.read_text())
    assert f.shape[1] == 3 and np.abs(vt).max() > 0.4            # triangles, pattern uv in metres
    with np.load(npz) as z:
        assert z["masses"].sum() == pytest.approx(0.15 * 0.3110, rel=0.01)
        assert str(z["length_unit"]) == "m" and json.loads(str(z["info"]))["length_unit"] == "m"
    assert _vts_arrays(vts)[1]["mass"].sum() == pytest.approx(0.15 * 0.3110, rel=0.01)


def test_cli_units_scale_the_masses(capsys, tmp_path):
    code, _, err = run(capsys, "generate", TSHIRT, "--nodes", "5", "-q", "-o", tmp_path / "t.npz",
                       "--density", "150gsm", "--units", "cm")
    assert code == 0, err
    with np.load(tmp_path / "t.npz") as z:
        assert str(z["length_unit"]) == "cm"
        assert z["masses"].sum() == pytest.approx(0.15 * 1e-4 * z["node_area"].sum(), rel=1e-12)


@pytest.mark.parametrize("flags, message", [
    (["--density", "heavy"], "invalid density 'heavy'"),
    (["--density", "150"], "give a unit"),
    (["--density", "150 stone/m2"], "unknown mass unit"),
    (["--density=-1kg/m2"], "positive"),
    (["--units", "furlong"], "unknown length unit"),
    (["--triangles", "diagonal"], "invalid choice"),
])
def test_cli_bad_cloth_options_exit_2_and_write_nothing(capsys, tmp_path, flags, message):
    code, out, err = run(capsys, "generate", TSHIRT, "--nodes", "5", "-o", tmp_path / "t.npz",
                         "-o", tmp_path / "t.vts", *flags)
    assert code == 2
    assert message in err and "clothgrid: error:" in err
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- the drape example


def test_drape_example_is_stable(monkeypatch):
    spec = importlib.util.spec_from_file_location("drape_example", ROOT / "examples" / "drape.py")
    drape = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, drape)   # its dataclasses look their module up
    spec.loader.exec_module(drape)
    grid = drape.load_piece("tshirt", (9, 11))
    result = drape.drape(grid, seconds=0.4, samples=40)
    assert result.finite
    assert result.energy_rise <= 1e-3                          # damped: the energy never grows
    assert result.energy[-1] < result.energy[0]                # it fell
    assert result.max_strain.max() < 0.05                      # structural springs within 5 % of rest
    top = result.positions.reshape(-1, 3)[result.pinned]
    np.testing.assert_array_equal(top[:, 2], [0.0, 0.0])       # the pins held
    assert result.positions[..., 2].min() < -0.2               # the rest swung down
