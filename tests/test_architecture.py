"""The layout: backends satisfy the protocol, and imports run one way.

- every registered backend module supplies every name of
  :class:`clothgrid.backends.protocol.Backend` (the module-level attributes
  exist without a device: gl and cuda are checked on every machine, their
  device-bound answers where the device is there);
- the multigrid operations classes of cpu, gl and cuda define every
  :class:`~clothgrid.backends.protocol.MultigridOps` operation, and the Jacobi
  sweepers every :class:`~clothgrid.backends.protocol.JacobiSweeper` one, with
  the protocol's parameters (classes, not instances: no GPU needed);
- the registry loads backends on demand: ``import clothgrid`` imports neither
  moderngl nor CuPy nor numba.cuda;
- the import graph of ``src/clothgrid`` (lazy imports inside functions and
  ``TYPE_CHECKING`` imports included) has no circle through the multigrid
  hierarchy, the backends or the solvers; the hierarchy imports neither, and
  the backends never import the solvers.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import clothgrid
from clothgrid.backends import BACKENDS, REGISTRY, get_backend, load_backend
from clothgrid.backends.protocol import (BACKEND_MEMBERS, HEAT_OPERATIONS, JACOBI_OPERATIONS, MULTIGRID_OPERATIONS,
                                         Backend, HeatOps, JacobiSweeper, MultigridOps)
from clothgrid.errors import InputError
from clothgrid.solvers import SOLVERS

SRC = Path(clothgrid.__file__).parent
DATA_MEMBERS = {"name", "solvers"}


# --- the backend protocol --------------------------------------------------------------------------------

def test_the_protocol_names_what_the_solvers_use():
    assert {"name", "solvers", "require", "available", "describe", "summary", "check_size", "device_bytes",
            "array_module", "residual", "max_step", "multigrid", "jacobi_sweeper", "heat_ops"} == set(BACKEND_MEMBERS)
    assert {"smooth", "restrict", "prolong", "restrict_full", "prolong_full", "max_step", "band_steps", "residual_solve",
            "relative_residual", "solution",
            "solution_into", "solution_max", "vector", "residual", "apply", "dot", "axpy", "xpay", "bind", "synchronize",
            "spare", "extra"} == set(MULTIGRID_OPERATIONS)
    assert {"sweeps", "result", "extra", "close"} == set(JACOBI_OPERATIONS)
    assert {"vector", "upload", "download", "copy", "dot", "apply", "residual", "axpy", "xpay", "bind", "smooth",
            "restrict", "coarse_solve", "prolong", "extra", "release"} == set(HEAT_OPERATIONS)


def test_the_registry():
    assert BACKENDS == ("auto", "cpu", "gl", "cuda") and set(REGISTRY) == {"cpu", "gl", "cuda"}
    for name in REGISTRY:
        assert load_backend(name).name == name
    for bad in ("nope", "auto"):
        with pytest.raises(InputError, match="unknown backend"):
            load_backend(bad)
    with pytest.raises(InputError, match="unknown backend 'nope': use one of auto, cpu, gl, cuda"):
        get_backend("nope")
    assert get_backend("cpu") is load_backend("cpu") is get_backend("auto")   # no GPU here (conftest)


@pytest.mark.parametrize("name", list(REGISTRY))
def test_every_backend_module_supplies_every_name(name):
    """Present and callable; the module-level attributes exist whether or not the device does."""
    be = load_backend(name)
    missing = [m for m in BACKEND_MEMBERS if not hasattr(be, m)]
    assert not missing, f"backend {name!r} lacks {missing}"
    for m in BACKEND_MEMBERS:
        if m not in DATA_MEMBERS:
            assert callable(getattr(be, m)), f"{name}.{m} is not callable"
    assert be.name == name
    assert isinstance(be.solvers, tuple) and set(be.solvers) <= set(SOLVERS)
    assert isinstance(be, Backend)
    for m in BACKEND_MEMBERS:   # the protocol's parameters, by name and in order
        if m not in DATA_MEMBERS:
            _assert_accepts(getattr(be, m), getattr(Backend, m), f"{name}.{m}", bound=False)


def test_the_cpu_backend_answers_without_a_device(rng):
    cpu = load_backend("cpu")
    assert cpu.solvers == () and cpu.require() is None and cpu.available()[0] is True
    assert cpu.describe() == {} and isinstance(cpu.summary(), str)
    assert cpu.device_bytes("multigrid", 100, 100) == 0 and cpu.check_size(100, 100, "multigrid", 10**12) == 0
    assert cpu.array_module() is np


@pytest.mark.parametrize("name", ["gl", "cuda"])
def test_device_backends_answer_where_the_device_is(name):
    be = load_backend(name)
    ok, why = be.available()
    assert isinstance(ok, bool) and isinstance(why, str) and why
    assert be.solvers and be.device_bytes(be.solvers[0], 64, 64) > 0
    if not ok:
        pytest.skip(f"backend {name!r}: {why}")
    assert be.require() is not None
    info = be.describe()
    assert info and all(k.startswith(name + "_") for k in info)
    assert isinstance(be.summary(), str) and be.check_size(64, 64, be.solvers[0]) > 0


def test_jacobi_where_it_does_not_run():
    with pytest.raises(InputError, match="solver 'jacobi' does not run on backend 'cuda'"):
        load_backend("cuda").jacobi_sweeper(None)


# --- the operations classes ------------------------------------------------------------------------------

def _ops_class(module: str, cls: str) -> type:
    if ".cuda." in module and importlib.util.find_spec("numba.cuda") is None:
        pytest.skip("numba.cuda is not installed")
    return getattr(importlib.import_module(module), cls)


@pytest.mark.parametrize("module, cls", [("clothgrid.backends._cpu_multigrid", "CpuMultigrid"),
                                         ("clothgrid.backends.gl._multigrid", "GLMultigrid"),
                                         ("clothgrid.backends.cuda._multigrid", "CudaMultigrid")])
def test_multigrid_ops_classes_define_every_operation(module, cls):
    ops = _ops_class(module, cls)
    missing = [m for m in MULTIGRID_OPERATIONS if not callable(getattr(ops, m, None))]
    assert not missing, f"{cls} lacks {missing}"
    for m in MULTIGRID_OPERATIONS:
        _assert_accepts(getattr(ops, m), getattr(MultigridOps, m), f"{cls}.{m}", bound=True)
    assert list(inspect.signature(ops).parameters)[:3] == ["levels", "x0", "rhs"]


@pytest.mark.parametrize("module, cls", [("clothgrid.backends._cpu_heat", "CpuHeatOps"),
                                         ("clothgrid.backends.gl._heat", "GLHeatOps"),
                                         ("clothgrid.backends.cuda._heat", "CudaHeatOps")])
def test_heat_ops_classes_define_every_operation(module, cls):
    """The heat solver's operations (clothgrid.heat_multigrid drives them on every backend)."""
    ops = _ops_class(module, cls)
    missing = [m for m in HEAT_OPERATIONS if not callable(getattr(ops, m, None))]
    assert not missing, f"{cls} lacks {missing}"
    for m in HEAT_OPERATIONS:
        _assert_accepts(getattr(ops, m), getattr(HeatOps, m), f"{cls}.{m}", bound=True)
    assert isinstance(ops.precise, bool)
    assert list(inspect.signature(ops).parameters)[:1] == ["hierarchy"]


