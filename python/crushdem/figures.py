"""One function per figure of a run directory, each returning its matplotlib Figure.

Every ``figure_*(run)`` takes a run directory (a path) or the :class:`~crushdem.rundir.RunData`
that :func:`~crushdem.rundir.read_run` returns (read once when drawing several), and returns a
:class:`matplotlib.figure.Figure`, laid out and ready to save or show, or ``None`` when the run
lacks the data the figure needs. The figures are made with pyplot under whatever backend is in
use (inline in a notebook); nothing here selects one. :data:`FIGURES` maps each file name that
``crushdem plot`` writes to its function; the module docstring of :mod:`crushdem.plot`
describes them.

Time: the figures against time use the DEM clock, except for "age" stages, whose off-DEM jumps
make a day of ageing a few milliseconds of DEM time: the figures with an ageing panel draw the
age stages against the ageing time (events.csv, one point per dynamic phase, log axis) and the
other stages against DEM time.
"""

from __future__ import annotations

import math
import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .analysis import (DAY_S, HOUR_S, PLAUSIBLE_OEDOMETRIC_1DAY, T_REF_S, WALLS,
                       age_stage_indices, ageing_groups, as_float, has_values, stage_label,
                       stage_rows, value_at, vertical_stress, walls_fixed)
from .rundir import PathLike, RunData, read_run

MPA = 1e-6
Run = Union[RunData, PathLike]
AGEING_TIME_LABEL = "ageing time $t$ [s] (log scale)"
WALL_COLORS = {w: f"C{i}" for i, w in enumerate(WALLS)}
_MARKERS = ("o", "s", "^", "D", "v")


def as_run(run: Run) -> RunData:
    """``run`` itself when it is RunData, else the run directory ``run`` read."""
    return run if isinstance(run, RunData) else read_run(run)


def _pyplot():
    import matplotlib.pyplot as plt

    return plt


# --- helpers shared by the figures (and crushdem reproduce) -------------------------------------


def unique_legend(ax, *twins, **kw):
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


def plain_log_ticks(ax) -> None:
    """Tick labels of a log x axis as plain numbers (0.1, 0.2, 1) instead of powers of ten."""
    from matplotlib.ticker import FuncFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    ax.xaxis.set_minor_formatter(FuncFormatter(
        lambda v, _pos: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""))


def mark_times(axes: Sequence[Any], label_ax=None,
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
    cycle = _pyplot().rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])
    return cycle[k % len(cycle)]


def _time_axis(d) -> Tuple[np.ndarray, str]:
    if has_values(d, "time_s"):
        return d["time_s"], "time $t$ [s]"
    if has_values(d, "step"):
        return d["step"], "step"
    n = len(next(iter(d.values()))) if d else 0
    return np.arange(n, dtype=np.float64), "row"


# --- time figures: DEM time, and ageing time for the age stages ---------------------------------


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
    plt = _pyplot()
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
        t, t_label = _time_axis(d)
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
            m = _MARKERS[i % len(_MARKERS)]
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


def figure_stress_time(run: Run):
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


def figure_coordination(run: Run):
    """coordination.png: the coordination number against time (age stages against ageing
    time)."""
    run = as_run(run)
    if not has_values(run.timeseries, "coordination_number"):
        return None
    return _time_figure(run, [("coordination_number", "coordination number $Z$", "C0", "-")],
                        "coordination number $Z$ [-]", f"{run.title}: coordination number")


def figure_kinetic_energy(run: Run):
    """kinetic_energy.png: the kinetic energy [J] against time, log axis (age stages against
    ageing time: the energy at the end of each dynamic phase)."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "kinetic_energy_J"):
        return None
    log_y = bool(np.any(d["kinetic_energy_J"] > 0))
    return _time_figure(run, [("kinetic_energy_J", "kinetic energy", "C0", "-")],
                        "kinetic energy [J]", f"{run.title}: kinetic energy", log_y=log_y)


# --- stress, strain, void ratio ------------------------------------------------------------------


def figure_strain_stress(run: Run):
    """strain_stress.png: deviator stress q (or the axial wall stress) [MPa] against axial
    strain [%], with the volumetric strain [%] on a second panel when present."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "axial_strain"):
        return None
    eps_a = d["axial_strain"] * 100.0
    curves = []
    if has_values(d, "deviator_stress_Pa"):
        curves.append(("deviator $q$", d["deviator_stress_Pa"]))
    for w in ("zmax", "zmin"):
        c = f"wall_{w}_stress_Pa"
        if has_values(d, c):
            curves.append((f"axial $\\sigma_a$ ({w})", d[c]))
            break
    if not curves:
        return None
    plt = _pyplot()
    with_vol = has_values(d, "volumetric_strain")
    fig, axes = plt.subplots(2 if with_vol else 1, 1, figsize=(7, 7 if with_vol else 4.5),
                             sharex=True, squeeze=False)
    ax = axes[0, 0]
    for label, s in curves:
        ax.plot(eps_a, s * MPA, label=label)
    ax.set_ylabel("stress [MPa]")
    ax.set_title(f"{run.title}: stress against axial strain")
    ax.grid(True, alpha=0.3)
    unique_legend(ax)
    if with_vol:
        axes[1, 0].plot(eps_a, d["volumetric_strain"] * 100.0, color="tab:green")
        axes[1, 0].set_ylabel("volumetric strain $\\varepsilon_v$ [%]")
        axes[1, 0].grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("axial strain $\\varepsilon_a$ [%]")
    fig.tight_layout()
    return fig


