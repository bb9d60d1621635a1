"""clothgrid batch: a 2-worker local Dask cluster on real and broken pattern files.

All good pieces written, broken files and pieces in the manifest with their
errors, a second run does no work, a changed file or option is redone, a worker
killed while gridding loses nothing, and a run killed in the middle (SIGTERM,
then SIGKILL of the whole process group) and restarted finishes with nothing
lost or duplicated. Edge length 2 cm keeps the grids small.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from clothgrid import batch as B                                         # noqa: E402
from clothgrid.batch_manifest import (MANIFEST, ManifestWriter, compact_manifest, is_done,   # noqa: E402
                                      options_key, read_manifest)
from clothgrid.cli import main                                           # noqa: E402
from clothgrid.errors import InputError                                  # noqa: E402
from clothgrid.pipeline import GridOptions, read_jobs                    # noqa: E402

SHARED = Path(__file__).parents[2] / "shared" / "patterns"
GOOD = {  # file -> pieces written at 2 cm
    "gcn_rand_KEJUMAMSBX_specification.json": 6,   # GarmentCode JSON (GarmentCodeData sample)
    "fs_simon_collarstandbend.svg": 2,             # Inkscape SVG (FreeSewing)
    "gpg_skirt_4_panels_specification.json": 4,    # GPG template
}
PARTIAL = "partial.svg"          # 3 pieces gridded, a bow-tie outline fails (written by _collection)
PARTIAL_SVG = """<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="100mm" viewBox="0 0 400 100">
<path id="a" d="M 0,0 L 100,0 L 100,60 L 0,60 Z"/><path id="bow" d="M 150,0 L 250,60 L 250,0 L 150,40 Z"/>
<path id="b" d="M 260,0 L 320,0 L 320,60 L 260,60 Z"/><path id="c" d="M 330,0 L 390,0 L 360,50 Z"/></svg>"""
OPTS = GridOptions(edge_length="2cm")
SRC = str(Path(__file__).parents[1] / "src")

needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/patterns is not here")


def _collection(folder: Path) -> Path:
    """Real files, a copy of one in a subfolder (same stem), a file with failing pieces, broken files."""
    folder.mkdir()
    for name in GOOD:
        shutil.copy(SHARED / name, folder / name)
    (folder / "sub").mkdir()
    shutil.copy(SHARED / "fs_simon_collarstandbend.svg", folder / "sub" / "fs_simon_collarstandbend.svg")
    (folder / PARTIAL).write_text(PARTIAL_SVG)
    text = (SHARED / "gpg_dress_specification.json").read_text()
    (folder / "truncated_specification.json").write_text(text[: len(text) // 3])
    (folder / "garbage.svg").write_text("<svg>not closed")
    (folder / "notes.txt").write_text("not a pattern: left out of folders")
    return folder


@pytest.fixture(scope="module")
def client():
    """One 2-worker local cluster (processes) for the API tests of this module."""
    with contextlib.ExitStack() as stack:
        yield B._client_for(None, 2, B.DEFAULT_RETRIES, 2, stack)


def _npz_files(outdir: Path) -> list[str]:
    return sorted(p.relative_to(outdir).as_posix() for p in outdir.rglob("*.npz"))


def _check_outputs(outdir: Path, entries: list[dict]) -> None:
    """Every output listed exists and loads; nothing else is there (no temporary or stray file)."""
    listed = sorted(o for e in entries for o in e["outputs"])
    assert len(listed) == len(set(listed))
    assert _npz_files(outdir) == listed
    for rel in listed:
        with np.load(outdir / rel) as z:
            assert z["points"].ndim == 3
    stray = [p for p in outdir.rglob("*") if p.is_file() and p.suffix != ".npz" and p.name != MANIFEST]
    assert not stray


# --------------------------------------------------------------------------- the cluster runs


@needs_shared
def test_batch_grids_good_files_and_records_broken_ones(tmp_path, client):
    src = _collection(tmp_path / "in")
    out = tmp_path / "out"
    seen = []
    run = B.batch([src], out, options=OPTS, client=client, on_entry=seen.append)
    by_name = {Path(e["input"]).name + ("/sub" if "/sub/" in e["input"] else ""): e for e in run.entries}
    assert len(run.entries) == len(seen) == 7
    for name, n in GOOD.items():
        e = by_name[name]
        assert e["status"] == "ok" and e["error"] is None and len(e["pieces"]) == n
        assert e["stem"] == Path(name).stem or name.startswith("fs_simon")
        for p in e["pieces"]:
            assert p["outputs"] == [f"{e['stem']}/{p['name']}.npz"]
            assert {"folded", "min_angle_deg", "edge_spread", "nodes", "seconds"} <= set(p)
        assert set(e["timings"]) == {"read", "grid", "write", "total", "cpu"}
    # the same piece names as generate would grid
    assert [p["name"] for p in by_name["gpg_skirt_4_panels_specification.json"]["pieces"]] == \
        [j.name for j in read_jobs(SHARED / "gpg_skirt_4_panels_specification.json", ["x_{piece}.npz"], options=OPTS)]
    # colliding stems: both simons, each its own folder with a stable suffix
    a, b = by_name["fs_simon_collarstandbend.svg"], by_name["fs_simon_collarstandbend.svg/sub"]
    assert a["stem"] != b["stem"] and a["stem"].startswith("fs_simon_collarstandbend-")
    assert B.assign_stems([Path(b["input"]), Path(a["input"])]) == [b["stem"], a["stem"]]
    part = by_name[PARTIAL]
    assert part["status"] == "partial" and len(part["pieces"]) == 3
    assert [f["name"] for f in part["failed_pieces"]] == ["bow"]
    assert "crosses or touches itself" in part["failed_pieces"][0]["reason"]
    for name, words in (("truncated_specification.json", "invalid JSON"), ("garbage.svg", "SVG")):
        e = by_name[name]
        assert e["status"] == "failed" and words in e["error"] and e["error_type"] == "InputError"
        assert e["retry"] is False and e["outputs"] == [] and not (out / e["stem"]).exists()
    _check_outputs(out, run.entries)
    # the manifest: one line per input, then the summary
    lines = [json.loads(x) for x in (out / MANIFEST).read_text().splitlines()]
    assert [x["stem"] for x in lines[:-1]] == [e["stem"] for e in run.entries]
    s = lines[-1]["summary"]
    assert (s["inputs"], s["ok"], s["partial"], s["failed"], s["skipped"]) == (7, 4, 1, 2, 0)
    assert s["pieces"] == sum(GOOD.values()) + 2 + 3 and s["pieces_failed"] == 1
    assert s["worst_pieces"] and s["slowest_files"] and len(s["failed_inputs"]) == 2
    assert s["workers"] == 2

    # a second run does no work: no task, not even a cluster; files untouched
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*.npz")}
    before = read_manifest(out / MANIFEST)
    again = B.batch([src], out, options=GridOptions(edge_length="20mm"), client=_NoClient())
    assert again.done_now == [] and again.counts == {"ok": 4, "partial": 1, "failed": 2, "skipped": 7}
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.npz")} == stamps
    assert read_manifest(out / MANIFEST) == before

    # a changed file and a failed file fixed are redone, the rest not
    shutil.copy(SHARED / "gpg_dress_specification.json", src / "truncated_specification.json")
    (src / "gpg_skirt_4_panels_specification.json").write_text(
        (SHARED / "gcn_rand_TLROKVCYFK_specification.json").read_text())
    third = B.batch([src], out, options=OPTS, client=client)
    assert sorted(Path(e["input"]).name for e in third.done_now) == [
        "gpg_skirt_4_panels_specification.json", "truncated_specification.json"]
    assert third.counts == {"ok": 5, "partial": 1, "failed": 1, "skipped": 5}
    # the skirt's old pieces (front, back, left, right) are gone, the new file's are there
    skirt = next(e for e in third.entries if e["stem"] == "gpg_skirt_4_panels_specification")
    assert not (out / skirt["stem"] / "left.npz").exists()
    _check_outputs(out, third.entries)
    assert len(read_manifest(out / MANIFEST)) == 7          # compacted: one line per input

    # other options: every file is redone (the bad one too: it may read now)
    fourth = B.batch([src / "gcn_rand_KEJUMAMSBX_specification.json"], out,
                     options=GridOptions(edge_length="3cm"), client=client)
    assert len(fourth.done_now) == 1 and fourth.entries[0]["pieces"][0]["edge_length"] == 30.0
    assert len(read_manifest(out / MANIFEST)) == 7


class _NoClient:
    """Stands in for a client where none may be used."""

    def __getattr__(self, name):
        raise AssertionError(f"the cluster was used ({name}) though there was no work")


@needs_shared
def test_a_worker_killed_while_gridding_loses_nothing(tmp_path, client):
    src = tmp_path / "in"
    src.mkdir()
    for k in range(3):
        for name in GOOD:
            shutil.copy(SHARED / name, src / f"{k}_{name}")
    pids = client.run(os.getpid)
    killed = []

    def kill_a_busy_worker(entry):
        if killed:
            return
        for addr, keys in client.processing().items():
            if keys and addr in pids:
                os.kill(pids[addr], signal.SIGKILL)
                killed.append((addr, list(keys)))
                return

    run = B.batch([src], tmp_path / "out", options=OPTS, client=client, on_entry=kill_a_busy_worker)
    assert killed, "no worker was busy to be killed"
    assert run.counts == {"ok": 9, "partial": 0, "failed": 0, "skipped": 0}
    assert sum(len(e["pieces"]) for e in run.entries) == 3 * sum(GOOD.values())
    _check_outputs(tmp_path / "out", run.entries)
    assert len(read_manifest(tmp_path / "out" / MANIFEST)) == 9
    client.wait_for_workers(2, timeout=60)    # the nanny restarts it (and warms it up) for the next test


# --------------------------------------------------------------------------- the command line


def _cli(args, **kw):
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen([sys.executable, "-m", "clothgrid", "batch", *map(str, args)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def _lines(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def _wait_for_lines(proc, manifest: Path, n: int, timeout: float = 60) -> int:
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        if _lines(manifest) >= n:
            return _lines(manifest)
        time.sleep(0.02)
    raise AssertionError(f"the run ended (or hung) before {n} files were done: {proc.communicate()}")


@needs_shared
def test_a_killed_run_restarted_finishes_with_nothing_lost_or_duplicated(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    for k in range(4):
        for name in GOOD:
            shutil.copy(SHARED / name, src / f"{k}_{name}")
    (src / "broken.svg").write_text("<svg><path d='M 0 0 L 1")
    out = tmp_path / "out"
    args = [src, "-o", out, "--edge-length", "2cm"]
    manifest = out / MANIFEST
    one, two = ["--workers", "1"], ["--workers", "2"]      # the killed runs on one worker: less start-up

    # SIGKILL to the whole process group (the command, the nannies, the workers)
    proc = _cli(args + one + ["-q"], start_new_session=True)
    n1 = _wait_for_lines(proc, manifest, 2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    # SIGTERM to the command: it stops like Ctrl-C (exit 130), closing its cluster
    proc = _cli(args + one)
    n2 = _wait_for_lines(proc, manifest, n1 + 2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "clothgrid: interrupted" in err
    done = read_manifest(manifest)
    assert len({e["stem"] for e in done}) < 13, "the runs were not stopped in the middle"
    for e in done:   # every line written is whole and its outputs are there
        assert all((out / o).is_file() for o in e["outputs"])

    proc = _cli(args + two + ["-q"])
    stdout, err = proc.communicate(timeout=120)
    assert proc.returncode == 4, err
    errors = [x for x in err.splitlines() if x.startswith("clothgrid: error:")]
    assert len(errors) == 1 and f"{src / 'broken.svg'}: " in errors[0]
    assert f"13 files: 12 ok, 0 partial, 1 failed ({len({e['stem'] for e in done})} done before" in stdout
    entries = read_manifest(manifest)
    assert len(entries) == 13 and len({e["stem"] for e in entries}) == 13
    assert sum(len(e["pieces"]) for e in entries) == 4 * sum(GOOD.values())
    _check_outputs(out, entries)
    # and a fourth run does nothing
    proc = _cli(args + ["-q"])
    stdout, _ = proc.communicate(timeout=60)
    assert proc.returncode == 4 and "(13 done before, 0 gridded now)" in stdout


# --------------------------------------------------------------------------- without a cluster


def test_local_workers_follow_the_cores_and_a_containers_cpu_limit(monkeypatch):
    """A local cluster's workers: the cores this process may use, at most a cgroup's CPU quota rounded
    up (a 2-CPU pod on a many-core node starts 2 workers, not one per core of the node, and their
    memory); each worker's Numba threads share the cores left (one worker, every core)."""
    import clothgrid.cgroups as startup
    from clothgrid.batch import default_workers, worker_threads

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    monkeypatch.setattr(startup, "cpu_quota", lambda: None)
    assert default_workers() == 16 and worker_threads(16) == 1 and worker_threads(4) == 4
    assert worker_threads(1) == 16 and worker_threads(5) == 3 and worker_threads(40) == 1
    monkeypatch.setattr(startup, "cpu_quota", lambda: 2.0)
    assert default_workers() == 2 and worker_threads(2) == 1 and worker_threads(1) == 2
    monkeypatch.setattr(startup, "cpu_quota", lambda: 0.5)
    assert default_workers() == 1 and worker_threads(1) == 1
    monkeypatch.setattr(startup, "cpu_quota", lambda: 64.0)
    assert default_workers() == 16


