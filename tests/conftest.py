from __future__ import annotations

import os
import zlib
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

DATA = Path(__file__).parent / "data"
REGIONS = DATA / "regions"


def pytest_report_header(config):
    return f"clothgrid test seed: {SEED} (set CLOTHGRID_TEST_SEED to replay)"


# Fresh random inputs every run; the seed is printed in the header to replay a failure.
SEED = int(os.environ.get("CLOTHGRID_TEST_SEED", np.random.SeedSequence().entropy % 2**32))


@pytest.fixture
def rng(request):
    return np.random.default_rng([SEED, zlib.crc32(request.node.nodeid.encode())])


@pytest.fixture(autouse=True)
def auto_backend_is_the_cpu(request, monkeypatch):
    """``backend="auto"`` stays the CPU outside the cuda tests, even on a GPU machine (where it
    would pick the cuda backend): the other tests check the CPU's solvers and their choices."""
    if request.node.path.name not in ("test_cuda.py", "cuda_simulated.py"):
        from clothgrid.backends import cuda

        monkeypatch.setattr(cuda, "on_gpu", lambda: False)


def smooth_quad_sides(rng, nu: int, nv: int, dim: int = 2, amp: float = 0.08):
    """Four smooth random sides of a quad (bottom, right, top, left) that do not cross."""
    from clothgrid import Boundary, BoundaryError

    for _ in range(100):
        sides = _draw_quad_sides(rng, nu, nv, dim, amp)
        try:
            Boundary.from_sides(*sides)
            return sides
        except BoundaryError:
            continue
    raise RuntimeError("could not draw a valid random quad")


def _draw_quad_sides(rng, nu, nv, dim, amp):
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.1, 1.0], [-0.1, 0.9]]) + rng.normal(scale=0.05, size=(4, 2))

    def side(p, q, n):
        t = np.linspace(0.0, 1.0, n)
        pts = (1 - t)[:, None] * p + t[:, None] * q
        d = q - p
        normal = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        bump = sum(rng.normal(scale=amp / m) * np.sin(m * np.pi * t) for m in (1, 2, 3))
        return pts + bump[:, None] * normal

    sides = [side(corners[0], corners[1], nu), side(corners[1], corners[2], nv),
             side(corners[3], corners[2], nu), side(corners[0], corners[3], nv)]
    if dim == 3:
        def lift(p):
            return np.column_stack([p, 0.3 * np.sin(2.0 * p[:, 0]) * np.cos(1.5 * p[:, 1])])
        sides = [lift(s) for s in sides]
    return sides


def regions_with_corners():
    import json

    out = []
    for f in sorted(REGIONS.glob("*.json")):
        if "corners" in json.loads(f.read_text()):
            out.append(f)
    return out


def parse_obj(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, texture coordinates and 0-based faces of an OBJ whose faces are ``v/vt`` pairs."""
    v, vt, f = [], [], []
    for line in text.splitlines():
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        if parts[0] == "v":
            v.append([float(x) for x in parts[1:]])
        elif parts[0] == "vt":
            vt.append([float(x) for x in parts[1:]])
        elif parts[0] == "f":
            pairs = [tuple(int(k) for k in corner.split("/")) for corner in parts[1:]]
            assert all(a == b for a, b in pairs)
            f.append([a - 1 for a, _ in pairs])
        else:
            raise AssertionError(f"unexpected OBJ line {line!r}")
    return np.array(v), np.array(vt), np.array(f, dtype=np.int64)


def fake_cgroup(folder, files: dict[str, str], proc: str) -> tuple[str, str]:
    """A cgroup file system in a new folder under ``folder``: ``files`` (paths under ``fs/``, their
    text) and a ``/proc/self/cgroup`` of text ``proc``; returns ``(root, proc)`` paths for
    :mod:`clothgrid.cgroups`' readers."""
    root = folder / f"cgroup{len(list(folder.glob('cgroup*')))}"
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    (root / "proc").write_text(proc)
    return str(root / "fs"), str(root / "proc")


def in_forked_child(fn, timeout: float = 60.0) -> str:
    """What ``fn()`` (a string) returns in a child made by ``os.fork()``, or ``"timeout"`` if the child
    has not answered after ``timeout`` seconds (it is then killed): a test of what survives a fork
    must not hang the run when it fails."""
    import select
    import signal

    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:   # the child: answer through the pipe, never return into pytest
        code = 0
        try:
            os.close(r)
            os.write(w, str(fn()).encode())
        except BaseException as exc:   # noqa: BLE001 - reported to the parent
            os.write(w, f"{type(exc).__name__}: {exc}".encode())
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    try:
        ready, _, _ = select.select([r], [], [], timeout)
        if not ready:
            os.kill(pid, signal.SIGKILL)
            return "timeout"
        chunks = []
        while chunk := os.read(r, 1 << 16):
            chunks.append(chunk)
        return b"".join(chunks).decode()
    finally:
        os.close(r)
        os.waitpid(pid, 0)
