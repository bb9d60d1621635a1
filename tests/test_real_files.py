"""Issue 12, file by file: the default command on every real pattern file in ../shared/patterns.

Each file is gridded by ``clothgrid generate FILE -o DIR/{piece}.npz --report R.json`` with
no other option (10 mm edges, uniform weights, ``--functional auto``, automatic corners), in
this process. Asserted per file: exit 0 (4 for the file of :data:`FAILED`, whose broken
outlines are named), one ``.npz`` per piece, no folded cell on any piece,
and the figures measured when this table was made (``python benchmarks/pattern_survey.py``,
2026-11-26, after the relax's two-level smoothing and given-up active sets; the four files whose
backs and fronts now take the whole relax where the local one left a narrow neck squeezed,
``generate.WHOLE_RETRY_DEG``, 2026-11-27; the five files whose pieces' poor edge spread a runner-up
corner set now lowers, ``pipeline.RUNNER_UP_SPREAD``, 2026-11-28) within small margins, so that a change that makes a file worse fails here:

- the smallest cell angle of any piece (corner cells aside) at least the measured one - 0.5°,
- no more pieces under 10° than measured,
- the median and the largest edge spread (longest / shortest edge of a piece) at most
  1.15x the measured ones.

The quality targets of the issue are 0 folded cells, a smallest angle of 10° on 95 % of
pieces and 3° on all, and a median edge spread of 4: over all 455 pieces, 0 folded, 97.1 %
at 10° or more, 100 % at 3° or more, median spread 2.58 (:func:`test_targets_over_all_files`).
The pieces under 10° share one reason: a deep dart (or a long thin slit-like dart) inside a
side. A single structured grid fans around the dart tip, so the cells there are small and
narrow (docs/patterns.md, "Where the targets are missed").
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
    "astm_DEEP_ARMHOLE_RACER.DXF": (25, 10.50, 0, 2.87, 51.5),
    "astm_GLX0924S16_NEW.DXF": (42, 20.31, 0, 2.1, 17.4),
    "astm_GLX0926S16.DXF": (56, 22.51, 0, 1.6, 11.0),
    "astm_GLX4802S19_AAMA.DXF": (42, 25.00, 0, 4.19, 5.3),
    "astm_GLX4802S19_ASTM.DXF": (42, 25.00, 0, 4.19, 5.3),
    "astm_GMH1006F18_AAMA.DXF": (90, 25.00, 0, 2.6, 4.6),
    "astm_clo-box.dxf": (1, 89.97, 0, 1, 1.0),
    "fs_bruce_draft-sample.svg": (4, 22.01, 0, 2.75, 7.1),
    "fs_cathrin_layout.svg": (7, 53.61, 0, 1.92, 3.0),
    "fs_florent_layout.svg": (5, 25.00, 0, 3.01, 24.3),
    "fs_shin_layout.svg": (3, 40.00, 0, 2.11, 2.2),
    "fs_simon_collarstandbend.svg": (2, 69.87, 0, 1.63, 1.6),
    "fs_wahid_layout.svg": (8, 6.71, 2, 2.14, 110.0),
    "gc_pattern_test.svg": (6, 8.61, 2, 36.7, 42.7),
    "gcn_rand_57NZEOIBHZ_specification.json": (12, 14.51, 0, 2.3, 5.9),
    "gcn_rand_BY5OEFCZVD_specification.json": (12, 9.28, 2, 3.23, 33.7),
    "gcn_rand_IMB4RPKGCM_specification.json": (8, 29.47, 0, 1.76, 2.0),
    "gcn_rand_JIT6TDX7XB_specification.json": (6, 8.15, 2, 2.13, 45.6),
    "gcn_rand_KEJUMAMSBX_specification.json": (6, 82.81, 0, 1.1, 1.1),
    "gcn_rand_L12WU7204Q_specification.json": (10, 8.06, 3, 24.8, 45.9),
    "gcn_rand_P96VKL21PE_specification.json": (13, 83.43, 0, 1.27, 1.3),
    "gcn_rand_RMOGWZ2A7X_specification.json": (14, 8.89, 2, 1.53, 37.0),
    "gcn_rand_TLROKVCYFK_specification.json": (6, 27.05, 0, 2.16, 2.9),
    "gpg_dress_specification.json": (8, 26.70, 0, 1.97, 6.9),
    "gpg_jacket_hood_specification.json": (9, 22.45, 0, 1.99, 6.4),
    "gpg_jumpsuit_specification.json": (10, 27.40, 0, 2.07, 4.0),
    "gpg_pants_flare_specification.json": (4, 27.67, 0, 2.24, 2.3),
    "gpg_skirt_4_panels_specification.json": (4, 78.34, 0, 2.35, 2.7),
}


#: Outlines that fail, with the reason; the command then exits 4 (some pieces failed) and
#: writes the others. They are in the file as drawn, not made by clothgrid.
FAILED = {
    # the cut line (layer 1, no sew line) of three of the racer backs crosses itself over a
    # large loop (its points run 1709 -> 1013 mm and back): the file's outline is broken
    # (the code before the real-pattern work failed on them in the same way)
    "astm_DEEP_ARMHOLE_RACER.DXF": {"DEEP ARMHOLE RACERBK_48", "DEEP ARMHOLE RACERBK_50",
                                    "DEEP ARMHOLE RACERBK_52"},
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


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/patterns is not here")
def test_targets_over_all_files():
    """The issue's targets over every piece of every file, from the measured table: the table is
    what the per-file test above holds each file to, so the pooled figures follow from it."""
    pieces = sum(m[0] for m in MEASURED.values())
    under10 = sum(m[2] for m in MEASURED.values())
    assert pieces >= 450 and 1 - under10 / pieces >= 0.95
    assert min(m[1] for m in MEASURED.values()) >= 3.0