@pytest.mark.parametrize("module, cls", [("clothgrid.backends.cpu", "HostJacobi"),
                                         ("clothgrid.backends.gl._jacobi", "GLJacobi")])
def test_jacobi_sweeper_classes_define_every_operation(module, cls):
    sweeper = _ops_class(module, cls)
    for m in JACOBI_OPERATIONS:
        assert callable(getattr(sweeper, m, None)), f"{cls} lacks {m}"
        _assert_accepts(getattr(sweeper, m), getattr(JacobiSweeper, m), f"{cls}.{m}", bound=True)


def test_cpu_instances_satisfy_the_protocols(rng):
    """The runtime-checkable protocols accept real objects (the cpu backend's, no device)."""
    from clothgrid.multigrid_levels import build_hierarchy
    from clothgrid.solvers import Problem
    from clothgrid.weights import make_weights

    cpu = load_backend("cpu")
    w = make_weights("paper", 9, 7)
    ops = cpu.multigrid(build_hierarchy(w), rng.standard_normal((9, 7, 3)))
    assert isinstance(ops, MultigridOps) and ops.extra() == {} and ops.synchronize() is None
    sweeper = cpu.jacobi_sweeper(Problem(rng.standard_normal((9, 7, 3)), w, 1.0))
    assert isinstance(sweeper, JacobiSweeper) and sweeper.extra() == {}
    from clothgrid.heat_multigrid import HeatHierarchy, Stencil5

    heat = cpu.heat_ops(HeatHierarchy(Stencil5.from_weights(np.ones((10, 9)), np.ones((11, 8)))))
    assert isinstance(heat, HeatOps) and heat.extra() == {} and heat.release() is None


def _assert_accepts(impl, proto, what: str, bound: bool) -> None:
    """``impl`` takes the protocol method's parameters, by name, in order (more optional ones allowed)."""
    want = list(inspect.signature(proto).parameters.values())[1:]   # without self
    have = list(inspect.signature(impl).parameters.values())
    if bound:
        have = have[1:]
    for w, h in zip(want, have):
        assert h.name == w.name, f"{what}: parameter {h.name!r} where the protocol has {w.name!r}"
        assert (h.default is inspect.Parameter.empty) == (w.default is inspect.Parameter.empty) or \
            h.default is not inspect.Parameter.empty, f"{what}: {h.name!r} must be optional"
    assert len(have) >= len(want), f"{what}: takes {[p.name for p in have]}, not {[p.name for p in want]}"
    assert all(p.default is not inspect.Parameter.empty or p.kind is p.VAR_KEYWORD or p.kind is p.VAR_POSITIONAL
               for p in have[len(want):]), f"{what}: extra parameters must be optional"