def figure_void_ratio(run: Run):
    """void_ratio.png: void ratio e against mean stress p [MPa] (log axis), one colour per
    stage."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "void_ratio"):
        return None
    p = None
    if has_values(d, "mean_stress_Pa"):
        p = d["mean_stress_Pa"]
    else:
        walls = [d[f"wall_{w}_stress_Pa"] for w in WALLS if has_values(d, f"wall_{w}_stress_Pa")]
        if walls:
            with np.errstate(all="ignore"):
                p = np.nanmean(np.vstack(walls), axis=0)
    if p is None or not np.any(p > 0):
        return None
    plt = _pyplot()
    e = d["void_ratio"]
    stages = stage_rows(d, run.summary)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    if stages:
        for k, rows, info in stages:
            keep = rows & (p > 0) & np.isfinite(e)
            if keep.any():
                ax.semilogx(p[keep] * MPA, e[keep], "o-", ms=3, color=stage_color(k),
                            label=stage_label(k, info))
        unique_legend(ax)
    else:
        keep = p > 0
        ax.semilogx(p[keep] * MPA, e[keep], "o-", ms=3)
    ax.set_xlabel("mean stress $p$ [MPa] (log scale)")
    ax.set_ylabel("void ratio $e$ [-]")
    ax.set_title(f"{run.title}: compression curve $e$ - log $p$")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return fig


def figure_triaxial(run: Run):
    """triaxial.png: for each triaxial stage, q [MPa] (peak marked with q_max and the peak
    friction angle) and the change of volumetric strain [%] against the stage's axial strain
    [%]. A stage's warning (summary.json) is figure text below the axes."""
    run = as_run(run)
    d = run.timeseries
    triaxial = [(k, rows, info) for k, rows, info in stage_rows(d, run.summary)
                if info.get("type") == "triaxial" and rows.any()]
    if not triaxial or not has_values(d, "deviator_stress_Pa"):
        return None
    plt = _pyplot()
    with_vol = has_values(d, "volumetric_strain")
    fig, axes = plt.subplots(2 if with_vol else 1, 1, figsize=(7, 7.5 if with_vol else 4.5),
                             sharex=True, squeeze=False)
    ax_q = axes[0, 0]
    warnings: List[Tuple[str, str]] = []
    for i, (k, rows, info) in enumerate(triaxial):
        color = stage_color(k)
        idx = np.flatnonzero(rows)
        if has_values(d, "stage_axial_strain"):
            eps = d["stage_axial_strain"][idx]
        elif has_values(d, "axial_strain"):
            eps = d["axial_strain"][idx] - d["axial_strain"][idx[0]]
        else:
            continue
        q = d["deviator_stress_Pa"][idx]
        label = stage_label(k, info)
        s3 = as_float(info.get("sigma_3_at_q_max_Pa"))
        if math.isfinite(s3):
            label += f", $\\sigma_3$ = {s3 * MPA:.3g} MPa"
        ax_q.plot(eps * 100.0, q * MPA, "-", color=color, label=label)
        # Peak: summary.json tracks every step; fall back to the sampled rows.
        q_max = as_float(info.get("q_max_Pa"))
        eps_peak = as_float(info.get("axial_strain_at_q_max"))
        if not (math.isfinite(q_max) and math.isfinite(eps_peak)) and np.isfinite(q).any():
            j = int(np.nanargmax(q))
            q_max, eps_peak = float(q[j]), float(eps[j])
        if math.isfinite(q_max) and math.isfinite(eps_peak):
            ax_q.plot([eps_peak * 100.0], [q_max * MPA], "o", color=color, ms=7, mfc="none",
                      mew=2)
            text = (f"$q_{{max}}$ = {q_max * MPA:.3g} MPa"
                    f" at $\\varepsilon_a$ = {eps_peak * 100:.2f} %")
            phi = as_float(info.get("friction_angle_peak_deg"))
            if math.isfinite(phi):
                text += f"\n$\\varphi_{{peak}}$ = {phi:.1f}$^\\circ$"
            ax_q.annotate(text, xy=(eps_peak * 100.0, q_max * MPA),
                          xytext=(0.35, 0.08 + 0.16 * i), textcoords="axes fraction",
                          color=color, fontsize=9,
                          arrowprops=dict(arrowstyle="->", color=color))
        if info.get("warning"):
            warnings.append((color, f"{stage_label(k, info)}: warning: {info['warning']}"))
        if with_vol:
            ev = d["volumetric_strain"][idx]
            axes[1, 0].plot(eps * 100.0, (ev - ev[0]) * 100.0, "-", color=color,
                            label=stage_label(k, info))
    ax_q.set_ylabel("deviator stress $q = \\sigma_1 - \\sigma_3$ [MPa]")
    ax_q.set_title(f"{run.title}: triaxial compression")
    ax_q.set_ylim(bottom=min(0.0, ax_q.get_ylim()[0]))
    ax_q.grid(True, alpha=0.3)
    unique_legend(ax_q, loc="lower right", fontsize=9)
    if with_vol:
        ax_v = axes[1, 0]
        ax_v.axhline(0.0, color="0.5", lw=0.8)
        ax_v.set_ylabel("volumetric strain (compression +) [%]")
        ax_v.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("axial strain of the stage $\\varepsilon_a$ [%]")
    _footnotes(fig, warnings)
    return fig


