"""The figures of a pile's ageing (``crushdem-sand plot`` of a run whose "age" stages name a pile,
and ``crushdem-sand pile``; docs/pile.md): the radial stress on the shaft by depth against ageing
time, the radial and hoop stress in rings of grains about the shaft, the contact forces near the
shaft, where grains failed while the sand aged, and the capacities of the load tests against ageing
time with the fitted set-up factor. They read DIR/pile_ageing.csv, pile_shaft.csv, pile_rings.csv,
phases.csv and breakage.csv."""

from __future__ import annotations

import csv
import os
from typing import TYPE_CHECKING, Any, Dict, Mapping, Optional

import numpy as np

from ..rundir import Columns, read_config, read_run_table
from .common import AGEING_TIME_LABEL, Run, as_run, label_axes, plain_log_ticks, pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

KPA = 1e-3


def read_pile_file(run_dir: str, name: str) -> Optional[Columns]:
    """DIR/NAME (pile_ageing.csv, pile_shaft.csv or pile_rings.csv) as columns; None when the run
    has none (no age stage named a pile) or it has no rows."""
    return read_run_table(run_dir, name)


def _positive_times(t: np.ndarray) -> np.ndarray:
    """Ageing times on a log axis: the first event (t = 0, just after installation) drawn at a
    tenth of the first positive time."""
    pos = t[t > 0]
    floor = 0.1 * pos.min() if pos.size else 1.0
    return np.where(t > 0, t, floor)


def figure_pile_shaft(run: Run) -> Optional[Figure]:
    """pile_shaft.png: the radial stress sigma_r on the shaft [kPa] against ageing time (log
    axis), one curve per depth bin that holds contacts (the shaft's lowest bins, near the tip,
    darkest); the first event (ageing time 0) drawn at a tenth of the first positive time."""
    run = as_run(run)
    s = read_pile_file(run.directory, "pile_shaft.csv")
    if s is None:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 5))
    cmap = plt.get_cmap("viridis")
    bins = np.unique(s["bin"])
    used = [b for b in bins if np.nansum(s["contacts"][s["bin"] == b]) > 0]
    for j, b in enumerate(used):
        rows = s["bin"] == b
        t = _positive_times(s["ageing_time_s"][rows])
        h = s["height_m"][rows][0] * 1e3
        ax.plot(t, s["sigma_r_Pa"][rows] * KPA, "o-", ms=3, lw=1.0,
                color=cmap(0.9 * j / max(len(used) - 1, 1)), label=f"{h:.3g} mm up the shaft")
    ax.set_xscale("log")
    plain_log_ticks(ax)
    label_axes(ax, AGEING_TIME_LABEL, r"radial stress on the shaft $\sigma_r$ [kPa]",
               f"{run.title}: shaft radial stress", fontsize=7)
    fig.tight_layout()
    return fig


def ring_profile(rings: Columns, shaft_top: Optional[float] = None) -> Dict[str, np.ndarray]:
    """The ring stresses averaged over the slices along the shaft (height above the tip below
    ``shaft_top``; all slices when None) that hold grains, weighted by the slices' volumes
    (equal): per ageing
    event and ring, ``ageing_time_s``, ``r_mid_m``, ``sigma_rr_Pa``, ``sigma_tt_Pa``,
    ``sigma_zz_Pa`` (events ordered by time, rings from the shaft out)."""
    keep = np.ones_like(rings["ring"], bool)
    if "grains" in rings:  # a slice without grains (beyond the chamber) has no stress to average
        keep &= rings["grains"] > 0
    if shaft_top is not None:
        keep &= rings["height_m"] < shaft_top
    times = np.unique(rings["ageing_time_s"][keep])
    ring_ids = np.unique(rings["ring"][keep])
    out: Dict[str, list] = {k: [] for k in ("ageing_time_s", "ring", "r_mid_m", "sigma_rr_Pa",
                                            "sigma_tt_Pa", "sigma_zz_Pa")}
    for t in times:
        for m in ring_ids:
            rows = keep & (rings["ageing_time_s"] == t) & (rings["ring"] == m)
            if not np.any(rows):
                continue
            out["ageing_time_s"].append(t)
            out["ring"].append(m)
            out["r_mid_m"].append(0.5 * (rings["r_in_m"][rows][0] + rings["r_out_m"][rows][0]))
            for k in ("sigma_rr_Pa", "sigma_tt_Pa", "sigma_zz_Pa"):
                out[k].append(float(np.mean(rings[k][rows])))
    return {k: np.asarray(v, dtype=float) for k, v in out.items()}


