"""A weight field grades the grid (``WeightField``, ``--weight-field``): the paper's "four weights per
node" given as one positive field over the piece's (u, v) square."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import clothgrid
from clothgrid.batch import _normalised
from clothgrid.boundary import Boundary
from clothgrid.cli import main
from clothgrid.errors import InputError
from clothgrid.pipeline import GridOptions, OutputOptions
from clothgrid.weights import WeightField, make_weights, sample_field

sys.path.insert(0, str(Path(__file__).parent))
from conftest import smooth_quad_sides  # noqa: E402

TSHIRT = Path(clothgrid.__file__).parent / "data" / "tshirt_front.json"


def test_sample_field_is_bilinear_between_the_centres(rng):
    mu, mv = rng.integers(3, 9, size=2)
    a, b, c = rng.uniform(1, 2, size=3)
    cu, cv = (np.arange(mu) + 0.5) / mu, (np.arange(mv) + 0.5) / mv
    plane = a + b * cu[:, None] + c * cv[None, :]           # a plane sampled at the raster's centres
    u = rng.uniform(cu[0], cu[-1], size=11)
    v = rng.uniform(cv[0], cv[-1], size=7)
    np.testing.assert_allclose(sample_field(plane, u, v), a + b * u[:, None] + c * v[None, :], rtol=1e-12)
    # beyond the outer centres the field is constant (nearest centre's row / column)
    edge = sample_field(plane, np.array([0.0, 1.0]), np.array([cv[2]]))
    np.testing.assert_allclose(edge[:, 0], plane[[0, -1], 2], rtol=1e-12)


def test_field_weights_are_the_base_times_the_field_at_each_edge_midpoint(rng):
    nu, nv = rng.integers(5, 20, size=2)
    s, t = rng.uniform(0.5, 3, size=2)
    # a field linear in u alone, on a 2 x 1 raster: at u it is 1 + s (u - 1/4) * 2 (clamped outside)
    field = np.array([[1.0], [1.0 + s]])
    w = make_weights(WeightField(field * t, base="paper"), nu, nv, k=0.7)
    base = make_weights("paper", nu, nv, k=0.7)
    um = (np.arange(nu - 1) + 0.5) / (nu - 1)
    f_mid = t * (1.0 + s * np.clip((um - 0.25) * 2.0, 0.0, 1.0))
    np.testing.assert_allclose(w.wu, base.wu * f_mid[:, None], rtol=1e-12)
    f_node = t * (1.0 + s * np.clip((np.arange(nu) / (nu - 1) - 0.25) * 2.0, 0.0, 1.0))
    np.testing.assert_allclose(w.wv, base.wv * f_node[:, None], rtol=1e-12)
    assert w.kind == "field" and w.factors is None


@pytest.mark.parametrize("values, words", [
    (np.zeros((2, 2)), "positive"),
    (np.array([[1.0, np.nan]]), "NaN"),
    (np.ones(4), "2D"),
    (np.array([["a"]]), "numbers"),
])
def test_bad_fields_are_refused(values, words):
    with pytest.raises(InputError, match=words):
        WeightField(values)


def test_a_field_solve_meets_its_bound_against_the_direct_solve(rng):
    """Multigrid with a fresh random smooth field's per-edge weights, its reported bound against
    the sparse direct solve of the same weights."""
    bnd = Boundary.from_sides(*smooth_quad_sides(rng, 97, 81))
    field = np.exp(rng.normal(0.0, 0.8, size=(5, 4)))       # contrast up to some 20:1
    wf = WeightField(field)
    g = clothgrid.generate(bnd, weights=wf, solver="multigrid")
    ref = clothgrid.generate(bnd, weights=wf, solver="direct")
    assert g.info["weights"] == "field" and g.info["error_bound"]
    err = np.abs(g.points - ref.points).max() / bnd.size
    assert err <= g.info["error_estimate"] <= g.info["tol"]


def test_the_grid_is_finer_where_the_field_is_larger():
    bnd = clothgrid.load_boundary(TSHIRT)
    field = np.array([[10.0, 10.0], [1.0, 1.0]])                # large on the left half (small u)
    g = clothgrid.generate(bnd, 64, weights=WeightField(field), functional="length")
    plain = clothgrid.generate(bnd, 64, weights="uniform", functional="length")
    du = lambda p: np.linalg.norm(np.diff(p, axis=0), axis=-1)   # noqa: E731
    left, right = du(g.points)[:16].mean(), du(g.points)[-16:].mean()
    assert left < 0.6 * right
    pl, pr = du(plain.points)[:16].mean(), du(plain.points)[-16:].mean()
    assert 0.8 < pl / pr < 1.25                                 # the uniform grid is not graded


def test_auto_evens_only_what_the_field_does_not_explain():
    """functional auto with a field: folds relaxed; the evening's bands widened by the square root of
    the field's contrast, so a 30:1 grading is kept, while a constant field (uniform weights, scaled)
    is evened as uniform weights are."""
    bnd = clothgrid.load_boundary(TSHIRT)
    field = np.array([[10.0, 10.0], [1.0, 1.0]])                # 10:1, finer on the small-u half
    g = clothgrid.generate(bnd, 64, weights=WeightField(field), functional="auto")
    assert g.info["evened"]["widened"] == pytest.approx(np.sqrt(10.0))
    assert g.info["folded"] == 0 < g.info["folded_before"]
    length = clothgrid.generate(bnd, 64, weights=WeightField(field), functional="length")
    du = lambda p: np.linalg.norm(np.diff(p, axis=0), axis=-1)   # noqa: E731
    graded = lambda p: du(p)[:16].mean() / du(p)[-16:].mean()    # noqa: E731
    assert graded(length.points) < 0.5 and graded(g.points) < 1.1 * graded(length.points)
    plain = clothgrid.generate(bnd, 65, weights="uniform", functional="auto")
    flat = clothgrid.generate(bnd, 65, weights=WeightField(np.full((1, 1), 3.0)), functional="auto")
    assert "widened" not in flat.info["evened"] and flat.info["evened"]["moved"] > 0
    assert flat.info["evened"]["spread_after"] == pytest.approx(plain.info["evened"]["spread_after"], rel=0.05)


def test_cli_weight_field_npy_and_image(tmp_path, capsys):
    u = np.linspace(0, 1, 20)[:, None]
    np.save(tmp_path / "f.npy", 1.0 + 9.0 * u * np.ones((1, 10)))
    code = main(["generate", str(TSHIRT), "--nodes", "33x33", "--weight-field", str(tmp_path / "f.npy"),
                 "--functional", "length", "-o", str(tmp_path / "g.npz"), "-q"])
    assert code == 0
    with np.load(tmp_path / "g.npz") as d:
        assert json.loads(str(d["info"]))["weights"] == "field"
        p = d["points"]
    du = np.linalg.norm(np.diff(p, axis=0), axis=-1)
    assert du[-8:].mean() < 0.6 * du[:8].mean()                  # finer where the field is larger (large u)

    import matplotlib.pyplot as plt

    plt.imsave(tmp_path / "f.png", np.linspace(0, 1, 16)[None, :].repeat(8, 0), cmap="gray")
    out = tmp_path / "out"
    out.mkdir()
    code = main(["generate", str(TSHIRT), "--nodes", "33x33", "--weight-field", str(tmp_path / "f.png"),
                 "-o", str(out / "g.npz"), "-q"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("clothgrid: error:") == 1 and "--weight-field-range" in err
    assert list(out.iterdir()) == []
    code = main(["generate", str(TSHIRT), "--nodes", "33x33", "--weight-field", str(tmp_path / "f.png"),
                 "--weight-field-range", "1,5", "-o", str(out / "g.npz"), "-q"])
    assert code == 0


@pytest.mark.parametrize("content, words", [
    (b"not an array", "not a complete NumPy .npy array"),
    (None, "no such file"),
])
def test_cli_bad_weight_field_exit_2(tmp_path, capsys, content, words):
    path = tmp_path / "f.npy"
    if content is not None:
        path.write_bytes(content)
    out = tmp_path / "out"
    out.mkdir()
    code = main(["generate", str(TSHIRT), "--nodes", "17x17", "--weight-field", str(path),
                 "-o", str(out / "g.npz")])
    err = capsys.readouterr().err
    assert code == 2 and words in err and "Traceback" not in err
    assert list(out.iterdir()) == []


def test_batch_resume_key_names_a_field_only_where_given():
    plain = _normalised(GridOptions(), OutputOptions(), ("{piece}.npz",), None, None, None)
    assert "weight_field" not in plain["grid"] and "weight_field_range" not in plain["grid"]
    a = _normalised(GridOptions(weight_field=np.ones((2, 2))), OutputOptions(), ("{piece}.npz",), None, None, None)
    b = _normalised(GridOptions(weight_field=np.full((2, 2), 2.0)), OutputOptions(), ("{piece}.npz",), None,
                    None, None)
    assert a["grid"]["weight_field"]["shape"] == [2, 2]
    assert a["grid"]["weight_field"]["sha256"] != b["grid"]["weight_field"]["sha256"]
    json.dumps(a)                                                 # plain JSON values


def test_a_field_file_too_large_is_refused_from_its_header(tmp_path, monkeypatch):
    """.npy and image fields are sized from their headers (a memory map; Pillow's header) and refused
    over limits.MAX_FIELD_VALUES before their values are read; under it they load."""
    import matplotlib.pyplot as plt

    from clothgrid import limits
    from clothgrid.fields import load_field

    monkeypatch.setattr(limits, "MAX_FIELD_VALUES", 300)
    np.save(tmp_path / "big.npy", np.ones((20, 20)))
    plt.imsave(tmp_path / "big.png", np.zeros((20, 20)), cmap="gray")
    for f in ("big.npy", "big.png"):
        with pytest.raises(InputError, match=r"holds 400 values, more than the limit of 300"):
            load_field(tmp_path / f, name="weight field", value_range=(1, 2))
    np.save(tmp_path / "ok.npy", np.full((10, 10), 2.0))
    plt.imsave(tmp_path / "ok.png", np.ones((10, 12)), cmap="gray")
    assert load_field(tmp_path / "ok.npy", name="w").shape == (10, 10)
    assert load_field(tmp_path / "ok.png", name="w", value_range=(1, 3)).shape == (12, 10)