def _footnotes(fig, notes: Sequence[Tuple[str, str]]) -> None:
    """Lays out ``fig`` with ``notes`` ((colour, text), wrapped) as figure text in a band
    below the axes, where no legend or curve can be."""
    import textwrap

    lines: List[Tuple[str, str]] = []
    for color, text in notes:
        for line in textwrap.wrap(text, 100):
            lines.append((color, line))
    if not lines:
        fig.tight_layout()
        return
    height_in = fig.get_size_inches()[1]
    line_frac = 0.16 / height_in  # a 9-point line with its spacing, in figure height
    band = line_frac * (len(lines) + 0.6)
    fig.tight_layout(rect=(0.0, band, 1.0, 1.0))
    for j, (color, line) in enumerate(lines):
        fig.text(0.01, band - line_frac * (j + 1), line, color=color, fontsize=8, ha="left",
                 va="bottom")


def figure_q_p_path(run: Run):
    """q_p_path.png: the stress path q [MPa] against p [MPa], one colour per stage."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "mean_stress_Pa", "deviator_stress_Pa"):
        return None
    plt = _pyplot()
    p, q = d["mean_stress_Pa"] * MPA, d["deviator_stress_Pa"] * MPA
    stages = stage_rows(d, run.summary)
    fig, ax = plt.subplots(figsize=(6, 5))
    if stages:
        for k, rows, info in stages:
            ax.plot(p[rows], q[rows], "o-", ms=2.5, color=stage_color(k),
                    label=stage_label(k, info))
        unique_legend(ax)
    else:
        ax.plot(p, q, "o-", ms=2.5)
    ax.set_xlabel("mean stress $p = (\\sigma_1 + \\sigma_2 + \\sigma_3)/3$ [MPa]")
    ax.set_ylabel("deviator stress $q$ [MPa]")
    ax.set_title(f"{run.title}: stress path")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def oedometer_label(k: int, info: Dict[str, Any], sigma_v: np.ndarray) -> str:
    """The legend label of an oedometric stage: its name, "loading" or "unloading" from the
    direction of sigma_v unless the name already says it, and K0."""
    label = stage_label(k, info)
    if len(sigma_v) > 1:
        direction = "loading" if sigma_v[-1] >= sigma_v[0] else "unloading"
        if direction not in str(info.get("name") or "").lower():
            label += f", {direction}"
    k0 = as_float(info.get("K0_end"))
    if math.isfinite(k0):
        label += f", $K_0$ = {k0:.3f}"
    return label


def figure_oedometer(run: Run):
    """oedometer.png: for oedometric stages, void ratio e against the vertical stress sigma_v
    [MPa] (log axis), each stage labelled loading or unloading, with its K0."""
    run = as_run(run)
    d = run.timeseries
    sigma_v = vertical_stress(d)
    oedo = [(k, rows, info) for k, rows, info in stage_rows(d, run.summary)
            if info.get("type") == "oedometric" and rows.any()]
    if not oedo or sigma_v is None or not has_values(d, "void_ratio"):
        return None
    plt = _pyplot()
    e = d["void_ratio"]
    fig, ax = plt.subplots(figsize=(6.5, 4.8))
    drawn = False
    for k, rows, info in oedo:
        keep = rows & (sigma_v > 0) & np.isfinite(e)
        if not keep.any():
            continue
        sv = sigma_v[keep]
        ax.semilogx(sv * MPA, e[keep], "o-", ms=3, color=stage_color(k),
                    label=oedometer_label(k, info, sv))
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_xlabel("vertical stress $\\sigma_v$ [MPa] (log scale)")
    ax.set_ylabel("void ratio $e$ [-]")
    ax.set_title(f"{run.title}: oedometric compression")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=9)
    fig.tight_layout()
    return fig


def figure_inertial_number(run: Run):
    """inertial_number.png: the inertial number I against DEM time (log axis) with the
    quasi-static limit I = 1e-3 dashed."""
    run = as_run(run)
    d = run.timeseries
    if not (has_values(d, "inertial_number") and np.any(d["inertial_number"] > 0)):
        return None
    plt = _pyplot()
    t, t_label = _time_axis(d)
    inum = d["inertial_number"]
    limit = 1e-3
    stages = stage_rows(d, run.summary)
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, rows, info in stages or [(0, np.ones(len(inum), dtype=bool), {})]:
        keep = rows & (inum > 0)
        if keep.any():
            ax.semilogy(t[keep], inum[keep], "-", color=stage_color(k),
                        label=stage_label(k, info) if stages else None)
    ax.axhline(limit, color="k", ls="--", lw=1.2, label="quasi-static limit")
    ax.set_ylim(top=max(float(np.nanmax(inum)), limit) * 3.0)
    ax.set_xlabel(t_label)
    ax.set_ylabel("inertial number $I$ [-]")
    ax.set_title(f"{run.title}: inertial number")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=9)
    fig.tight_layout()
    return fig


def figure_preparation(run: Run):
    """preparation.png: void ratio (with the target) and the preparation friction coefficient
    against time (a ``friction`` column)."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "friction"):
        return None
    plt = _pyplot()
    t, t_label = _time_axis(d)
    summary = run.summary
    sample = summary.get("sample") if isinstance(summary.get("sample"), dict) else {}
    with_e = has_values(d, "void_ratio")
    fig, axes = plt.subplots(2 if with_e else 1, 1, figsize=(7, 6.5 if with_e else 4),
                             sharex=True, squeeze=False)
    if with_e:
        ax = axes[0, 0]
        ax.plot(t, d["void_ratio"], color="tab:blue", label="void ratio $e$")
        e_target = as_float(sample.get("void_ratio_target"))
        if math.isfinite(e_target):
            ax.axhline(e_target, color="tab:red", ls="--", lw=1.2,
                       label=f"target $e$ = {e_target:.3g}")
        e_final = as_float(sample.get("void_ratio"))
        if math.isfinite(e_final) and len(t):
            ax.plot([t[-1]], [e_final], "o", color="tab:blue",
                    label=f"prepared $e$ = {e_final:.4g}")
        ax.set_ylabel("void ratio $e$ [-]")
        ax.set_title(f"{run.title}: sample preparation")
        ax.grid(True, alpha=0.3)
        unique_legend(ax, fontsize=9)
    ax = axes[-1, 0]
    ax.plot(t, d["friction"], color="tab:orange", drawstyle="steps-post",
            label="grain friction $\\mu$")
    mu_prep = as_float(sample.get("preparation_friction"))
    if math.isfinite(mu_prep):
        ax.axhline(mu_prep, color="0.4", ls=":", lw=1.2,
                   label=f"preparation friction = {mu_prep:.3g}")
    ax.set_ylabel("friction coefficient $\\mu$ [-]")
    ax.set_xlabel(t_label)
    if not with_e:
        ax.set_title(f"{run.title}: sample preparation")
    ax.grid(True, alpha=0.3)
    unique_legend(ax, fontsize=9)
    fig.tight_layout()
    return fig