def figure_pile_rings(run: Run) -> Optional[Figure]:
    """pile_rings.png: the radial (sigma_rr) and hoop (sigma_theta) stress [kPa] in the rings of
    grains about the shaft against the distance from the axis over the shaft's radius, averaged
    along the embedded length, at the first and last ageing events and a few between
    (Axelsson 2000: the hoop stress relaxing next to the shaft lets the radial stress rise)."""
    run = as_run(run)
    rings = read_pile_file(run.directory, "pile_rings.csv")
    if rings is None:
        return None
    prof = ring_profile(rings)
    times = np.unique(prof["ageing_time_s"])
    picks = times[np.unique(np.linspace(0, times.size - 1, 4).round().astype(int))]
    R = float(np.min(rings["r_in_m"]))
    plt = pyplot()
    fig, (a_r, a_t) = plt.subplots(1, 2, figsize=(9, 4.5), sharey=True)
    cmap = plt.get_cmap("viridis")
    for j, t in enumerate(picks):
        rows = prof["ageing_time_s"] == t
        c = cmap(0.9 * j / max(picks.size - 1, 1))
        lab = f"t = {t:.3g} s"
        a_r.plot(prof["r_mid_m"][rows] / R, prof["sigma_rr_Pa"][rows] * KPA, "o-", ms=3, color=c,
                 label=lab)
        a_t.plot(prof["r_mid_m"][rows] / R, prof["sigma_tt_Pa"][rows] * KPA, "o-", ms=3, color=c,
                 label=lab)
    for a in (a_r, a_t):
        a.set_xscale("log")
        plain_log_ticks(a)
    label_axes(a_r, "distance from the axis r / R", r"radial stress $\sigma_{rr}$ [kPa]",
               f"{run.title}: rings about the shaft", fontsize=7)
    label_axes(a_t, "distance from the axis r / R", r"hoop stress $\sigma_{\theta\theta}$ [kPa]",
               "hoop stress")
    fig.tight_layout()
    return fig


def figure_pile_forces(run: Run) -> Optional[Figure]:
    """pile_forces.png: the standard deviation of the normal and tangential contact forces [N]
    near the shaft (pile_ageing.csv's near field) against ageing time, each over its value at
    the first event: the homogenisation of the force chains about the pile that Zhang and Wang
    (2015) tie to set-up, the study's Figure 4 at the pile."""
    run = as_run(run)
    a = read_pile_file(run.directory, "pile_ageing.csv")
    if a is None or "std_Fn_near_N" not in a:
        return None
    t = _positive_times(a["ageing_time_s"])
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, lab in (("std_Fn_near_N", r"std $F_n$"), ("std_Ft_near_N", r"std $F_t$"),
                     ("mean_Fn_near_N", r"mean $F_n$")):
        v = a[key]
        if v.size and v[0] > 0:
            ax.plot(t, v / v[0], "o-", ms=3, label=lab)
    ax.set_xscale("log")
    plain_log_ticks(ax)
    label_axes(ax, AGEING_TIME_LABEL, "over its value at the first event",
               f"{run.title}: contact forces near the shaft", fontsize=8)
    fig.tight_layout()
    return fig


def read_breakages(run_dir: str) -> Optional[Dict[str, np.ndarray]]:
    """Every breakage of DIR/breakage.csv with a position: ``time_s``, ``diameter_m``, ``x_m``,
    ``y_m``, ``z_m`` and ``crack`` (1 for a failure by crack growth, 0 for an instant one)."""
    path = os.path.join(run_dir, "breakage.csv")
    if not os.path.isfile(path):
        return None
    rows = []
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        if not reader.fieldnames or "x_m" not in reader.fieldnames:
            return None
        for r in reader:
            try:
                rows.append([float(r["time_s"]), float(r["diameter_m"]), float(r["x_m"]),
                             float(r["y_m"]), float(r["z_m"]),
                             1.0 if (r.get("cause") or "").strip() == "crack" else 0.0])
            except (KeyError, TypeError, ValueError):
                continue
    table = np.asarray(rows, dtype=float).reshape(-1, 6)
    return {k: table[:, j] for j, k in enumerate(("time_s", "diameter_m", "x_m", "y_m", "z_m",
                                                   "crack"))}


def pile_outline(run_dir: str, head_position_m: float) -> Optional[np.ndarray]:
    """The outline of the pile that the age stages of DIR/config.toml name, in the plane of its
    axis, for the degree of freedom ``head_position_m`` (pile_ageing.csv): points (r, z) [m] from
    the tip (a cone's apex or a flat tip's centre) round the tip's edge and up the shaft to the
    pile's top, from its [[body]] (origin, axis, direction, radius, length, half_angle, tip).
    None for a run without such a pile, or one whose axis is not the z axis (the figure's r is
    the distance from the z axis)."""
    cfg = read_config(run_dir)
    names = {st.get("body") for st in cfg.get("stage", []) if isinstance(st, dict)
             and st.get("type") == "age"}
    bodies = [b for b in cfg.get("body", []) if isinstance(b, dict) and b.get("name") in names
              and b.get("shape") == "pile"]
    if not bodies:
        return None
    b = bodies[0]
    axis = np.asarray(b.get("axis", [0.0, 0.0, 1.0]), dtype=float)
    axis /= np.linalg.norm(axis)
    origin = np.asarray(b.get("origin", [0.0, 0.0, 0.0]), dtype=float)
    if axis[2] < 0.999 or np.hypot(origin[0], origin[1]) > 1e-12:
        return None
    d = np.asarray(b.get("direction", [0.0, 0.0, 0.0]), dtype=float)
    d = -axis if not np.any(d) else d / np.linalg.norm(d)
    z_tip = float(origin[2] + head_position_m * d[2])
    R, L = float(b["radius"]), float(b["length"])
    rise = 0.0 if b.get("tip", "cone") == "flat" else R / np.tan(np.radians(b.get("half_angle",
                                                                                  30.0)))
    return np.array([[0.0, z_tip], [R, z_tip + rise], [R, z_tip + L]])


