"""Pieces cut on the fold (:mod:`clothgrid.patterns.fold`): the fold line the readers find (AAMA/ASTM
DXF layer 6, FreeSewing's "cut on fold" marks), the whole piece ``--unfold`` makes, and a garment
sewn from unfolded halves."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from clothgrid import InputError
from clothgrid.cli import main
from clothgrid.patterns.fold import fold_edge, unfold
from clothgrid.patterns.piece import piece_from_polygon
from clothgrid.pipeline import select_pieces

pytest.importorskip("ezdxf")
pytest.importorskip("svgpathtools")

HERE = Path(__file__).parent
SHARED = HERE.resolve().parents[1] / "shared" / "patterns"
AARON = HERE / "data" / "freesewing" / "aaron_v3_pattern.svg"


def _moved(points: np.ndarray, angle: float, shift: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, s], [-s, c]]) + shift


def _mirror(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = (b - a) / np.linalg.norm(b - a)
    rel = points - a
    return a + 2.0 * np.outer(rel @ d, d) - rel


def _off(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of ``points`` from the line through ``a`` and ``b``."""
    d = (b - a) / np.linalg.norm(b - a)
    rel = points - a
    return np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])


def _symmetric(outline: np.ndarray, a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Every outline point's mirror image is an outline point (within ``tol``)."""
    img = _mirror(outline, a, b)
    d = np.sqrt(((img[:, None, :] - outline[None, :, :]) ** 2).sum(-1)).min(axis=1)
    return bool(d.max() <= tol)


def _half(rng: np.random.Generator, v_neck: bool):
    """A half bodice with its centre on x = 0 (the fold: hem corner, two points along it, neck
    point), a square hem corner at the fold and a square or V-shaped neck point, moved at random."""
    w, h = rng.uniform(150, 250), rng.uniform(300, 500)
    neck = np.array([0.0, h - (60 if v_neck else 0)])
    pts = np.array([[0.0, 0.0], [w, 0.0], [w, 0.6 * h], [0.7 * w, h], [0.25 * w, h],
                    [0.1 * w, h - 10] if v_neck else [0.0, h], neck,
                    [0.0, 0.66 * h], [0.0, 0.33 * h]])
    if not v_neck:
        pts = np.delete(pts, 6, axis=0)                 # the neck point is (0, h)
    angle, shift = rng.uniform(0, 2 * np.pi), rng.uniform(-500, 500, 2)
    moved = _moved(pts, angle, shift)
    a, b = _moved(np.array([[0.0, 0.0], [0.0, h]]), angle, shift)
    return moved, a, b


@pytest.mark.parametrize("v_neck", [False, True])
def test_unfold_mirrors_the_half_across_its_fold_line(v_neck):
    """The whole piece is the half and its mirror image: twice the area, symmetric about the fold
    line, counter-clockwise, without the points inside the fold edge; a square corner at the fold
    is no turn point any more, a V-neck's point stays one; vertices come in mirror pairs."""
    rng = np.random.default_rng()
    pts, a, b = _half(rng, v_neck)
    n = len(pts)
    half = piece_from_polygon("half", pts, vertices=np.arange(n), turn_points=np.arange(n),
                              meta={"fold_line": [a.tolist(), b.tolist()]})
    first, last = fold_edge(half)
    on = set(np.flatnonzero(_off(half.outline, a, b) < 1e-9 * half.size).tolist())
    assert {first, last} <= on and len(on) == 4
    whole = unfold(half)
    assert whole.area == pytest.approx(2 * half.area, rel=1e-12)
    assert whole.area > 0 and whole.meta["unfolded"] and "unfolded across its fold line" in whole.notes[-1]
    assert _symmetric(whole.outline, a, b, 1e-9 * whole.size)
    # off the fold line: every point but the two where the halves meet
    d = _off(whole.outline, a, b)
    assert int((d < 1e-9 * whole.size).sum()) == 2
    # the off-line points twice, the two meeting points once
    assert len(whole.outline) == 2 * (n - len(on)) + 2
    assert len(whole.vertices) == len(whole.outline)
    turns = whole.outline[whole.turn_points]
    meet = whole.outline[d < 1e-9 * whole.size]
    kept = [bool(np.isclose(turns, m, atol=1e-9 * whole.size).all(axis=1).any()) for m in meet]
    neck_kept = kept[int(np.argmax(np.linalg.norm(meet - a, axis=1)))]
    hem_kept = kept[int(np.argmin(np.linalg.norm(meet - a, axis=1)))]
    assert not hem_kept and neck_kept == v_neck
    # the fold line's direction does not matter
    again = unfold(half, [b.tolist(), a.tolist()])
    assert again.area == pytest.approx(whole.area, rel=1e-12)


def test_fold_lines_that_cannot_unfold():
    """A fold line along no edge, or one whose outline lies on both of its sides, is one clear
    InputError naming the piece."""
    square = piece_from_polygon("sq", np.array([[0, 0], [10, 0], [10, 10], [0, 10.0]]))
    with pytest.raises(InputError, match="piece 'sq': no fold line"):
        unfold(square)
    with pytest.raises(InputError, match="runs along no edge"):
        unfold(square, [[5, 0], [5, 10]])                 # across the middle
    with pytest.raises(InputError, match="runs along no edge"):
        unfold(square, [[0, 2], [0, 30]])                 # along an edge, mostly past it
    ell = piece_from_polygon("L", np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2.0]]))
    with pytest.raises(InputError, match="piece 'L': its outline lies on both sides"):
        unfold(ell, [[1, 1], [1, 2]])
    with pytest.raises(InputError, match="no length"):
        unfold(square, [[0, 0], [0, 0]])