# --- grain crushing ------------------------------------------------------------------------------


def _crushing(run: RunData) -> Dict[str, Any]:
    c = run.summary.get("crushing")
    return c if isinstance(c, dict) else {}


def figure_grading(run: Run):
    """grading.png: grading curves, mass passing [%] against d [mm] (log axis): the initial
    curve, the end of every stage (when grading.csv has one row per time-series row) and the
    final curve, each with B_r; d_c dashed when summary.json gives it."""
    run = as_run(run)
    if run.grading is None:
        return None
    plt = _pyplot()
    d = run.timeseries
    n_rows = len(next(iter(d.values()))) if d else 0
    br = d["relative_breakage_Br"] if has_values(d, "relative_breakage_Br") else None
    d_c = as_float(_crushing(run).get("d_c_m"))
    sieves, passing = run.grading
    n = passing.shape[0]
    same_rows = n == n_rows
    # {row: label parts}; a row that ends a stage and is also the last row is drawn once.
    picks: Dict[int, List[str]] = {0: ["initial"]}
    if same_rows:
        for k, rows, info in stage_rows(d, run.summary):
            idx = np.flatnonzero(rows)
            # The stage still running has no end yet, only a last output.
            if idx.size and (run.finished or idx[-1] != n - 1):
                picks.setdefault(int(idx[-1]), []).append("end of " + stage_label(k, info))
    picks.setdefault(n - 1, []).insert(
        0, "final" if run.finished else "last output (run not finished)")
    if n == 1:
        picks = {0: ["initial"]}
    fig, ax = plt.subplots(figsize=(7, 5))
    order = sorted(picks)
    cmap = plt.get_cmap("viridis")
    for j, row in enumerate(order):
        f = passing[row]
        keep = np.isfinite(f)
        if not keep.any():
            continue
        label = ", ".join(picks[row])
        if br is not None and same_rows and math.isfinite(br[row]):
            label += f", $B_r$ = {br[row]:.3f}"
        if row == 0 and len(order) > 1:
            fmt, color = "--", "k"
        else:
            fmt, color = "o-", cmap(0.9 * j / max(len(order) - 1, 1))
        ax.semilogx(sieves[keep] * 1e3, f[keep] * 100.0, fmt, ms=3, color=color, label=label)
    if math.isfinite(d_c) and d_c > 0:
        ax.axvline(d_c * 1e3, color="0.4", ls=":", lw=1.2, label=f"$d_c$ = {d_c * 1e3:.3g} mm")
    ax.set_ylim(0.0, 100.0)
    plain_log_ticks(ax)
    ax.set_xlabel("particle size d [mm]")
    ax.set_ylabel("mass passing [%]")
    ax.set_title(f"{run.title}: grading")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=8, loc="upper left")
    fig.tight_layout()
    return fig


