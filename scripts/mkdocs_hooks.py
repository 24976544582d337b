"""MkDocs hooks of the docs site (mkdocs.yml; built by scripts/docs.sh).

The Markdown files stay written for GitHub, where a relative link leads to a file of the
repository; the site needs three things more, which these hooks add:

* headings get GitHub's anchors (lower case, punctuation dropped, one '-' per space), so that a
  link ``page.md#some-heading`` that works on GitHub works on the site, and MkDocs's anchor
  validation checks exactly what tests/python/test_docs.py checks;
* the notebooks of notebooks/ become pages (``notebooks/NAME.md``): the executed copies that
  scripts/notebooks.py keeps in build/notebooks/ with their outputs (tables, figures) where
  they are current, otherwise the stored notebook without outputs (and a note that says so);
  each page offers its notebook for download;
* files outside docs/ that pages link to: README.md and ARCHITECTURE.md become pages
  (``project/``), a notebook link leads to its page, and a link to any other file of the
  repository leads to it on ``repo_url`` (``CRUSHDEM_REPO_URL``) when that is set; otherwise it
  stays a broken link, which the strict build reports.

A link that leads nowhere is left as it is, for MkDocs's validation (mkdocs.yml: every kind of
link problem is a warning, and ``--strict`` makes warnings errors).
"""

from __future__ import annotations

import base64
import logging
import os
import posixpath
import re
import sys
from typing import Dict, Optional

from mkdocs.structure.files import File, Files

log = logging.getLogger("mkdocs.hooks.crushdem")

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(SCRIPTS)
NOTEBOOK_DIR = "notebooks"
EXECUTED_DIR = os.environ.get("CRUSHDEM_NOTEBOOK_OUT",
                              os.path.join(ROOT, "build", "notebooks"))
# Repository files shown as pages: repository path -> path in the site.
PROJECT_PAGES = {"README.md": "project/readme.md", "ARCHITECTURE.md": "project/architecture.md"}

# The repository path of every page of the site (docs/... for the docs' own pages), by site path.
_REPO_PATH: Dict[str, str] = {}
# The site path of every repository file that is a page, by repository path.
_SITE_PATH: Dict[str, str] = {}
# The header of each notebook page (its download link), inserted after the links are mapped.
_NOTEBOOK_HEADER: Dict[str, str] = {}


# ----------------------------------------------------------------------------------------------
# Anchors as GitHub makes them.

def github_slug(value: str, separator: str = "-") -> str:
    """GitHub's anchor for a heading's text (as tests/python/test_docs.py computes it)."""
    value = re.sub(r"[^\w\- ]", "", value.strip().lower())
    return value.replace(" ", separator)


# The theme keeps each table cell on one line (and lets the table scroll): right for a notebook's
# DataFrames, not for the docs' tables of keys and meanings, whose cells are sentences.
EXTRA_CSS = "css/crushdem.css"
_CSS = """.rst-content .wy-table-responsive table td { white-space: normal; }
.notebook-output .wy-table-responsive table td { white-space: nowrap; }
.notebook-output { overflow-x: auto; font-size: 90%; }
"""


def on_config(config, **kwargs):
    toc = config.mdx_configs.setdefault("toc", {})
    toc["slugify"] = github_slug
    if EXTRA_CSS not in config.extra_css:
        config.extra_css.append(EXTRA_CSS)
    return config


# ----------------------------------------------------------------------------------------------
# Notebooks as pages.

_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def _fence(text: str, lang: str = "") -> str:
    text = _ANSI.sub("", text).rstrip("\n")
    ticks = "```"
    while ticks in text:
        ticks += "`"
    return f"{ticks}{lang}\n{text}\n{ticks}"


def _joined(value) -> str:
    return "".join(value) if isinstance(value, list) else str(value)


