"""The figures against time (``crushdem-sand plot``): the DEM clock, and for the "age" stages, whose
off-DEM jumps make a day of ageing a few milliseconds of DEM time, the ageing time on a second
panel (events.csv, one point per dynamic phase, log axis)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from ..analysis import WALLS, age_stage_indices, ageing_groups, has_values
from ..rundir import RunData
from .common import (AGEING_TIME_LABEL, MARKERS, MPA, WALL_COLORS, WALL_STYLES, Run, as_run,
                     mark_times, pyplot, time_axis, unique_legend)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class Series(NamedTuple):
    """A curve of a figure against time: its column, label, colour and line style, and how it
    stays visible where another lies on it (a wall and the one opposite carry the same stress):
    a width and opacity, markers (on the DEM-time panel; on the ageing panel the markers tell
    the age stages apart), open or filled, starting ``phase`` of a marker spacing along the
    curve so that two curves' markers alternate."""

    column: str
    label: str
    color: str
    ls: str = "-"
    lw: float = 1.5
    alpha: float = 1.0
    marker: Optional[str] = None
    open: bool = False
    phase: float = 0.0

    def style(self) -> Dict[str, Any]:
        """The keywords of ``Axes.plot`` for the line, its markers filled or open."""
        return dict(ls=self.ls, lw=self.lw, alpha=self.alpha, color=self.color,
                    mfc="none" if self.open else self.color)


# Markers along a curve on the DEM-time panel.
_MARKS_PER_CURVE = 12


def _ageing_plan(run: RunData):
    """(rows of the time series on the DEM clock, ageing groups of events.csv with a phase at
    t > 0). Without such a group every row is on the DEM clock."""
    d, ev = run.timeseries, run.events
    n = len(next(iter(d.values()))) if d else 0
    all_rows = np.ones(n, dtype=bool)
    if ev is None or not has_values(ev, "ageing_time_s"):
        return all_rows, []
    t_age = ev["ageing_time_s"]
    groups = [g for g in ageing_groups(ev, run.summary) if np.any(t_age[g[1]] > 0)]
    if not groups:
        return all_rows, []
    age = age_stage_indices(run.summary, ev)
    if has_values(d, "stage") and age:
        st = d["stage"]
        dem = ~np.isin(st, age)
        # The first row of an age stage is the last of the stage before: kept there.
        dem[1:] |= np.isin(st[1:], age) & ~np.isin(st[:-1], age)
        return dem, groups
    return all_rows, groups


Row = Tuple[str, Sequence[Series]]  # a row of panels: its title ("" for none), its curves


def _time_figure(run: RunData, rows: Sequence[Row], y_label: str, title: str,
                 log_y: bool = False):
    """Each row's ``series`` against DEM time (the stages before and between age stages) and,
    for the age stages, against ageing time on a panel to the right (log axis, one point per
    dynamic phase, the t = 0 phase drawn open at a tenth of the first ageing time). The rows
    share their axes."""
    plt = pyplot()
    d, ev = run.timeseries, run.events
    dem_rows, groups = _ageing_plan(run)

    def on_age_panel(s: Series) -> bool:
        return bool(groups) and ev is not None and has_values(ev, s.column)

    rows = [(name, series) for name, series in rows
            if any(has_values(d, s.column) or on_age_panel(s) for s in series)]
    every = [s for _, series in rows for s in series]
    with_dem = bool(dem_rows.any()) and any(has_values(d, s.column) for s in every)
    with_age = any(on_age_panel(s) for s in every)
    if not (with_dem or with_age):
        return None
    n_cols = int(with_dem) + int(with_age)
    fig, axes = plt.subplots(len(rows), n_cols, figsize=(7 if n_cols == 1 else 11,
                                                         4.5 if len(rows) == 1
                                                         else 1.0 + 2.6 * len(rows)),
                             sharex="col", sharey=True, squeeze=False)
    for r, (name, series) in enumerate(rows):
        bottom = r == len(rows) - 1
        if with_dem:
            ax = axes[r, 0]
            t, t_label = time_axis(d)
            _draw_dem(ax, t, d, dem_rows, series, log_y)
            if bottom:
                ax.set_xlabel(t_label + (" (stages before ageing)" if with_age else ""))
            ax.set_ylabel(y_label)
            if name:
                ax.set_title(name, fontsize=10)
        if with_age:
            ax = axes[r, -1]
            _draw_ageing(ax, ev, groups, [s for s in series if on_age_panel(s)], with_dem,
                         log_y)
            if bottom:
                ax.set_xlabel(AGEING_TIME_LABEL)
            if not with_dem:
                ax.set_ylabel(y_label)
            parts = [] if with_dem else [name]  # the row's name is on its DEM panel
            parts += ["age stages: one point per dynamic phase"] if r == 0 else []
            ax.set_title(", ".join(p for p in parts if p), fontsize=10)
            mark_times([ax], label_ax=ax if r == 0 else None)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def _draw_dem(ax, t: np.ndarray, d, dem_rows: np.ndarray, series: Sequence[Series],
              log_y: bool) -> None:
    """The DEM-time panel: each series at the rows on the DEM clock, its markers spread along
    it."""
    for s in series:
        if not has_values(d, s.column):
            continue
        y = np.where(dem_rows, d[s.column], math.nan)
        keep = np.isfinite(y) & (y > 0) if log_y else np.ones(len(y), dtype=bool)
        marks: Dict[str, Any] = {}
        if s.marker is not None:
            # Every other point at least, so that two curves' markers can alternate.
            every = max(2, int(np.count_nonzero(keep)) // _MARKS_PER_CURVE)
            marks = dict(marker=s.marker, ms=5, markevery=(int(s.phase * every), every))
        ax.plot(t[keep], y[keep], label=s.label, **s.style(), **marks)
    if log_y:
        ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=9)


