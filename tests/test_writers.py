"""Tests for clothgrid.writers and clothgrid.plot."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from conftest import parse_obj

from clothgrid import writers
from clothgrid.errors import InputError
from clothgrid.grid import Grid
from clothgrid.plot import CORNER_LABELS, draw_grid, plane_coordinates, plot_grid
from clothgrid.quality import quality
from clothgrid.readers import load_npz
from clothgrid.writers import register_writer, save


@pytest.fixture
def grid() -> Grid:
    """A small warped 3D grid with awkward floats and numpy values in its info."""
    rng = np.random.default_rng(3)
    i, j = np.meshgrid(np.linspace(0, 1, 6), np.linspace(0, 1, 4), indexing="ij")
    p = np.stack([i + 0.1 * np.sin(3 * j), j / 3.0, 0.2 * i * j], axis=-1)
    p[1:-1, 1:-1] += rng.normal(scale=1e-3, size=(4, 2, 3))
    info = {"solver": "fdm", "iterations": np.int64(0), "error_estimate": np.float64(1e-13),
            "shape": np.array([6, 4]), "converged": np.bool_(True), "tol": 2.0 ** -12}
    return Grid.from_points(p, info=info, dim=3)


def listing(directory) -> list[str]:
    return sorted(os.listdir(directory))


def test_npz_round_trip(grid, tmp_path):
    path = save(grid, tmp_path / "g.npz")
    assert path == tmp_path / "g.npz"
    back = load_npz(path)
    np.testing.assert_array_equal(back.points, grid.points)
    np.testing.assert_array_equal(back.uv, grid.uv)
    np.testing.assert_array_equal(back.quads, grid.quads)
    assert back.dim == 3
    assert back.info == {"solver": "fdm", "iterations": 0, "error_estimate": 1e-13,
                         "shape": [6, 4], "converged": True, "tol": 2.0 ** -12}
    with np.load(path) as z:
        assert set(z.files) >= {"points", "uv", "quads", "info"}
        assert z["points"].shape == (6, 4, 3) and z["uv"].shape == (6, 4, 2)
    assert listing(tmp_path) == ["g.npz"]


def test_savez_matches_numpy_member_for_member(tmp_path):
    """writers.savez writes arrays from their own memory: the same members and bytes as np.savez."""
    import io
    import zipfile

    rng = np.random.default_rng()
    arrays = {"f": rng.standard_normal((5, 7, 3)), "i": rng.integers(0, 9, (11, 4)),
              "t": np.arange(12.0).reshape(3, 4).T,        # not C-contiguous: numpy's own path
              "s": np.array("text"), "x": np.float64(2.5), "b": np.array([True, False]),
              "be": np.arange(6, dtype=">f8"), "r": np.zeros(3, dtype=[("x", "<f4"), ("y", ">i2")]),
              "e": np.empty((0, 4), dtype=np.int32)}
    ours, theirs = io.BytesIO(), io.BytesIO()
    writers.savez(ours, **arrays)
    np.savez(theirs, **arrays)
    a, b = zipfile.ZipFile(io.BytesIO(ours.getvalue())), zipfile.ZipFile(io.BytesIO(theirs.getvalue()))
    assert a.namelist() == b.namelist() == [k + ".npy" for k in arrays]
    for name in a.namelist():
        assert a.read(name) == b.read(name), name      # zipfile checks each member's CRC as it reads
    back = np.load(io.BytesIO(ours.getvalue()))
    for k, v in arrays.items():
        assert back[k].dtype == np.asarray(v).dtype and np.array_equal(back[k], v), k
    with pytest.raises(ValueError):                    # object arrays are refused, never pickled
        writers.savez(io.BytesIO(), o=np.array([{}, 1], dtype=object))


@pytest.mark.parametrize("flip", [False, True])
@pytest.mark.parametrize("shape", [(2, 2), (7, 3), (40, 1700), (1700, 40)])
def test_quad_blocks_stream_the_quads(shape, flip, tmp_path):
    """Grid.quad_blocks (a reused buffer, or views once made) concatenates to quads; the .npz
    writer streams them and numpy reads back the very array."""
    from clothgrid.grid import quad_indices

    nu, nv = shape
    rng = np.random.default_rng()
    g = Grid.from_points(rng.standard_normal((nu, nv, 3)), flip=flip)
    expected = quad_indices(nu, nv, flip=flip)
    cells = int(rng.integers(1, 3 * nv))
    made = [b.copy() for b in g.quad_blocks(cells)]     # copies: the buffer is reused
    assert g._quads is None                             # streaming made no whole array
    assert np.array_equal(np.concatenate(made), expected)
    save(g, tmp_path / "g.npz")
    with np.load(tmp_path / "g.npz") as z:
        assert z["quads"].dtype == np.int64 and np.array_equal(z["quads"], expected)
    g.quads                                             # made: the blocks are its views
    views = list(g.quad_blocks(cells))
    assert all(np.shares_memory(v, g.quads) for v in views)
    assert np.array_equal(np.concatenate(views), expected)


def test_savez_streamed_checks_its_length():
    import io

    short = writers.Streamed((10, 4), np.int64, lambda: iter([np.zeros((9, 4), np.int64)]))
    with pytest.raises(ValueError, match="shape needs"):
        writers.savez(io.BytesIO(), a=short)


def test_grid_save_method_and_2d_dim(grid, tmp_path):
    g2 = Grid.from_points(grid.points * np.array([1.0, 1.0, 0.0]), dim=2)
    g2.save(tmp_path / "flat.NPZ")
    assert load_npz(tmp_path / "flat.NPZ").dim == 2


def test_obj_exact(grid, tmp_path):
    text = save(grid, tmp_path / "g.obj").read_text()
    assert text.startswith("# ")
    assert '"solver": "fdm"' in text.splitlines()[1]
    v, vt, f = parse_obj(text)
    np.testing.assert_array_equal(v, grid.points.reshape(-1, 3))
    np.testing.assert_array_equal(vt, grid.uv.reshape(-1, 2))
    np.testing.assert_array_equal(f, grid.quads)
    assert f.shape == (5 * 3, 4)


def test_ply_header_and_counts(grid, tmp_path):
    lines = save(grid, tmp_path / "g.ply").read_text().splitlines()
    end = lines.index("end_header")
    header, body = lines[:end], lines[end + 1:]
    assert header[:2] == ["ply", "format ascii 1.0"]
    assert "element vertex 24" in header and "element face 15" in header
    props = [line.split()[-1] for line in header if line.startswith("property double")]
    assert props == ["x", "y", "z", "s", "t"]
    assert "property list uchar int vertex_indices" in header
    assert len(body) == 24 + 15
    vertices = np.array([[float(x) for x in line.split()] for line in body[:24]])
    np.testing.assert_array_equal(vertices[:, :3], grid.points.reshape(-1, 3))
    np.testing.assert_array_equal(vertices[:, 3:], grid.uv.reshape(-1, 2))
    faces = np.array([[int(x) for x in line.split()] for line in body[24:]])
    assert (faces[:, 0] == 4).all()
    np.testing.assert_array_equal(faces[:, 1:], grid.quads)


def test_json_round_trip(grid, tmp_path):
    doc = json.loads(save(grid, tmp_path / "g.json").read_text())
    assert doc["shape"] == [6, 4]
    np.testing.assert_array_equal(np.array(doc["points"]), grid.points)
    np.testing.assert_array_equal(np.array(doc["uv"]), grid.uv)
    np.testing.assert_array_equal(np.array(doc["quads"]), grid.quads)
    assert doc["info"]["iterations"] == 0 and doc["info"]["shape"] == [6, 4]
    assert doc["info"]["converged"] is True


def test_unknown_extension(grid, tmp_path):
    with pytest.raises(InputError, match=r"\.npz.*\.obj|\.obj.*\.npz"):
        save(grid, tmp_path / "g.stl")
    with pytest.raises(InputError):
        save(grid, tmp_path / "noextension")
    assert listing(tmp_path) == []


def test_missing_directory(grid, tmp_path):
    target = tmp_path / "missing" / "g.npz"
    with pytest.raises(InputError, match="does not exist"):
        save(grid, target)
    assert listing(tmp_path) == []


def test_failing_writer_leaves_nothing(grid, tmp_path, monkeypatch):
    def half_way(g, fh):
        fh.write(b"v 0 0 0\n" * 1000)
        raise RuntimeError("disk on fire")

    monkeypatch.setitem(writers.WRITERS, ".obj", half_way)
    with pytest.raises(RuntimeError, match="disk on fire"):
        save(grid, tmp_path / "g.obj")
    assert listing(tmp_path) == []


def test_failing_writer_keeps_the_old_file(grid, tmp_path, monkeypatch):
    path = save(grid, tmp_path / "g.obj")
    before = path.read_bytes()
    monkeypatch.setitem(writers.WRITERS, ".obj", lambda g, fh: (fh.write(b"x"), 1 / 0))
    with pytest.raises(ZeroDivisionError):
        save(grid, path)
    assert path.read_bytes() == before
    assert listing(tmp_path) == ["g.obj"]


def test_register_writer(grid, tmp_path, monkeypatch):
    monkeypatch.setattr(writers, "WRITERS", dict(writers.WRITERS))
    register_writer("XYZ", lambda g, fh: fh.write(b"%d\n" % g.points.size))
    assert save(grid, tmp_path / "g.xyz").read_text() == "72\n"


def test_load_npz_rejects_bad_files(tmp_path):
    with pytest.raises(InputError):
        load_npz(tmp_path / "nothing.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(InputError):
        load_npz(tmp_path / "other.npz")


def test_plot_writes_png(grid, tmp_path):
    p = grid.points.copy()
    p[2, 1] = p[3, 1] + 0.5 * (p[3, 1] - p[2, 1])
    folded = Grid.from_points(p)
    q = quality(folded)
    assert q.folded > 0
    path = plot_grid(folded, tmp_path / "g.png", title="folded", quality=q)
    data = path.read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 1000
    assert listing(tmp_path) == ["g.png"]


def test_plot_marks_the_four_grid_corners(grid):
    fig = draw_grid(grid, title="corners")
    ax = fig.axes[0]
    marked = [c for c in ax.collections if c.get_label() == "grid corners"]
    assert len(marked) == 1
    xy = plane_coordinates(grid)
    expected = np.array([xy[0, 0], xy[-1, 0], xy[-1, -1], xy[0, -1]])
    np.testing.assert_allclose(marked[0].get_offsets(), expected)
    assert [t.get_text() for t in ax.texts] == list(CORNER_LABELS)


def test_plot_large_2d_grid_and_errors(tmp_path):
    i, j = np.meshgrid(np.arange(300.0), np.arange(200.0), indexing="ij")
    g = Grid.from_points(np.stack([i, j + 0.1 * i, 0 * i], axis=-1), dim=2)
    assert plot_grid(g, tmp_path / "big.png", max_lines=16).stat().st_size > 1000
    with pytest.raises(InputError):
        plot_grid(g, tmp_path / "missing" / "big.png")
    with pytest.raises(InputError):
        plot_grid(g, tmp_path / "big.notanimage")
    assert listing(tmp_path) == ["big.png"]
