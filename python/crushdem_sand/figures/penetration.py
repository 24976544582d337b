"""The figures of a penetration test (``crushdem-sand plot``, "penetrate" stages): the cone
resistance q_c and the sleeve friction f_s against the travel, the radial stress on the shaft
along it at a few travels, and where grains broke around the body (penetration.csv,
shaft_profile.csv, breakage.csv; docs/chamber.md)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import numpy as np

from .common import MPA, Run, as_run, label_axes, pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

KPA = 1e-3


def figure_penetration(run: Run) -> Optional[Figure]:
    """penetration.png: q_c [MPa] and f_s [kPa] against the body's travel [mm] (depth axis
    downwards, as CPT logs are drawn), one curve per penetrate stage."""
    run = as_run(run)
    p = run.penetration
    if p is None or "travel_m" not in p or p["travel_m"].size == 0:
        return None
    plt = pyplot()
    fig, (a_q, a_f) = plt.subplots(1, 2, figsize=(8, 6), sharey=True)
    stages = p["stage"] if "stage" in p else np.zeros_like(p["travel_m"])
    for k in np.unique(stages):
        rows = stages == k
        label = f"stage {int(k)}"
        a_q.plot(p["q_c_Pa"][rows] * MPA, p["travel_m"][rows] * 1e3, "-", lw=1.2, label=label)
        a_f.plot(p["f_s_Pa"][rows] * KPA, p["travel_m"][rows] * 1e3, "-", lw=1.2, label=label)
    a_q.invert_yaxis()
    label_axes(a_q, "cone resistance $q_c$ [MPa]", "travel [mm]", f"{run.title}: $q_c$",
               fontsize=8)
    label_axes(a_f, "sleeve friction $f_s$ [kPa]", "", "$f_s$")
    fig.tight_layout()
    return fig


def figure_shaft_stress(run: Run) -> Optional[Figure]:
    """shaft_stress.png: the radial stress sigma_r [kPa] on the shaft against the height above
    its start [mm], at four travels of the last penetrate stage (its last row included)."""
    run = as_run(run)
    s = run.shaft_profile
    if s is None or "travel_m" not in s or s["travel_m"].size == 0:
        return None
    last = s["stage"] == s["stage"][-1] if "stage" in s else np.ones_like(s["travel_m"], bool)
    travels = np.unique(s["travel_m"][last])
    picks = travels[np.unique(np.linspace(0, travels.size - 1, 4).round().astype(int))]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 6))
    cmap = plt.get_cmap("viridis")
    for j, t in enumerate(picks):
        rows = last & (s["travel_m"] == t)
        ax.plot(s["sigma_r_Pa"][rows] * KPA, s["height_m"][rows] * 1e3, "o-", ms=3,
                color=cmap(0.9 * j / max(picks.size - 1, 1)), label=f"travel {t * 1e3:.3g} mm")
    label_axes(ax, r"radial stress $\sigma_r$ [kPa]", "height above the shaft's start [mm]",
               f"{run.title}: shaft", fontsize=8)
    fig.tight_layout()
    return fig


def figure_breakage_field(run: Run) -> Optional[Figure]:
    """breakage_field.png: where grains broke during the penetrate stages, in the plane of the
    body's axis: the distance r [mm] from the axis (through the tip's last x, y) against z
    [mm], each breakage a dot coloured by the body's travel when it happened, sized by the
    grain; the tip's path and the top wall at the start drawn; the count of breakages by
    distance from the axis on the side."""
    run = as_run(run)
    p, b = run.penetration, run.breakage_positions
    if p is None or b is None or "travel_m" not in p or p["travel_m"].size == 0:
        return None
    t = p["time_s"]
    during = (b["time_s"] >= t[0]) & (b["time_s"] <= t[-1])
    if not np.any(during):
        return None
    x0, y0 = p["tip_x_m"][-1], p["tip_y_m"][-1]
    r = np.hypot(b["x_m"][during] - x0, b["y_m"][during] - y0) * 1e3
    z = b["z_m"][during] * 1e3
    travel = np.interp(b["time_s"][during], t, p["travel_m"]) * 1e3
    d = b["diameter_m"][during]
    plt = pyplot()
    fig, (ax, ah) = plt.subplots(1, 2, figsize=(9, 6), gridspec_kw={"width_ratios": [3, 1]})
    sc = ax.scatter(r, z, c=travel, s=12.0 * (d / d.max()) ** 2 + 2.0, cmap="viridis")
    fig.colorbar(sc, ax=ax, label="travel when it broke [mm]")
    ax.plot(np.zeros_like(p["tip_z_m"]), p["tip_z_m"] * 1e3, "k-", lw=2, label="tip's path")
    if "wall_zmax_position_m" in p:
        ax.axhline(p["wall_zmax_position_m"][0] * 1e3, color="0.5", ls="--", lw=1,
                   label="top at the start")
    ax.set_xlim(left=0.0)
    label_axes(ax, "distance from the axis r [mm]", "z [mm]",
               f"{run.title}: {int(r.size)} breakages", fontsize=8)
    ah.hist(r, bins=min(30, max(5, r.size // 5)), orientation="vertical", color="C1")
    label_axes(ah, "r [mm]", "breakages", "by distance")
    fig.tight_layout()
    return fig
