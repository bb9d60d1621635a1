"""A corpus of hostile inputs and option combinations, run through the command line (issue 15).

Each case builds its input files in a scratch folder, runs ``python -m clothgrid
generate`` (or ``pieces``) with a timeout and classifies the outcome:

- ``clean``: exit 2, 3 or 4 with ``clothgrid: error:`` line(s) and nothing else on
  stderr, no file left in the output folder (the case expected an error);
- ``ok``: exit 0 and the case expected success (finite outputs written);
- ``accepted``: exit 0 where an error was expected (a bad input gridded or listed);
- ``rejected``: an error where success was expected;
- ``traceback``: a Python traceback on stderr;
- ``hang``: killed at the timeout;
- ``partial``: a temporary or half-written file left behind, or a written output
  with non-finite numbers;
- ``noise``: a clean error with other lines (warnings) above it;
- ``signal``: a signal case that did not end with 128+signum and its message.

    python benchmarks/hostile_corpus.py [--only NAME] [--timeout S]

(``CLOTHGRID_SRC=/other/checkout/src`` runs another checkout's code.)

prints one line per case and the counts by class.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Case:
    name: str
    build: Callable[[Path], list[str]]      # writes files in the folder, returns the CLI arguments
    expect: str = "error"                   # "error" or "ok"
    sig: int | None = None                  # send this signal once a temporary output file appears
    timeout: float = 30.0
    env: dict = field(default_factory=dict)
    pre: str | None = None                  # shell prefix (ulimit ...)


# --------------------------------------------------------------------------- input builders


def square_outline(n: int) -> list[list[float]]:
    """A square outline with ``n`` points (counter-clockwise)."""
    per = max(n // 4, 1)
    pts = []
    for k in range(4):
        for i in range(per):
            t = i / per
            x, y = [(t, 0.0), (1.0, t), (1.0 - t, 1.0), (0.0, 1.0 - t)][k]
            pts.append([x, y])
    return pts


def circle_outline(n: int, r: float = 100.0) -> list[list[float]]:
    return [[r * math.cos(2 * math.pi * i / n), r * math.sin(2 * math.pi * i / n)] for i in range(n)]


def wjson(d: Path, name: str, obj) -> Path:
    p = d / name
    p.write_text(json.dumps(obj))
    return p


def boundary_json(outline, corners=None) -> dict:
    n = len(outline)
    return {"outline": outline, "corners": corners or [0, n // 4, n // 2, 3 * n // 4]}


def gen(path: Path, d: Path, *extra: str, out: str = "g.obj") -> list[str]:
    return ["generate", str(path), "-o", str(d / "out" / out), "-q", *extra]


def pieces(path: Path) -> list[str]:
    return ["pieces", str(path)]


def garment_json(panels: dict, **pattern) -> dict:
    return {"pattern": {"panels": panels, **pattern}, "properties": {"units_in_meter": 100}}


def panel(verts, edges=None, curv=None) -> dict:
    n = len(verts)
    edges = edges or [{"endpoints": [i, (i + 1) % n]} for i in range(n)]
    if curv is not None:
        edges[0]["curvature"] = curv
    return {"vertices": verts, "edges": edges}


SQUARE = [[0, 0], [50, 0], [50, 60], [0, 60]]


def dxf_text(entities: list[str], insunits: int = 4) -> str:
    """An ASCII DXF of these entities: R12 (AC1009), or R2000 (AC1015) when there is an
    LWPOLYLINE (an R2000 entity: ezdxf ignores its closed flag in an R12 file)."""
    version = "AC1015" if any(e.startswith("0\nLWPOLYLINE\n") for e in entities) else "AC1009"
    head = (f"0\nSECTION\n2\nHEADER\n9\n$ACADVER\n1\n{version}\n9\n$INSUNITS\n70\n"
            f"{insunits}\n0\nENDSEC\n0\nSECTION\n2\nENTITIES\n")
    return head + "".join(entities) + "0\nENDSEC\n0\nEOF\n"


def dxf_line(a, b, layer="0") -> str:
    return f"0\nLINE\n8\n{layer}\n10\n{a[0]!r}\n20\n{a[1]!r}\n30\n0.0\n11\n{b[0]!r}\n21\n{b[1]!r}\n31\n0.0\n"


def dxf_lwpoly(pts, bulges=None, closed=True) -> str:
    """An LWPOLYLINE with the subclass markers ezdxf needs (without them ezdxf refuses the
    file as malformed, before any bulge or coordinate is looked at)."""
    s = (f"0\nLWPOLYLINE\n100\nAcDbEntity\n8\n0\n100\nAcDbPolyline\n90\n{len(pts)}\n"
         f"70\n{1 if closed else 0}\n")
    for k, (x, y) in enumerate(pts):
        s += f"10\n{x!r}\n20\n{y!r}\n"
        if bulges and bulges[k]:
            s += f"42\n{bulges[k]!r}\n"
    return s


def svg_doc(body: str) -> str:
    return ('<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" '
            f'viewBox="0 0 200 200">{body}</svg>')


def wtext(d: Path, name: str, text: str | bytes) -> Path:
    p = d / name
    (p.write_bytes if isinstance(text, bytes) else p.write_text)(text)
    return p


# --------------------------------------------------------------------------- the cases


def cases() -> list[Case]:
    C: list[Case] = []

    def add(name, build, expect="error", **kw):
        C.append(Case(name, build, expect, **kw))

    # JSON boundary files
    add("json-deep-arrays", lambda d: gen(wtext(d, "a.json", '{"outline": ' + "[" * 200000
                                                + "]" * 200000 + ', "corners": [0,1,2,3]}'), d))
    add("json-deep-objects", lambda d: gen(wtext(d, "a.json", '{"name": ' + '{"a":' * 200000 + "1"
                                                 + "}" * 200000 + "}"), d))
    add("json-huge-int", lambda d: gen(wtext(d, "a.json", json.dumps(boundary_json(square_outline(8)))
                                             .replace("0.0", "1" + "0" * 400, 1)), d))
    add("json-huge-float", lambda d: gen(wtext(d, "a.json", json.dumps(boundary_json(square_outline(8)))
                                               .replace("0.0", "1e400", 1)), d))
    add("json-bool-coords", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[False, False], [True, False], [True, True], [False, True]])), d, "--nodes", "9"))
    add("json-string-coords", lambda d: gen(wjson(d, "a.json", boundary_json(
        [["0", "0"], ["1", "0"], ["1", "1"], ["0", "1"]])), d, "--nodes", "9"))
    add("json-mixed-bool-coords", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[0.0, 0.0], [True, 0.0], [1.0, 1.0], [0.0, 1.0]])), d, "--nodes", "9"))
    add("json-bool-sides", lambda d: gen(wjson(d, "a.json", {
        "bottom": [[0, 0], [True, 0]], "right": [[1, 0], [1, 1]], "top": [[0, 1], [1, 1]],
        "left": [[0, 0], [0, 1]]}), d, "--nodes", "9"))
    add("json-bowtie", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[0, 0], [1, 1], [1, 0], [0, 1]], [0, 1, 2, 3])), d))
    add("json-figure-eight", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[0, 0], [1, 0], [2, 1], [3, 1], [3, 0], [2, 0], [1, 1], [0, 1]], [0, 3, 4, 7])), d))
    add("json-self-touching", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[0, 0], [2, 0], [2, 2], [1, 0], [0, 2]], [0, 1, 2, 4])), d))
    add("json-1e6-outline", lambda d: gen(wjson(d, "a.json", boundary_json(circle_outline(1_000_000))), d,
                                           "--nodes", "65"), expect="ok", timeout=60)
    add("json-400k-side", lambda d: gen(wjson(d, "a.json", {
        "bottom": [[i / 400000, 0.0] for i in range(400001)], "right": [[1, 0], [1, 1]],
        "top": [[0, 1], [1, 1]], "left": [[0, 0], [0, 1]]}), d, "--nodes", "65"), expect="ok", timeout=60)
    add("json-coords-1e300", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[x * 1e300, y * 1e300] for x, y in square_outline(8)])), d, "--nodes", "9"))
    add("json-coords-1e-320", lambda d: gen(wjson(d, "a.json", boundary_json(
        [[x * 1e-320, y * 1e-320] for x, y in square_outline(8)])), d, "--nodes", "9"))
    add("json-too-many-points", lambda d: gen(wjson(d, "a.json", boundary_json(
        square_outline(6_000_000))), d), timeout=90)

    # options
    sq = lambda d: wjson(d, "sq.json", boundary_json(square_outline(64)))
    add("opt-k-1e300", lambda d: gen(sq(d), d, "--weights", "paper", "--k", "1e300"))
    add("opt-k-1e-300", lambda d: gen(sq(d), d, "--weights", "paper", "--k", "1e-300"))
    add("opt-tol-1e-30-direct", lambda d: gen(sq(d), d, "--solver", "direct", "--tol", "1e-30"))
    add("opt-tol-1e-30-fdm", lambda d: gen(sq(d), d, "--solver", "fdm", "--tol", "1e-30"), expect="any")
    add("opt-edge-1e-12", lambda d: gen(sq(d), d, "--edge-length", "1e-12"))
    add("opt-edge-1e-320", lambda d: gen(sq(d), d, "--edge-length", "1e-320"))
    add("opt-edge-1e-12-pattern", lambda d: gen(wtext(d, "p.svg", svg_doc(
        '<rect x="10" y="10" width="50" height="60"/>')), d, "--edge-length", "1e-12"))
    add("opt-edge-1e-320mm-pattern", lambda d: gen(wtext(d, "p.svg", svg_doc(
        '<rect x="10" y="10" width="50" height="60"/>')), d, "--edge-length", "1e-320mm"))
    add("opt-long-output-name", lambda d: gen(sq(d), d, out="x" * 300 + ".obj"))
    add("opt-long-output-name-piece", lambda d: gen(wtext(d, "p.svg", svg_doc(
        f'<rect id="{"y" * 300}" x="10" y="10" width="50" height="60"/>')), d, out="{piece}.obj"), expect="any")
    add("opt-nodes-1e9", lambda d: gen(sq(d), d, "--nodes", "1000000000x1000000000"))
    add("opt-nodes-1e9-ulimit", lambda d: gen(sq(d), d, "--nodes", "1000000000x1000000000"),
        pre="ulimit -v 3000000;")
    add("opt-nodes-1e8x3", lambda d: gen(sq(d), d, "--nodes", "100000000x3"), timeout=60)
    add("opt-nodes-1e20", lambda d: gen(sq(d), d, "--nodes", "1" + "0" * 20))
    add("opt-tol-huge-power", lambda d: gen(sq(d), d, "--tol", "10**400"))
    add("opt-max-iter-huge", lambda d: gen(sq(d), d, "--max-iter", "1" + "0" * 400), expect="any")
    add("opt-min-turn-nan", lambda d: ["pieces", str(wtext(d, "p.svg", svg_doc(
        '<rect x="10" y="10" width="50" height="60"/>'))), "--min-turn", "nan"])
    add("opt-corners-near-inf", lambda d: gen(wtext(d, "p.svg", svg_doc(
        '<rect x="10" y="10" width="50" height="60"/>')), d, "--corners-near", "inf,0;1,0;1,1;0,1"))
    add("opt-corners-huge", lambda d: gen(wtext(d, "p.svg", svg_doc(
        '<rect x="10" y="10" width="50" height="60"/>')), d, "--corners", "0,1,2," + "9" * 30))
    # weight fields
    def npy_header(d, shape="(100000, 100000)"):     # a header that claims 80 GB, and no data
        head = "{'descr': '<f8', 'fortran_order': False, 'shape': %s, }" % shape
        head += " " * (118 - len(head)) + "\n"
        return wtext(d, "w.npy", b"\x93NUMPY\x01\x00" + len(head).to_bytes(2, "little") + head.encode())

    add("field-npy-huge-header", lambda d: gen(sq(d), d, "--weight-field", str(npy_header(d))))
    add("field-npy-truncated", lambda d: gen(sq(d), d, "--weight-field", str(npy_header(d, "(50, 50)"))))
    add("field-npy-text", lambda d: gen(sq(d), d, "--weight-field", str(wtext(d, "w.npy", "1 2 3"))))
    add("field-npy-object", lambda d: gen(sq(d), d, "--weight-field", str(wtext(
        d, "w.npy", b"\x93NUMPY\x01\x00v\x00{'descr': '|O', 'fortran_order': False, 'shape': (2, 2), }"
        + b" " * 47 + b"\n" + b"\x80\x04N."))))
    add("field-png-garbage", lambda d: gen(sq(d), d, "--weight-field", str(wtext(d, "w.png", b"\x89PNG\r\n\x1a\nxx")),
                                           "--weight-field-range", "1,2"))
    add("field-negative", lambda d: gen(sq(d), d, "--weight-field", "-1"))
    add("field-nan", lambda d: gen(sq(d), d, "--weight-field", "nan"))

    # special files
    def devzero(d):
        (d / "z.json").symlink_to("/dev/zero")
        return gen(d / "z.json", d)
    add("dev-zero", devzero, timeout=30)

    def fifo(d):
        os.mkfifo(d / "f.json")
        return gen(d / "f.json", d)
    add("fifo", fifo)

    def fifo_svg(d):
        os.mkfifo(d / "f.svg")
        return ["pieces", str(d / "f.svg")]
    add("fifo-svg", fifo_svg)

    def big_file(d):
        p = d / "big.json"
        with open(p, "wb") as fh:
            fh.seek(300 * 2**20)
            fh.write(b" ")
        return gen(p, d)
    add("json-300MB-sparse", big_file)

    # SVG
    add("svg-deep-groups", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        "<g>" * 50000 + '<rect x="1" y="1" width="5" height="5"/>' + "</g>" * 50000))))
    add("svg-huge-number", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        '<path d="M 0 0 L 1' + "0" * 400 + ' 0 L 10 10 Z"/>'))))
    add("svg-inf-number", lambda d: pieces(wtext(d, "a.svg", svg_doc('<path d="M 0 0 L 1e400 0 L 10 10 Z"/>'))))
    add("svg-huge-rect", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        '<rect x="0" y="0" width="1e308" height="1e308"/>'))))
    add("svg-huge-transform", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        '<g transform="scale(1e300)"><rect x="0" y="0" width="10" height="10"/></g>'))))
    add("svg-bowtie", lambda d: pieces(wtext(d, "a.svg", svg_doc('<polygon points="0,0 50,50 50,0 0,50"/>'))))
    add("svg-bowtie-generate", lambda d: gen(wtext(d, "a.svg", svg_doc(
        '<polygon points="0,0 50,50 50,0 0,50"/>')), d))
    add("svg-figure-eight", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        '<polygon points="0,0 40,0 80,40 120,40 120,0 80,0 40,40 0,40"/>'))))
    add("svg-self-touching", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        '<polygon points="0,0 100,0 100,100 50,0 0,100"/>'))))
    add("svg-1e5-paths", lambda d: pieces(wtext(d, "a.svg", svg_doc("".join(
        f'<rect x="{(k % 300) * 2}" y="{(k // 300) * 2}" width="1" height="1"/>' for k in range(100_000))))),
        expect="ok", timeout=90)
    add("svg-1e6-point-path", lambda d: pieces(wtext(d, "a.svg", svg_doc(
        '<polygon points="' + " ".join(f"{x:.6f},{y:.6f}" for x, y in circle_outline(1_000_000)) + '"/>'))),
        expect="ok", timeout=90)
    add("svg-billion-laughs", lambda d: pieces(wtext(d, "a.svg", '<?xml version="1.0"?><!DOCTYPE svg ['
        '<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">'
        '<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;"><!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">'
        '<!ENTITY e "&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;"><!ENTITY f "&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;">'
        '<!ENTITY g "&f;&f;&f;&f;&f;&f;&f;&f;&f;&f;"><!ENTITY h "&g;&g;&g;&g;&g;&g;&g;&g;&g;&g;">]>'
        '<svg xmlns="http://www.w3.org/2000/svg"><desc>&h;</desc></svg>')))
    add("svg-binary", lambda d: pieces(wtext(d, "a.svg", bytes(random.Random(1).randrange(256)
                                                                for _ in range(5000)))))

    # DXF
    add("dxf-binary-garbage", lambda d: pieces(wtext(d, "a.dxf", b"AutoCAD Binary DXF\r\n\x1a\x00"
                                                      + bytes(random.Random(2).randrange(256) for _ in range(5000)))))
    add("dxf-text-garbage", lambda d: pieces(wtext(d, "a.dxf", "0\nSECTION\n2\nENTITIES\n0\nLINE\n10\nabc\n")))
    add("dxf-bulge-1e308", lambda d: pieces(wtext(d, "a.dxf", dxf_text([dxf_lwpoly(
        [[0, 0], [50, 0], [50, 60], [0, 60]], [1e308, 0, 0, 0])]))))
    add("dxf-bulge-nan", lambda d: pieces(wtext(d, "a.dxf", dxf_text([dxf_lwpoly(
        [[0, 0], [50, 0], [50, 60], [0, 60]], [float("nan"), 0, 0, 0])]))))
    add("dxf-coords-1e15", lambda d: pieces(wtext(d, "a.dxf", dxf_text([dxf_lwpoly(
        [[0, 0], [1e15, 0], [1e15, 1e15 + 1], [0, 1e15]], [0.5, 0, 0, 0])]))), expect="any")
    add("dxf-coords-1e300", lambda d: gen(wtext(d, "a.dxf", dxf_text([dxf_lwpoly(
        [[0, 0], [1e300, 0], [1e300, 1e300], [0, 1e300]])])), d))
    add("dxf-coords-inf", lambda d: pieces(wtext(d, "a.dxf", dxf_text([dxf_lwpoly(
        [[0, 0], [float("inf"), 0], [50, 60], [0, 60]])]))))
    add("dxf-bowtie", lambda d: pieces(wtext(d, "a.dxf", dxf_text([dxf_lwpoly([[0, 0], [50, 50], [50, 0], [0, 50]])]))))

    def shuffled_lines(d, n=20_000):
        pts = circle_outline(n)
        segs = [(pts[i], pts[(i + 1) % n]) for i in range(n)]
        rng = random.Random(3)
        rng.shuffle(segs)
        segs = [(b, a) if rng.random() < 0.5 else (a, b) for a, b in segs]
        return pieces(wtext(d, "a.dxf", dxf_text([dxf_line(a, b) for a, b in segs])))
    add("dxf-20k-shuffled-lines", shuffled_lines, expect="ok", timeout=120)
    add("dxf-too-many-entities", lambda d: pieces(wtext(d, "a.dxf", dxf_text(
        [dxf_line([k, 0], [k, 1]) for k in range(600_000)]))), timeout=120)

    # GarmentCode
    gc = lambda d, obj: wjson(d, "g.json", obj)
    add("gc-curv-strings", lambda d: pieces(gc(d, garment_json({"a": panel(SQUARE, curv={
        "type": "cubic", "params": ["x", "y"]})}))))
    add("gc-curv-null-params", lambda d: pieces(gc(d, garment_json({"a": panel(SQUARE, curv={
        "type": "quadratic", "params": None})}))))
    add("gc-curv-null-list", lambda d: pieces(gc(d, garment_json({"a": panel(
        SQUARE, edges=[{"endpoints": [1, 0], "curvature": [None, "a"]}, {"endpoints": [1, 2]},
                       {"endpoints": [2, 3]}, {"endpoints": [3, 0]}])}))))
    add("gc-curv-string-reversed", lambda d: pieces(gc(d, garment_json({"a": panel(
        SQUARE, edges=[{"endpoints": [1, 0], "curvature": {"type": "cubic", "params": [["a", 1], [0.5, None]]}},
                       {"endpoints": [1, 2]}, {"endpoints": [2, 3]}, {"endpoints": [3, 0]}])}))))
    add("gc-curv-string", lambda d: pieces(gc(d, garment_json({"a": panel(SQUARE, curv="curvy")}))))
    add("gc-circle-strings", lambda d: pieces(gc(d, garment_json({"a": panel(
        SQUARE, edges=[{"endpoints": [1, 0], "curvature": {"type": "circle", "params": ["r", None, "x"]}},
                       {"endpoints": [1, 2]}, {"endpoints": [2, 3]}, {"endpoints": [3, 0]}])}))))
    add("gc-unhashable-order", lambda d: pieces(gc(d, garment_json({"a": panel(SQUARE)},
                                                                  panel_order=[[1], {"x": 2}]))))
    add("gc-bool-vertices", lambda d: pieces(gc(d, garment_json({"a": panel(
        [[False, False], [True, False], [True, True], [False, True]])}))))
    add("gc-bowtie", lambda d: pieces(gc(d, garment_json({"a": panel([[0, 0], [50, 50], [50, 0], [0, 50]])}))))

    def gc_many_edges(d, n=30_000):
        verts = circle_outline(n, 50.0)
        edges = [{"endpoints": [i, (i + 1) % n]} for i in range(n)]
        random.Random(4).shuffle(edges)
        return pieces(gc(d, garment_json({"a": {"vertices": verts, "edges": edges}})))
    add("gc-30k-shuffled-edges", gc_many_edges, expect="ok", timeout=120)
    add("gc-deep-nesting", lambda d: pieces(wtext(d, "g.json", '{"pattern": {"panels": ' + "[" * 100000
                                                   + "]" * 100000 + "}}")))
    add("gc-huge-int", lambda d: pieces(wtext(d, "g.json", json.dumps(garment_json({"a": panel(SQUARE)}))
                                              .replace("50", "5" + "0" * 400, 1))))
    add("gc-huge-units", lambda d: pieces(wtext(d, "g.json", json.dumps(garment_json({"a": panel(SQUARE)}))
                                                .replace('"units_in_meter": 100', '"units_in_meter": 1e-320'))))

    # signals during a large .obj write
    for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        add(f"signal-{s.name}", lambda d: gen(sq(d), d, "--nodes", "1500x1500", "--solver", "multigrid"),
            sig=s, timeout=120)
    return C


# --------------------------------------------------------------------------- running


def classify(case: Case, rc: int | None, err: str, outdir: Path) -> str:
    left = sorted(p.name for p in outdir.rglob("*")) if outdir.exists() else []
    tmp = [n for n in left if n.endswith(".tmp")]
    if rc is None:
        return "hang"
    if "Traceback" in err:
        return "traceback"
    if tmp:
        return "partial"
    if case.sig is not None:
        want = 128 + case.sig
        if rc == want and left == [] and "clothgrid:" in err:
            return "clean"
        return "ok" if rc == 0 and left else "signal"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if rc == 0:
        for p in outdir.rglob("*.obj"):
            for ln in p.read_text(errors="replace").lower().splitlines():
                if ln.startswith(("v ", "vt ")) and ("nan" in ln or "inf" in ln):
                    return "partial"
        return "ok" if case.expect in ("ok", "any") else "accepted"
    # argparse's usage block (a "usage:" line and its indented continuation) goes with a usage error
    other = [ln for ln in lines if not ln.startswith(("clothgrid:", "usage:", " "))]
    if other:
        return "noise"
    if left and rc != 4:
        return "partial"
    if rc in (2, 3, 4) and any(ln.startswith("clothgrid: error:") for ln in lines):
        return "clean" if case.expect in ("error", "any") else "rejected"
    return "noise"


def run_case(case: Case, timeout: float | None = None) -> tuple[str, int | None, str, float]:
    d = Path(tempfile.mkdtemp(prefix="hostile-"))
    try:
        (d / "out").mkdir()
        args = case.build(d)
        env = {**os.environ, "PYTHONPATH": os.environ.get("CLOTHGRID_SRC", str(ROOT / "src")), **case.env}
        cmd = [sys.executable, "-m", "clothgrid", *args]
        if case.pre:
            cmd = ["bash", "-c", case.pre + " exec " + " ".join(map(repr, cmd))]
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True,
                                start_new_session=True)
        limit = timeout or case.timeout
        if case.sig is not None:
            deadline = time.monotonic() + limit
            while time.monotonic() < deadline and proc.poll() is None:
                if any(p.name.endswith(".tmp") for p in (d / "out").iterdir()):
                    time.sleep(0.05)
                    proc.send_signal(case.sig)
                    break
                time.sleep(0.01)
        try:
            out, err = proc.communicate(timeout=max(limit - (time.perf_counter() - t0), 1))
            rc = proc.returncode
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
            rc = None
        if rc is not None and rc < 0:
            err += f"\n(killed by signal {-rc})"
        cls = classify(case, rc, err, d / "out")
        return cls, rc, err, time.perf_counter() - t0
    finally:
        shutil.rmtree(d, ignore_errors=True)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", action="append", help="run only cases whose name contains this")
    ap.add_argument("--timeout", type=float, default=None)
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("-v", action="store_true", help="print stderr of the bad cases")
    a = ap.parse_args()
    counts: dict[str, int] = {}
    results = []
    for case in cases():
        if a.only and not any(s in case.name for s in a.only):
            continue
        cls, rc, err, secs = run_case(case, a.timeout)
        counts[cls] = counts.get(cls, 0) + 1
        tail = [ln for ln in err.strip().splitlines() if ln.strip()][-1:] or [""]
        print(f"{cls:10s} rc={rc!s:4s} {secs:6.1f}s {case.name:32s} {tail[0][:110]}", flush=True)
        if a.v and cls not in ("clean", "ok"):
            print("    " + "\n    ".join(err.strip().splitlines()[-8:]))
        results.append({"case": case.name, "class": cls, "rc": rc, "seconds": round(secs, 2),
                        "stderr": err[-2000:]})
    print("counts:", json.dumps(dict(sorted(counts.items()))))
    if a.json:
        Path(a.json).write_text(json.dumps({"counts": counts, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