def figure_breakage(run: Run):
    """breakage.png: cumulative breakages by cause with the number of particles, and B_r with
    the void ratios, against axial strain [%] (time without axial strain)."""
    run = as_run(run)
    d = run.timeseries
    br = d["relative_breakage_Br"] if has_values(d, "relative_breakage_Br") else None
    counts = [(c, lab) for c, lab in (("breakages_instant", "instant failure"),
                                      ("breakages_crack", "crack")) if has_values(d, c)]
    if not counts and br is None:
        return None
    plt = _pyplot()
    x, x_label = _time_axis(d)
    if has_values(d, "axial_strain") and np.nanmax(np.abs(d["axial_strain"])) > 0:
        x, x_label = d["axial_strain"] * 100.0, "axial strain $\\varepsilon_a$ [%]"
    fig, (ax_top, ax_bot) = plt.subplots(2, 1, figsize=(7, 7.5), sharex=True)
    for (c, lab), color in zip(counts, ("tab:red", "tab:blue")):
        ax_top.plot(x, d[c], "-", color=color, label=f"breakages: {lab}")
    ax_top.set_ylabel("cumulative breakages [-]")
    ax_top.set_title(f"{run.title}: grain crushing")
    ax_top.grid(True, alpha=0.3)
    if has_values(d, "n_particles"):
        ax_n = ax_top.twinx()
        ax_n.plot(x, d["n_particles"], "--", color="tab:green", label="particles")
        ax_n.set_ylabel("number of particles [-]", color="tab:green")
        unique_legend(ax_top, ax_n, fontsize=9, loc="upper left")
    else:
        unique_legend(ax_top, fontsize=9, loc="upper left")
    if br is not None:
        ax_bot.plot(x, br, "-", color="tab:purple", label="relative breakage $B_r$")
    ax_bot.set_ylabel("relative breakage $B_r$ [-]")
    ax_bot.grid(True, alpha=0.3)
    voids = [(c, lab, color) for c, lab, color in (
        ("void_ratio", "void ratio $e$", "tab:blue"),
        ("void_ratio_with_fines", "void ratio with fines as solid", "tab:orange"))
        if has_values(d, c)]
    if voids:
        ax_e = ax_bot.twinx()
        for c, lab, color in voids:
            ax_e.plot(x, d[c], "--", color=color, label=lab)
        ax_e.set_ylabel("void ratio $e$ [-]")
        unique_legend(ax_bot, ax_e, fontsize=9, loc="center left")
    else:
        unique_legend(ax_bot, fontsize=9)
    ax_bot.set_xlabel(x_label)
    fig.tight_layout()
    return fig


