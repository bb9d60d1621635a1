"""Pieces, not drawings (annotations skipped with reasons) and the sew-line / cut-line choice."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from clothgrid.cli import main
from clothgrid.errors import InputError
from clothgrid.readers import read_pieces

SHARED = Path(__file__).resolve().parents[2] / "shared" / "patterns"


def _shared(name: str) -> Path:
    path = SHARED / name
    if not path.exists():
        pytest.skip(f"{path} not here (the third-party pattern files)")
    return path


# --------------------------------------------------------------------------- real files

SA = "seam allowance"
# checked by eye on a rendering of pieces (filled) against skipped outlines (dashed)
REAL_SVG = {
    # FreeSewing 2 names its paths by running numbers (kept as aliases) in a group named after the part:
    # a part's sew line and cut line are both named after the group, the one gridded keeps the name.
    # 'side' and 'inset': seam-allowance outlines drawn as open paths (joined, see test_patterns)
    "fs_bruce_draft-sample.svg": (["front", "back", "side", "inset"], {"front-2": SA, "side-2": SA, "inset-2": SA}),
    "fs_cathrin_layout.svg": ([f"panel{k}" for k in range(1, 8)], {f"panel{k}-2": SA for k in range(1, 8)}),
    # 'side' (a half piece on the fold: open paths '14' and '15') and 'brimPlastic' (open curves '53',
    # '54' and the 2-point closed paths '55', '56') are joined from open paths (see test_patterns)
    "fs_florent_layout.svg": (["top", "brimBottom", "brimTop", "side", "brimPlastic"],
                              {"top-2": SA, "brimBottom-2": SA, "brimTop-2": SA}),
    "fs_shin_layout.svg": (["front", "back", "waistband"], {"front-2": SA, "back-2": SA}),
    "fs_wahid_layout.svg": (["front", "back", "frontFacing", "frontLining", "pocketWelt", "pocketFacing", "pocketBag",
                             "pocketInterfacing"], {"front-2": SA, "back-2": SA, "frontFacing-2": SA, "frontLining-2": SA}),
    "fs_simon_collarstandbend.svg": (["205", "1668"], {}),
    "gc_pattern_test.svg": ([f"piece{k}" for k in range(1, 7)], {}),
}

#: what the pieces of REAL_SVG were named before their group names were read (their made-up ids)
REAL_SVG_ALIASES = {
    "fs_bruce_draft-sample.svg": ["2", "14", "29", "49"],
    "fs_cathrin_layout.svg": ["2", "9", "16", "23", "30", "38", "45"],
    "fs_florent_layout.svg": ["2", "31", "42", None, None],
    "fs_shin_layout.svg": ["2", "13", "26"],
    "fs_wahid_layout.svg": ["4", "24", "33", "41", "50", "61", "72", "81"],
}

REAL_SVG_FAILED: dict[str, list[str]] = {}


@pytest.mark.parametrize("name", sorted(REAL_SVG))
def test_real_svg_pieces_and_annotations(name):
    pieces_want, skipped_want = REAL_SVG[name]
    got = read_pieces(_shared(name))
    assert [p.name for p in got] == pieces_want
    # the files' notches, buttons and logos are <use> clones: drawn, and marked by their names
    drawn = {s.name: s.kind for s in got.skipped if "use" in s.meta}
    assert {s.name: s.kind for s in got.skipped if "use" not in s.meta} == skipped_want
    assert set(drawn.values()) <= {"mark", "button", "notch", "text", "drill hole", "small", "inside"}
    assert [f.name for f in got.failed] == REAL_SVG_FAILED.get(name, [])
    for p, alias in zip(got, REAL_SVG_ALIASES.get(name, [None] * len(got))):
        assert p.aliases == ((alias,) if alias else ())
        assert got.resolve(alias or p.name) == p.name
    for s in got.skipped:
        if s.kind == SA:
            assert s.of in pieces_want and f"around piece {s.of!r}" in s.reason
            assert next(p for p in got if p.name == s.of).meta["line"] == "sew"


@pytest.mark.parametrize("name", ["fs_bruce_draft-sample.svg", "fs_cathrin_layout.svg", "fs_florent_layout.svg",
                                  "fs_wahid_layout.svg"])
def test_freesewing_scale_box_measures_what_it_says(name):
    """FreeSewing's layouts carry a scale box whose white inside 'should measure 10 by 5 cm' and
    black outside '4 by 2 inch'. Their first (PHP) core wrote 90 px an inch (millimetres scaled by
    3.54330709 px), so read at CSS's 96 the box measured 93.75 x 46.9 mm; read as the program wrote it,
    it measures what it says."""
    got = read_pieces(_shared(name))
    boxes = sorted(sorted(s.as_dict()["size_mm"]) for s in got.skipped if "scalebox" in s.reason)
    assert boxes == [pytest.approx([50.0, 100.0], rel=1e-6), pytest.approx([50.8, 101.6], rel=1e-6)]
    assert any("90 px an inch" in n for n in got[0].notes)


def test_real_svg_cut_line_swaps_the_pairs():
    path = _shared("fs_cathrin_layout.svg")
    got = read_pieces(path, line="cut")
    # the gridded line keeps the part's name (the group's), whichever line it is
    assert [p.name for p in got] == [f"panel{k}" for k in range(1, 8)]
    assert [p.aliases for p in got] == [(n,) for n in ["3", "10", "17", "24", "31", "39", "46"]]
    assert {s.name: s.kind for s in got.skipped if "use" not in s.meta} == {
        f"panel{k}-2": "sew line" for k in range(1, 8)}
    assert all(p.meta["line"] == "cut" for p in got)
    sew = {p.name: p for p in read_pieces(path)}
    cut = {p.name: p for p in got}
    assert cut["panel1"].area > sew["panel1"].area
    # an earlier release's name of the sew line, skipped here, still finds it
    assert got.resolve("2") == "panel1-2"
    # the waistband of Shin has only its seam-allowance outline closed: the cut line, noted
    shin = {p.name: p for p in read_pieces(_shared("fs_shin_layout.svg"))}
    assert shin["waistband"].meta["line"] == "cut"
    assert any("no sew line" in n for n in shin["waistband"].notes)


def test_real_aama_sew_line_layer_14():
    path = _shared("astm_GLX0926S16.DXF")
    sew = read_pieces(path)
    cut = read_pieces(path, line="cut")
    assert [p.name for p in sew] == [p.name for p in cut]
    lines = {p.name: p.meta["line"] for p in sew}
    bindings = [n for n in lines if "BIN" in n or "BIA" in n]
    assert len(bindings) == 28 and all(lines[n] == "sew" for n in bindings)
    assert all(v == "cut" for n, v in lines.items() if n not in bindings)
    assert all(p.meta["line"] == "cut" for p in cut)
    a = next(p for p in sew if p.name in bindings)
    b = next(p for p in cut if p.name == a.name)
    # the sew line lies just inside the cut line (about 0.004 in)
    assert 0 < a.meta["cut_line_gap_mm"] < 0.2
    assert a.area < b.area
    assert any(n.startswith("line: sew (layer 14)") for n in a.notes)
    # internal lines (layer 8) are kept, not gridded
    assert all(isinstance(p.meta.get("internal_lines", []), list) for p in sew)
    assert sum(len(p.meta.get("internal_lines", [])) for p in sew) > 0
    # an AAMA file without layer 14 falls back to the cut line, with a note
    other = read_pieces(_shared("astm_GMH1006F18_AAMA.DXF"))
    assert all(p.meta["line"] == "cut" for p in other)
    assert all(any("no sew line (layer 14)" in n for n in p.notes) for p in other)


# --------------------------------------------------------------------------- synthetic SVG

ANNOTATED = """<svg xmlns="http://www.w3.org/2000/svg" width="600mm" height="400mm" viewBox="0 0 600 400">
  <path id="body" d="M 50 50 L 250 50 L 250 350 L 50 350 Z"/>
  <path id="body-sa" d="M 40 40 L 260 40 L 260 360 L 40 360 Z"/>
  <circle id="hole" cx="150" cy="200" r="3"/>
  <path id="notch" d="M 147 347 L 153 347 L 153 353 L 147 353 Z"/>
  <g aria-label="L"><path id="glyph" d="M 300 50 L 304 50 L 304 60 L 310 60 L 310 64 L 300 64 Z"/></g>
  <path id="arrow" d="M 400 100 L 440 100 L 440 96 L 460 104 L 440 112 L 440 108 L 400 108 Z"/>