def _draw_ageing(ax, ev, groups, series: Sequence[Series], with_dem: bool,
                 log_y: bool) -> None:
    """The ageing-time panel: each series at the dynamic phases with t > 0 (with several age
    stages, a marker shape per stage), the t = 0 phase open at the left."""
    t_age = ev["ageing_time_s"]
    multi = len(groups) > 1
    zero_label = "t = 0 (before the first jump), drawn open"
    for i, (group, idx, ref) in enumerate(groups):
        pos = idx[t_age[idx] > 0]
        m = MARKERS[i % len(MARKERS)]
        for s in series:
            y = ev[s.column]
            # The DEM-time panel's legend names the colours already.
            lab = f"{s.label} ({group})" if multi else None if with_dem else s.label
            # The series' own marker, unless the shapes must tell several age stages apart.
            marker = s.marker if s.marker is not None and not multi else m
            ms = 5 if s.open else 3.5 if s.marker is not None else 4
            ax.plot(t_age[pos], y[pos], marker=marker, ms=ms, **dict(s.style(), lw=0.6 * s.lw),
                    label=lab)
        # The state before the first jump has no place on a log axis: drawn open at a tenth
        # of the first ageing time, joined by a dotted line.
        if t_age[ref] <= 0 and pos.size:
            x0 = t_age[pos[0]] / 10.0
            for s in series:
                y = ev[s.column]
                ax.plot([x0, t_age[pos[0]]], [y[ref], y[pos[0]]], ls=":", lw=0.8,
                        color=s.color)
                ax.plot([x0], [y[ref]], marker=m, ms=4, mfc="none", ls="none",
                        color=s.color, label=zero_label)
    ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=8)


def figure_stress_time(run: Run) -> Optional[Figure]:
    """stress_time.png: the wall normal stresses [MPa] against time (age stages against ageing
    time, on panels to the right), a row of panels per axis (x, y, z walls; one stress scale),
    each with the mean stress p dotted. The two walls of an axis, which often carry the same
    stress, are both visible: the low one (xmin, ymin, zmin) a wide pale solid line with filled
    circles, the high one a dashed line with open squares between them."""
    run = as_run(run)
    d = run.timeseries
    cols = [f"wall_{w}_stress_Pa" for w in WALLS] + ["mean_stress_Pa"]
    if not any(has_values(d, c) for c in cols):
        return None
    mean = Series("mean_stress_Pa", "mean $p$", "k", ls=":", lw=1.5)
    rows: List[Row] = []
    for axis in "xyz":
        walls = [Series(f"wall_{w}_stress_Pa", w, WALL_COLORS[w], **WALL_STYLES[w[1:]])
                 for w in (axis + "min", axis + "max")]
        rows.append((f"{axis} walls", walls + [mean]))
    # Only the mean where no wall has a column.
    rows = [row for row in rows if any(has_values(d, s.column) for s in row[1][:2])] or \
        [("", [mean])]
    return _time_figure(_scaled(run, cols, MPA), rows, "normal stress $\\sigma$ [MPa]",
                        f"{run.title}: wall stresses")


def _scaled(run: RunData, cols: Sequence[str], factor: float) -> RunData:
    """``run`` with the columns ``cols`` of its time series and events multiplied by
    ``factor`` (a unit change for drawing)."""
    def scale(d):
        if d is None:
            return None
        return {k: (v * factor if k in cols else v) for k, v in d.items()}

    return RunData(directory=run.directory, timeseries=scale(run.timeseries),
                   summary=run.summary, finished=run.finished, events=scale(run.events),
                   grading=run.grading, breakage=run.breakage)


def figure_coordination(run: Run) -> Optional[Figure]:
    """coordination.png: the coordination number against time (age stages against ageing
    time)."""
    run = as_run(run)
    if not has_values(run.timeseries, "coordination_number"):
        return None
    return _time_figure(run, [("", [Series("coordination_number", "coordination number $Z$",
                                            "C0")])],
                        "coordination number $Z$ [-]", f"{run.title}: coordination number")


def figure_kinetic_energy(run: Run) -> Optional[Figure]:
    """kinetic_energy.png: the kinetic energy [J] against time, log axis (age stages against
    ageing time: the energy at the end of each dynamic phase)."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "kinetic_energy_J"):
        return None
    log_y = bool(np.any(d["kinetic_energy_J"] > 0))
    return _time_figure(run, [("", [Series("kinetic_energy_J", "kinetic energy", "C0")])],
                        "kinetic energy [J]", f"{run.title}: kinetic energy", log_y=log_y)
