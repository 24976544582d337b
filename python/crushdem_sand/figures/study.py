"""The reference study's four figures (``crushdem-sand reproduce``), one point per dynamic phase
(the study's red dots) against the ageing time t (the relaxation clock, off-DEM jumps only) on a log
axis. Each draws the table of :mod:`crushdem_sand.study_analysis` that ``crushdem-sand reproduce``
writes beside it as CSV, so the figure and its CSV hold the same numbers."""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Any, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..analysis import DAY_S, PLAUSIBLE_OEDOMETRIC_1DAY, T_REF_S
from ..rundir import RunData
from ..study_analysis import (FIG2_PHASE, FORCE_COLUMNS, FigureData, dynamic_phase,
                              force_statistics, oedometric_relaxation, triaxial_relaxation)
from .common import MPA, Run, mark_times, pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def run_directory(run: Run) -> str:
    """The directory of ``run`` (a path, or RunData: these figures read events.csv and
    phases.csv themselves)."""
    return run.directory if isinstance(run, RunData) else os.fspath(run)


def _draw_fit(ax, fit: Mapping[str, Any], t: np.ndarray, scale: float, unit: str) -> None:
    """The straight line in log t over the phases with t > 0, dashed, with its slope and R^2."""
    if not math.isfinite(fit["slope"]):
        return
    pos = t > 0
    tt = np.geomspace(np.min(t[pos]), np.max(t[pos]), 50)
    r2 = f"{fit['r2']:.3f}" if math.isfinite(fit["r2"]) else f"n/a ({fit['points']} points)"
    ax.semilogx(tt, (fit["intercept"] + fit["slope"] * np.log10(tt)) * scale, "--", color="k",
                lw=1.2, label=f"fit: {fit['slope'] * scale:+.3g} {unit}, $R^2$ = {r2}")


def figure_oedometric_relaxation(run: Run) -> Optional[Figure]:
    """fig1_oedometric_relaxation.png: sigma_v(t) / sigma_v(4 s) of the oedometric relaxation
    (:func:`crushdem_sand.study_analysis.oedometric_relaxation`) against ageing time, with its
    straight line in log t, sigma_v(4 s) marked and the plausible band at 1 day."""
    try:
        data = oedometric_relaxation(run_directory(run))
    except ValueError:
        return None
    t, ratio, s = (data.columns[c] for c in ("ageing_time_s", "sigma_v_ratio", "sigma_v_Pa"))
    s_ref = data.numbers["sigma_v_4s_Pa"]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.8))
    pos = t > 0
    ax.semilogx(t[pos], ratio[pos], "-", color="0.3", lw=1.2, zorder=1, label="DEM")
    ax.semilogx(t[pos], ratio[pos], "o", color="red", ms=5, zorder=2,
                label="dynamic phases (end)")
    _draw_fit(ax, data.fit, t, 1.0, "per log cycle")
    if math.isfinite(s_ref):
        ax.plot([T_REF_S], [1.0], "s", mfc="none", mec="k", ms=7,
                label=f"$\\sigma_v$(4 s) = {s_ref * MPA:.3g} MPa")
    lo, hi = PLAUSIBLE_OEDOMETRIC_1DAY
    ax.errorbar([DAY_S], [(lo + hi) / 2], yerr=[[(hi - lo) / 2], [(hi - lo) / 2]], fmt="none",
                ecolor="tab:blue",
                capsize=4, lw=1.5, label="plausible band at 1 day (docs/model.md 4.4)")
    ax.axhline(1.0, color="0.6", lw=0.8)
    ax.set_xlabel("ageing time $t$ [s] (log scale)")
    ax.set_ylabel("$\\sigma_v(t) / \\sigma_v(4\\,\\mathrm{s})$ [-]")
    ax.set_title("Oedometric stress relaxation from $\\sigma_v$ = "
                 f"{s[0] * MPA:.3g} MPa" if s.size else "Oedometric stress relaxation")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    mark_times([ax], label_ax=ax)
    fig.tight_layout()
    return fig