def figure_breakage_sizes(run: Run):
    """breakage_sizes.png: histogram of the diameters [mm] of the broken grains by cause."""
    run = as_run(run)
    broken = run.breakage
    if not broken:
        return None
    plt = _pyplot()
    crushing = _crushing(run)
    d_c = as_float(crushing.get("d_c_m"))
    dia = np.asarray([b[0] for b in broken]) * 1e3
    causes = list(dict.fromkeys(["instant", "crack"] + [b[1] for b in broken]))
    groups = [(c, dia[np.asarray([b[1] == c for b in broken])]) for c in causes]
    groups = [(c, v) for c, v in groups if v.size]
    lo, hi = float(dia.min()), float(dia.max())
    log_x = hi > 3.0 * lo
    if hi <= lo:
        lo, hi = lo * 0.95, hi * 1.05
    n_bins = int(min(30, max(5, math.sqrt(dia.size) * 2)))
    bins = np.geomspace(lo, hi, n_bins + 1) if log_x else np.linspace(lo, hi, n_bins + 1)
    colors = {"instant": "tab:red", "crack": "tab:blue"}
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.hist([v for _, v in groups], bins=bins, stacked=True,
            color=[colors.get(c, f"C{2 + i}") for i, (c, _) in enumerate(groups)],
            label=[f"{c} ({v.size})" for c, v in groups], edgecolor="white", lw=0.5)
    if log_x:
        ax.set_xscale("log")
        plain_log_ticks(ax)
    if math.isfinite(d_c) and d_c > 0:
        ax.axvline(d_c * 1e3, color="0.3", ls=":", lw=1.2, label=f"$d_c$ = {d_c * 1e3:.3g} mm")
    d50 = as_float(crushing.get("d50_initial_m"))
    if math.isfinite(d50) and d50 > 0:
        ax.axvline(d50 * 1e3, color="0.3", ls="--", lw=1.2,
                   label=f"initial $d_{{50}}$ = {d50 * 1e3:.3g} mm")
    ax.set_xlabel("diameter of the broken grain d [mm]")
    ax.set_ylabel("breakages [-]")
    ax.set_title(f"{run.title}: sizes of the broken grains ({dia.size})")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=9)
    fig.tight_layout()
    return fig


# --- ageing (events.csv) -------------------------------------------------------------------------


def _ageing_groups_drawn(run: RunData):
    """(events, ageing time, groups with a phase at t > 0) or None when there is none: the log
    axis holds the phases with ageing time > 0 only."""
    ev = run.events
    if ev is None or not has_values(ev, "ageing_time_s"):
        return None
    t_age = ev["ageing_time_s"]
    groups = [g for g in ageing_groups(ev, run.summary) if np.any(t_age[g[1]] > 0)]
    return (ev, t_age, groups) if groups else None