def test_find_inputs(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / ".hidden").mkdir()
    for rel in ("a/x.svg", "a/y.JSON", "a/z.txt", "a/.hidden/h.svg", "b.dxf"):
        (tmp_path / rel).write_text("")
    got = B.find_inputs([tmp_path / "a", str(tmp_path / "*.dxf"), tmp_path / "a" / "x.svg"])
    assert got == sorted([(tmp_path / p).resolve() for p in ("a/x.svg", "a/y.JSON", "b.dxf")])
    assert B.find_inputs([str(tmp_path / "**" / "*.svg")]) == [(tmp_path / "a" / "x.svg").resolve()]
    for bad, words in (("nope.svg", "no such file or folder"), ("*.nope", "no file matches")):
        with pytest.raises(InputError, match=words):
            B.find_inputs([str(tmp_path / bad)])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no pattern file"):
        B.find_inputs([tmp_path / "empty"])


def test_stems_are_safe_unique_and_do_not_depend_on_order(tmp_path):
    paths = [tmp_path / "a" / "front.svg", tmp_path / "b" / "Front.dxf", tmp_path / "back piece.json",
             tmp_path / "manifest.json"]
    stems = B.assign_stems(paths)
    assert stems[2] == "back_piece" and len(set(s.lower() for s in stems)) == 4
    assert stems[0].startswith("front-") and stems[1].startswith("Front-") and stems[3].startswith("manifest-")
    assert B.assign_stems(paths[::-1]) == stems[::-1]


