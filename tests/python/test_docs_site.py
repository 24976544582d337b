"""The docs site (mkdocs.yml, scripts/mkdocs_hooks.py, built by scripts/docs.sh): it builds in
strict mode (a broken link or anchor, or a docs page left out of the nav, fails it), and its
hooks read the Markdown as GitHub does: the same anchors, links to files outside docs/ leading
to their pages (README, ARCHITECTURE.md, the notebooks) or to the repository, lists that
start right after a paragraph. A few seconds."""

import importlib.util
import os
import re
import subprocess
import sys
import types

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, path))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _needs_mkdocs():
    if importlib.util.find_spec("mkdocs") is None:
        if os.environ.get("CI"):
            pytest.fail("mkdocs not installed: pip install '.[docs]'")
        pytest.skip("mkdocs not installed: pip install '.[docs]'")


@pytest.fixture(scope="module")
def hooks():
    _needs_mkdocs()
    return _load("crushdem_mkdocs_hooks", os.path.join("scripts", "mkdocs_hooks.py"))


def test_site_builds_strict_with_every_page(tmp_path):
    _needs_mkdocs()
    site = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                           str(site)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    pages = sorted(os.path.splitext(n)[0] for n in os.listdir(os.path.join(ROOT, "docs"))
                   if n.endswith(".md"))
    for page in pages:
        assert (site / f"{page}.html").is_file(), page
    for page in ("notebooks/oedometric_relaxation", "notebooks/triaxial", "project/readme",
                 "project/architecture"):
        assert (site / f"{page}.html").is_file(), page
    # The figures of the docs are in the site, where the pages' images point.
    figures = [os.path.relpath(os.path.join(d, n), os.path.join(ROOT, "docs"))
               for d, _, names in os.walk(os.path.join(ROOT, "docs", "figures"))
               for n in names if n.endswith(".png")]
    assert figures
    for figure in figures:
        assert (site / figure).is_file(), figure
    reproduction = (site / "reproduction.html").read_text(encoding="utf-8")
    assert 'src="figures/reproduction/' in reproduction
    index = (site / "index.html").read_text(encoding="utf-8")
    assert 'href="notebooks/triaxial.html"' in index and 'href="project/readme.html"' in index


def test_anchors_are_githubs(hooks):
    test_docs = _load("crushdem_test_docs", os.path.join("tests", "python", "test_docs.py"))
    headings = ["Which rotation model, and which grain strength: the decision study",
                "q_max under the uncertain choices (`crushdem-sand sensitivity`)",
                "The study's REV", "5. What is uncertain", "Backends: the CPU engine and a device"]
    for heading in headings:
        text = re.sub(r"`([^`]*)`", r"\1", heading)  # what the toc extension passes on
        assert hooks.github_slug(text) == test_docs._slug(heading), heading


def test_links_outside_docs_lead_to_their_pages(hooks, monkeypatch):
    monkeypatch.setattr(hooks, "_SITE_PATH", {
        "README.md": "project/readme.md", "ARCHITECTURE.md": "project/architecture.md",
        "notebooks/triaxial.ipynb": "notebooks/triaxial.md"})
    plain = types.SimpleNamespace(repo_url=None)
    text = ("See [the README](../README.md), [layout](../ARCHITECTURE.md#the-step), "
            "[a page](model.md#5-what-is-uncertain), [nb](../notebooks/triaxial.ipynb), "
            "[web](https://example.org/x.md) and [an example](../examples/triaxial_small.toml).\n"
            "```\n[in code](../README.md)\n```\n")
    out = hooks.map_links(text, "getting-started.md", "docs/getting-started.md", plain)
    assert "[the README](project/readme.md)" in out
    assert "[layout](project/architecture.md#the-step)" in out
    assert "[a page](model.md#5-what-is-uncertain)" in out
    assert "[nb](notebooks/triaxial.md)" in out
    assert "[web](https://example.org/x.md)" in out
    # No page and no repository address: left for the strict build to report.
    assert "[an example](../examples/triaxial_small.toml)" in out
    assert "[in code](../README.md)" in out
    # With repo_url, a repository file that is no page leads to the repository.
    repo = types.SimpleNamespace(repo_url="https://example.org/crushdem/")
    out = hooks.map_links(text, "getting-started.md", "docs/getting-started.md", repo)
    assert "(https://example.org/crushdem/blob/main/examples/triaxial_small.toml)" in out
    # A page from elsewhere: its links into docs/ lead to the docs' pages; a notebook's own
    # images stay beside it.
    out = hooks.map_links("[a](docs/model.md#x) [b](../docs/api.md) ![f](t_files/c1_0.png)",
                          "project/readme.md", "README.md", plain)
    assert out.startswith("[a](../model.md#x)")
    out = hooks.map_links("[b](../docs/api.md) ![f](t_files/c1_0.png)",
                          "notebooks/t.md", "notebooks/t.ipynb", plain)
    assert out == "[b](../api.md) ![f](t_files/c1_0.png)"


def test_lists_after_a_paragraph_start_as_on_github(hooks):
    text = ("A new kind touches three files:\n1. one\n2. two\n\nkeep 0 of them\n"
            "0. is not a list\n\n- a\n- b\n  more\n\n```\nx\n- y\n```\n")
    out = hooks.gfm_lists(text)
    assert "files:\n\n1. one\n2. two" in out
    assert "them\n0. is not" in out
    assert "- a\n- b\n  more" in out and "x\n- y" in out


def test_notebook_markdown(hooks):
    import nbformat
    from nbformat.v4 import (new_code_cell, new_markdown_cell, new_notebook, new_output)

    nb = new_notebook(cells=[
        new_markdown_cell("# Title\n\nText."),
        new_code_cell("print(1)", outputs=[new_output("stream", name="stdout", text="1\n")]),
        new_code_cell("df", outputs=[new_output("execute_result", execution_count=1,
                                                data={"text/html": "<table></table>",
                                                      "text/plain": "df"})]),
        new_code_cell("plot()", outputs=[new_output("display_data",
                                                    data={"image/png": "iVBORw0KGgo=",
                                                          "text/plain": "<Figure>"})]),
    ])
    nbformat.validate(nb)
    images = {}
    md = hooks.notebook_markdown(nb, "t", images)
    assert md.startswith("# Title\n\nText.\n\n```python\nprint(1)\n```\n\n```\n1\n```")
    assert '<div class="notebook-output">\n<table></table>\n</div>' in md
    assert "![output of cell 3](t_files/cell3_0.png)" in md
    assert images == {"t_files/cell3_0.png": b"\x89PNG\r\n\x1a\n"}
