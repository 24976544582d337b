"""The Python package's layers (python/crushdem): reading a run directory and the analysis are
NumPy only, the figures draw without choosing a backend, and no module reaches into another's
private names (a helper two modules need is public in the layer it belongs to). Source checks:
they read python/crushdem/*.py and need neither the compiled _core nor a rebuild."""

import ast
import glob
import os
import subprocess
import sys

from _source import SOURCE_DIR

MODULES = sorted(glob.glob(os.path.join(SOURCE_DIR, "*.py")))
# Names that start with an underscore but are public parts of the package.
PUBLIC_UNDERSCORE = {"_core", "__version__", "__commit__", "__main__"}


def _tree(path):
    with open(path) as f:
        return ast.parse(f.read(), path)


def _imported_modules(tree):
    """Top-level module names that each `import` / `from ... import` of ``tree`` brings in."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return out


def test_no_module_imports_private_names_of_another():
    package_modules = {os.path.splitext(os.path.basename(p))[0] for p in MODULES}
    found = []
    for path in MODULES:
        tree = _tree(path)
        aliases = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "")
                                                     .startswith("crushdem")):
                for a in node.names:
                    if a.name.startswith("_") and a.name not in PUBLIC_UNDERSCORE:
                        found.append(f"{os.path.basename(path)}:{node.lineno}: from "
                                     f"{node.module} import {a.name}")
                    if a.name in package_modules:
                        aliases.add(a.asname or a.name)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.value.id in aliases and node.attr.startswith("_") \
                    and node.attr not in PUBLIC_UNDERSCORE and not node.attr.startswith("__"):
                found.append(f"{os.path.basename(path)}:{node.lineno}: "
                             f"{node.value.id}.{node.attr}")
    assert not found, "\n".join(found)


def test_reading_and_analysis_are_numpy_only():
    for name in ("rundir.py", "analysis.py"):
        imported = _imported_modules(_tree(os.path.join(SOURCE_DIR, name)))
        assert not imported & {"matplotlib", "pandas", "scipy"}, (name, imported)


def test_no_module_selects_a_backend_outside_the_commands():
    # matplotlib.use() only in figures.use_file_backend_without_display, which the commands
    # (crushdem plot, crushdem reproduce) call.
    for path in MODULES:
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                    and node.func.attr == "use" and getattr(node.func.value, "id", "") \
                    == "matplotlib":
                assert os.path.basename(path) == "figures.py", path


def test_importing_plot_loads_no_matplotlib():
    code = ("import sys; sys.path.insert(0, %r); from _source import load; load('plot'); "
            "load('reproduce'); print('matplotlib' in sys.modules)"
            % os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"


def test_package_is_marked_typed():
    assert os.path.isfile(os.path.join(SOURCE_DIR, "py.typed"))
