#!/usr/bin/env python3
"""Writes docs/api.md, the reference of crushdem's Python API, from the public names'
signatures and docstrings.

    .venv/bin/python scripts/api_reference.py            # rewrite docs/api.md
    .venv/bin/python scripts/api_reference.py --check    # exit 1 if docs/api.md is out of date
    .venv/bin/python scripts/api_reference.py --stdout   # print it instead

In a checkout the Python modules are read from python/crushdem_sand/ (so that an edited docstring
needs no rebuild) and the compiled ``crushdem_sand._core`` from the installed package; a change to
the C++ bindings' docstrings needs ``pip install .`` first. ``--installed`` documents the
installed package alone.

Public names: a module's ``__all__`` when it has one, otherwise the functions and classes it
defines whose names do not start with an underscore; in a class, the methods and properties
whose names do not start with an underscore, in definition order. The output depends only on
the code: no addresses, versions or commits.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import importlib.util
import inspect
import os
import re
import sys
from typing import Any, List, Optional, Tuple

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOURCE = os.path.join(ROOT, "python", "crushdem_sand")
OUTPUT = os.path.join(ROOT, "docs", "api.md")
COMMAND = ".venv/bin/python scripts/api_reference.py"


def import_package(installed: bool):
    """crushdem_sand, with its Python modules from the checkout unless `installed`; returns the
    package and the directory its Python modules come from."""
    spec = importlib.util.find_spec("crushdem_sand")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("crushdem_sand is not installed in this Python: run `pip install .` (or "
                         "`bash scripts/test.sh`, which installs it into .venv) first")
    installed_dir = os.path.abspath(list(spec.submodule_search_locations)[0])
    if installed or not os.path.isfile(os.path.join(SOURCE, "__init__.py")) or \
            os.path.samefile(installed_dir, SOURCE):
        return importlib.import_module("crushdem_sand"), installed_dir
    # The checkout's modules first; _core (compiled) is found in the installed package.
    src = importlib.util.spec_from_file_location(
        "crushdem_sand", os.path.join(SOURCE, "__init__.py"),
        submodule_search_locations=[SOURCE, installed_dir])
    module = importlib.util.module_from_spec(src)
    sys.modules["crushdem_sand"] = module
    src.loader.exec_module(module)
    return module, SOURCE


def module_names(package_dir: str) -> List[str]:
    """The public modules of a package directory, a subpackage followed by its modules
    ("figures", "figures.ageing", ...)."""
    names = []
    for entry in sorted(os.listdir(package_dir)):
        stem, ext = os.path.splitext(entry)
        if stem.startswith("_"):
            continue
        if ext == ".py":
            names.append(stem)
        elif os.path.isfile(os.path.join(package_dir, entry, "__init__.py")):
            names.append(entry)
            names += [f"{entry}.{sub}" for sub in module_names(os.path.join(package_dir, entry))]
    return names


_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj):`~?([^`]+)`")
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


_LIST_ITEM = re.compile(r"^(\*|-|\d+\.) ")


def clean_doc(doc: Optional[str]) -> str:
    """A docstring as Markdown: dedented, Sphinx roles as code, the indented block after a
    `::` line or under a definition-list term kept as preformatted text."""
    if not doc:
        return "*No docstring.*"
    text = inspect.cleandoc(doc)
    text = _ROLE.sub(lambda m: f"`{m.group(1)}`", text)
    text = re.sub(r"(\S)::$", r"\1:", text, flags=re.M)
    lines = text.split("\n")
    out: List[str] = []
    for i, line in enumerate(lines):
        out.append(line)
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        # A term line followed by an indented block (reST definition list): a blank line in
        # between makes the block preformatted instead of one run-on paragraph.
        if line.strip() and not line.startswith(" ") and not _LIST_ITEM.match(line) and \
                nxt.startswith("    ") and nxt.strip():
            out.append("")
    return "\n".join(out).strip()


def split_native(doc: Optional[str]) -> Tuple[List[str], str]:
    """A nanobind docstring: its signature lines, then the rest."""
    if not doc:
        return [], ""
    lines = doc.strip("\n").split("\n")
    sig: List[str] = []
    while lines and re.match(r"^[A-Za-z_]\w*\(.*\)( -> .+)?$", lines[0]):
        sig.append(lines.pop(0))
    return sig, "\n".join(lines).strip()


class _Annotation:
    """A string annotation (``from __future__ import annotations``) shown without quotes."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _unquoted(sig: inspect.Signature) -> inspect.Signature:
    def ann(a: Any) -> Any:
        return _Annotation(a) if isinstance(a, str) else a
    params = [p.replace(annotation=ann(p.annotation)) for p in sig.parameters.values()]
    return sig.replace(parameters=params, return_annotation=ann(sig.return_annotation))