def test_the_key_follows_content_and_options_not_their_spelling():
    k = B._normalised
    from clothgrid.pipeline import OutputOptions

    same = [k(GridOptions(edge_length=h), OutputOptions(), ["{piece}.npz"], None, None, None)
            for h in ("2cm", "20mm", "20 mm")]
    assert len({options_key("abc", o) for o in same}) == 1
    assert options_key("abc", same[0]) != options_key("abd", same[0])
    other = k(GridOptions(edge_length="2cm", weights="paper"), OutputOptions(), ["{piece}.npz"], None, None, None)
    assert options_key("abc", other) != options_key("abc", same[0])
    nodes = [k(GridOptions(nodes=n), OutputOptions(), ["{piece}.npz"], None, None, None) for n in (65, "65x65")]
    assert options_key("abc", nodes[0]) == options_key("abc", nodes[1])


def test_manifest_survives_a_torn_line_and_knows_what_is_done(tmp_path):
    path = tmp_path / MANIFEST
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "p.npz").write_bytes(b"x")
    with ManifestWriter(path) as w:
        w.append({"stem": "a", "key": "k1", "status": "failed", "retry": True, "outputs": []})
        w.append({"stem": "a", "key": "k1", "status": "ok", "outputs": ["a/p.npz"]})
    with open(path, "a") as fh:
        fh.write('{"stem": "b", "key": "k2", "sta')           # killed while appending
    entries = read_manifest(path)
    assert [e["stem"] for e in entries] == ["a", "a"]
    with ManifestWriter(path) as w:                            # the torn line is cut off first
        w.append({"stem": "b", "key": "k2", "status": "failed", "retry": False, "outputs": []})
    assert [json.loads(x)["stem"] for x in path.read_text().splitlines()] == ["a", "a", "b"]
    kept = compact_manifest(path, {"inputs": 2})
    assert [(e["stem"], e["status"]) for e in kept] == [("a", "ok"), ("b", "failed")]
    assert json.loads(path.read_text().splitlines()[-1]) == {"summary": {"inputs": 2}}
    a, b = kept
    assert is_done(a, "k1", tmp_path) and not is_done(a, "k0", tmp_path)
    assert is_done(b, "k2", tmp_path) and not is_done(b, "k2", tmp_path, redo_failed=True)
    assert not is_done({**b, "retry": True}, "k2", tmp_path)
    (tmp_path / "a" / "p.npz").unlink()
    assert not is_done(a, "k1", tmp_path)                      # an output gone: redone