def figure_pile_breakage(run: Run) -> Optional[Figure]:
    """pile_breakage.png: where grains failed while the sand aged (breakages during the age
    stages, by crack growth as dots, instant ones as crosses), in the plane of the pile's axis:
    the distance from the axis [mm] against z [mm], coloured by the ageing time of the dynamic
    phase they broke in; the pile's outline at the end of the ageing drawn."""
    run = as_run(run)
    a = read_pile_file(run.directory, "pile_ageing.csv")
    b = read_breakages(run.directory)
    ph = read_pile_file(run.directory, "phases.csv")
    if a is None or b is None or ph is None or b["time_s"].size == 0:
        return None
    t0, t1 = float(np.min(ph["time_s"])), float(np.max(ph["time_s"]))
    during = (b["time_s"] >= t0) & (b["time_s"] <= t1)
    if not np.any(during):
        return None
    order = np.argsort(ph["time_s"], kind="stable")
    idx = np.clip(np.searchsorted(ph["time_s"][order], b["time_s"][during], side="right") - 1, 0,
                  order.size - 1)
    t_age = _positive_times(ph["ageing_time_s"][order][idx])
    r = np.hypot(b["x_m"][during], b["y_m"][during]) * 1e3
    z = b["z_m"][during] * 1e3
    crack = b["crack"][during] > 0
    plt = pyplot()
    from matplotlib.colors import LogNorm

    fig, ax = plt.subplots(figsize=(6.5, 6))
    norm = LogNorm(vmin=float(t_age.min()), vmax=float(max(t_age.max(), 1.01 * t_age.min())))
    sc = None
    for mask, marker, lab in ((crack, "o", "crack growth"), (~crack, "x", "instant")):
        if np.any(mask):
            sc = ax.scatter(r[mask], z[mask], c=t_age[mask], norm=norm, cmap="viridis", s=14,
                            marker=marker, label=f"{lab} ({int(mask.sum())})")
    if sc is not None:
        fig.colorbar(sc, ax=ax, label="ageing time of the phase [s]")
    outline = pile_outline(run.directory, float(a["head_position_m"][-1]))
    if outline is not None:
        lo = min(float(z.min()), outline[0, 1] * 1e3)
        hi = max(float(z.max()), outline[1, 1] * 1e3)
        ax.fill_betweenx(outline[:, 1] * 1e3, 0.0, outline[:, 0] * 1e3, color="0.85", zorder=0,
                         label="the pile")
        ax.plot(outline[:, 0] * 1e3, outline[:, 1] * 1e3, color="0.4", lw=1.0, zorder=1)
        margin = 0.05 * (hi - lo)
        ax.set_ylim(lo - margin, hi + margin)
    ax.set_xlim(left=0.0)
    label_axes(ax, "distance from the pile's axis r [mm]", "z [mm]",
               f"{run.title}: failures while ageing", fontsize=8)
    fig.tight_layout()
    return fig


def figure_pile_setup(table: Mapping[str, Any], fits: Mapping[str, Mapping[str, float]],
                      title: str = "") -> Optional[Figure]:
    """pile_setup.png (``crushdem-sand pile``): each load test's capacity over the fit's Q0 (the
    fitted line's value at t0) against ageing time (log axis), with the fitted
    Q(t)/Q(t0) = 1 + A log10(t/t0) (Skov and Denver 1988) and A with its standard error; table:
    columns ``test``, ``ageing_time_s``, ``capacity_N``; fits: test -> {A, A_std, Q0_N, t0_s}."""
    tests = list(dict.fromkeys(table["test"]))
    if not tests:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    t_all = np.asarray(table["ageing_time_s"], float)
    q_all = np.asarray(table["capacity_N"], float)
    names = np.asarray(table["test"])
    for j, test in enumerate(tests):
        rows = names == test
        f = fits.get(test, {})
        q0 = f.get("Q0_N", float("nan"))
        t0 = f.get("t0_s", float("nan"))
        ax.plot(t_all[rows], q_all[rows] / q0, "os^D"[j % 4], color=f"C{j}", label=test)
        if np.isfinite(f.get("A", float("nan"))):
            tt = np.geomspace(t0, max(t_all[rows].max(), t0 * 1.01), 50)
            ax.plot(tt, 1.0 + f["A"] * np.log10(tt / t0), "-", color=f"C{j}", lw=1,
                    label=f"A = {f['A']:.3g} ± {f['A_std']:.2g}")
    ax.set_xscale("log")
    plain_log_ticks(ax)
    label_axes(ax, AGEING_TIME_LABEL, "capacity Q(t) / Q(t$_0$)",
               f"{title}: set-up" if title else "set-up", fontsize=8)
    fig.tight_layout()
    return fig