def signature(obj: Any, name: str) -> Tuple[List[str], str]:
    """(signature lines, docstring) of a function, method or class."""
    if type(obj).__name__ in ("nb_func", "nb_method"):
        sig, rest = split_native(obj.__doc__)
        return [_ADDRESS.sub("", s) for s in sig], rest
    try:
        s = str(_unquoted(inspect.signature(obj)))
    except (TypeError, ValueError):
        return [f"{name}(...)"], obj.__doc__ or ""
    return [name + _ADDRESS.sub("", s)], obj.__doc__ or ""


def constant_comment(module: Any, name: str) -> str:
    """The `#:` comment lines just above `name = ...` in the module's source."""
    try:
        lines = inspect.getsource(module).split("\n")
    except (OSError, TypeError):
        return ""
    for i, line in enumerate(lines):
        if re.match(rf"^{re.escape(name)}\s*(:[^=]+)?=", line):
            comment = []
            j = i - 1
            while j >= 0 and lines[j].startswith("#:"):
                comment.insert(0, lines[j][2:].strip())
                j -= 1
            return " ".join(comment)
    return ""


def anchor(title: str) -> str:
    """GitHub's heading anchor for a heading text."""
    a = title.strip().lower()
    a = re.sub(r"[^\w\- ]", "", a)
    return a.replace(" ", "-")


class Writer:
    def __init__(self) -> None:
        self.out: List[str] = []

    def add(self, *lines: str) -> None:
        self.out.extend(lines)

    def code(self, lines: List[str]) -> None:
        if lines:
            self.add("```python", *lines, "```", "")

    def text(self, doc: str) -> None:
        self.add(doc, "")


def public_names(module: Any) -> List[str]:
    if hasattr(module, "__all__"):
        return list(module.__all__)
    names = []
    for name, obj in vars(module).items():
        if name.startswith("_"):
            continue
        if callable(obj) and not inspect.ismodule(obj) and \
                getattr(obj, "__module__", None) == module.__name__:
            names.append(name)
    return names


def document_class(w: Writer, qualname: str, cls: Any) -> None:
    bases = [b.__name__ for b in cls.__bases__ if b is not object]
    w.add(f"### `{qualname}`", "")
    init = vars(cls).get("__init__")
    if init is not None and type(init).__name__ == "nb_method":
        sig, rest = split_native(init.__doc__)
        opening = "class " + cls.__name__ + "("
        w.code([re.sub(r" -> None$", "", re.sub(r"^__init__\(self(, )?", opening, s)) for s in sig])
        class_doc = cls.__doc__ or ""
        doc = "\n\n".join(d for d in (inspect.cleandoc(class_doc) if class_doc else "", rest) if d)
        w.text(clean_doc(doc))
    elif issubclass(cls, BaseException):
        w.code([f"class {cls.__name__}({', '.join(bases)})"])
        w.text(clean_doc(cls.__doc__))
    else:
        sig, doc = signature(cls, "class " + cls.__name__)
        w.code([re.sub(r" -> None$", "", s) for s in sig])
        w.text(clean_doc(cls.__doc__))
    for name, member in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(member, property) or type(member).__name__ == "nb_property" or \
                inspect.isdatadescriptor(member):
            w.add(f"#### `{qualname}.{name}`", "", "*property*", "")
            w.text(clean_doc(getattr(member, "__doc__", None)))
        elif isinstance(member, (staticmethod, classmethod)):
            sig, doc = signature(member.__func__, name)
            w.add(f"#### `{qualname}.{name}`", "")
            w.code(sig)
            w.text(clean_doc(doc))
        elif callable(member):
            sig, doc = signature(member, name)
            sig = [re.sub(r"^(\w+)\(self(, )?", r"\1(", s) for s in sig]
            w.add(f"#### `{qualname}.{name}`", "")
            w.code(sig)
            w.text(clean_doc(doc))


