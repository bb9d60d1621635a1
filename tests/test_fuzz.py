"""Fuzzing the readers and the options (issue 15, item 6).

Hypothesis generates inputs for every reader (boundary JSON, GarmentCode JSON, SVG, DXF) and
option lists for ``generate`` and ``garment``, both as structured documents with hostile values
in their fields and as byte-level splices into valid files, and runs ``clothgrid.cli.main``
in-process on each. Whatever the input, a run must end within :data:`PER_RUN_S` seconds with a
documented exit code; an error is ``clothgrid: error:`` lines and nothing else (no traceback, no
warning) and leaves the output folder empty; a success writes only finite numbers and no
temporary file.

In CI the examples are derandomized (the same ones every run, so that a stop cannot fail by
chance) and capped at ``CLOTHGRID_FUZZ_EXAMPLES`` (default 100) per test; to hunt for new
failures run, e.g.::

    CLOTHGRID_FUZZ_RANDOM=1 CLOTHGRID_FUZZ_EXAMPLES=2000 python -m pytest tests/test_fuzz.py

A failure Hypothesis finds is shrunk to a small input and printed; turn it into a regression in
``tests/test_hostile.py`` when fixing it.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import os
import signal
import tempfile
import warnings
from pathlib import Path

import numpy as np

import hypothesis          # the test extra: a missing one fails here, it is not skipped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clothgrid.cli import main

ROOT = Path(__file__).resolve().parents[1]
GARMENTCODE = ROOT / "tests" / "data" / "garmentcode" / "flare_skirt_specification.json"

#: the exit codes a run may end with (README, "Exit codes")
EXIT_CODES = (0, 2, 3, 4)
#: longest a single run may take before it counts as a hang
PER_RUN_S = 60

EXAMPLES = int(os.environ.get("CLOTHGRID_FUZZ_EXAMPLES", "100"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, database=None,
                derandomize=os.environ.get("CLOTHGRID_FUZZ_RANDOM") != "1",
                suppress_health_check=list(HealthCheck))


class Hang(Exception):
    """A run took longer than :data:`PER_RUN_S`."""


def _alarm(signum, frame):
    raise Hang(f"no exit within {PER_RUN_S} s")


def run_cli(args: list[str], out_dir: Path) -> tuple[int, str]:
    """Run the command line in-process and check what every run must satisfy."""
    err, out = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, PER_RUN_S)
    try:
        with warnings.catch_warnings(record=True) as shown, contextlib.redirect_stderr(err), \
                contextlib.redirect_stdout(out):
            warnings.simplefilter("always")
            code = main(args)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    hypothesis.event(f"exit {code}")
    context = f"clothgrid {' '.join(args)}\nexit {code}\n{text}"
    assert code in EXIT_CODES, context
    assert "Traceback" not in text, context
    # what a user would see printed: warnings shown by default (not deprecations)
    loud = [w for w in shown if not issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning,
                                                            ImportWarning, ResourceWarning))]
    assert not loud, f"{context}\nwarnings: {[str(w.message) for w in loud]}"
    left = sorted(p.name for p in out_dir.iterdir())
    assert not [n for n in left if ".tmp" in n or n.startswith(".")], (context, left)
    if code != 0:
        lines = [ln for ln in text.splitlines() if ln.strip()]
        assert any(ln.startswith("clothgrid: error:") for ln in lines), context
    if code in (2, 3):
        assert left == [], (context, left)
        lines = [ln for ln in text.splitlines() if ln.strip()]
        errors = [ln for ln in lines if not ln.startswith(("clothgrid:", "usage:", " "))]
        assert not errors, context
    for name in left:
        _check_finite(out_dir / name, context)
    return code, text


def _check_finite(path: Path, context: str) -> None:
    """No NaN or infinity in a written output."""
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            for key in z.files:
                a = z[key]
                if a.dtype.kind == "f":
                    assert np.isfinite(a).all(), (context, path.name, key)
    elif path.suffix in (".obj", ".ply", ".json", ".vts"):
        text = path.read_text(errors="replace").lower()
        for bad in ("nan", "inf"):
            # a number token, not a word in a header ("info", "binary_little_endian" ...)
            assert not any(tok in (bad, "-" + bad, "+" + bad) for tok in text.replace('"', " ").replace(",", " ")
                           .replace("[", " ").replace("]", " ").split()), (context, path.name)


# --------------------------------------------------------------------------- strategies

#: tokens spliced into files: structure, numbers at the limits, non-numbers
TOKENS = ["-", "1e308", "-1e308", "1e-320", "nan", "NaN", "inf", "Infinity", "[", "]", "{", "}", '"', ",",
          "0", "-0", "1" + "0" * 30, "99999999999999999999", "true", "null", "<", ">", "/>", "e", ".", " ",
          "\n", "\x00", "\u00e9", "\ufffd", "0x1F", "1,2", "M", "z", "L", "A", "C", "Q", "SECTION", "ENDSEC", "EOF"]

numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-1e3, max_value=1e3),
    st.integers(min_value=-10**40, max_value=10**40),
    st.integers(min_value=-3, max_value=50),
)
json_leaf = st.one_of(numbers, st.booleans(), st.none(), st.text(max_size=6), st.sampled_from(["", "a", "0", "mm"]))
json_values = st.recursive(json_leaf, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=5), inner, max_size=4)), max_leaves=12)


@st.composite
def splices(draw, seed: str, lo: int = 0, hi: int | None = None) -> str:
    """``seed`` with up to 4 spans (within ``[lo, hi)``) deleted or replaced by tokens or text."""
    text = seed
    hi = len(seed) if hi is None else hi
    for _ in range(draw(st.integers(1, 4))):
        a = draw(st.integers(lo, max(lo, min(hi, len(text)) - 1)))
        b = a + draw(st.integers(0, 12))
        new = draw(st.one_of(st.sampled_from(TOKENS), st.text(max_size=4), st.just("")))
        text = text[:a] + new + text[b:]
    return text


def _square(n: int = 12) -> list[list[float]]:
    t = np.linspace(0, 1, n // 4, endpoint=False)
    return ([[float(s), 0.0] for s in t] + [[1.0, float(s)] for s in t]
            + [[1.0 - float(s), 1.0] for s in t] + [[0.0, 1.0 - float(s)] for s in t])


BOUNDARY = {"outline": _square(), "corners": [0, 3, 6, 9]}
SIDES = {"bottom": [[0, 0], [0.5, 0.1], [1, 0]], "right": [[1, 0], [1, 1]],
         "top": [[0, 1], [0.5, 1.2], [1, 1]], "left": [[0, 0], [0, 1]]}

SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" viewBox="0 0 200 200">'
       '<g id="front" transform="translate(5,5)"><path id="a" d="M 0 0 L 60 0 C 70 20 70 40 60 60 '
       'L 0 60 Q -10 30 0 0 Z"/></g>'
       '<polygon id="b" points="100,0 160,0 170,50 100,60"/>'
       '<rect id="c" x="10" y="100" width="50" height="40" rx="3"/>'
       '<path id="d" d="m 100 100 h 50 a 10 10 0 0 1 10 10 v 40 h -60 z"/></svg>')


def _dxf_seed() -> str:
    head = "0\nSECTION\n2\nHEADER\n9\n$ACADVER\n1\nAC1009\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n0\nSECTION\n2\nENTITIES\n"
    poly = ("0\nLWPOLYLINE\n8\n1\n90\n5\n70\n1\n10\n0.0\n20\n0.0\n10\n80.0\n20\n0.0\n42\n0.3\n"
            "10\n90.0\n20\n60.0\n10\n40.0\n20\n70.0\n10\n0.0\n20\n60.0\n")
    lines = "".join(f"0\nLINE\n8\n1\n10\n{a[0]}\n20\n{a[1]}\n11\n{b[0]}\n21\n{b[1]}\n"
                    for a, b in [((100, 0), (150, 0)), ((150, 40), (100, 40)), ((150, 0), (150, 40)),
                                 ((100, 40), (100, 0))])
    return head + poly + lines + "0\nENDSEC\n0\nEOF\n"


DXF = _dxf_seed()


def _leaf_paths(obj, path=()):
    """Every path to a value inside nested lists and dicts (containers included)."""
    yield path
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaf_paths(v, path + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _leaf_paths(v, path + (i,))


@st.composite
def mutated(draw, doc):
    """``doc`` with up to three of its values (at any depth) replaced, or deleted from a dict."""
    doc = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _leaf_paths(doc) if p]
        if not paths:
            break
        path = paths[draw(st.integers(0, len(paths) - 1))]
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if isinstance(parent, dict) and draw(st.booleans()):
            del parent[path[-1]]
        else:
            parent[path[-1]] = draw(json_values)
    return doc


def _dump(doc) -> str:
    try:
        return json.dumps(doc)           # NaN and Infinity as JavaScript writes them
    except (TypeError, ValueError):
        return "{}"


@contextlib.contextmanager
def _folders():
    with tempfile.TemporaryDirectory(prefix="clothgrid-fuzz-") as d:
        src, out = Path(d) / "in", Path(d) / "out"
        src.mkdir()
        out.mkdir()
        yield src, out


# --------------------------------------------------------------------------- readers


@FUZZ
@given(doc=st.one_of(mutated(BOUNDARY), mutated(SIDES), json_values.map(lambda v: {"outline": v})),
       command=st.sampled_from(["generate", "pieces"]))
def test_fuzz_boundary_json(doc, command):
    with _folders() as (src, out):
        f = src / "b.json"
        f.write_text(_dump(doc))
        args = ["generate", str(f), "-o", str(out / "g.npz"), "-q", "--nodes", "9"] if command == "generate" \
            else ["pieces", str(f)]
        run_cli(args, out)


@FUZZ
@given(text=st.one_of(splices(json.dumps(BOUNDARY)), splices(json.dumps(SIDES))))
def test_fuzz_boundary_json_bytes(text):
    with _folders() as (src, out):
        f = src / "b.json"
        f.write_text(text, errors="surrogatepass")
        run_cli(["generate", str(f), "-o", str(out / "g.obj"), "-q", "--nodes", "9"], out)


_GC = json.loads(GARMENTCODE.read_text())


@FUZZ
@given(doc=mutated(_GC), command=st.sampled_from(["pieces", "garment", "generate"]))
def test_fuzz_garmentcode(doc, command):
    with _folders() as (src, out):
        f = src / "spec.json"
        f.write_text(_dump(doc))
        args = {"pieces": ["pieces", str(f)],
                "garment": ["garment", str(f), "-o", str(out / "g.npz"), "--edge-length", "10cm", "-q"],
                "generate": ["generate", str(f), "-o", str(out / "{piece}.npz"), "--edge-length", "10cm", "-q"],
                }[command]
        run_cli(args, out)


def _pattern_args(command: str, f: Path, out: Path) -> list[str]:
    """``pieces FILE`` or ``generate FILE`` of every piece at 10 mm into ``out``."""
    if command == "pieces":
        return ["pieces", str(f)]
    return ["generate", str(f), "-o", str(out / "{piece}.npz"), "--edge-length", "10mm", "-q"]


# the path data and attributes of an SVG, and anything in the document
_SVG_BODY = SVG.index("<g"), SVG.rindex("</svg>")


@FUZZ
@given(text=st.one_of(splices(SVG, *_SVG_BODY), splices(SVG)), command=st.sampled_from(["pieces", "generate"]))
def test_fuzz_svg(text, command):
    with _folders() as (src, out):
        f = src / "p.svg"
        f.write_text(text, errors="surrogatepass")
        run_cli(_pattern_args(command, f, out), out)


path_commands = st.lists(st.one_of(st.sampled_from(list("MmLlHhVvCcSsQqTtAaZz")), numbers.map(repr),
                                   st.sampled_from([",", " ", "-", ".", "e"])), min_size=1, max_size=30)


@FUZZ
@given(d=path_commands.map(" ".join), transform=st.sampled_from(
    ["", "scale(1e300)", "matrix(0 0 0 0 0 0)", "rotate(45)", "scale(-1 1)", "translate(1e308)", "skewX(90)",
     "scale(", "matrix(1,2)"]))
def test_fuzz_svg_path_data(d, transform):
    with _folders() as (src, out):
        f = src / "p.svg"
        f.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" viewBox="0 0 200 200">'
                     f'<g transform="{transform}"><path d="{d}"/></g></svg>', errors="surrogatepass")
        run_cli(_pattern_args("generate", f, out), out)


_DXF_ENTITIES = DXF.index("ENTITIES"), DXF.rindex("ENDSEC")


@st.composite
def dxf_lines(draw) -> str:
    """The seed DXF with some of its entity values replaced and group pairs deleted or repeated."""
    lines = DXF.split("\n")
    first = DXF[:_DXF_ENTITIES[0]].count("\n") + 1
    last = DXF[:_DXF_ENTITIES[1]].count("\n") - 1
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(first, max(first, min(last, len(lines) - 1))))
        op = draw(st.sampled_from(["value", "delete", "repeat"]))
        if op == "value":
            lines[k] = draw(st.one_of(numbers.map(repr), st.sampled_from(TOKENS), st.text(max_size=4)))
        elif op == "delete":
            del lines[k:k + 2]
        else:
            lines[k:k] = lines[k:k + 2] * draw(st.integers(1, 3))
    return "\n".join(lines)


@FUZZ
@given(text=st.one_of(dxf_lines(), splices(DXF, *_DXF_ENTITIES)), command=st.sampled_from(["pieces", "generate"]))
def test_fuzz_dxf(text, command):
    with _folders() as (src, out):
        f = src / "p.dxf"
        f.write_text(text, errors="surrogatepass")
        run_cli(_pattern_args(command, f, out), out)


# --------------------------------------------------------------------------- options

#: the options of ``generate`` with values good and bad (small grids, so that good runs are quick)
GENERATE_OPTIONS = {
    "--nodes": ["9", "17x9", "5x33", "0", "1", "2x2", "3x100000000", "-5", "abc", "9x", "1e3", "9x9x9", ""],
    "--init": ["zero", "average", "tfi", "bogus"],
    "--weights": ["paper", "uniform", "4"],
    "--k": ["1", "1e-6", "1e6", "1e300", "-1", "0", "nan", "inf", "x"],
    "--solver": ["auto", "direct", "fdm", "jacobi", "multigrid", "cg"],
    "--backend": ["auto", "cpu", "gl", "cuda", "tpu"],
    "--tol": ["1e-4", "2**-12", "1e-30", "0", "-1", "nan", "1e300", "2**", "1/0"],
    "--stop": ["error", "paper", "never"],
    "--max-iter": ["1", "5", "0", "-3", "1e9", "x"],
    "--functional": ["length", "foldfree", "auto", "none"],
    "--density": ["150gsm", "0.2kg/m2", "150g/m2", "-1gsm", "1e400gsm", "nan", "gsm", "12"],
    "--units": ["m", "cm", "mm", "in", "parsec", ""],
    "--triangles": ["fixed", "alternate", "none"],
    "--uv": ["normalised", "pattern", "polar"],
    "--edge-length": ["5cm", "0.1", "1e-12", "1e-320", "-1mm", "10furlong", "nan", "inf", "0"],
    "--min-turn": ["20", "0", "180", "-5", "nan", "1e400"],
    "--corners": ["0,3,6,9", "0,1,2", "9,6,3,0", "0,0,0,0", "a,b,c,d", "-1,3,6,99"],
    "--corners-near": ["0,0;1,0;1,1;0,1", "0,0;1,0", "nan,0;1,0;1,1;0,1", "x"],
    "--piece": ["piece1", "nope", ""],
}
FLAGS = ["--allow-unconverged", "--cloth", "--strict", "-v", "-q"]
OUTPUT_NAMES = ["g.npz", "g.obj", "g.ply", "g.json", "g.vts", "g.xyz", "g", "g.npz", "{piece}.obj", "g.png"]


@st.composite
def generate_options(draw) -> tuple[list[str], list[str], list[str]]:
    names = draw(st.lists(st.sampled_from(sorted(GENERATE_OPTIONS)), max_size=5, unique=True))
    opts: list[str] = []
    for name in names:
        opts += [name, draw(st.sampled_from(GENERATE_OPTIONS[name]))]
    opts += draw(st.lists(st.sampled_from(FLAGS), max_size=2, unique=True))
    outputs = draw(st.lists(st.sampled_from(OUTPUT_NAMES), min_size=0, max_size=3))
    extra = []
    if draw(st.booleans()):
        extra = ["--report", "report.json"] if draw(st.booleans()) else ["--plot", "plot.png"]
    return opts, outputs, extra


@FUZZ
@given(options=generate_options(), kind=st.sampled_from(["boundary", "sides", "svg"]))
def test_fuzz_generate_options(options, kind):
    opts, outputs, extra = options
    with _folders() as (src, out):
        if kind == "svg":
            f = src / "p.svg"
            f.write_text(SVG)
        else:
            f = src / "b.json"
            f.write_text(json.dumps(BOUNDARY if kind == "boundary" else SIDES))
        args = ["generate", str(f)]
        for name in outputs:
            args += ["-o", str(out / name)]
        if extra:
            args += [extra[0], str(out / extra[1])]
        run_cli(args + opts, out)
