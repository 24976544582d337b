"""The optional dependencies: each imported only by what needs it, and when missing, an error
that names the package and the pip command of the extra that installs it (pyproject.toml)."""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType
from typing import Optional, Sequence

# The extra of pyproject.toml that installs each optional package.
EXTRAS = {"matplotlib": "plot", "distributed": "sweep", "dask": "sweep", "pyarrow": "sweep",
          "scipy": "calibrate"}


class MissingDependency(ImportError):
    """An optional package is not installed; the message says how to install it."""


def message(package: str, feature: str, extra: Optional[str] = None) -> str:
    """``FEATURE needs PACKAGE: pip install "crushdem-sand[EXTRA]"``."""
    return f'{feature} needs {package}: pip install "crushdem-sand[{extra or EXTRAS[package]}]"'


def available(package: str) -> bool:
    """Whether ``package`` can be imported (without importing it)."""
    try:
        return importlib.util.find_spec(package) is not None
    except (ImportError, ValueError):
        return False


def require(module: str, feature: str, extra: Optional[str] = None) -> ModuleType:
    """``module`` (e.g. "matplotlib.pyplot") imported; MissingDependency naming its package
    and the extra when the package is not installed."""
    package = module.partition(".")[0]
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise MissingDependency(message(package, feature, extra)) from e


def check(feature: str, packages: Sequence[str], extra: Optional[str] = None) -> None:
    """Raises MissingDependency for the first of ``packages`` that is not installed (a command
    checks what it needs before it runs anything)."""
    for package in packages:
        if not available(package):
            raise MissingDependency(message(package, feature, extra))