# --- imports -----------------------------------------------------------------------------------------------

def test_importing_clothgrid_loads_no_device_library():
    code = ("import sys, clothgrid, clothgrid.backends, clothgrid.solvers\n"
            "clothgrid.backends.get_backend('cpu')\n"
            "bad = [m for m in ('moderngl', 'cupy', 'numba.cuda', 'numba') if m in sys.modules]\n"
            "assert not bad, bad\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """``module -> modules of clothgrid it imports``, every import statement (in functions, under
    ``TYPE_CHECKING``) counted; ``from package import name`` counts the submodule where ``name`` is one."""
    files = {_module_name(p): p for p in SRC.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        out = graph.setdefault(mod, set())
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = package
                for _ in range(node.level - 1):
                    base = base.rpartition(".")[0]
                base = ".".join(filter(None, [base if node.level else "", node.module or ""]))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names]
            else:
                continue
            out.update(t for t in targets if t in files and t != mod)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in graph:
        if v not in index:
            visit(v)
    return out


LAYERED = ("clothgrid.backends", "clothgrid.solvers", "clothgrid.multigrid_levels", "clothgrid._galerkin")


def _under(mod: str, *prefixes: str) -> bool:
    return any(mod == p or mod.startswith(p + ".") for p in prefixes)


def test_the_graph_sees_the_lazy_imports():
    g = import_graph()
    assert "clothgrid._galerkin" in g["clothgrid.multigrid_levels"]            # inside coarsen()
    assert "clothgrid.backends._cpu_multigrid" in g["clothgrid.backends.cpu"]  # inside multigrid()


def test_the_circle_search_finds_planted_circles():
    graph = {"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"e"}, "e": {"c"}, "f": {"a"}}
    assert sorted(sorted(c) for c in _cycles(graph)) == [["a", "b"], ["c", "d", "e"]]


def test_no_import_circle_in_src():
    """Issue 14's check: imports run one way through the whole package, lazy imports included."""
    graph = import_graph()
    assert len(graph) > 30 and any(graph.values())   # the package was read
    bad = [sorted(c) for c in _cycles(graph)]
    assert not bad, "import circles: " + "; ".join(" <-> ".join(c) for c in bad)


def test_the_stages_are_layered():
    """The input stage does not reach up into grids or solvers; the command line is on top."""
    g = import_graph()
    for mod, targets in g.items():
        if _under(mod, "clothgrid.patterns"):
            up = sorted(t for t in targets if _under(t, "clothgrid.readers", "clothgrid.generate", "clothgrid.pipeline",
                                                     "clothgrid.cli", "clothgrid.solvers", "clothgrid.backends"))
            assert not up, f"{mod} imports {up}"
        if mod != "clothgrid.__main__":
            assert "clothgrid.cli" not in targets, f"{mod} imports the command line"
    assert not any(_under(t, "clothgrid.grid", "clothgrid.writers") for t in g["clothgrid.cloth"])
    assert "clothgrid.grid" not in g["clothgrid.writers"]


def test_imports_run_one_way():
    """hierarchy and its kernel: below both; backends: below the solvers (they import the hierarchy)."""
    g = import_graph()
    for low in ("clothgrid.multigrid_levels", "clothgrid._galerkin", "clothgrid.heat_multigrid",
                "clothgrid._heat_kernels"):
        up = sorted(t for t in g[low] if _under(t, "clothgrid.backends", "clothgrid.solvers"))
        assert not up, f"{low} imports {up}"
    assert g["clothgrid._galerkin"] == {"clothgrid.jit_variants"}     # the low level's fork_safe only
    for mod, targets in g.items():
        if _under(mod, "clothgrid.backends"):
            up = sorted(t for t in targets if _under(t, "clothgrid.solvers"))
            assert not up, f"{mod} imports {up}"


def test_the_package_says_it_is_typed():
    """PEP 561: the py.typed marker ships in the package (and is listed as package data), so type
    checkers read the public API's annotations."""
    import importlib.resources

    import clothgrid

    assert importlib.resources.files(clothgrid).joinpath("py.typed").is_file()
    root = Path(clothgrid.__file__).resolve().parents[2]
    if (root / "pyproject.toml").is_file():            # an editable or source install
        data = (root / "pyproject.toml").read_text()
        line = data.split("[tool.setuptools.package-data]", 1)[1].strip().splitlines()[0]
        assert line.startswith("clothgrid =") and '"py.typed"' in line