def document_module(w: Writer, module: Any, documented: dict) -> None:
    name = module.__name__
    w.add(f"## `{name}`", "")
    w.text(clean_doc(module.__doc__))
    pointers = []
    for public in public_names(module):
        obj = getattr(module, public)
        home = documented.get(id(obj))
        if inspect.ismodule(obj):
            pointers.append(f"- `{public}`: the module [`{obj.__name__}`](#{anchor(obj.__name__)})")
        elif home and home != f"{name}.{public}":
            pointers.append(f"- `{public}`: [`{home}`](#{anchor(home)})")
    if pointers:
        w.add(f"Also in `{name}`:", "", *pointers, "")
    for public in public_names(module):
        obj = getattr(module, public)
        qual = f"{name}.{public}"
        home = documented.get(id(obj))
        if inspect.ismodule(obj) or (home and home != qual):
            continue
        if inspect.isclass(obj):
            document_class(w, qual, obj)
        elif callable(obj):
            sig, doc = signature(obj, public)
            w.add(f"### `{qual}`", "")
            w.code(sig)
            w.text(clean_doc(doc))
        else:
            comment = constant_comment(module, public)
            w.add(f"### `{qual}`", "")
            w.code([f"{public} = {_ADDRESS.sub('', repr(obj))}"])
            if comment:
                w.text(comment)


def render(installed: bool = False) -> str:
    package, package_dir = import_package(installed)
    from crushdem_sand import _core  # noqa: E402  (the compiled engine)

    modules = [importlib.import_module(f"crushdem_sand.{m}") for m in module_names(package_dir)]
    order = [package] + modules + [_core]
    # Where each object is documented: the module that defines it (a re-export points there).
    documented: dict = {}
    for module in order:
        for public in public_names(module):
            obj = getattr(module, public)
            if inspect.ismodule(obj) or not (callable(obj) or inspect.isclass(obj)):
                continue
            owner = getattr(obj, "__module__", None)
            if owner == module.__name__:
                documented.setdefault(id(obj), f"{module.__name__}.{public}")
    w = Writer()
    w.add("# Python API reference", "",
          "<!-- generated by scripts/api_reference.py from the docstrings; do not edit. "
          "tests/python/test_docs.py fails when it is out of date. -->", "",
          "Every public name of the `crushdem_sand` package and of its compiled engine "
          "`crushdem_sand._core`, with its signature and docstring (SI units throughout). "
          "Configuration keys: [configuration.md](configuration.md); the command line: "
          "`crushdem-sand COMMAND --help` and [getting-started.md](getting-started.md). "
          f"Regenerate with `{COMMAND}`.", "")
    w.add("| module | |", "|---|---|")
    for module in order:
        first = clean_doc(module.__doc__).split("\n\n")[0].replace("\n", " ")
        first = first.replace("|", "\\|")
        w.add(f"| [`{module.__name__}`](#{anchor(module.__name__)}) | {first} |")
    w.add("")
    for module in order:
        document_module(w, module, documented)
    text = "\n".join(w.out)
    text = re.sub(r"\n{3,}", "\n\n", text).rstrip("\n") + "\n"
    return text


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if docs/api.md differs")
    ap.add_argument("--stdout", action="store_true", help="print instead of writing")
    ap.add_argument("--installed", action="store_true",
                    help="document the installed package, not the checkout's modules")
    ap.add_argument("--out", default=OUTPUT, help="file to write (default docs/api.md)")
    args = ap.parse_args(argv)
    text = render(args.installed)
    if args.stdout:
        sys.stdout.write(text)
        return 0
    if args.check:
        try:
            with open(args.out, encoding="utf-8") as f:
                old = f.read()
        except FileNotFoundError:
            old = ""
        if old == text:
            return 0
        sys.stdout.writelines(difflib.unified_diff(
            old.splitlines(True), text.splitlines(True), "docs/api.md", "generated", n=1))
        print(f"\ndocs/api.md is out of date: regenerate it with `{COMMAND}`", file=sys.stderr)
        return 1
    with open(args.out, "w", encoding="utf-8") as f:
        f.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
