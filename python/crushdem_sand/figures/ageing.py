"""The figures of ageing (``crushdem-sand plot``; events.csv, one point per dynamic phase against
the ageing time on a log axis): the vertical stress relaxation or creep with q and the axial strain,
the contact forces, and the breakages."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Optional

import numpy as np

from ..analysis import (DAY_S, PLAUSIBLE_OEDOMETRIC_1DAY, T_REF_S, ageing_groups, has_values,
                        value_at, vertical_stress, walls_fixed)
from ..rundir import RunData
from .common import (AGEING_TIME_LABEL, MARKERS, MPA, Run, as_run, label_axes, mark_times,
                     pyplot, stacked_axes, stage_color, unique_legend)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _ageing_groups_drawn(run: RunData):
    """(events, ageing time, groups with a phase at t > 0) or None when there is none: the log
    axis holds the phases with ageing time > 0 only."""
    ev = run.events
    if ev is None or not has_values(ev, "ageing_time_s"):
        return None
    t_age = ev["ageing_time_s"]
    groups = [g for g in ageing_groups(ev, run.summary) if np.any(t_age[g[1]] > 0)]
    return (ev, t_age, groups) if groups else None


def figure_relaxation(run: Run) -> Optional[Figure]:
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
    multi = len(groups) > 1
    with_q = has_values(ev, "deviator_stress_Pa")
    with_ea = has_values(ev, "axial_strain")
    lower = with_q or with_ea
    fig, axes = stacked_axes(lower, 7.5)
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
        m = MARKERS[i % len(MARKERS)]
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
            m = MARKERS[i % len(MARKERS)]
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


def figure_relaxation_forces(run: Run) -> Optional[Figure]:
    """relaxation_forces.png: standard deviations (solid) and means (dashed) of the contact
    normal and tangential forces against ageing time, each over its value at t = 0 (the start
    of the age stage; in N in the legend), on an axis that spans what the curves reach, so that
    a change of a percent shows."""
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
    plt = pyplot()
    multi = len(groups) > 1
    fig, ax = plt.subplots(figsize=(7, 4.8))
    reached = [1.0]
    for i, (label, idx, ref) in enumerate(groups):
        p = idx[t_age[idx] > 0]
        m = MARKERS[i % len(MARKERS)]
        for c, lab, color, ls in cols:
            f0 = ev[c][ref]
            if not (math.isfinite(f0) and f0 != 0.0):
                continue
            ratio = ev[c][p] / f0
            reached += [float(v) for v in ratio if math.isfinite(v)]
            ax.semilogx(t_age[p], ratio, marker=m, ls=ls, ms=4, color=color,
                        mfc=color if ls == "-" else "none",
                        label=f"{lab}{f' ({label})' if multi else ''}, $F(0)$ = {f0:.3g} N")
    if len(reached) == 1:
        plt.close(fig)
        return None
    ax.axhline(1.0, color="0.5", lw=0.8)
    lo, hi = min(reached), max(reached)
    pad = max(0.08 * (hi - lo), 1e-4)  # flat curves still get an axis of their own scale
    ax.set_ylim(lo - pad, hi + pad)
    ax.ticklabel_format(axis="y", useOffset=False)
    label_axes(ax, AGEING_TIME_LABEL, "contact force $F(t) / F(0)$ [-]",
               f"{run.title}: ageing, contact forces", fontsize=8, loc="best")
    mark_times([ax], label_ax=ax)
    fig.tight_layout()
    return fig


def figure_relaxation_breakage(run: Run) -> Optional[Figure]:
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
    plt = pyplot()
    multi = len(groups) > 1
    fig, ax = plt.subplots(figsize=(7, 4.8))
    ax_n = ax.twinx() if with_n else None
    for i, (label, idx, _ref) in enumerate(groups):
        p = idx[t_age[idx] > 0]
        m = MARKERS[i % len(MARKERS)]
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