def test_progress_line_on_a_terminal_and_in_logs():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty, log = Tty(), io.StringIO()
    bar, plain = B.ProgressLine(tty), B.ProgressLine(log, every=2)
    p = B.BatchProgress(total=4, started=time.perf_counter() - 2)
    for k in range(1, 5):
        p.done, p.pieces, p.failed_files = k, 3 * k, k // 3
        bar(p)
        plain(p)
    assert tty.getvalue().count("\r") == 4 and tty.getvalue().endswith("\n")
    assert "[" + "#" * 24 + "]" in tty.getvalue() and "failed 1 files" in tty.getvalue()
    lines = log.getvalue().splitlines()
    assert [x.split(",")[0] for x in lines] == ["clothgrid: 2/4 files", "clothgrid: 4/4 files"]
    assert "\r" not in log.getvalue() and "pieces/s" in lines[0] and "left" in lines[0]
    quiet = io.StringIO()
    B.ProgressLine(quiet, every=0)(B.BatchProgress(total=4, done=1))
    assert quiet.getvalue() == ""


@pytest.mark.parametrize("args, words", [
    (["{x}", "-o", "{out}"], "no such file or folder"),
    (["{src}", "-o", "{out}", "-t", "{{piece}}.xyz"], "unknown output format"),
    (["{src}", "-o", "{out}", "-t", "grid.npz"], "put {piece} in the name"),
    (["{src}", "-o", "{out}", "-t", "../{{piece}}.npz"], "inside the input's folder"),
    (["{src}", "-o", "{src}/f.svg"], "is not a folder"),
    (["{src}", "-o", "{out}", "--workers", "2", "--scheduler", "tcp://x:1"], "not allowed with"),
    (["{src}", "-o", "{out}", "--nodes", "9", "--edge-length", "2cm"], "not both"),
])
def test_bad_input_or_options_exit_2_with_one_error_line(tmp_path, capsys, args, words):
    src = tmp_path / "in"
    src.mkdir()
    (src / "f.svg").write_text("<svg/>")
    code = main(["batch", *[a.format(x=tmp_path / "x", out=tmp_path / "out", src=src) for a in args]])
    err = capsys.readouterr().err
    assert code == 2
    assert [x for x in err.splitlines() if x.startswith("clothgrid: error:")] == \
        [next(x for x in err.splitlines() if x.startswith("clothgrid: error:"))]
    assert words in err


