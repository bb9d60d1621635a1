"""Issue 12, file by file: the default command on every real pattern file in ../shared/patterns.

Each file is gridded by ``clothgrid generate FILE -o DIR/{piece}.npz --report R.json`` with
no other option (10 mm edges, uniform weights, ``--functional auto``, automatic corners), in
this process. Asserted per file: exit 0 (4 for the two files of :data:`FAILED`, whose broken
outlines are named), one ``.npz`` per piece, no folded cell on any piece,
and the figures measured when this table was made (``python benchmarks/pattern_survey.py``,
2026-11-23) within small margins, so that a change that makes a file worse fails here:

- the smallest cell angle of any piece (corner cells aside) at least the measured one - 0.5°,
- no more pieces under 10° than measured,
- the median and the largest edge spread (longest / shortest edge of a piece) at most
  1.15x the measured ones.

The quality targets of the issue are 0 folded cells (met on every file), a smallest angle
of 10° on 95 % of pieces and 3° on all, and a median edge spread of 4; where a file misses
the latter two, the reason is the same on every such piece: a deep dart (or a long thin
slit-like dart) inside a side. A single structured grid fans around the dart tip, so the
cells there are small and narrow (docs/patterns.md, "Where the targets are missed").
"""

from __future__ import annotations

import json
import statistics
from pathlib import Path

import pytest

from clothgrid.cli import main

SHARED = Path(__file__).resolve().parents[2] / "shared" / "patterns"

#: file: (pieces, smallest angle of any piece (deg), pieces under 10°, median spread, largest spread)
MEASURED = {
    "astm_DEEP_ARMHOLE_RACER.DXF": (25, 4.28, 3, 24.07, 252.8),
    "astm_GLX0924S16_NEW.DXF": (42, 15.84, 0, 5.24, 146.7),
    "astm_GLX0926S16.DXF": (56, 5.40, 4, 2.80, 125.8),
    "astm_GLX4802S19_AAMA.DXF": (42, 27.94, 0, 8.34, 22.9),
    "astm_GLX4802S19_ASTM.DXF": (42, 27.94, 0, 8.34, 22.9),
    "astm_GMH1006F18_AAMA.DXF": (90, 25.89, 0, 4.07, 273.5),
    "astm_clo-box.dxf": (1, 89.97, 0, 1.00, 1.0),
    "fs_bruce_draft-sample.svg": (4, 11.64, 0, 3.31, 39.3),
    "fs_cathrin_layout.svg": (7, 49.77, 0, 2.08, 3.5),
    "fs_florent_layout.svg": (3, 27.82, 0, 9.32, 20.6),
    "fs_shin_layout.svg": (3, 5.27, 1, 9.07, 151.2),
    "fs_simon_collarstandbend.svg": (2, 72.91, 0, 1.44, 1.7),
    "fs_wahid_layout.svg": (8, 4.17, 2, 2.18, 215.3),
    "gc_pattern_test.svg": (6, 5.35, 4, 72.63, 145.4),
    "gcn_rand_57NZEOIBHZ_specification.json": (12, 13.64, 0, 3.75, 7.5),
    "gcn_rand_BY5OEFCZVD_specification.json": (12, 7.53, 2, 4.47, 98.1),
    "gcn_rand_IMB4RPKGCM_specification.json": (8, 26.77, 0, 1.81, 2.0),
    "gcn_rand_JIT6TDX7XB_specification.json": (6, 6.78, 2, 3.43, 150.7),
    "gcn_rand_KEJUMAMSBX_specification.json": (6, 82.81, 0, 1.08, 1.1),
    "gcn_rand_L12WU7204Q_specification.json": (10, 5.64, 6, 63.10, 140.9),
    "gcn_rand_P96VKL21PE_specification.json": (13, 83.43, 0, 1.14, 1.1),
    "gcn_rand_RMOGWZ2A7X_specification.json": (14, 5.28, 4, 1.55, 155.5),
    "gcn_rand_TLROKVCYFK_specification.json": (6, 26.02, 0, 3.90, 5.9),
    "gpg_dress_specification.json": (8, 18.48, 0, 2.06, 23.1),
    "gpg_jacket_hood_specification.json": (9, 20.81, 0, 3.94, 8.1),
    "gpg_jumpsuit_specification.json": (10, 20.70, 0, 3.75, 19.6),
    "gpg_pants_flare_specification.json": (4, 29.47, 0, 4.07, 4.2),
    "gpg_skirt_4_panels_specification.json": (4, 79.87, 0, 2.64, 3.0),
}


#: Outlines that fail, with the reason; the command then exits 4 (some pieces failed) and
#: writes the others. Both are in the files as drawn, not made by clothgrid.
FAILED = {
    # the cut line (layer 1, no sew line) of three of the racer backs crosses itself over a
    # large loop (its points run 1709 -> 1013 mm and back): the file's outline is broken
    # (the code before the real-pattern work failed on them in the same way)
    "astm_DEEP_ARMHOLE_RACER.DXF": {"DEEP ARMHOLE RACERBK_48", "DEEP ARMHOLE RACERBK_50",
                                    "DEEP ARMHOLE RACERBK_52"},
    # two closed paths of two distinct points (lines drawn closed), not marked as annotations
    "fs_florent_layout.svg": {"55", "56"},
}


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/patterns is not here")
@pytest.mark.parametrize("name", sorted(MEASURED))
def test_default_command_on_a_real_pattern_file(name, tmp_path, capsys):
    pieces, lowest, under10, median_spread, max_spread = MEASURED[name]
    out = tmp_path / "out"
    report = tmp_path / "quality.json"
    code = main(["generate", str(SHARED / name), "-o", str(out / "{piece}.npz"),
                 "--report", str(report), "-q"])
    capsys.readouterr()
    failed = FAILED.get(name, set())
    assert code == (4 if failed else 0)
    data = json.loads(report.read_text())
    rows = data["pieces"]
    assert {f["name"] for f in data["failed"]} == failed and len(rows) == pieces
    assert len(list(out.glob("*.npz"))) == pieces                # one grid per piece
    assert [r["name"] for r in rows if r["folded"]] == []         # no folded cell anywhere
    angles = [r["min_angle_deg"] for r in rows]
    spreads = [r["edge_spread"] for r in rows]
    assert min(angles) >= lowest - 0.5
    assert sum(a < 10 for a in angles) <= under10
    assert statistics.median(spreads) <= 1.15 * median_spread
    assert max(spreads) <= 1.15 * max_spread


def test_the_table_covers_every_shared_pattern_file():
    if not SHARED.is_dir():
        pytest.skip("../shared/patterns is not here")
    files = {p.name for p in SHARED.iterdir() if p.suffix.lower() in (".svg", ".dxf", ".json")}
    assert files == set(MEASURED)
