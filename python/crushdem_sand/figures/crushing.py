"""The figures of grain crushing (``crushdem-sand plot``): the grading curves, the breakages with
B_r and the void ratios, and the sizes of the broken grains."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Dict, List, Optional

import numpy as np

from ..analysis import as_float, has_values, stage_label, stage_rows
from ..rundir import RunData
from .common import (Run, as_run, label_axes, plain_log_ticks, pyplot, time_axis,
                     unique_legend)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _crushing(run: RunData) -> Dict[str, Any]:
    c = run.summary.get("crushing")
    return c if isinstance(c, dict) else {}


def figure_grading(run: Run) -> Optional[Figure]:
    """grading.png: grading curves, mass passing [%] against d [mm] (log axis): the initial
    curve, the end of every stage (when grading.csv has one row per time-series row) and the
    final curve, each with B_r; d_c dashed when summary.json gives it."""
    run = as_run(run)
    if run.grading is None:
        return None
    plt = pyplot()
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
    label_axes(ax, "particle size d [mm]", "mass passing [%]", f"{run.title}: grading",
               fontsize=8, loc="upper left")
    fig.tight_layout()
    return fig


def figure_breakage(run: Run) -> Optional[Figure]:
    """breakage.png: cumulative breakages by cause with the number of particles, and B_r with
    the void ratios, against axial strain [%] (time without axial strain)."""
    run = as_run(run)
    d = run.timeseries
    br = d["relative_breakage_Br"] if has_values(d, "relative_breakage_Br") else None
    counts = [(c, lab) for c, lab in (("breakages_instant", "instant failure"),
                                      ("breakages_crack", "crack")) if has_values(d, c)]
    if not counts and br is None:
        return None
    plt = pyplot()
    x, x_label = time_axis(d)
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


def figure_breakage_sizes(run: Run) -> Optional[Figure]:
    """breakage_sizes.png: histogram of the diameters [mm] of the broken grains by cause."""
    run = as_run(run)
    broken = run.breakage
    if not broken:
        return None
    plt = pyplot()
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
    label_axes(ax, "diameter of the broken grain d [mm]", "breakages [-]",
               f"{run.title}: sizes of the broken grains ({dia.size})", fontsize=9)
    fig.tight_layout()
    return fig
