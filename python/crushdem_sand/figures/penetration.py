"""The figures of a penetration test (``crushdem-sand plot``, "penetrate" stages): the cone
resistance q_c and the sleeve friction f_s against the travel, the radial stress on the shaft
along it at a few travels, the stress field about the body, and where grains broke around it
(penetration.csv, shaft_profile.csv, penetration_field.csv, breakage.csv; docs/chamber.md)."""

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


def figure_stress_field(run: Run) -> Optional[Figure]:
    """stress_field.png: the radial, hoop and vertical stress [kPa] of the grains about the body
    at the last record of penetration_field.csv (a penetrate stage's ``field_interval``), in
    rings from its axis (r [mm]) by slices from the bottom platen up (z [mm]); cells without a
    grain (inside the body, beyond the chamber) left blank; the tip's path drawn on the axis."""
    run = as_run(run)
    f = run.penetration_field
    if f is None or "time_s" not in f or f["time_s"].size == 0:
        return None
    last = f["time_s"] == f["time_s"][-1]
    rings = f["ring"][last].astype(int)
    bins = f["bin"][last].astype(int)
    n_r, n_z = rings.max() + 1, bins.max() + 1
    if rings.size != n_r * n_z:
        return None
    r_edges = np.zeros(n_r + 1)
    r_edges[rings + 1] = f["r_out_m"][last] * 1e3
    z_mid = np.zeros(n_z)
    z_mid[bins] = f["z_m"][last] * 1e3
    # The slices' height: from the bottom platen at the record (penetration.csv's row then), or
    # from their spacing.
    p = run.penetration
    stage = f["stage"][last][0] if "stage" in f else None
    rows = np.zeros(0, bool)
    if p is not None and "time_s" in p:
        rows = p["time_s"] == f["time_s"][-1]
    if rows.any() and "wall_zmin_position_m" in p:
        dz = 2.0 * (z_mid[0] - p["wall_zmin_position_m"][rows][0] * 1e3)
    else:
        dz = (z_mid[-1] - z_mid[0]) / (n_z - 1) if n_z > 1 else 1.0
    z_edges = np.concatenate([z_mid - 0.5 * dz, [z_mid[-1] + 0.5 * dz]])
    empty = np.zeros((n_z, n_r), bool)
    empty[bins, rings] = f["grains"][last] == 0
    tip_z = f["tip_z_m"][last][0] * 1e3
    top = z_edges[-1]  # the tip's path from where its stage began
    if p is not None and "tip_z_m" in p:
        of_stage = p["stage"] == stage if stage is not None and "stage" in p else \
            np.ones_like(p["tip_z_m"], bool)
        if of_stage.any():
            top = p["tip_z_m"][of_stage][0] * 1e3
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, 6), sharey=True)
    for ax, (key, name) in zip(axes, (("sigma_rr_Pa", r"radial $\sigma_{rr}$"),
                                      ("sigma_tt_Pa", r"hoop $\sigma_{\theta\theta}$"),
                                      ("sigma_zz_Pa", r"vertical $\sigma_{zz}$"))):
        grid = np.zeros((n_z, n_r))
        grid[bins, rings] = f[key][last] * KPA
        mesh = ax.pcolormesh(r_edges, z_edges, np.ma.masked_array(grid, empty), cmap="YlOrRd",
                             shading="flat")
        fig.colorbar(mesh, ax=ax, label=f"{name} [kPa]", orientation="horizontal", pad=0.1)
        ax.plot([0.0, 0.0], [tip_z, max(top, tip_z)], "k-", lw=3, label="the tip's path")
        ax.plot([0.0], [tip_z], "kv", ms=8)
        label_axes(ax, "distance from the axis r [mm]", "z [mm]" if ax is axes[0] else "", name)
    travel = f["travel_m"][last][0] * 1e3
    fig.suptitle(f"{run.title}: the stress about the body at {travel:.4g} mm of travel")
    fig.tight_layout()
    return fig
