"""What a pattern says to cut of each piece ("Cut 2 mirrored from main fabric"): parsed from the
texts drawn on SVG pieces, from AAMA/flat DXF ``Quantity:`` texts, and listed by ``clothgrid pieces``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from clothgrid.cli import main
from clothgrid.patterns.piece import cut_instructions
from clothgrid.pipeline import cut_of, select_pieces

pytest.importorskip("svgpathtools")

SHARED = Path(__file__).resolve().parents[2] / "shared" / "patterns"


def C(n, material=None, mirrored=False, on_fold=False):
    return {"count": n, "material": material, "mirrored": mirrored, "on_fold": on_fold}


@pytest.mark.parametrize("text, want", [
    # FreeSewing 3 and 4 (a translation key names the material)
    ("Cut  2 mirrored  from  main fabric  ", [C(2, "main fabric", mirrored=True)]),
    ("Cut  1 on the fold  from  main fabric", [C(1, "main fabric", on_fold=True)]),
    ("Cut  1 from  plugin-annotations:ribbing", [C(1, "ribbing")]),
    # FreeSewing 2
    ("2x from main fabric", [C(2, "main fabric")]),
    ("4x from main fabric, 4x from interfacing", [C(4, "main fabric"), C(4, "interfacing")]),
    ("1x  main, 1x lining Cut on fold", [C(1, "main", on_fold=True), C(1, "lining", on_fold=True)]),
    ("Cut 2 Fabric", [C(2, "Fabric")]),
    ("cut 3 pairs", [C(3, mirrored=True)]),
    # not cut instructions
    ("Cut on fold", []), ("Front", []), ("cutTwoStripsToFinishTheArmholes :", []), ("2x4 lumber, front", []),
    ("Cut 0 from fabric", []),
])
def test_cut_instructions_parse(text, want):
    assert cut_instructions(text) == want


@pytest.mark.skipif(not (SHARED / "fs_wahid_layout.svg").is_file(), reason=f"no {SHARED}")
def test_freesewing_pieces_say_what_to_cut(capsys):
    """FreeSewing 2's Wahid waistcoat and Florent cap: each part's title says how many to cut of
    which material, a line (``<tspan>``) at a time; the text goes to the smallest piece around it;
    `pieces` prints it and its JSON has it."""
    got = {p.name: cut_of(p) for p in select_pieces(SHARED / "fs_wahid_layout.svg")}
    assert got["front"] == [C(2, "main fabric")]
    assert got["back"] == [C(2, "main fabric"), C(2, "lining")]          # two lines, one text
    assert got["pocketBag"] == [C(2, "lining")] and got["pocketInterfacing"] == [C(2, "interfacing")]
    florent = {p.name: cut_of(p) for p in select_pieces(SHARED / "fs_florent_layout.svg")}
    assert florent["side"] == [C(1, "main", on_fold=True), C(1, "lining", on_fold=True)]
    assert main(["pieces", str(SHARED / "fs_wahid_layout.svg")]) == 0
    assert "  cut 2 from main fabric; 2 from lining" in capsys.readouterr().out
    assert main(["pieces", str(SHARED / "fs_wahid_layout.svg"), "--json"]) == 0
    listing = {p["name"]: p for p in json.loads(capsys.readouterr().out)["pieces"]}
    assert listing["pocketWelt"]["cut"] == [C(2, "main fabric")]


def test_dxf_quantity_is_what_to_cut(tmp_path):
    """An AAMA or flat DXF piece's ``Quantity:`` text (whether mirrored unknown: None)."""
    ezdxf = pytest.importorskip("ezdxf")
    doc = ezdxf.new("R2010")
    doc.units = 4
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (100, 0), (100, 60), (0, 60)], close=True)
    for text, at in (("Piece Name: Cuff", (10, 30)), ("Quantity: 2", (10, 20)), ("Material: Rib", (10, 10))):
        msp.add_text(text, dxfattribs={"insert": at, "height": 2})
    path = tmp_path / "cuff.dxf"
    doc.saveas(path)
    (piece,) = select_pieces(path)
    assert piece.name == "Cuff" and cut_of(piece) == [C(2, "Rib", mirrored=None)]


def test_svg_text_lines_and_owner(tmp_path):
    """A text's lines are its positioned ``<tspan>`` elements; an inline one stays on its line. Each
    text goes to the smallest piece around its anchor (a pocket drawn on a front takes its own)."""
    svg = tmp_path / "p.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" viewBox="0 0 300 200">'
        '<path id="front" d="M 10 190 L 140 190 L 140 10 L 10 10 Z"/>'
        '<path id="pocket" d="M 80 150 L 130 150 L 130 110 L 80 110 Z"/>'
        '<path id="back" d="M 160 190 L 290 190 L 290 10 L 160 10 Z"/>'
        '<text x="20" y="40">Cut 2 mirrored from <tspan font-weight="bold">main fabric</tspan></text>'
        '<text x="90" y="130">Cut 4</text>'
        '<text x="170" y="40"><tspan x="170" y="40">2x from main fabric</tspan>'
        '<tspan x="170" dy="8">2x from lining</tspan><tspan x="170" dy="8">With good sides together</tspan></text>'
        '</svg>')
    got = {p.name: cut_of(p) for p in select_pieces(svg)}      # the pocket: a piece drawn over the front
    assert got["front"] == [C(2, "main fabric", mirrored=True)]
    assert got["pocket"] == [C(4)]
    assert got["back"] == [C(2, "main fabric"), C(2, "lining")]


def test_optitex_quantities():
    """Optitex's graded Basic Tee (tests/data, MIT) writes Quantity and Material on its sample size:
    one front and back of the self fabric, two sleeves, one neck binding of the contrast."""
    pytest.importorskip("ezdxf")
    src = Path(__file__).parent / "data" / "optitex" / "basic_tee_graded.dxf"
    got = {p.name: cut_of(p) for p in select_pieces(src, units="cm", grade="Small")}
    assert got == {"Front_Small": [C(1, "Self", mirrored=None)], "Back_Small": [C(1, "Self", mirrored=None)],
                   "Right Sleeve_Small": [C(2, "Self", mirrored=None)],
                   "Neck Binding_Small": [C(1, "Contrast 1", mirrored=None)]}