def test_every_file_bad_exits_2_without_starting_a_cluster(tmp_path, capsys, monkeypatch):
    src = tmp_path / "in"
    src.mkdir()
    (src / "a.json").write_text("{")
    out = tmp_path / "out"
    # a first run would need a cluster; a manifest saying the file is bad does not
    from clothgrid.batch_manifest import file_sha256

    key = options_key(file_sha256(src / "a.json"), B._normalised(GridOptions(), B.OutputOptions(),
                                                                  (B.DEFAULT_TEMPLATE,), None, None, None))
    out.mkdir()
    with ManifestWriter(out / MANIFEST) as w:
        w.append({"input": str(src / "a.json"), "stem": "a", "key": key, "status": "failed", "retry": False,
                  "error": f"{src / 'a.json'}: invalid JSON", "pieces": [], "failed_pieces": [], "outputs": []})
    monkeypatch.setattr(B, "_client_for", lambda *a: pytest.fail("a cluster was started"))
    assert main(["batch", str(src), "-o", str(out), "-q"]) == 2
    cap = capsys.readouterr()
    assert cap.err.splitlines() == [f"clothgrid: error: {src / 'a.json'}: invalid JSON"]
    assert "1 files: 0 ok, 0 partial, 1 failed (1 done before, 0 gridded now)" in cap.out


