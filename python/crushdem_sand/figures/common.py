"""What the figures of :mod:`crushdem_sand.figures` share: how a run is given (a directory or its
:class:`~crushdem_sand.rundir.RunData`), pyplot imported when a figure is drawn (never on import,
and under whatever backend is in use), the legend, log-tick, time-mark and colour helpers."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ..analysis import DAY_S, HOUR_S, WALLS, has_values
from ..rundir import PathLike, RunData, read_run

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.legend import Legend

MPA = 1e-6
Run = Union[RunData, PathLike]
AGEING_TIME_LABEL = "ageing time $t$ [s] (log scale)"
# A colour per axis, the same for its two walls; what tells them apart (figures.time_series):
# the low wall wide, pale and solid with filled circles, the high one dashed with open squares
# half a marker spacing on, so that both show where they lie on each other.
WALL_COLORS = {w: f"C{k // 2}" for k, w in enumerate(WALLS)}
WALL_STYLES: Dict[str, Dict[str, Any]] = {
    "min": dict(ls="-", lw=3.0, alpha=0.5, marker="o"),
    "max": dict(ls="--", lw=1.4, marker="s", open=True, phase=0.5)}
MARKERS = ("o", "s", "^", "D", "v")


def as_run(run: Run) -> RunData:
    """``run`` itself when it is RunData, else the run directory ``run`` read."""
    return run if isinstance(run, RunData) else read_run(run)


def pyplot() -> Any:
    """matplotlib.pyplot, imported when a figure is drawn."""
    from .._optional import require

    return require("matplotlib.pyplot", "crushdem's figures")


def unique_legend(ax: Axes, *twins: Axes, **kw: Any) -> Optional[Legend]:
    """One legend for the curves of ``ax`` and its twin axes, each label once (a stage drawn in
    several segments, or one curve per wall of several groups, repeats its label); None when
    nothing is labelled."""
    handles, labels = [], []
    for a in (ax,) + twins:
        h, lab = a.get_legend_handles_labels()
        handles += h
        labels += lab
    seen: Dict[str, Any] = {}
    for h, lab in zip(handles, labels):
        if lab and not lab.startswith("_") and lab not in seen:
            seen[lab] = h
    if not seen:
        return None
    return ax.legend(list(seen.values()), list(seen), **kw)


def stacked_axes(two: bool, height_two: float, height_one: float = 4.5) -> Tuple[Any, Any]:
    """A figure 7 inches wide of one axes, or of two stacked that share x: (figure, the axes as
    a 2-D array, one column)."""
    return pyplot().subplots(2 if two else 1, 1, figsize=(7, height_two if two else height_one),
                             sharex=True, squeeze=False)


def label_axes(ax: Axes, x_label: str, y_label: str, title: str, **legend: Any) -> None:
    """Names the axes of ``ax`` and its title and grids it (log decades too); with ``legend``
    keywords, draws :func:`unique_legend` with them."""
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    if legend:
        unique_legend(ax, **legend)


def tick_number(v: float) -> str:
    """A tick label: plain from 1e-4 to 1e5 (0.001, 0.2, 3600, 86400), else a power of ten in
    mathtext ($10^{6}$, $2.6\\times10^{6}$) instead of Python's 1e+06."""
    if v == 0 or 1e-4 <= abs(v) < 1e5:
        return f"{v:g}"
    e = int(math.floor(math.log10(abs(v)) + 1e-9))
    m = float(f"{v / 10.0 ** e:.3g}")
    return f"$10^{{{e}}}$" if m == 1.0 else f"${m:g}\\times10^{{{e}}}$"


def plain_log_ticks(ax: Axes) -> None:
    """Tick labels of a log x axis as plain numbers (0.1, 0.2, 1) instead of powers of ten,
    up to 1e5; beyond it as $10^{6}$ (tick_number)."""
    from matplotlib.ticker import FuncFormatter

    def minor(v: float, _pos: int) -> str:
        # 2 and 5 between the decades only on an axis of at most two decades: on a wider one
        # their labels (20000, 50000, 100000) run into each other.
        lo, hi = sorted(ax.get_xlim())
        narrow = lo > 0 and hi / lo <= 10 ** 2.05
        return tick_number(v) if narrow and f"{v:.0e}"[0] in "25" else ""

    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: tick_number(v)))
    ax.xaxis.set_minor_formatter(FuncFormatter(minor))


def mark_times(axes: Sequence[Axes], label_ax: Optional[Axes] = None,
               marks: Sequence[Tuple[float, str]] = ((HOUR_S, "1 h"), (DAY_S, "1 day"))) -> None:
    """Dotted vertical lines at ``marks`` (1 h and 1 day) on log-time axes, where inside the
    data range; labelled on ``label_ax``."""
    for ax in axes:
        lo, hi = ax.get_xlim()
        for x, text in marks:
            if lo <= x <= hi * 1.0001:
                ax.axvline(x, color="0.35", ls=":", lw=1.2)
                if ax is label_ax:
                    ax.text(x, 0.97, f"{text} ", transform=ax.get_xaxis_transform(),
                            rotation=90, ha="right", va="top", fontsize=8, color="0.25",
                            bbox=dict(facecolor="white", alpha=0.7, lw=0, pad=1))
        ax.set_xlim(lo, hi)


def stage_color(k: int) -> str:
    """The colour of stage ``k`` (the colour cycle, in order)."""
    cycle = pyplot().rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])
    return cycle[k % len(cycle)]


def time_axis(d: Mapping[str, np.ndarray]) -> Tuple[np.ndarray, str]:
    """The x axis of a figure against time: DEM time, else the step, else the row, with its
    label."""
    if has_values(d, "time_s"):
        return d["time_s"], "time $t$ [s]"
    if has_values(d, "step"):
        return d["step"], "step"
    n = len(next(iter(d.values()))) if d else 0
    return np.arange(n, dtype=np.float64), "row"

