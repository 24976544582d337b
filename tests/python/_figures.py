"""Checks shared by the figure tests: what a figure draws, read back from its matplotlib objects
and from the CSV written beside it, and whether a PNG written from it shows a drawing."""

import csv

import numpy as np


def read_csv_with_comments(path):
    """(the ``#`` lines, the rows as dicts) of a CSV that ``crushdem-sand reproduce`` wrote."""
    with open(path) as f:
        lines = f.read().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if not ln.startswith("#")]
    return comments, list(csv.DictReader(body))


def labelled(ax, label):
    """The one line of ``ax`` whose label is ``label``."""
    found = [ln for ln in ax.get_lines() if ln.get_label() == label]
    assert len(found) == 1, (label, [ln.get_label() for ln in ax.get_lines()])
    return found[0]


def labelled_like(ax, start):
    """The one line of ``ax`` whose label starts with ``start``."""
    found = [ln for ln in ax.get_lines() if str(ln.get_label()).startswith(start)]
    assert len(found) == 1, (start, [ln.get_label() for ln in ax.get_lines()])
    return found[0]


def legend_texts(ax):
    legend = ax.get_legend()
    return [] if legend is None else [t.get_text() for t in legend.get_texts()]


def assert_drawn(line, x, y):
    """``line`` draws exactly the points (x, y) (NaN where y is NaN)."""
    np.testing.assert_array_equal(np.asarray(line.get_xdata(), dtype=float), x)
    np.testing.assert_array_equal(np.asarray(line.get_ydata(), dtype=float), y)


def assert_png_shows_a_drawing(path, max_ink=0.5):
    """``path`` is a PNG whose pixels are neither blank nor filled: a few percent of them carry
    ink (axes, curves, text) in several colours; a colour map (``max_ink`` raised) fills its
    axes."""
    import matplotlib.image

    with open(path, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n", path
    rgb = matplotlib.image.imread(path)[..., :3].reshape(-1, 3)
    ink = float(np.mean(np.any(rgb < 0.9, axis=1)))
    assert 0.005 < ink < max_ink, (path, ink)
    level = np.round(rgb * 255).astype(np.uint32)
    colours = np.unique((level[:, 0] << 16) | (level[:, 1] << 8) | level[:, 2])
    assert len(colours) > 16, (path, len(colours))