@needs_shared
def test_garment_mode_sews_each_spec_and_resumes(tmp_path, client):
    src = tmp_path / "specs"
    src.mkdir()
    for name in ("gpg_skirt_4_panels_specification.json", "gcn_rand_KEJUMAMSBX_specification.json"):
        shutil.copy(SHARED / name, src / name)
    (src / "broken_specification.json").write_text('{"pattern": {"panels": ')
    out = tmp_path / "out"
    opts = GridOptions(edge_length="3cm")
    run = B.batch([src], out, options=opts, client=client, garment=True, seams="weld",
                  templates=("garment.npz", "garment.obj"))
    by = {e["stem"]: e for e in run.entries}
    assert by["broken_specification"]["status"] == "failed" and by["broken_specification"]["error"]
    for stem in ("gpg_skirt_4_panels_specification", "gcn_rand_KEJUMAMSBX_specification"):
        e = by[stem]
        assert e["status"] == "ok" and e["outputs"] == [f"{stem}/garment.npz", f"{stem}/garment.obj"]
        with np.load(out / stem / "garment.npz") as z:
            assert len(z["panel_names"]) == e["garment"]["panels"] == len(e["pieces"])
            assert z["stitches"].shape[0] == e["garment"]["stitched_node_pairs"] > 0
            assert "weld_map" in z.files
        assert all(p["folded"] == 0 for p in e["pieces"])
    again = B.batch([src], out, options=opts, client=client, garment=True, seams="weld",
                    templates=("garment.npz", "garment.obj"))
    assert again.done_now == []                                  # nothing to redo
    keep = B.batch([src], out, options=opts, client=client, garment=True, seams="keep",
                   templates=("garment.npz", "garment.obj"), force=False)
    assert {e["stem"] for e in keep.done_now} == set(by)       # other options: every input again
    with pytest.raises(InputError, match="garment is written as"):
        B.batch([src], out, options=opts, client=client, garment=True, templates=("{piece}.ply",))