def notebook_markdown(nb, stem: str, images: Dict[str, bytes]) -> str:
    """The Markdown of a notebook (nbformat 4 node): its Markdown cells as they are, each code
    cell as a Python block followed by its outputs (text as blocks, HTML tables as HTML, PNG
    images as files ``STEM_files/cellK_J.png``, which go into ``images``)."""
    parts = []
    for k, cell in enumerate(nb.cells):
        source = _joined(cell.get("source", ""))
        if cell.cell_type == "markdown":
            parts.append(source)
        elif cell.cell_type == "code":
            if source.strip():
                parts.append(_fence(source, "python"))
            for j, out in enumerate(cell.get("outputs", [])):
                kind = out.get("output_type")
                if kind == "stream":
                    parts.append(_fence(_joined(out.get("text", ""))))
                elif kind == "error":
                    parts.append(_fence("\n".join(out.get("traceback", []))))
                elif kind in ("execute_result", "display_data"):
                    data = out.get("data", {})
                    if "image/png" in data:
                        name = f"{stem}_files/cell{k}_{j}.png"
                        images[name] = base64.b64decode(_joined(data["image/png"]))
                        parts.append(f"![output of cell {k}]({name})")
                    elif "text/html" in data:
                        parts.append('<div class="notebook-output">\n' +
                                     _joined(data["text/html"]).strip() + "\n</div>")
                    elif "text/markdown" in data:
                        parts.append(_joined(data["text/markdown"]))
                    elif "text/plain" in data:
                        parts.append(_fence(_joined(data["text/plain"])))
    return "\n\n".join(parts) + "\n"


def _notebook(path: str):
    """The notebook to show for the stored notebook ``path`` and the path of its executed copy
    when that is current (scripts/notebooks.py ran it as it is now), else the stored notebook
    (without outputs) and None."""
    import nbformat

    if SCRIPTS not in sys.path:
        sys.path.insert(0, SCRIPTS)
    import notebooks as runner  # scripts/notebooks.py

    if runner.is_fresh(path, EXECUTED_DIR):
        done = runner.executed_path(path, EXECUTED_DIR)
        return nbformat.read(done, as_version=4), done
    return nbformat.read(path, as_version=4), None


def on_files(files: Files, config, **kwargs) -> Files:
    files.append(File.generated(config, EXTRA_CSS, content=_CSS))
    _REPO_PATH.clear()
    _SITE_PATH.clear()
    _NOTEBOOK_HEADER.clear()
    for f in files.documentation_pages():
        _REPO_PATH[f.src_uri] = "docs/" + f.src_uri
    for repo_path, site_path in PROJECT_PAGES.items():
        with open(os.path.join(ROOT, repo_path), encoding="utf-8") as fh:
            files.append(File.generated(config, site_path, content=fh.read()))
        _REPO_PATH[site_path] = repo_path
        _SITE_PATH[repo_path] = site_path
    source_dir = os.path.join(ROOT, NOTEBOOK_DIR)
    names = sorted(n for n in os.listdir(source_dir) if n.endswith(".ipynb")) \
        if os.path.isdir(source_dir) else []
    for name in names:
        stem = name[:-len(".ipynb")]
        repo_path = f"{NOTEBOOK_DIR}/{name}"
        site_path = f"{NOTEBOOK_DIR}/{stem}.md"
        nb, executed = _notebook(os.path.join(source_dir, name))
        images: Dict[str, bytes] = {}
        text = notebook_markdown(nb, stem, images)
        files.append(File.generated(config, site_path, content=text))
        for image, data in images.items():
            files.append(File.generated(config, f"{NOTEBOOK_DIR}/{image}", content=data))
        if executed:
            with open(executed, "rb") as fh:
                files.append(File.generated(config, f"{NOTEBOOK_DIR}/{name}",
                                            content=fh.read()))
            seconds = nb.metadata.get("crushdem", {}).get("seconds")
            header = (f"*The notebook `{repo_path}` as `scripts/notebooks.py` ran it"
                      f"{f' ({seconds:.0f} s)' if seconds is not None else ''}: "
                      f"[download it with its outputs]({name}).*")
        else:
            log.info("%s: no current executed copy in %s; the page shows it without outputs "
                     "(run scripts/notebooks.py)", repo_path, os.path.relpath(EXECUTED_DIR, ROOT))
            header = (f"*The notebook `{repo_path}`, shown without outputs: "
                      "`scripts/notebooks.py` runs it.*")
        _REPO_PATH[site_path] = repo_path
        _SITE_PATH[repo_path] = site_path
        _NOTEBOOK_HEADER[site_path] = header
    return files