</svg>
"""


@pytest.fixture
def annotated(tmp_path: Path) -> Path:
    path = tmp_path / "annotated.svg"
    path.write_text(ANNOTATED)
    return path


def test_synthetic_svg_only_the_piece_is_gridded(annotated):
    got = read_pieces(annotated)
    assert [p.name for p in got] == ["body"]
    assert got[0].extent == pytest.approx((200.0, 300.0))
    assert got[0].meta["line"] == "sew"
    kinds = {s.name: s.kind for s in got.skipped}
    assert kinds == {"body-sa": "seam allowance", "hole": "drill hole", "notch": "notch",
                     "glyph": "text", "arrow": "arrow"}
    reasons = {s.name: s.reason for s in got.skipped}
    assert "around piece 'body'" in reasons["body-sa"]
    assert "inside piece 'body'" in reasons["hole"]
    assert "piece 'body'" in reasons["notch"]
    # --line cut grids the seam-allowance outline instead
    cut = read_pieces(annotated, line="cut")
    assert [p.name for p in cut] == ["body-sa"]
    assert cut[0].extent == pytest.approx((220.0, 320.0))
    assert {s.name: s.kind for s in cut.skipped}["body"] == "sew line"
    # a skipped outline is gridded when named
    inc = read_pieces(annotated, include=["hole"])
    assert [p.name for p in inc] == ["body", "hole"]
    assert "hole" not in {s.name for s in inc.skipped}
    with pytest.raises(InputError, match="no outline named 'nope'"):
        read_pieces(annotated, include=["nope"])


def test_cli_pieces_lists_skipped_and_include(annotated, tmp_path, capsys):
    assert main(["pieces", str(annotated)]) == 0
    out = capsys.readouterr().out
    assert "1 piece (coordinates in mm), 5 closed outlines skipped as annotations" in out
    assert "body: 200 x 300 mm" in out and "sew line]" in out
    assert "  hole: drill hole inside piece 'body'" in out
    assert "  arrow: arrow" in out and "  glyph: text" in out
    assert main(["pieces", str(annotated), "--json", "--include", "arrow"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in data["pieces"]] == ["body", "arrow"]
    assert data["pieces"][0]["line"] == "sew"
    assert {s["name"] for s in data["skipped"]} == {"body-sa", "hole", "notch", "glyph"}
    assert all(s["reason"] for s in data["skipped"])
    # generate grids the piece only, or the included outline too
    out_tpl = str(tmp_path / "out_{piece}.npz")
    assert main(["generate", str(annotated), "-o", out_tpl, "-q", "--edge-length", "20mm"]) == 0
    assert sorted(p.name for p in tmp_path.glob("out_*.npz")) == ["out_body.npz"]
    assert main(["generate", str(annotated), "-o", out_tpl, "-q", "--edge-length", "20mm",
                 "--include", "hole", "--line", "cut"]) == 0
    assert sorted(p.name for p in tmp_path.glob("out_*.npz")) == [
        "out_body-sa.npz", "out_body.npz", "out_hole.npz"]
    # --piece may name a skipped outline
    assert main(["generate", str(annotated), "-o", str(tmp_path / "one.npz"), "-q",
                 "--edge-length", "20mm", "--piece", "body-sa"]) == 0
    with np.load(tmp_path / "one.npz") as z:
        info = json.loads(str(z["info"]))
    assert info["piece"]["name"] == "body-sa" and info["piece"]["meta"]["line"] == "cut"


def test_svg_only_annotations_is_an_error(tmp_path, capsys):
    path = tmp_path / "marks.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
                    'viewBox="0 0 100 100"><g aria-label="AB"><path id="a" d="M 0 0 L 5 0 L 5 8 '
                    'L 0 8 Z"/><path id="b" d="M 10 0 L 15 0 L 15 8 L 10 8 Z"/></g></svg>')
    with pytest.raises(InputError, match="every closed outline was taken for an annotation"):
        read_pieces(path)
    assert [p.name for p in read_pieces(path, include=["a"])] == ["a"]


def test_a_path_named_as_a_line_is_not_taken_for_its_layers_annotation(tmp_path):
    """TauMeta's pattern files put every piece in a layer labelled 'Label-pattern', each piece's
    seam line and cutting line named by their ids ('A.seamline', 'A.cuttingline'), beside small
    reference circles: the lines are a piece (its sew line, the cutting line its seam allowance),
    not text because of the layer's word 'label'; the circles stay annotations. The piece is named
    'A' (its sew line's id without the line's word); its cut line keeps its id."""
    ink = 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"'
    path = tmp_path / "taumeta.svg"
    path.write_text(
        f'<svg xmlns="http://www.w3.org/2000/svg" {ink} width="400mm" height="400mm" viewBox="0 0 400 400">'
        '<g inkscape:label="Label-pattern" id="pattern" inkscape:groupmode="layer">'
        '<g id="document.dress.Bodice Front.pattern">'
        '<path id="A.seamline" d="M 10 10 L 210 10 L 210 310 L 10 310 L 10 10"/>'
        '<path id="A.cuttingline" d="M 0 0 L 220 0 L 220 320 L 0 320 Z"/>'
        '<circle id="A.FNC" cx="50" cy="50" r="1"/><circle id="A.FWC" cx="60" cy="50" r="1"/>'
        '</g></g></svg>')
    pieces = read_pieces(path)
    assert [p.name for p in pieces] == ["A"]
    assert pieces[0].meta["line"] == "sew" and pieces[0].meta["id"] == "A.seamline"
    assert [p.name for p in read_pieces(path, line="cut")] == ["A.cuttingline"]


def test_qt_svg_groups_carry_the_painters_font_on_seam_lines_too(tmp_path):
    """Qt's SVG writer (Seamly2D's and Valentina's piece exports) puts the painter's font on every
    group: a real Seamly2D trouser export had every outline taken for text. A font on an unfilled
    group is no text cue; the labels' glyphs, filled, still are."""
    path = tmp_path / "seamly.svg"
    font = 'font-family="Arial" font-size="10.6667" font-style="normal" font-weight="400"'
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" baseProfile="tiny" version="1.2" width="300mm" height="300mm" '
        'viewBox="0 0 300 300"><g fill="none" id="Dos" stroke="black">'
        f'<g fill="none" {font} transform="matrix(1,0,0,1,10,10)"><path d="M0,0 L200,0 L200,250 L0,250 L0,0" fill-rule="evenodd"/></g>'
        f'<g fill="none" {font} transform="matrix(1,0,0,1,10,10)"><path d="M-10,-10 L210,-10 L210,260 L-10,260 L-10,-10"/></g>'
        f'<g fill="#000000" {font} transform="matrix(1,0,0,1,50,50)"><path d="M0,0 L4,0 L4,6 L0,6 Z"/>'
        '<path d="M6,0 L10,0 L10,6 L6,6 Z"/><path d="M12,0 L16,0 L16,6 L12,6 Z"/></g></g></svg>')
    got = read_pieces(path)
    assert [p.extent for p in got] == [pytest.approx((200.0, 250.0))] and got[0].meta["line"] == "sew"
    kinds = sorted(s.kind for s in got.skipped)
    assert kinds == [SA, "text", "text", "text"]
    # the lines have no id: the piece is named after its group (not a made-up one like g12 or layer1)
    assert got[0].name == "Dos" and {s.name for s in got.skipped if s.kind == SA} == {"Dos-2"}
    from clothgrid.patterns.svg import _group_name

    assert _group_name("/layer1/g12/Devant/g3") == "Devant" and _group_name("/Layer_1/g7") is None