@pytest.mark.skipif(not (SHARED / "astm_GLX0926S16.DXF").is_file(), reason=f"no {SHARED}")
def test_aama_mirror_lines_unfold_every_size():
    """Gerber AccuMark's AAMA export astm_GLX0926S16.DXF draws the front and back halves with a
    mirror line (layer 6) along their centre edge, in every size: each is read with its fold line
    and unfolds to exactly twice its area, symmetric; the other pieces are untouched."""
    src = SHARED / "astm_GLX0926S16.DXF"
    halves = select_pieces(src)
    wholes = select_pieces(src, unfold=True)
    assert [p.name for p in halves] == [p.name for p in wholes] and not wholes.failed
    folded = [p for p in halves if p.meta.get("fold_line") is not None]
    assert len(folded) >= 20 and {p.name.rsplit("_", 1)[0] for p in folded} == {"GLX0926S16SBK", "GLX0926S16SFR"}
    for h, w in zip(halves, wholes):
        if h.meta.get("fold_line") is None:
            np.testing.assert_array_equal(w.outline, h.outline)
            continue
        a, b = (np.array(x) for x in h.meta["fold_line"])
        assert w.area == pytest.approx(2 * h.area, rel=1e-9)
        assert _symmetric(w.outline, a, b, 1e-6 * w.size)


def test_freesewing_cut_on_fold_marks(capsys, tmp_path):
    """FreeSewing 3's Aaron: both parts are halves with a cut-on-fold mark (markers cutonfoldFrom/To);
    `pieces` says so, `--unfold` grids the whole (twice the area, fold-free), and a boundary file
    refuses the option (exit 2, one error line, nothing written)."""
    assert main(["pieces", str(AARON)]) == 0
    out = capsys.readouterr().out
    assert out.count("cut on the fold:") == 2 and "--unfold for the whole" in out
    halves = {p.name: p for p in select_pieces(AARON)}
    assert main(["pieces", str(AARON), "--unfold", "--json"]) == 0
    got = {p["name"]: p for p in json.loads(capsys.readouterr().out)["pieces"]}
    assert sorted(got) == ["back", "front"]
    for name, e in got.items():
        assert e["unfolded"] and e["area_mm2"] == pytest.approx(2 * halves[name].area, rel=1e-9)
        assert e["size_mm"][0] == pytest.approx(2 * halves[name].extent[0], rel=1e-6)
    report = tmp_path / "r.json"
    assert main(["generate", str(AARON), "--unfold", "--piece", "back", "-o", str(tmp_path / "{piece}.npz"),
                 "--report", str(report), "-q"]) == 0, capsys.readouterr().err
    (piece,) = json.loads(report.read_text())["pieces"]
    assert piece["name"] == "back" and piece["folded"] == 0 and not piece["missed"]
    # the whole back, 551 mm wide at 10 mm cells (the half: 276 mm)
    assert max(piece["nodes"]) * 10 > 1.4 * halves["back"].extent[0]
    boundary = tmp_path / "b.json"
    boundary.write_text(json.dumps({"outline": [[0, 0], [1, 0], [1, 1], [0, 1]], "corners": [0, 1, 2, 3]}))
    assert main(["generate", str(boundary), "--unfold", "-o", str(tmp_path / "g.npz"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "--unfold is for pattern files" in err and err.count("clothgrid: error:") == 1
    assert not (tmp_path / "g.npz").exists()


@pytest.mark.skipif(not (SHARED / "fs_cathrin_layout.svg").is_file(), reason=f"no {SHARED}")
def test_freesewing_2_cut_on_fold_text():
    """FreeSewing 2 writes "Cut on fold" along the grain line's bracket (a textPath): Cathrin's
    centre-front panel and Florent's cap side are halves; the other panels are not."""
    got = {p.name: p for p in select_pieces(SHARED / "fs_cathrin_layout.svg")}
    assert [n for n, p in got.items() if p.meta.get("fold_line")] == ["panel1"]
    (side,) = [p for p in select_pieces(SHARED / "fs_florent_layout.svg") if p.meta.get("fold_line")]
    whole = unfold(side)
    assert whole.area == pytest.approx(2 * side.area, rel=1e-9)


@pytest.mark.skipif(not (SHARED / "astm_DEEP_ARMHOLE_RACER.DXF").is_file(), reason=f"no {SHARED}")
def test_unfolded_racer_back_grids_fold_free_with_corners_in_mirror_pairs(tmp_path):
    """The racer back, unfolded, is a whole piece of two narrow straps: its corners are chosen in
    mirror pairs (the piece is symmetric: so is its grid's frame) and its grid folds nowhere at
    10 mm; the automatic choice without the pairing left 5-20 folded cells on such pieces (a loose
    tank's back: 15)."""
    from clothgrid.pipeline import GridOptions, read_jobs, run_job

    src = SHARED / "astm_DEEP_ARMHOLE_RACER.DXF"
    jobs = read_jobs(src, [str(tmp_path / "{piece}.npz")], options=GridOptions(edge_length="10mm"),
                     grade="26", unfold=True)
    names = [j.name for j in jobs]
    assert {"DEEP ARMHOLE RACERBK_26", "DEEP ARMHOLE RACE FR_26"} <= set(names)
    for job in jobs:
        if not job.pattern.meta.get("unfolded"):
            continue
        a, b = (np.array(x) for x in job.pattern.meta["fold_line"])
        corners = job.choice.outline[list(job.choice.corners)]
        assert _symmetric(corners, a, b, 1e-6 * job.pattern.size), job.name
        assert "mirror pairs" in job.choice.message
        result = run_job(job)
        assert result.grid.info["quality"]["folded"] == 0, job.name
