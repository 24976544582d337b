"""The Python package's layers (python/crushdem_sand): reading a run directory, the analysis and the
study's recipes are NumPy only, the figures draw without choosing a backend, the study's modules
depend one way, no module reaches into another's private names (a helper two modules need is
public in the layer it belongs to), no module is longer than 800 lines, and the package that
py.typed marks as typed is annotated. Source checks: they read python/crushdem_sand/**/*.py and
need neither the compiled _core nor a rebuild."""

import ast
import glob
import os
import subprocess
import sys

from _source import SOURCE_DIR

MODULES = sorted(glob.glob(os.path.join(SOURCE_DIR, "**", "*.py"), recursive=True))
# Names that start with an underscore but are public parts of the package.
PUBLIC_UNDERSCORE = {"_core", "__version__", "__commit__", "__main__"}
# ``crushdem-sand reproduce`` from the bottom up: a module imports only modules to its left.
STUDY_LAYERS = ("study", "study_analysis", "study_summary", "figures.study", "study_pipeline",
                "reproduce")
MAX_LINES = 800


def _tree(path):
    with open(path) as f:
        return ast.parse(f.read(), path)


def _module_name(path):
    """"figures.study" for python/crushdem_sand/figures/study.py, "figures" for its __init__.py."""
    parts = os.path.relpath(os.path.splitext(path)[0], SOURCE_DIR).split(os.sep)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported_modules(tree):
    """Top-level module names that each `import` / `from ... import` of ``tree`` brings in."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return out


def _package_imports(path):
    """The crushdem modules ``path`` imports (relative imports resolved, dotted names; ``from .
    import lab`` counts as lab), at any depth of the file."""
    name = _module_name(path)
    package = name.split(".") if path.endswith("__init__.py") else name.split(".")[:-1]
    out = set()
    for node in ast.walk(_tree(path)):
        if not (isinstance(node, ast.ImportFrom) and node.level):
            continue
        base = package[:len(package) - (node.level - 1)]
        if node.module:
            out.add(".".join(base + node.module.split(".")))
        else:
            out |= {".".join(base + [a.name]) for a in node.names}
    return out


def test_no_module_imports_private_names_of_another():
    package_modules = {os.path.splitext(os.path.basename(p))[0] for p in MODULES}
    package_modules |= {_module_name(p) for p in MODULES if p.endswith("__init__.py")}
    found = []
    for path in MODULES:
        tree = _tree(path)
        aliases = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "")
                                                     .startswith("crushdem_sand")):
                for a in node.names:
                    if a.name.startswith("_") and a.name not in PUBLIC_UNDERSCORE:
                        found.append(f"{_module_name(path)}:{node.lineno}: from "
                                     f"{node.module} import {a.name}")
                    if a.name in package_modules:
                        aliases.add(a.asname or a.name)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.value.id in aliases and node.attr.startswith("_") \
                    and node.attr not in PUBLIC_UNDERSCORE and not node.attr.startswith("__"):
                found.append(f"{_module_name(path)}:{node.lineno}: "
                             f"{node.value.id}.{node.attr}")
    assert not found, "\n".join(found)


def test_reading_analysis_and_recipes_are_numpy_only():
    for name in ("rundir.py", "analysis.py", "study.py", "study_analysis.py",
                 "study_summary.py"):
        imported = _imported_modules(_tree(os.path.join(SOURCE_DIR, name)))
        assert not imported & {"matplotlib", "pandas", "scipy"}, (name, imported)


def test_the_study_layers_depend_one_way():
    by_name = {_module_name(p): p for p in MODULES}
    assert set(STUDY_LAYERS) <= set(by_name)
    upward = []
    for k, name in enumerate(STUDY_LAYERS):
        later = set(STUDY_LAYERS[k + 1:])
        imported = _package_imports(by_name[name])
        upward += [f"{name} imports {m}" for m in sorted(imported & later)]
    assert not upward, upward
    # The resolver sees what it must: the pipeline imports the recipes and the figures.
    assert {"study", "figures.study"} <= _package_imports(by_name["study_pipeline"])
    assert "analysis" in _package_imports(by_name["figures.study"])


def test_no_module_is_longer_than_800_lines():
    lengths = {}
    for path in MODULES:
        with open(path) as f:
            lengths[_module_name(path)] = sum(1 for _ in f)
    assert len(lengths) >= 20
    assert not {m: n for m, n in lengths.items() if n > MAX_LINES}, lengths


def test_no_module_selects_a_backend_outside_the_commands():
    # matplotlib.use() only in figures.use_file_backend_without_display, which the commands
    # (crushdem-sand plot, crushdem-sand reproduce) call.
    for path in MODULES:
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                    and node.func.attr == "use" and getattr(node.func.value, "id", "") \
                    == "matplotlib":
                assert _module_name(path) == "figures", path


def test_importing_the_commands_loads_no_matplotlib():
    code = ("import sys; sys.path.insert(0, %r); from _source import load; load('plot'); "
            "load('reproduce'); load('study_pipeline'); load('figures.study'); "
            "print('matplotlib' in sys.modules)" % os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"


def _unannotated(tree):
    """The public functions and methods at module and class level of ``tree`` with a parameter
    or the return value not annotated."""
    found = []
    bodies = [tree.body] + [c.body for c in tree.body if isinstance(c, ast.ClassDef)]
    for body in bodies:
        for f in body:
            if not isinstance(f, ast.FunctionDef) or f.name.startswith("_"):
                continue
            args = f.args.posonlyargs + f.args.args + f.args.kwonlyargs
            args += [a for a in (f.args.vararg, f.args.kwarg) if a is not None]
            missing = [a.arg for a in args if a.annotation is None and a.arg not in
                       ("self", "cls")]
            if missing or f.returns is None:
                found.append(f"{f.name}({', '.join(missing)})"
                             + (" -> ?" if f.returns is None else ""))
    return found


def test_the_package_marked_typed_is_annotated():
    # PEP 561: an empty py.typed marks the whole package as typed ("partial\n" would say that
    # type checkers should look for stubs elsewhere), so every public function says its types.
    with open(os.path.join(SOURCE_DIR, "py.typed"), "rb") as f:
        assert f.read().strip() == b""
    found = {_module_name(p): _unannotated(_tree(p)) for p in MODULES}
    found = {m: f for m, f in found.items() if f}
    assert not found, found
    # The check sees what it must: a public function without a return type is reported.
    assert _unannotated(ast.parse("def f(x: int): pass\ndef _g(y): pass\n")) == ["f() -> ?"]