def test_a_piece_cut_on_the_fold_pairs_with_its_cut_line():
    """A piece cut on the fold has no seam allowance along the fold: its cut line runs on its seam
    line there (a real Seamly2D export's back and front). The cut line is still its seam-allowance
    outline (the points on the shared edge count as inside), not a second piece."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "fold.svg"
        fold = " ".join(f"L 300 {y}" for y in range(20, 300, 10))                   # the fold, x = 300
        path.write_text(
            '<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="400mm" viewBox="0 0 400 400">'
            f'<g id="Dos"><path d="M 100 10 L 300 10 {fold} L 300 300 L 100 300 Z"/>'   # sew line
            '<path d="M 90 0 L 300 0 L 300 310 L 90 310 Z"/></g></svg>')             # cut line, 10 mm SA
        got = read_pieces(path)
        assert [p.name for p in got] == ["Dos"] and got[0].meta["line"] == "sew"
        assert [(s.name, s.kind) for s in got.skipped] == [("Dos-2", SA)]


# --------------------------------------------------------------------------- synthetic AAMA DXF


def _aama_sew(path: Path, sew: bool = True) -> None:
    import ezdxf

    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    msp.add_text("Units: METRIC", dxfattribs={"layer": "1"})
    blk = doc.blocks.new("FRONT_M")
    blk.add_polyline2d([(0, 0), (100, 0), (100, 200), (0, 200), (0, 0)], dxfattribs={"layer": "1"})
    if sew:
        blk.add_polyline2d([(10, 10), (90, 10), (90, 190), (10, 190), (10, 10)],
                           dxfattribs={"layer": "14"})
    blk.add_line((50, 20), (50, 180), dxfattribs={"layer": "8"})
    for x, y in ((0, 0), (100, 0), (100, 200), (0, 200)):
        blk.add_point((x, y), dxfattribs={"layer": "2"})
    blk.add_text("Piece Name: FRONT", dxfattribs={"layer": "1"})
    msp.add_blockref("FRONT_M", (0, 0))
    doc.saveas(path)


def test_aama_sew_and_cut_line(tmp_path, capsys):
    path = tmp_path / "sew.dxf"
    _aama_sew(path)
    (sew,) = read_pieces(path)
    assert sew.name == "FRONT" and sew.meta["line"] == "sew"
    assert sew.extent == pytest.approx((80.0, 180.0))
    assert sew.meta["cut_line_gap_mm"] == pytest.approx(10 * np.sqrt(2), rel=1e-6)
    assert sew.meta["internal_lines"] == [[[50.0, 20.0], [50.0, 180.0]]]
    (cut,) = read_pieces(path, line="cut")
    assert cut.meta["line"] == "cut" and cut.extent == pytest.approx((100.0, 200.0))
    assert any("line: cut (layer 1), as asked" in n for n in cut.notes)
    # the listing says which line, and generate grids it
    assert main(["pieces", str(path)]) == 0
    out = capsys.readouterr().out
    assert "FRONT: 80 x 180 mm" in out and "sew line]" in out
    assert "note: line: sew (layer 14)" in out
    assert main(["pieces", str(path), "--line", "cut"]) == 0
    out = capsys.readouterr().out
    assert "FRONT: 100 x 200 mm" in out and "cut line]" in out
    for line, size in (("sew", [80.0, 180.0]), ("cut", [100.0, 200.0])):
        target = tmp_path / f"{line}.npz"
        assert main(["generate", str(path), "-o", str(target), "-q", "--line", line,
                     "--edge-length", "20mm"]) == 0
        with np.load(target) as z:
            info = json.loads(str(z["info"]))
            pts = z["points"]
        assert info["piece"]["meta"]["line"] == line
        assert np.ptp(pts[..., 0]) == pytest.approx(size[0]) and np.ptp(pts[..., 1]) == pytest.approx(size[1])
    # without a sew line the cut line is used, with a note
    bare = tmp_path / "bare.dxf"
    _aama_sew(bare, sew=False)
    (p,) = read_pieces(bare)
    assert p.meta["line"] == "cut" and p.extent == pytest.approx((100.0, 200.0))
    assert any("no sew line (layer 14)" in n for n in p.notes)


def test_plain_dxf_layers_and_nesting(tmp_path):
    import ezdxf

    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (300, 0), (300, 400), (0, 400)], close=True, dxfattribs={"layer": "PIECES"})
    msp.add_lwpolyline([(-10, -10), (310, -10), (310, 410), (-10, 410)], close=True,
                       dxfattribs={"layer": "CUT"})
    msp.add_circle((150, 200), 2, dxfattribs={"layer": "PIECES"})
    msp.add_lwpolyline([(400, 0), (410, 0), (410, 10), (400, 10)], close=True, dxfattribs={"layer": "TEXT"})
    path = tmp_path / "plain.dxf"
    doc.saveas(path)
    got = read_pieces(path)
    assert [p.name for p in got] == ["piece1"]
    assert {s.name: s.kind for s in got.skipped} == {"piece2": SA, "piece3": "drill hole", "piece4": "text"}
    assert [p.name for p in read_pieces(path, line="cut")] == ["piece2"]


def test_a_degenerate_outline_is_skipped_when_marked_else_failed(tmp_path, capsys):
    """The joined rule: an outline that cannot be made (2 points, no area) is skipped when the file
    marks it as an annotation, and is a failed piece (exit 4) otherwise."""
    path = tmp_path / "degenerate.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" viewBox="0 0 300 200">'
                    '<path id="body" d="M 10 10 L 110 10 L 110 110 L 10 110 Z"/>'
                    '<path id="tick" class="note" d="M 150 10 L 160 10 Z"/>'          # marked: skipped
                    '<path id="edge" class="fabric" d="M 150 50 L 200 50 Z"/>'        # a piece: failed
                    '</svg>')
    got = read_pieces(path)
    assert [p.name for p in got] == ["body"]
    assert [(s.name, s.kind, s.piece) for s in got.skipped] == [("tick", "mark", None)]
    assert got.skipped[0].reason == "mark (the file marks it 'note')"     # not made, so not looked at
    assert [(f.name, f.stage) for f in got.failed] == [("edge", "read")]
    with pytest.raises(InputError, match="outline 'tick' cannot be gridded: .*only 2 distinct points"):
        read_pieces(path, include=["tick"])
    assert main(["pieces", str(path)]) == 4
    out = capsys.readouterr().out
    assert out.splitlines()[0].endswith("1 piece, 1 failed (coordinates in mm), 1 closed outline skipped as annotations")
    assert "edge: FAILED (cannot be read): only 2 distinct points" in out and "  tick: mark" in out


# --------------------------------------------------------------------------- the distance kernel


def _numpy_distance(points, poly, monkeypatch):
    """``outline_distance`` by its NumPy form whatever the size."""
    from clothgrid.patterns import annotations

    monkeypatch.setattr(annotations, "KERNEL_PAIRS", np.inf)
    return annotations.outline_distance(points, poly)


@pytest.mark.parametrize("dim", [2, 3])
def test_distance_kernel_is_the_numpy_form_bit_for_bit(rng, dim, monkeypatch):
    """Fresh outlines (repeated points: zero-length segments) against outlines of 1 to 300 points:
    the kernel's distances are the NumPy form's exactly, and the true distances (a point's distance
    to every segment by its own projection, min over segments) within rounding."""
    from clothgrid.patterns.distance_kernels import dist_to_polyline

    for _ in range(20):
        pts = rng.normal(size=(int(rng.integers(1, 200)), dim)) * 100.0
        poly = rng.normal(size=(int(rng.integers(1, 300)), dim)) * 100.0
        poly[int(rng.integers(0, len(poly)))] = poly[0]
        got = dist_to_polyline(pts, poly)
        assert np.array_equal(got, _numpy_distance(pts, poly, monkeypatch))
        a, b = poly, np.roll(poly, -1, axis=0)
        true = np.full(len(pts), np.inf)
        for s in range(len(poly)):
            ab = b[s] - a[s]
            t = np.zeros(len(pts)) if not ab.any() else np.clip((pts - a[s]) @ ab / (ab @ ab), 0, 1)
            true = np.minimum(true, np.linalg.norm(pts - (a[s] + t[:, None] * ab), axis=1))
        assert np.allclose(got, true, rtol=1e-12, atol=1e-9)


def test_large_pairs_take_the_kernel(monkeypatch):
    """The classification's large comparisons (a 400-point outline against 2000 segments) go to the
    kernel; a small one stays in NumPy (no compiled code needed to read a small file)."""
    from clothgrid.patterns import annotations, distance_kernels

    calls = []
    real = distance_kernels.dist_to_polyline
    monkeypatch.setattr(distance_kernels, "dist_to_polyline", lambda p, q: calls.append(len(p)) or real(p, q))
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)]) * 50.0
    big = annotations.outline_distance(circle[::5] * 1.1, circle)
    assert calls == [400] and np.allclose(big, 5.0, atol=1e-3)
    annotations.outline_distance(circle[:4], circle[:8])
    assert calls == [400]


def _frame_svg(tmp_path, inner: str, name: str = "frame.svg") -> Path:
    path = tmp_path / name
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="600mm" height="500mm" viewBox="0 0 600 500">'
                    + inner + "</svg>")
    return path


def test_a_frame_around_the_pieces_is_no_piece(tmp_path):
    """A drawing's frame (matplotlib's white figure and axes backgrounds, its four spines drawn as
    lines: OpenPattern's SVGs) or a page border around two pieces is skipped as a "frame", and the
    pieces it holds are gridded (they were taken for marks drawn on a 600 x 500 mm piece). A
    rectangle holding rectangles (a bag panel with two pocket placements), or one shape, stays a
    piece."""
    bodice = "M 50,50 L 250,50 L 260,300 C 200,320 120,330 40,300 Z"
    sleeve = "M 320,60 L 540,60 C 560,200 520,300 430,420 C 340,300 300,200 320,60 Z"
    frame = ('<rect x="0" y="0" width="600" height="500" style="fill:#ffffff;stroke:none"/>'
             '<rect x="0" y="0" width="600" height="500" style="fill:#ffffff;stroke:none"/>'
             '<g id="spines"><path d="M 0,0 V 500"/><path d="M 600,0 V 500"/><path d="M 0,0 H 600"/>'
             '<path d="M 0,500 H 600"/></g>')
    got = read_pieces(_frame_svg(tmp_path, frame + f'<path id="bodice" d="{bodice}"/><path id="sleeve" d="{sleeve}"/>'))
    assert sorted(p.name for p in got) == ["bodice", "sleeve"]
    assert [s.kind for s in got.skipped] == ["frame"] * 3
    assert all("frame around 2 outlines" in s.reason for s in got.skipped)
    # a bag panel with two rectangular pocket placements: a piece and its marks
    bag = ('<rect id="panel" x="0" y="0" width="600" height="500"/>'
           '<rect id="pocket1" x="50" y="50" width="200" height="150"/>'
           '<rect id="pocket2" x="350" y="50" width="200" height="150"/>')
    got = read_pieces(_frame_svg(tmp_path, bag, "bag.svg"))
    assert "panel" in [p.name for p in got] and not got.skipped
    # one shape inside a rectangle: the rectangle stays a piece, as before
    got = read_pieces(_frame_svg(tmp_path, f'<rect id="panel" x="0" y="0" width="600" height="500"/>'
                                           f'<path id="bodice" d="{bodice}" style="stroke-dasharray:4,2"/>',
                                 "one.svg"))
    assert [p.name for p in got] == ["panel"] and [s.kind for s in got.skipped] == ["inside"]
