"""The installed package: the compiled module's type stubs (_core.pyi, made by nanobind's
stubgen at build time) and the py.typed marker sit beside it (PEP 561), so that type checkers
and editors see crushdem._core's signatures."""

import ast
import importlib.util
import os

import pytest

pytest.importorskip("crushdem._core")


def _package_dir():
    spec = importlib.util.find_spec("crushdem._core")
    return os.path.dirname(os.path.abspath(spec.origin))


def test_core_stubs_and_py_typed_are_installed():
    where = _package_dir()
    assert os.path.isfile(os.path.join(where, "py.typed")), where
    stub = os.path.join(where, "_core.pyi")
    assert os.path.isfile(stub), where
    with open(stub) as f:
        tree = ast.parse(f.read(), stub)
    names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    import crushdem._core as core

    public = {n for n in dir(core) if not n.startswith("_") and callable(getattr(core, n))}
    assert {"Simulation", "set_threads", "resume"} <= names
    # Interrupted is made with PyErr_NewException("crushdem._core.Interrupted"): stubgen, which
    # imports the module as `_core` at build time, takes it for a name from another module.
    assert public - {"Interrupted"} <= names, sorted(public - names)