def figure_relaxation(run: Run):
    """relaxation.png: sigma_v(t)/sigma_v(0) against ageing time (sigma_v(t)/sigma_v(4 s)
    with the plausible band at 1 day for a relaxation with every wall fixed), and q [MPa] with
    the axial strain [%] on a second panel."""
    run = as_run(run)
    drawn = _ageing_groups_drawn(run)
    if drawn is None:
        return None
    ev, t_age, groups = drawn
    sigma_v = vertical_stress(ev)
    if sigma_v is None:
        return None
    plt = _pyplot()
    multi = len(groups) > 1
    with_q = has_values(ev, "deviator_stress_Pa")
    with_ea = has_values(ev, "axial_strain")
    lower = with_q or with_ea
    fig, axes = plt.subplots(2 if lower else 1, 1, figsize=(7, 7.5 if lower else 4.5),
                             sharex=True, squeeze=False)
    ax = axes[0, 0]
    band_drawn = False
    any_4s = False
    for i, (label, idx, ref) in enumerate(groups):
        p = idx[t_age[idx] > 0]
        # An oedometric relaxation (every wall fixed) is normalised as the study does, by
        # sigma_v at 4 s of ageing, and drawn with the plausible band at one day.
        s_ref, ref_text = sigma_v[ref], "$\\sigma_v(0)$"
        relaxation = walls_fixed(ev, idx)
        if relaxation:
            s4, _ = value_at(t_age[idx], sigma_v[idx], T_REF_S)
            if math.isfinite(s4) and s4 != 0.0:
                s_ref, ref_text, any_4s = s4, "$\\sigma_v$(4 s)", True
        text = f"{ref_text} = {s_ref * MPA:.2f} MPa"
        if relaxation and s_ref != sigma_v[ref]:
            r_day, _ = value_at(t_age[idx], sigma_v[idx] / s_ref, DAY_S)
            if math.isfinite(r_day):
                text += f", 1 day: {r_day:.3f}"
        m = _MARKERS[i % len(_MARKERS)]
        if math.isfinite(s_ref) and s_ref != 0.0:
            ax.semilogx(t_age[p], sigma_v[p] / s_ref, marker=m, ls="-", lw=0.8, ms=6,
                        color=stage_color(i), label=f"{label}, {text}" if multi else text)
            # The state before the first jump (t = 0) has no place on a log axis: drawn open
            # at a tenth of the first ageing time, joined by a dotted line.
            if t_age[ref] <= 0 and p.size:
                x0 = t_age[p[0]] / 10.0
                ax.semilogx([x0, t_age[p[0]]], [sigma_v[ref] / s_ref, sigma_v[p[0]] / s_ref],
                            ls=":", lw=0.8, color=stage_color(i))
                ax.semilogx([x0], [sigma_v[ref] / s_ref], marker=m, ms=6, mfc="none",
                            color=stage_color(i), ls="none",
                            label="t = 0 (before the first jump), drawn at the left")
        if relaxation and any_4s and not band_drawn and np.nanmax(t_age[p]) >= DAY_S / 2:
            lo, hi = PLAUSIBLE_OEDOMETRIC_1DAY
            ax.fill_between([DAY_S / 1.3, DAY_S * 1.3], lo, hi, color="tab:green", alpha=0.2,
                            lw=0, label=f"plausible at 1 day: {lo:.2f}-{hi:.2f} of "
                                        "$\\sigma_v$(4 s)")
            band_drawn = True
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_ylabel("$\\sigma_v(t) / \\sigma_v$(4 s) [-]" if any_4s and not multi
                  else "$\\sigma_v(t) / \\sigma_v$(reference) [-]" if any_4s
                  else "$\\sigma_v(t) / \\sigma_v(0)$ [-]")
    ax.set_title(f"{run.title}: ageing (relaxation / creep), vertical stress")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=9, loc="lower left")
    if lower:
        ax_q = axes[1, 0]
        ax_e = ax_q.twinx() if with_ea else None
        for i, (label, idx, _ref) in enumerate(groups):
            p = idx[t_age[idx] > 0]
            m = _MARKERS[i % len(_MARKERS)]
            suffix = f" ({label})" if multi else ""
            if with_q:
                ax_q.semilogx(t_age[p], ev["deviator_stress_Pa"][p] * MPA, marker=m, ls="-",
                              ms=4, color="tab:blue", label=f"deviator $q${suffix}")
            if ax_e is not None:
                ax_e.semilogx(t_age[p], ev["axial_strain"][p] * 100.0, marker=m, ls="--",
                              ms=4, mfc="none", color="tab:red",
                              label=f"axial strain $\\varepsilon_a${suffix}")
        ax_q.set_ylabel("deviator stress $q$ [MPa]", color="tab:blue")
        ax_q.grid(True, which="both", alpha=0.3)
        if ax_e is not None:
            ax_e.set_ylabel("axial strain $\\varepsilon_a$ [%]", color="tab:red")
            ax_e.ticklabel_format(axis="y", useOffset=False)
            unique_legend(ax_q, ax_e, fontsize=9, loc="best")
        else:
            unique_legend(ax_q, fontsize=9)
    axes[-1, 0].set_xlabel(AGEING_TIME_LABEL)
    mark_times([a[0] for a in axes], label_ax=axes[0, 0])
    fig.tight_layout()
    return fig


