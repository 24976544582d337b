"""The ``crushdem-sand`` command: the C++ command line (run, check, bench, ...) plus ``plot``,
``reproduce`` and ``sensitivity``.

``crushdem-sand plot DIR`` draws the time series of a finished run;
``crushdem-sand reproduce --out DIR`` runs the reference study's section 3 and draws its figures;
``crushdem-sand sensitivity`` measures q_max under each uncertain choice of docs/model.md section 5;
``crushdem-sand sweep`` runs many variants of one configuration on Dask and
``crushdem-sand calibrate`` fits one or two parameters to targets with them; ``crushdem-sand pile``
installs, ages and load-tests a pile at every ageing time and fits its set-up; every other command
is handed to the same C++ front end as the standalone executable.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import List, Optional

from ._cli import ALIAS_NOTE, PROG

# The extra of pyproject.toml and the optional packages each Python command needs, checked
# before it runs anything: a study should not fail after hours of runs for want of a package.
NEEDS = {
    "plot": ("plot", "matplotlib"),
    "reproduce": ("plot", "matplotlib"),
    "pile": ("plot", "matplotlib"),
    "sensitivity": ("sweep", "distributed"),
    "sweep": ("sweep", "distributed"),
    "calibrate": ("calibrate", "distributed", "scipy"),
}


def _check_needs(command: str) -> None:
    """Exits with status 2 and the pip command when an optional package ``command`` needs is
    missing."""
    from ._optional import MissingDependency, check

    try:
        extra, *packages = NEEDS[command]
        check(f"{PROG} {command}", packages, extra)
    except MissingDependency as e:
        sys.stderr.write(f"{e}\n")
        sys.exit(2)


def main(argv: Optional[List[str]] = None) -> None:
    """Entry point of the console script; exits with the command's status."""
    args = list(sys.argv[1:] if argv is None else argv)
    if argv is None and os.path.basename(sys.argv[0]) == "crushdem":  # the old name, an alias
        sys.stderr.write(ALIAS_NOTE)
    if "--version" in args:  # anywhere, for the Python commands as for the C++ ones
        from . import __version__

        print(f"{PROG} {__version__}")
        sys.exit(0)
    if args and args[0] in NEEDS and not ("-h" in args or "--help" in args):
        _check_needs(args[0])
    from . import _core
    from ._cli import COMMANDS

    if args and args[0] in COMMANDS:  # each command is the module of its name
        command = importlib.import_module(f".{args[0]}", __package__).main
        try:
            sys.exit(command(args[1:]))
        except _core.Interrupted as e:
            # SIGINT / SIGTERM: the run in progress saved its checkpoint; the command, run
            # again, resumes it (finished runs are reused).
            sys.stderr.write(f"{PROG}: {e}\n")
            sys.exit(128 + e.signal)

    # The C++ code writes through C stdio: empty Python's buffers first so that output stays in
    # order (_core.cli_main flushes the C streams before it returns).
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(_core.cli_main(args, list(COMMANDS.items())))


if __name__ == "__main__":
    main()
