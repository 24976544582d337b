"""The fixtures in tests/data that the C++ and the Python tests share."""

import os

DATA = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir,
                                     "data"))


def data_text(*names):
    """The texts of tests/data/NAME..., one after the other (e.g. the grains of grains_300.toml,
    then the test of creep_300.toml)."""
    out = []
    for name in names:
        with open(os.path.join(DATA, name)) as f:
            out.append(f.read())
    return "".join(out)
