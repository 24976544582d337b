"""The installed package: the compiled module's type stubs (_core.pyi, made by nanobind's
stubgen at build time) and the py.typed marker sit beside it (PEP 561), so that type checkers
and editors see crushdem_sand._core's signatures. Its dependencies: numpy, pandas and tqdm only,
the others in extras, imported only by what needs them and named with their pip command when
missing. The installed CMake package passes no -march to its consumers."""

import ast
import glob
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib

import pytest

pytest.importorskip("crushdem_sand._core")


def _package_dir():
    spec = importlib.util.find_spec("crushdem_sand._core")
    return os.path.dirname(os.path.abspath(spec.origin))


def test_core_stubs_and_py_typed_are_installed():
    where = _package_dir()
    assert os.path.isfile(os.path.join(where, "py.typed")), where
    stub = os.path.join(where, "_core.pyi")
    assert os.path.isfile(stub), where
    with open(stub) as f:
        tree = ast.parse(f.read(), stub)
    names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    import crushdem_sand._core as core

    public = {n for n in dir(core) if not n.startswith("_") and callable(getattr(core, n))}
    assert {"Simulation", "set_threads", "resume"} <= names
    # Interrupted is made with PyErr_NewException("crushdem_sand._core.Interrupted"): stubgen, which
    # imports the module as `_core` at build time, takes it for a name from another module.
    assert public - {"Interrupted"} <= names, sorted(public - names)


ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PYPROJECT = os.path.join(ROOT, "pyproject.toml")
OPTIONAL = ("matplotlib", "dask", "distributed", "scipy", "pyarrow")


def _names(requirements):
    return sorted(re.match(r"[A-Za-z0-9_.-]+", r).group(0).lower() for r in requirements)


@pytest.mark.skipif(not os.path.isfile(PYPROJECT), reason="not run from a checkout")
def test_required_dependencies_are_minimal_and_the_rest_are_extras():
    with open(PYPROJECT, "rb") as f:
        project = tomllib.load(f)["project"]
    assert _names(project["dependencies"]) == ["numpy", "pandas", "tqdm"]
    extras = project["optional-dependencies"]
    assert extras["plot"] == ["matplotlib"]
    assert sorted(extras["sweep"]) == ["dask[distributed]", "pyarrow"]
    assert sorted(extras["calibrate"]) == ["dask[distributed]", "scipy"]
    assert extras["all"] == ["crushdem-sand[plot,sweep,calibrate]"]
    assert any(e.startswith("crushdem-sand[") and "all" in e[len("crushdem-sand["):-1].split(",")
               for e in extras["test"]) and "pytest" in _names(extras["test"])
    # The message of a missing package names an extra that exists.
    from crushdem_sand import _optional

    assert set(_optional.EXTRAS.values()) <= set(extras)


def _python(code, *args):
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=120, cwd=os.path.dirname(os.path.abspath(__file__)))


def test_importing_crushdem_imports_no_optional_package():
    r = _python("import crushdem_sand, crushdem_sand.lab, crushdem_sand.rundir, "
                "crushdem_sand.runs, sys; "
                f"print([m for m in {OPTIONAL!r} if m in sys.modules])")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


# Each command with a missing optional package: exit status 2 before it runs anything, and the
# package and the pip command of its extra on stderr.
@pytest.mark.parametrize("missing, command, message", [
    ("matplotlib", "plot",
     'crushdem-sand plot needs matplotlib: pip install "crushdem-sand[plot]"'),
    ("matplotlib", "reproduce",
     'crushdem-sand reproduce needs matplotlib: pip install "crushdem-sand[plot]"'),
    ("distributed", "sweep",
     'crushdem-sand sweep needs distributed: pip install "crushdem-sand[sweep]"'),
    ("scipy", "calibrate",
     'crushdem-sand calibrate needs scipy: pip install "crushdem-sand[calibrate]"'),
])
def test_a_command_names_the_extra_of_a_missing_package(missing, command, message, tmp_path):
    r = _python(f"import sys; sys.modules[{missing!r}] = None\n"
                "from crushdem_sand.__main__ import main\n"
                "main(sys.argv[1:])", command, "FILE", "--out", str(tmp_path / "out"))
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert message in r.stderr
    assert not os.path.exists(tmp_path / "out")
    # --help needs no optional package.
    r = _python(f"import sys; sys.modules[{missing!r}] = None\n"
                "from crushdem_sand.__main__ import main\n"
                "main(sys.argv[1:])", command, "--help")
    assert r.returncode == 0, r.stderr


def test_the_python_api_names_the_extra_of_a_missing_package(tmp_path):
    r = _python("import sys; sys.modules['matplotlib'] = None\n"
                "import crushdem_sand.plot, crushdem_sand.figures.common\n"
                "for call in (lambda: crushdem_sand.plot.make_plots(sys.argv[1]),\n"
                "             crushdem_sand.figures.common.pyplot):\n"
                "    try:\n"
                "        call()\n"
                "    except ImportError as e:\n"
                "        print(e)\n", str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [
        'crushdem-sand plot needs matplotlib: pip install "crushdem-sand[plot]"',
        'crushdem\'s figures needs matplotlib: pip install "crushdem-sand[plot]"']


@pytest.mark.skipif(not (shutil.which("cmake")
                         and os.path.isfile(os.path.join(ROOT, "CMakeLists.txt"))),
                    reason="needs cmake and the checkout")
def test_installed_cmake_package_passes_no_march(tmp_path):
    """-march=native builds the project's own targets only: the exported targets (what
    find_package(crushdem) gives a consumer) carry no -march. Configuring alone generates
    them."""
    build = tmp_path / "build"
    r = subprocess.run(["cmake", "-S", ROOT, "-B", str(build), "-DCRUSHDEM_NATIVE=ON",
                        "-DCRUSHDEM_TESTS=OFF", "-DCRUSHDEM_CUDA=OFF"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    # CMakeFiles/Export/<hash>/ (CMake 3.24 on) or CMakeFiles/Export/lib/cmake/crushdem/.
    exported = glob.glob(str(build / "CMakeFiles" / "Export" / "**" / "crushdemTargets*.cmake"),
                         recursive=True)
    assert exported
    for path in exported:
        with open(path) as f:
            text = f.read()
        assert "-march" not in text, path
    # The library itself is still built for this machine.
    flags = glob.glob(str(build / "CMakeFiles" / "crushdem.dir" / "flags.make"))
    flags += glob.glob(str(build / "build.ninja"))
    assert flags and any("-march=native" in open(p).read() for p in flags)


def test_the_distribution_package_and_command_are_crushdem_sand_with_the_old_command_an_alias():
    """The PyPI name crushdem is another project's: the distribution (crushdem-sand), the import
    package (crushdem_sand) and the command (crushdem-sand) all differ from it, so that both can
    live in one environment; the compiled module lands in the import package; `crushdem` stays a
    console script, an alias until 0.2."""
    import importlib.metadata as metadata

    dist = metadata.distribution("crushdem-sand")
    files = {str(f) for f in dist.files or ()}
    assert any(f.startswith("crushdem_sand/_core") and f.endswith(".so") for f in files), files
    assert "crushdem_sand/__init__.py" in files
    assert not any(f.startswith("crushdem/") for f in files), files
    scripts = dist.entry_points.select(group="console_scripts")
    assert {e.name: e.value for e in scripts} == {"crushdem-sand": "crushdem_sand.__main__:main",
                                                 "crushdem": "crushdem_sand.__main__:main"}
