"""One command line: the Python package's commands (plot, reproduce, sensitivity, sweep,
calibrate, pile) parse with argparse but print their help and their errors in the layout of the
C++ commands (CLI11: the one-line description, ``Usage:``, ``Positionals:``, ``Options:`` with the
value's type and ``REQUIRED``, then the longer text), and the top-level help lists them with the
C++ commands (``_core.cli_main(args, COMMANDS)``)."""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn, Optional

# The command's name: the C++ front end's (src/crushdem/cli/cli.hpp: kCommand, kAliasNote; held
# equal by tests/python/test_cli.py).
PROG = "crushdem-sand"
ALIAS_NOTE = "note: `crushdem` is now `crushdem-sand`; the old name is an alias until version 0.2\n"

# The Python package's commands and their one-line descriptions: the top-level help's list and
# the first line of each command's help.
COMMANDS = {
    "plot": "draw the time series of a run (DIR/timeseries.csv) as PNG figures",
    "reproduce": "run the reference study's section 3 and draw its figures",
    "sensitivity": "q_max of the triaxial test under each uncertain modelling choice",
    "sweep": "run many variants of one configuration on Dask",
    "calibrate": "fit one or two parameters to targets with sweep runs",
    "pile": "install, age and load-test a pile at each ageing time, and fit its set-up",
}

# CLI11's layout: names and value types padded to this column, the description after them (on the
# next line, at the column, when the names are longer).
_COLUMN = 30


def _type_name(action: argparse.Action) -> str:
    """The value's type as CLI11 writes it: INT, FLOAT or TEXT (or the metavar that names it),
    its choices, `...` for a list, REQUIRED."""
    if action.nargs == 0:  # a flag
        return ""
    if action.metavar is not None and action.option_strings:
        name = str(action.metavar)
    else:  # a positional's metavar is its name, shown before this
        name = {int: "INT", float: "FLOAT"}.get(action.type, "TEXT")  # type: ignore[arg-type]
    if action.choices is not None:
        name += ":{" + ",".join(str(c) for c in action.choices) + "}"
    if action.nargs in ("+", "*") or isinstance(action, argparse._AppendAction):
        name += " ..."
    required = action.required if action.option_strings else action.nargs not in ("?", "*")
    return name + (" REQUIRED" if required else "")


def _entry(names: str, description: str) -> str:
    head = "  " + names
    if not description:
        return head + "\n"
    if len(head) >= _COLUMN:
        return head + "\n" + " " * _COLUMN + description + "\n"
    return head.ljust(_COLUMN) + description + "\n"


class CommandParser(argparse.ArgumentParser):
    """An ``argparse.ArgumentParser`` whose help and errors read as the C++ commands' do:
    ``crushdem-sand NAME: error: MESSAGE`` and ``Run 'crushdem-sand NAME --help' for the options.``,
    exit status 2."""

    def __init__(self, name: str, details: Optional[str] = None) -> None:
        super().__init__(prog=f"{PROG} {name}", description=COMMANDS[name], epilog=details,
                         add_help=False)
        self.add_argument("-h", "--help", action="help",
                          help="Print this help message and exit")

    def add_backend(self, what: str) -> None:
        """``--backend cpu|cuda|emulated`` (default cpu), described by ``what``."""
        self.add_argument("--backend", default="cpu", choices=("cpu", "cuda", "emulated"),
                          help=what)

    def _expand(self, action: argparse.Action) -> str:
        # argparse's %-formatting of help texts (%(default)s, %%); a stray % raises, as there.
        return (action.help or "") % dict(vars(action), prog=self.prog)

    def format_usage(self) -> str:
        positionals = [a.metavar or a.dest.upper() for a in self._actions
                       if not a.option_strings and a.help != argparse.SUPPRESS]
        return " ".join(["Usage:", self.prog, "[OPTIONS]", *map(str, positionals)]) + "\n"

    def format_help(self) -> str:
        shown = [a for a in self._actions if a.help != argparse.SUPPRESS]
        positionals = [a for a in shown if not a.option_strings]
        options = [a for a in shown if a.option_strings]
        out = [(self.description or "") + "\n", self.format_usage(), "\n"]
        if positionals:
            out.append("Positionals:\n")
            for a in positionals:
                names = f"{a.metavar or a.dest.upper()} {_type_name(a)}"
                out.append(_entry(names, self._expand(a)))
            out.append("\n")
        out.append("Options:\n")
        for a in options:
            names = ",".join(a.option_strings)
            type_name = _type_name(a)
            out.append(_entry(f"{names} {type_name}" if type_name else names, self._expand(a)))
        if self.epilog:
            out.append("\n" + self.epilog.strip("\n") + "\n")
        return "".join(out)

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message}\n"
                         f"Run '{self.prog} --help' for the options.\n")
        sys.exit(2)
