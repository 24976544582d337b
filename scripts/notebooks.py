#!/usr/bin/env python3
"""Runs the Jupyter notebooks of notebooks/ from top to bottom and keeps the executed copies.

    .venv/bin/python scripts/notebooks.py              # execute every notebook
    .venv/bin/python scripts/notebooks.py --if-stale   # only those without a current executed copy
    .venv/bin/python scripts/notebooks.py --check      # only check they are stored without outputs
    .venv/bin/python scripts/notebooks.py triaxial     # one of them (a name or a path)

Each notebook runs in a kernel of this Python (the package installed here, ipykernel) with a new
temporary directory as its working directory, so its ``runs/`` go there and are removed after;
a cell that raises fails the run (nbclient), and the last cell of each notebook asserts what it
found. The executed copy goes to ``--out`` (build/notebooks/NAME.ipynb by default) with the
SHA-256 of the source and the seconds it took in its metadata (``crushdem``): the docs site
(scripts/docs.sh, mkdocs.yml) shows those copies, and ``--if-stale`` reruns only a notebook
whose source changed since. tests/python/test_notebooks.py runs the same function.

The notebooks are stored without outputs (``--check``): clear them before committing
(Jupyter's "Clear All Outputs", or ``--clear``).
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import os
import sys
import tempfile
import time
from typing import List, Optional

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOURCE_DIR = os.path.join(ROOT, "notebooks")
OUT_DIR = os.path.join(ROOT, "build", "notebooks")
TIMEOUT_S = 900  # per cell


def notebooks() -> List[str]:
    """The notebooks of notebooks/, sorted by name."""
    return sorted(glob.glob(os.path.join(SOURCE_DIR, "*.ipynb")))


def source_hash(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def executed_path(path: str, out_dir: str = OUT_DIR) -> str:
    return os.path.join(out_dir, os.path.basename(path))


def is_fresh(path: str, out_dir: str = OUT_DIR) -> bool:
    """Whether ``out_dir`` holds an executed copy of the notebook ``path`` as it is now."""
    import nbformat

    done = executed_path(path, out_dir)
    if not os.path.isfile(done):
        return False
    try:
        meta = nbformat.read(done, as_version=4).metadata.get("crushdem", {})
    except Exception:  # a damaged copy is stale
        return False
    return meta.get("source_sha256") == source_hash(path)


def problems(path: str) -> List[str]:
    """What keeps the stored notebook ``path`` from being clean: outputs or execution counts
    left in its code cells, or an invalid notebook."""
    import nbformat

    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    out = []
    for k, cell in enumerate(nb.cells):
        if cell.cell_type != "code":
            continue
        if cell.get("outputs"):
            out.append(f"cell {k}: has outputs")
        if cell.get("execution_count") is not None:
            out.append(f"cell {k}: has an execution count")
    return out


def clear(path: str) -> None:
    """Removes the outputs and execution counts of the notebook ``path`` in place."""
    import nbformat

    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    nbformat.write(nb, path)


def execute(path: str, out_dir: str = OUT_DIR, timeout: int = TIMEOUT_S) -> float:
    """Executes the notebook ``path`` in a kernel of this Python, in a temporary working
    directory, and writes the executed copy to ``out_dir``; returns the seconds it took. Raises
    nbclient's CellExecutionError (naming the cell and its traceback) when a cell fails."""
    import nbformat
    from nbclient import NotebookClient

    digest = source_hash(path)
    nb = nbformat.read(path, as_version=4)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="crushdem-notebook-") as work:
        # The kernel "python3" is ipykernel's, which jupyter_client starts with this Python
        # (sys.executable), so the notebooks see the package installed here. It talks to this
        # process over Unix sockets in the working directory, not over TCP.
        from traitlets.config import Config

        config = Config({"KernelManager": {"transport": "ipc",
                                           "ip": os.path.join(work, "kernel")}})
        client = NotebookClient(nb, timeout=timeout, kernel_name="python3", config=config,
                                resources={"metadata": {"path": work}})
        client.execute()
    seconds = time.perf_counter() - start
    nb.metadata["crushdem"] = {"source_sha256": digest, "seconds": round(seconds, 1)}
    os.makedirs(out_dir, exist_ok=True)
    nbformat.write(nb, executed_path(path, out_dir))
    return seconds


def _select(names: List[str]) -> List[str]:
    if not names:
        return notebooks()
    chosen = []
    for name in names:
        path = name if os.path.isfile(name) else os.path.join(
            SOURCE_DIR, name if name.endswith(".ipynb") else name + ".ipynb")
        if not os.path.isfile(path):
            raise SystemExit(f"{name}: no such notebook (notebooks/: "
                             f"{', '.join(os.path.basename(p) for p in notebooks())})")
        chosen.append(os.path.abspath(path))
    return chosen


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="notebooks (names or paths); default: all")
    parser.add_argument("--out", default=OUT_DIR, help="folder of the executed copies")
    parser.add_argument("--if-stale", action="store_true",
                        help="skip a notebook whose executed copy is current")
    parser.add_argument("--check", action="store_true",
                        help="only check that the notebooks are stored without outputs")
    parser.add_argument("--clear", action="store_true",
                        help="remove the outputs of the stored notebooks and stop")
    parser.add_argument("--timeout", type=int, default=TIMEOUT_S, help="seconds per cell")
    args = parser.parse_args(argv)
    paths = _select(args.names)
    if not paths:
        raise SystemExit("no notebooks in notebooks/")
    if args.clear:
        for path in paths:
            clear(path)
        return 0
    bad = [f"{os.path.relpath(p, ROOT)}: {msg}" for p in paths for msg in problems(p)]
    if bad:
        print("notebooks stored with outputs (clear them: scripts/notebooks.py --clear):\n  " +
              "\n  ".join(bad), file=sys.stderr)
        return 1
    if args.check:
        print(f"{len(paths)} notebooks stored without outputs")
        return 0
    for path in paths:
        name = os.path.relpath(path, ROOT)
        if args.if_stale and is_fresh(path, args.out):
            print(f"{name}: executed copy is current ({os.path.relpath(args.out, ROOT)})")
            continue
        seconds = execute(path, args.out, args.timeout)
        print(f"{name}: executed in {seconds:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
