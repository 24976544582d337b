"""The notebooks of notebooks/ run from top to bottom on the installed package: each in a kernel
of this Python (nbclient, ipykernel) in a temporary directory, failing on the first cell that
raises; the last cell of each asserts what the run gave (the relaxation's stress fell, q_max
was reached with the lateral stress held). They are stored without outputs, and an executed
notebook shows its figures and no warnings. The executed copies go to build/notebooks/, where
the docs site (scripts/docs.sh) takes them from. About a minute each on two cores."""

import importlib.util
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_spec = importlib.util.spec_from_file_location(
    "crushdem_notebook_runner", os.path.join(ROOT, "scripts", "notebooks.py"))
runner = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(runner)

NOTEBOOKS = runner.notebooks()
# What each notebook must draw at least (figures: image/png outputs).
FIGURES = {"oedometric_relaxation.ipynb": 3, "triaxial.ipynb": 2}


def _needs(*modules):
    """Skips (fails in CI, which installs the docs extra) without the notebook tools."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        message = f"{', '.join(missing)} not installed: pip install '.[docs]'"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)


def test_the_notebooks_are_there():
    assert set(FIGURES) <= {os.path.basename(p) for p in NOTEBOOKS}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=os.path.basename)
def test_notebook_is_stored_without_outputs(path):
    _needs("nbformat")
    assert runner.problems(path) == [], (
        f"{os.path.relpath(path, ROOT)} is stored with outputs: clear them "
        f"(.venv/bin/python scripts/notebooks.py --clear)")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=os.path.basename)
def test_notebook_runs(path):
    _needs("nbformat", "nbclient", "ipykernel", "matplotlib")
    import nbformat

    runner.execute(path)  # CellExecutionError, with the cell and its traceback, on a failure
    done = nbformat.read(runner.executed_path(path), as_version=4)
    assert done.metadata["crushdem"]["source_sha256"] == runner.source_hash(path)
    assert runner.is_fresh(path)
    code = [c for c in done.cells if c.cell_type == "code"]
    assert code and all(c.execution_count is not None for c in code)
    outputs = [o for c in code for o in c.outputs]
    warnings = [o.get("text", "") for o in outputs
                if o.output_type == "stream" and o.name == "stderr"]
    assert not warnings, "the notebook printed to stderr:\n" + "\n".join(warnings)
    figures = sum("image/png" in o.get("data", {}) for o in outputs)
    assert figures >= FIGURES.get(os.path.basename(path), 1)
