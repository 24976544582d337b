"""The Python modules of the checkout, for tests that must follow the source without a rebuild:
python/crushdem_sand/<name>.py (or the subpackage python/crushdem_sand/<name>/, or a dotted name
such as ``figures.study``) imported as a module of a stand-in package (so that its relative imports
resolve in the source tree too, without the package __init__ and its compiled _core); the
installed crushdem_sand module where this file does not sit in a checkout."""

import importlib
import os
import sys
import types

SOURCE_DIR = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir,
                                          os.pardir, "python", "crushdem_sand"))
_PACKAGE = "crushdem_src_under_test"


def load(name):
    path = os.path.join(SOURCE_DIR, *name.split("."))
    if not (os.path.isfile(path + ".py") or os.path.isfile(os.path.join(path, "__init__.py"))):
        return importlib.import_module(f"crushdem_sand.{name}")
    if _PACKAGE not in sys.modules:
        pkg = types.ModuleType(_PACKAGE)
        pkg.__path__ = [SOURCE_DIR]
        sys.modules[_PACKAGE] = pkg
    return importlib.import_module(f"{_PACKAGE}.{name}")


def load_script(name):
    """scripts/<name>.py of the checkout as a module (the scripts are not part of the package)."""
    import importlib.util

    path = os.path.join(os.path.dirname(os.path.dirname(SOURCE_DIR)), "scripts", name + ".py")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
