"""Lighter imports for the command line: what a dependency imports at start-up and clothgrid never uses.

- :func:`preload_cython_blas`: Numba's BLAS check without SciPy's whole ``linalg`` package (0.1 s
  off every command that runs a kernel).
- :func:`svgpathtools_without_quad`: svgpathtools without ``scipy.integrate`` (0.4 s off every
  command that reads an SVG file).

**Numba's BLAS check.** The first Numba kernel a process runs (compiled or loaded from the disk
cache) makes Numba load its implementation registries, and one of them (``numba.np.arraymath``)
checks that a BLAS is there with ``import scipy.linalg.cython_blas``. That statement imports the
package ``scipy.linalg`` first, which imports most of SciPy's linear algebra: 0.11 s of a 0.75 s
``clothgrid generate`` at 1024^2, measured, while no clothgrid kernel calls BLAS.
:func:`preload_cython_blas` loads the extension module ``scipy.linalg.cython_blas`` itself (the
real one, from SciPy's own file, 2 ms) under its own name, without running the package's
``__init__``; Numba's import then finds it in ``sys.modules``. Should anything import
``scipy.linalg`` later, the package is imported as usual and gets the module as its attribute
(a finder on ``sys.meta_path`` that stands aside after that one import).

**svgpathtools.** ``svgpathtools.path`` tries ``from scipy.integrate import quad`` at import (for
arc lengths by quadrature, ``Path.length``; without SciPy it falls back to subdivision), and
``scipy.integrate`` imports ``scipy.special`` and more: 0.39 s, a fifth of gridding a real SVG
pattern file. clothgrid only parses paths with svgpathtools and samples the segments itself
(:mod:`clothgrid.patterns.sampling`): it never asks svgpathtools for a length.
:func:`svgpathtools_without_quad` makes that one import fail while ``svgpathtools.path`` runs
(``None`` in ``sys.modules``, which its ``try`` catches), and only then; ``scipy.integrate``
imports as usual before and after.

Both are used by the command line only (:func:`clothgrid.cli.main`): a program that imports
clothgrid as a library keeps its import system as it is. Every step is optional: if anything
differs from what it expects (the module already imported, no such file, another layout), it does
nothing and the import happens as before.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
from types import ModuleType
from typing import Callable

__all__ = ["preload_cython_blas", "svgpathtools_without_quad", "after_import"]

_PACKAGE = "scipy.linalg"
_MODULE = "scipy.linalg.cython_blas"


def preload_cython_blas() -> bool:
    """Load ``scipy.linalg.cython_blas`` without its package, if that has not been imported.

    Returns
    -------
    bool
        True if the module was loaded here, False if nothing was done (already imported, or
        not found where SciPy keeps it).
    """
    if _PACKAGE in sys.modules or _MODULE in sys.modules:
        return False
    try:
        import scipy
    except ImportError:
        return False
    try:
        where = os.path.join(os.path.dirname(scipy.__file__), "linalg")
        found = importlib.machinery.PathFinder.find_spec("cython_blas", [where])
        if found is None or not isinstance(found.loader, importlib.machinery.ExtensionFileLoader):
            return False
        spec = importlib.util.spec_from_file_location(_MODULE, found.origin)
        if spec is None or spec.loader is None:
            return False
        module = importlib.util.module_from_spec(spec)
        sys.modules[_MODULE] = module
        spec.loader.exec_module(module)
    except Exception:     # any surprise: leave the import to Numba, as without this module
        sys.modules.pop(_MODULE, None)
        return False
    sys.meta_path.insert(0, _WrapOnce(_PACKAGE, lambda loader: _Attaching(loader, module)))
    return True


class _WrapOnce(importlib.abc.MetaPathFinder):
    """Find module ``name`` the usual way, the next time it is imported, and give it the loader
    ``wrap(loader)``; then stand aside."""

    def __init__(self, name: str, wrap):  # type: ignore[no-untyped-def]
        self.name = name
        self.wrap = wrap

    def find_spec(self, name, path, target=None):  # type: ignore[no-untyped-def]
        if name != self.name:
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None or spec.loader is None:
            return spec
        spec.loader = self.wrap(spec.loader)
        return spec


class _Wrapping(importlib.abc.Loader):
    """A loader around ``loader``: the module is made and run by it (:meth:`_run`), which then
    stays the module's loader."""

    def __init__(self, loader: importlib.abc.Loader):
        self.loader = loader

    def create_module(self, spec):  # type: ignore[no-untyped-def]
        return self.loader.create_module(spec)

    def _run(self, module: ModuleType) -> None:
        try:
            self.loader.exec_module(module)
        finally:
            module.__loader__ = self.loader
            if module.__spec__ is not None:
                module.__spec__.loader = self.loader


class _Attaching(_Wrapping):
    """Sets ``module.cython_blas`` on the new package and then runs it."""

    def __init__(self, loader: importlib.abc.Loader, child: ModuleType):
        super().__init__(loader)
        self.child = child

    def exec_module(self, module: ModuleType) -> None:
        module.cython_blas = self.child     # before the package's own code, which may import it
        self._run(module)


_SVG_PATH = "svgpathtools.path"
_INTEGRATE = "scipy.integrate"


def svgpathtools_without_quad() -> bool:
    """Have ``svgpathtools.path``, when it is first imported, skip its ``scipy.integrate`` import.

    Returns
    -------
    bool
        True if the hook was installed, False if nothing was done (svgpathtools or
        ``scipy.integrate`` imported already, or the hook is in place).
    """
    if (_SVG_PATH in sys.modules or _INTEGRATE in sys.modules
            or any(isinstance(f, _WrapOnce) and f.name == _SVG_PATH for f in sys.meta_path)):
        return False
    sys.meta_path.insert(0, _WrapOnce(_SVG_PATH, _Blocking))
    return True


class _Blocking(_Wrapping):
    """Runs the module with ``scipy.integrate`` marked unimportable (if it is not imported)."""

    def exec_module(self, module: ModuleType) -> None:
        block = _INTEGRATE not in sys.modules
        if block:
            sys.modules[_INTEGRATE] = None      # type: ignore[assignment]  # "import halted": ImportError
        try:
            self._run(module)
        finally:
            if block and sys.modules.get(_INTEGRATE, 0) is None:
                del sys.modules[_INTEGRATE]


def after_import(name: str, then: Callable[[ModuleType], None]) -> bool:
    """Call ``then(module)`` once module ``name`` has been imported: now if it is, else right after
    its first import (a finder on ``sys.meta_path`` that stands aside after it), without importing
    it here. An exception in ``then`` is swallowed: the import itself goes on as usual.

    Returns
    -------
    bool
        True if ``then`` ran now or will run, False if the hook could not be placed (one for
        ``name`` is in place already).
    """
    if name in sys.modules:
        _quietly(then, sys.modules[name])
        return True
    if any(isinstance(f, _WrapOnce) and f.name == name for f in sys.meta_path):
        return False
    sys.meta_path.insert(0, _WrapOnce(name, lambda loader: _Then(loader, then)))
    return True


def _quietly(then: Callable[[ModuleType], None], module: ModuleType) -> None:
    try:
        then(module)
    except Exception:         # a hook's failure must not fail the import it follows
        pass


class _Then(_Wrapping):
    """Runs the module, then ``then(module)``."""

    def __init__(self, loader: importlib.abc.Loader, then: Callable[[ModuleType], None]):
        super().__init__(loader)
        self.then = then

    def exec_module(self, module: ModuleType) -> None:
        self._run(module)
        _quietly(self.then, module)
