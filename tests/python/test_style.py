"""The Python sources keep the C++ sources' 100-column limit (.clang-format's ColumnLimit), code,
docstrings and comments alike: a limit nothing checks drifts (a rename once pushed 54 lines over
it). Every .py of the package, the tests, scripts/ and bench/ is read; none is imported."""

import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LIMIT = 100


def _sources():
    for top in ("python", "tests", "scripts", "bench"):
        for d, dirs, files in os.walk(os.path.join(ROOT, top)):
            dirs[:] = sorted(x for x in dirs if not x.startswith((".", "_")) and x != "build")
            for f in sorted(files):
                if f.endswith(".py"):
                    yield os.path.join(d, f)


def test_the_column_limit_is_that_of_clang_format():
    with open(os.path.join(ROOT, ".clang-format")) as f:
        assert f"ColumnLimit: {LIMIT}" in f.read()


@pytest.mark.parametrize("path", list(_sources()), ids=lambda p: os.path.relpath(p, ROOT))
def test_no_python_line_is_over_the_column_limit(path):
    with open(path, encoding="utf-8") as f:
        over = [f"{n}: {len(line)} columns" for n, line in enumerate(f.read().split("\n"), 1)
                if len(line) > LIMIT]
    assert not over, f"{os.path.relpath(path, ROOT)} has lines over {LIMIT} columns: {over}"
