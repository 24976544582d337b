"""The documentation stays true to the code: docs/api.md is what scripts/api_reference.py
generates from the docstrings, every relative link in the Markdown files leads to a file (and
heading) that exists, every path to a page or an example named in their text exists, every
example configuration passes `crushdem-sand check`, and the README's first Python example prints
what the README says it prints. All fast: the one thing run is that example (27 grains, a tenth of a
second)."""

import glob
import os
import re
import subprocess
import sys
import tomllib

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PAGES = sorted(glob.glob(os.path.join(ROOT, "docs", "*.md"))) + [
    os.path.join(ROOT, "README.md"), os.path.join(ROOT, "ARCHITECTURE.md")]
EXAMPLES = sorted(glob.glob(os.path.join(ROOT, "examples", "*.toml")))
REGENERATE = ".venv/bin/python scripts/api_reference.py"


def _rel(path):
    return os.path.relpath(path, ROOT)


def test_api_reference_is_up_to_date():
    script = os.path.join(ROOT, "scripts", "api_reference.py")
    proc = subprocess.run([sys.executable, script, "--check"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, (
        f"docs/api.md is out of date with the docstrings (or could not be generated): "
        f"regenerate it with `{REGENERATE}` and commit it (a change to the C++ bindings' "
        f"docstrings needs `pip install .` first).\n"
        f"{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}")


def _without_code(text):
    """The text with fenced code blocks and inline code spans blanked (line numbers kept)."""
    text = re.sub(r"^(```|~~~).*?^\1[^\n]*$", lambda m: "\n" * m.group(0).count("\n"), text,
                  flags=re.M | re.S)
    return re.sub(r"``.*?``|`[^`\n]*`", "", text)


_LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def _links(path):
    with open(path, encoding="utf-8") as f:
        text = _without_code(f.read())
    for n, line in enumerate(text.split("\n"), 1):
        for m in _LINK.finditer(line):
            yield n, m.group(1)


def _slug(heading):
    """GitHub's anchor for a heading."""
    heading = re.sub(r"`([^`]*)`", r"\1", heading.strip())
    heading = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    heading = re.sub(r"[^\w\- ]", "", heading.lower())
    return heading.replace(" ", "-")


def _anchors(path):
    with open(path, encoding="utf-8") as f:
        text = re.sub(r"^(```|~~~).*?^\1[^\n]*$", "", f.read(), flags=re.M | re.S)
    seen = {}
    anchors = set()
    for m in re.finditer(r"^#{1,6}\s+(.+?)\s*#*\s*$", text, flags=re.M):
        slug = _slug(m.group(1))
        k = seen.get(slug, 0)
        seen[slug] = k + 1
        anchors.add(slug if k == 0 else f"{slug}-{k}")
    return anchors


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_relative_links_lead_somewhere(page):
    broken = []
    for line, target in _links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, flags=re.I):  # http:, https:, mailto:
            continue
        path, _, fragment = target.partition("#")
        dest = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
        if not os.path.exists(dest):
            broken.append(f"{_rel(page)}:{line}: {target} (no file {_rel(dest)})")
        elif fragment and dest.endswith(".md") and fragment not in _anchors(dest):
            broken.append(f"{_rel(page)}:{line}: {target} (no heading #{fragment} in "
                          f"{_rel(dest)})")
    assert not broken, "broken links:\n" + "\n".join(broken)


# A page, figure or example named in the text: docs/NAME.md, docs/figures/NAME.png,
# examples/NAME.toml (patterns such as examples/{a,b}_rev.toml are left out).
_MENTION = re.compile(r"(?<![\w/.{])((?:docs|examples)/[\w./-]+\.(?:md|toml|png))(?![\w{*])")


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_named_pages_and_examples_exist(page):
    with open(page, encoding="utf-8") as f:
        text = f.read()
    missing = []
    for n, line in enumerate(text.split("\n"), 1):
        for m in _MENTION.finditer(line):
            if not os.path.exists(os.path.join(ROOT, m.group(1))):
                missing.append(f"{_rel(page)}:{n}: {m.group(1)}")
    assert not missing, "named but missing:\n" + "\n".join(missing)


# The *_rev examples read the prepared REV (`../runs/sample_rev/sample.txt`), chamber_k0 its
# chamber sample; a few grains in a file of the same format stand in for them, so that the check
# covers everything else.
SAMPLE = """# box_xmin=0.0005
# box_xmax=0.0045
# box_ymin=0.0005
# box_ymax=0.0045
# box_zmin=0.0005
# box_zmax=0.0045
0 0.0015 0.0015 0.0015 0.00013
1 0.0030 0.0030 0.0030 0.00012
"""


@pytest.fixture(scope="module")
def example_tree(tmp_path_factory):
    root = tmp_path_factory.mktemp("examples_checked")
    (root / "examples").mkdir()
    for path in EXAMPLES:
        with open(path, encoding="utf-8") as f:
            text = f.read()
        (root / "examples" / os.path.basename(path)).write_text(text)
        # The prepared sample it reads (the REV's, the K0 chamber's), stood in for.
        file = tomllib.loads(text).get("particles", {}).get("file")
        if file:
            sample = root / "examples" / file
            sample.parent.mkdir(parents=True, exist_ok=True)
            sample.write_text(SAMPLE)
    return root


@pytest.mark.parametrize("path", EXAMPLES, ids=os.path.basename)
def test_example_passes_crushdem_check(path, example_tree):
    target = example_tree / "examples" / os.path.basename(path)
    proc = subprocess.run([sys.executable, "-m", "crushdem_sand", "check", str(target)],
                          cwd=example_tree, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"crushdem-sand check {_rel(path)}:\n{proc.stdout}{proc.stderr}"


def _python_blocks(path):
    """The fenced ```python blocks of a Markdown file, in order."""
    with open(path, encoding="utf-8") as f:
        return re.findall(r"^```python\n(.*?)^```", f.read(), flags=re.M | re.S)


def test_readme_first_python_example_prints_what_it_says():
    # The README's first example is the one a new user runs: it must show grains in contact and
    # the stress the servo wall reached (it once printed one grain's position and an empty
    # array of contact forces).
    readme = os.path.join(ROOT, "README.md")
    code = _python_blocks(readme)[0]
    assert "crushdem_sand.Simulation(" in code
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-4000:]
    lines = proc.stdout.splitlines()
    with open(readme, encoding="utf-8") as f:
        said = re.search(r"^prints `([^`]*)`", f.read(), flags=re.M)
    assert said and lines[0] == said.group(1), (lines, said)
    # The contacts grouped by is_wall: 18 between grains and 18 with the walls, 1/9 N each.
    table = {line.split()[0]: line.split()[1:] for line in lines[1:] if line.split()}
    assert table["False"][0] == table["True"][0] == "18"
    assert float(table["False"][1]) == pytest.approx(1.0 / 9.0, rel=1e-6)