def figure_relaxation_forces(run: Run):
    """relaxation_forces.png: standard deviations (solid) and means (dashed) of the contact
    normal and tangential forces [N] against ageing time."""
    run = as_run(run)
    drawn = _ageing_groups_drawn(run)
    if drawn is None:
        return None
    ev, t_age, groups = drawn
    cols = [(c, lab, color, ls) for c, lab, color, ls in (
        ("std_Fn_N", "std. dev. normal force $F_n$", "tab:blue", "-"),
        ("std_Ft_N", "std. dev. tangential force $F_t$", "tab:orange", "-"),
        ("mean_Fn_N", "mean normal force $F_n$", "tab:blue", "--"),
        ("mean_Ft_N", "mean tangential force $F_t$", "tab:orange", "--")) if has_values(ev, c)]
    if not cols:
        return None
    plt = _pyplot()
    multi = len(groups) > 1
    fig, ax = plt.subplots(figsize=(7, 4.8))
    for i, (label, idx, _ref) in enumerate(groups):
        p = idx[t_age[idx] > 0]
        m = _MARKERS[i % len(_MARKERS)]
        for c, lab, color, ls in cols:
            ax.semilogx(t_age[p], ev[c][p], marker=m, ls=ls, ms=4, color=color,
                        mfc=color if ls == "-" else "none",
                        label=f"{lab} ({label})" if multi else lab)
    ax.set_xlabel(AGEING_TIME_LABEL)
    ax.set_ylabel("contact force [N]")
    ax.set_title(f"{run.title}: ageing, contact forces")
    ax.grid(True, which="both", alpha=0.3)
    unique_legend(ax, fontsize=8, loc="best")
    mark_times([ax], label_ax=ax)
    fig.tight_layout()
    return fig


def figure_relaxation_breakage(run: Run):
    """relaxation_breakage.png: cumulative breakages by cause, with the number of particles,
    against ageing time."""
    run = as_run(run)
    drawn = _ageing_groups_drawn(run)
    if drawn is None:
        return None
    ev, t_age, groups = drawn
    counts = [(c, lab, color) for c, lab, color in (
        ("breakages_instant", "breakages: instant failure", "tab:red"),
        ("breakages_crack", "breakages: crack", "tab:blue")) if has_values(ev, c)]
    with_n = has_values(ev, "n_particles")
    if not counts and not with_n:
        return None
    plt = _pyplot()
    multi = len(groups) > 1
    fig, ax = plt.subplots(figsize=(7, 4.8))
    ax_n = ax.twinx() if with_n else None
    for i, (label, idx, _ref) in enumerate(groups):
        p = idx[t_age[idx] > 0]
        m = _MARKERS[i % len(_MARKERS)]
        suffix = f" ({label})" if multi else ""
        for c, lab, color in counts:
            ax.semilogx(t_age[p], ev[c][p], marker=m, ls="-", ms=4, color=color,
                        label=lab + suffix)
        if ax_n is not None:
            ax_n.semilogx(t_age[p], ev["n_particles"][p], marker=m, ls="--", ms=4,
                          mfc="none", color="tab:green", label="particles" + suffix)
    ax.set_xlabel(AGEING_TIME_LABEL)
    ax.set_ylabel("cumulative breakages [-]")
    ax.set_title(f"{run.title}: ageing, grain crushing")
    ax.grid(True, which="both", alpha=0.3)
    if ax_n is not None:
        ax_n.set_ylabel("number of particles [-]", color="tab:green")
        unique_legend(ax, ax_n, fontsize=9, loc="best")
    else:
        unique_legend(ax, fontsize=9, loc="best")
    mark_times([ax], label_ax=ax)
    fig.tight_layout()
    return fig


# The figures of `crushdem plot`, in the order they are written: file name -> function.
FIGURES: Dict[str, Callable[[Run], Any]] = {
    "stress_time.png": figure_stress_time,
    "strain_stress.png": figure_strain_stress,
    "void_ratio.png": figure_void_ratio,
    "triaxial.png": figure_triaxial,
    "q_p_path.png": figure_q_p_path,
    "oedometer.png": figure_oedometer,
    "inertial_number.png": figure_inertial_number,
    "preparation.png": figure_preparation,
    "coordination.png": figure_coordination,
    "kinetic_energy.png": figure_kinetic_energy,
    "grading.png": figure_grading,
    "breakage.png": figure_breakage,
    "breakage_sizes.png": figure_breakage_sizes,
    "relaxation.png": figure_relaxation,
    "relaxation_forces.png": figure_relaxation_forces,
    "relaxation_breakage.png": figure_relaxation_breakage,
}


def draw_all(run: Run) -> List[Tuple[str, Any]]:
    """[(file name, Figure)] of every figure ``run`` has the data for, in FIGURES order."""
    run = as_run(run)
    out = []
    for name, make in FIGURES.items():
        fig = make(run)
        if fig is not None:
            out.append((name, fig))
    return out


def display_available() -> bool:
    """Whether a GUI display can be opened (on Linux and the BSDs: $DISPLAY or
    $WAYLAND_DISPLAY set)."""
    import sys

    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def use_file_backend_without_display() -> None:
    """For the commands that only write files: selects the Agg backend when no display can be
    opened (never called on import: a notebook or an application keeps its backend)."""
    if not display_available():
        import matplotlib

        matplotlib.use("Agg")
