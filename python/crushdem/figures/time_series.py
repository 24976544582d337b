"""The figures against time (``crushdem plot``): the DEM clock, and for the "age" stages, whose
off-DEM jumps make a day of ageing a few milliseconds of DEM time, the ageing time on a second
panel (events.csv, one point per dynamic phase, log axis)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, List, Optional, Sequence, Tuple

import numpy as np

from ..analysis import WALLS, age_stage_indices, ageing_groups, has_values
from ..rundir import RunData
from .common import (AGEING_TIME_LABEL, MARKERS, MPA, WALL_COLORS, Run, as_run, mark_times,
                     pyplot, time_axis, unique_legend)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


Series = Tuple[str, str, str, str]  # column, label, colour, line style


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


def _time_figure(run: RunData, series: Sequence[Series], y_label: str, title: str,
                 log_y: bool = False):
    """``series`` against DEM time (the stages before and between age stages) and, for the age
    stages, against ageing time on a second panel (log axis, one point per dynamic phase, the
    t = 0 phase drawn open at a tenth of the first ageing time)."""
    plt = pyplot()
    d, ev = run.timeseries, run.events
    dem_rows, groups = _ageing_plan(run)
    series_ev = [s for s in series if ev is not None and has_values(ev, s[0])] if groups else []
    with_dem = bool(dem_rows.any()) and any(has_values(d, s[0]) for s in series)
    with_age = bool(series_ev)
    if not (with_dem or with_age):
        return None
    n_panels = int(with_dem) + int(with_age)
    fig, axes = plt.subplots(1, n_panels, figsize=(7 if n_panels == 1 else 11, 4.5),
                             sharey=True, squeeze=False)
    axes = list(axes[0])
    if with_dem:
        ax = axes[0]
        t, t_label = time_axis(d)
        for col, label, color, ls in series:
            if not has_values(d, col):
                continue
            y = np.where(dem_rows, d[col], math.nan)
            keep = np.isfinite(y) & (y > 0) if log_y else np.ones(len(y), dtype=bool)
            ax.plot(t[keep], y[keep], ls=ls, color=color, label=label)
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel(t_label + (" (stages before ageing)" if with_age else ""))
        ax.set_ylabel(y_label)
        ax.grid(True, which="both", alpha=0.3)
        unique_legend(ax, fontsize=9)
    if with_age:
        ax = axes[-1]
        t_age = ev["ageing_time_s"]
        multi = len(groups) > 1
        zero_label = "t = 0 (before the first jump), drawn open"
        for i, (group, idx, ref) in enumerate(groups):
            pos = idx[t_age[idx] > 0]
            m = MARKERS[i % len(MARKERS)]
            for col, label, color, ls in series_ev:
                y = ev[col]
                # The DEM-time panel's legend names the colours already.
                lab = f"{label} ({group})" if multi else None if with_dem else label
                ax.plot(t_age[pos], y[pos], marker=m, ms=4, ls=ls, lw=0.9, color=color,
                        label=lab)
            # The state before the first jump has no place on a log axis: drawn open at a
            # tenth of the first ageing time, joined by a dotted line.
            if t_age[ref] <= 0 and pos.size:
                x0 = t_age[pos[0]] / 10.0
                for col, _label, color, _ls in series_ev:
                    y = ev[col]
                    ax.plot([x0, t_age[pos[0]]], [y[ref], y[pos[0]]], ls=":", lw=0.8,
                            color=color)
                    ax.plot([x0], [y[ref]], marker=m, ms=4, mfc="none", ls="none",
                            color=color, label=zero_label)
        ax.set_xscale("log")
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel(AGEING_TIME_LABEL)
        if not with_dem:
            ax.set_ylabel(y_label)
        ax.set_title("age stages: one point per dynamic phase", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        unique_legend(ax, fontsize=8)
        mark_times([ax], label_ax=ax)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def figure_stress_time(run: Run) -> Optional[Figure]:
    """stress_time.png: the wall normal stresses and the mean stress p [MPa] against time (age
    stages against ageing time, on a second panel)."""
    run = as_run(run)
    d = run.timeseries
    cols = [f"wall_{w}_stress_Pa" for w in WALLS] + ["mean_stress_Pa"]
    if not any(has_values(d, c) for c in cols):
        return None
    series: List[Series] = [(f"wall_{w}_stress_Pa", w, WALL_COLORS[w], "-") for w in WALLS]
    series.append(("mean_stress_Pa", "mean $p$", "k", "--"))
    return _time_figure(_scaled(run, cols, MPA), series, "normal stress $\\sigma$ [MPa]",
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
    return _time_figure(run, [("coordination_number", "coordination number $Z$", "C0", "-")],
                        "coordination number $Z$ [-]", f"{run.title}: coordination number")


def figure_kinetic_energy(run: Run) -> Optional[Figure]:
    """kinetic_energy.png: the kinetic energy [J] against time, log axis (age stages against
    ageing time: the energy at the end of each dynamic phase)."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "kinetic_energy_J"):
        return None
    log_y = bool(np.any(d["kinetic_energy_J"] > 0))
    return _time_figure(run, [("kinetic_energy_J", "kinetic energy", "C0", "-")],
                        "kinetic energy [J]", f"{run.title}: kinetic energy", log_y=log_y)