def figure_dynamic_phase(run: Run, phase: int = FIG2_PHASE) -> Optional[Figure]:
    """fig2_dynamic_phase4.png: during dynamic phase ``phase`` (0-based: the study's 4th) of the
    triaxial relaxation (:func:`crushdem_sand.study_analysis.dynamic_phase`, from phases.csv), (a)
    the confining pressure fluctuation and (b) the volumetric strain generated [%], against the
    cycles of the phase. None without phases.csv or without that phase."""
    data = dynamic_phase(run_directory(run), phase)
    if "skipped" in data.numbers:
        return None
    cyc = data.columns["cycle"]
    fluct, vol = data.columns["confining_fluctuation"], data.columns["volumetric_strain_phase"]
    plt = pyplot()
    fig, (ax_a, ax_b) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    ax_a.plot(cyc, fluct * 100.0, "-", color="tab:blue", marker="o", ms=2.5)
    ax_a.axhline(0.0, color="0.5", lw=0.8)
    ax_a.set_ylabel("confining pressure fluctuation [%]")
    ax_a.set_title(f"(a) dynamic phase {phase + 1} of the triaxial relaxation "
                   f"(ageing time {data.numbers['ageing_time_s']:.4g} s)")
    ax_a.grid(True, alpha=0.3)
    ax_b.plot(cyc, vol * 100.0, "-", color="tab:green", marker="o", ms=2.5)
    ax_b.axhline(0.0, color="0.5", lw=0.8)
    ax_b.set_ylabel("volumetric strain generated [%]")
    ax_b.set_xlabel("cycles within the dynamic phase")
    ax_b.set_title("(b) volumetric strain since cycle 0 (compression +)")
    ax_b.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def figure_triaxial_relaxation(run: Run, q_max: float = math.nan) -> Optional[Figure]:
    """fig3_triaxial_relaxation.png: q [MPa] of the triaxial relaxation
    (:func:`crushdem_sand.study_analysis.triaxial_relaxation`) against ageing time with its straight
    line in log t, q at t = 0 as a level; ``q_max`` (the shear's) in the title."""
    try:
        data = triaxial_relaxation(run_directory(run), q_max)
    except ValueError:
        return None
    t, q = data.columns["ageing_time_s"], data.columns["deviator_stress_Pa"]
    q0 = data.numbers["q_start_Pa"]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.8))
    pos = t > 0
    ax.semilogx(t[pos], q[pos] * MPA, "o-", color="tab:red", ms=5, label="dynamic phases (end)")
    if math.isfinite(q0):  # t = 0 has no place on the log axis: drawn as a level
        ax.axhline(q0 * MPA, color="tab:red", ls=":", lw=1.0,
                   label=f"q at t = 0: {q0 * MPA:.3g} MPa")
    _draw_fit(ax, data.fit, t, MPA, "MPa per log cycle")
    ax.set_xlabel("ageing time $t$ [s] (log scale)")
    ax.set_ylabel("deviator stress $q$ [MPa]")
    ax.set_title(f"Triaxial stress relaxation from q = {q0 * MPA:.3g} MPa" +
                 (f" ($q_{{max}}$ = {q_max * MPA:.3g} MPa)" if math.isfinite(q_max) else ""))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=9, loc="best")
    mark_times([ax], label_ax=ax)
    fig.tight_layout()
    return fig


def _by_test(data: FigureData) -> Sequence[Tuple[str, np.ndarray, Any]]:
    """The rows of force_statistics' table regrouped by test, in table order: (label, ageing
    time, {column: values})."""
    test = data.columns["test"]
    out = []
    for label in dict.fromkeys(test):
        rows = [i for i, name in enumerate(test) if name == label]
        out.append((label, np.array([data.columns["ageing_time_s"][i] for i in rows]),
                    {c: np.array([data.columns[c][i] for i in rows]) for c in FORCE_COLUMNS}))
    return out


def figure_force_statistics(runs: Sequence[Tuple[str, Run]]) -> Optional[Figure]:
    """fig4_force_statistics.png: standard deviations of |F_n| (a) and |F_t| (b) [N] against
    ageing time for each (label, run) that has them
    (:func:`crushdem_sand.study_analysis.force_statistics`), their t = 0 values in the legend. None
    when no run has them."""
    try:
        data = force_statistics([(label, run_directory(run)) for label, run in runs])
    except ValueError:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(7, 7.5), sharex=True)
    colors = {"triaxial relaxation": "tab:red", "oedometric relaxation": "tab:blue"}
    markers = ("o", "s", "^")
    for k, (label, t, v) in enumerate(_by_test(data)):
        pos = t > 0
        for ax, c, sym in ((axes[0], "std_Fn_N", "F_n"), (axes[1], "std_Ft_N", "F_t")):
            ax.semilogx(t[pos], v[c][pos], marker=markers[k % 3], ls="-", ms=4,
                        color=colors.get(label, f"C{k}"),
                        label=f"{label} (t = 0: {v[c][0]:.3g} N)")
    axes[0].set_ylabel("std. dev. of $|F_n|$ [N]")
    axes[0].set_title("(a) normal contact forces")
    axes[1].set_ylabel("std. dev. of $|F_t|$ [N]")
    axes[1].set_title("(b) tangential contact forces")
    axes[1].set_xlabel("ageing time $t$ [s] (log scale)")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        mark_times([ax], label_ax=ax)
    fig.tight_layout()
    return fig