def test_a_file_whose_pieces_suggest_other_units_has_warnings_in_its_manifest_line(tmp_path):
    """grid_file (what a worker runs) copies read_jobs' warnings into the file's line: a 40 mm
    piece read in the file's own units is gridded and named as such; with --units, no warning."""
    from clothgrid.pipeline import OutputOptions

    src = tmp_path / "tiny.svg"
    src.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="80mm" height="80mm" viewBox="0 0 80 80">'
                   '<rect id="patch" x="5" y="5" width="40" height="24"/></svg>')
    for units, warned in ((None, True), ("mm", False)):
        out = tmp_path / f"out{units}"
        task = B.FileTask(str(src), "tiny", str(out), ("{piece}.npz",), OPTS, OutputOptions(), units)
        entry = B.grid_file(task)
        assert entry["status"] == "ok" and entry["outputs"] == ["tiny/patch.npz"], entry
        assert ("warnings" in entry) == warned
        if warned:
            assert "40 mm across" in entry["warnings"][0] and "--units" in entry["warnings"][0]


def test_unfold_in_a_batch_grids_the_whole_pieces_and_keys_the_option(tmp_path):
    """``batch --unfold``: grid_file (what a worker runs) grids the pieces cut on the fold whole
    (FreeSewing's Aaron: both halves, about twice as many nodes across), and the option is part of
    the resume key (a run without it is not taken for one with it); without it the key is as before."""
    from clothgrid.pipeline import OutputOptions

    src = Path(__file__).parent / "data" / "freesewing" / "aaron_v3_pattern.svg"
    nodes = {}
    for unfold in (False, True):
        out = tmp_path / f"out{unfold}"
        task = B.FileTask(str(src), "aaron", str(out), ("{piece}.npz",), OPTS, OutputOptions(), unfold=unfold)
        entry = B.grid_file(task)
        assert entry["status"] == "ok" and sorted(entry["outputs"]) == ["aaron/back.npz", "aaron/front.npz"]
        nodes[unfold] = {p["name"]: p["nodes"] for p in entry["pieces"]}
        assert all(p["folded"] == 0 for p in entry["pieces"])
    for name in ("front", "back"):
        assert max(nodes[True][name]) * min(nodes[True][name]) > 1.6 * max(nodes[False][name]) * min(nodes[False][name])
    k = B._normalised
    plain = k(OPTS, OutputOptions(), ["{piece}.npz"], None, None, None)
    assert "unfold" not in plain
    assert options_key("abc", k(OPTS, OutputOptions(), ["{piece}.npz"], None, None, None, unfold=True)) != \
        options_key("abc", plain)


def test_grade_in_a_batch_grids_one_size(tmp_path):
    """``batch --grade SIZE``: a worker grids only that size of a graded pattern (Optitex's Basic Tee,
    4 pieces of 32); a file without that size is a bad file, with the reason; the size is part of
    the resume key, spelled any case."""
    from clothgrid.pipeline import OutputOptions

    src = Path(__file__).parent / "data" / "optitex" / "basic_tee_graded.dxf"
    task = B.FileTask(str(src), "tee", str(tmp_path / "out"), ("{piece}.npz",), OPTS, OutputOptions(), "cm",
                      grade="medium")
    entry = B.grid_file(task)
    assert entry["status"] == "ok", entry
    assert sorted(p["name"] for p in entry["pieces"]) == sorted(
        f"{n}_Medium" for n in ("Front", "Back", "Right Sleeve", "Neck Binding"))
    bad = B.grid_file(B.FileTask(str(src), "tee", str(tmp_path / "out2"), ("{piece}.npz",), OPTS, OutputOptions(),
                                 "cm", grade="XXXL"))
    assert bad["status"] == "failed" and "no piece of that size" in bad["error"]
    k = B._normalised
    keys = {options_key("abc", k(OPTS, OutputOptions(), ["{piece}.npz"], None, None, None, grade=g))
            for g in ("M", " m")}
    assert len(keys) == 1
    assert options_key("abc", k(OPTS, OutputOptions(), ["{piece}.npz"], None, None, None)) not in keys