# ----------------------------------------------------------------------------------------------
# Links to files outside docs/.

_LINK = re.compile(r"(!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?)([^)\s>]+)(>?(?:\s+\"[^\"]*\")?\s*\))")
_FENCE = re.compile(r"^\s*(```|~~~)")


def _site_target(repo_target: str, page_site_path: str, config) -> Optional[str]:
    """Where a link to the repository file ``repo_target`` from the page at
    ``page_site_path`` should lead in the site, or None to leave it as written."""
    if repo_target in _SITE_PATH:
        site = _SITE_PATH[repo_target]
    elif repo_target.startswith("docs/"):
        site = repo_target[len("docs/"):]
    else:
        repo_url = (config.repo_url or "").rstrip("/")
        if repo_url and os.path.exists(os.path.join(ROOT, repo_target)):
            kind = "tree" if os.path.isdir(os.path.join(ROOT, repo_target)) else "blob"
            branch = os.environ.get("CRUSHDEM_REPO_BRANCH", "main")
            return f"{repo_url}/{kind}/{branch}/{repo_target}"
        return None
    return posixpath.relpath(site, posixpath.dirname(page_site_path) or ".")


def map_links(markdown: str, page_site_path: str, repo_path: str, config) -> str:
    """``markdown`` (of the repository file ``repo_path``, shown at ``page_site_path``) with
    each relative link that leaves docs/ (or, in a page from elsewhere, any relative link)
    leading to its place in the site; fenced code is left alone."""
    repo_dir = posixpath.dirname(repo_path)
    from_docs = repo_path.startswith("docs/")

    def fix(m: re.Match) -> str:
        target = m.group(2)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, flags=re.I) or target.startswith(("#", "/")):
            return m.group(0)
        path, sep, fragment = target.partition("#")
        repo_target = posixpath.normpath(posixpath.join(repo_dir, path))
        if from_docs and repo_target.startswith("docs/"):
            return m.group(0)  # inside docs/: MkDocs resolves (and checks) it
        site = _site_target(repo_target, page_site_path, config)
        if site is None:  # e.g. a notebook's own images, beside its page
            return m.group(0)
        return m.group(1) + site + sep + fragment + m.group(3)

    out, fenced = [], None
    for line in markdown.split("\n"):
        f = _FENCE.match(line)
        if f and (fenced is None or f.group(1) == fenced):
            fenced = f.group(1) if fenced is None else None
            out.append(line)
            continue
        out.append(line if fenced else _LINK.sub(fix, line))
    return "\n".join(out)


# ----------------------------------------------------------------------------------------------
# Lists as GitHub reads them.

_ITEM = re.compile(r"^(?:[-*+]|1[.)])\s+\S")


def gfm_lists(markdown: str) -> str:
    """``markdown`` with a blank line put before a list that starts right after a paragraph's
    line: GitHub (CommonMark) starts the list there, Python-Markdown would read it as more of the
    paragraph. As in CommonMark only a bullet or "1." interrupts a paragraph; fenced code, tables
    and lists already going on are left alone."""
    out, fenced, block_first = [], None, ""
    for line in markdown.split("\n"):
        f = _FENCE.match(line)
        if f and (fenced is None or f.group(1) == fenced):
            fenced = f.group(1) if fenced is None else None
        elif fenced is None and _ITEM.match(line) and out and out[-1].strip() and \
                not _ITEM.match(block_first.lstrip()) and \
                not re.match(r"^\s*(?:[-*+]|\d+[.)])\s", block_first) and \
                not block_first.lstrip().startswith(("|", "#", "<", ">")):
            out.append("")
            block_first = line
        if not line.strip():
            block_first = ""
        elif not block_first:
            block_first = line
        out.append(line)
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:
    site_path = page.file.src_uri
    repo_path = _REPO_PATH.get(site_path, "docs/" + site_path)
    markdown = gfm_lists(map_links(markdown, site_path, repo_path, config))
    header = _NOTEBOOK_HEADER.get(site_path)
    if header:  # after the title
        lines = markdown.split("\n")
        at = next((k + 1 for k, line in enumerate(lines) if line.startswith("# ")), 0)
        lines[at:at] = ["", header, ""]
        markdown = "\n".join(lines)
    return markdown
