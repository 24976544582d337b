"""``crushdem plot DIR``: figures of a run's DIR/timeseries.csv (and DIR/summary.json).

The CSV has one header row whose column names carry their SI unit (``time_s``,
``wall_zmax_stress_Pa``, ``kinetic_energy_J``, ...); strains are fractions, compression positive,
counted from the start of the test. Every figure is drawn only when the columns (and, for the
laboratory figures, the stages listed in summary.json) it needs exist, so the command works for
any experiment. A run still going, or stopped with a checkpoint, has no summary.json yet: its
stage types then come from DIR/config.toml and the figures show the rows written so far.
Stresses are drawn in MPa and strains in %. Figures written (PNG, into DIR unless ``--out`` is
given):

* ``stress_time.png``      wall normal stresses (and mean stress p) [MPa] against time [s]
* ``strain_stress.png``    deviator stress q (or axial wall stress) [MPa] against axial strain [%],
                           with volumetric strain [%] on a second panel when present
* ``void_ratio.png``       void ratio e against mean stress p [MPa] on a log axis (the e - log p
                           compression curve), one colour per test stage when there is a
                           ``stage`` column
* ``coordination.png``     coordination number against time
* ``kinetic_energy.png``   kinetic energy [J] against time (log axis)

Laboratory tests (a ``stage`` column, stages described in summary.json ``"stages"``):

* ``triaxial.png``         for each triaxial stage, deviator stress q [MPa] (peak marked with
                           q_max and the peak friction angle from summary.json) and the change of
                           volumetric strain during the stage [%] against the stage's axial
                           strain [%]
* ``q_p_path.png``         stress path q [MPa] against p [MPa], one colour per stage (drawn for
                           any run with both columns)
* ``oedometer.png``        for oedometric stages: void ratio e against vertical stress
                           sigma_v = mean of the zmin/zmax wall stresses [MPa] (log axis), each
                           stage labelled loading or unloading, with its K0 = sigma_h/sigma_v
* ``inertial_number.png``  inertial number I against time (log axis) with the quasi-static
                           limit I = 1e-3 dashed

Sample preparation (a ``friction`` column):

* ``preparation.png``      void ratio (with the target) and the preparation friction coefficient
                           against time

Grain crushing (DIR/grading.csv, DIR/breakage.csv and the crushing columns of the time series):

* ``grading.png``          grading curves, mass passing [%] against particle size d [mm] (log
                           axis): the initial curve, the end of every stage (when grading.csv has
                           one row per time-series row) and the final curve, each labelled with
                           the relative breakage B_r; removed fragments count as finer than every
                           sieve. The size d_c below which grains crack is dashed when
                           summary.json ``"crushing"`` gives it
* ``breakage.png``         cumulative breakages by cause (instant, crack) with the number of
                           particles on a second axis, and the relative breakage B_r with the
                           void ratio e and the void ratio counting the removed fines as solid,
                           against axial strain [%] (time [s] when there is no axial strain)
* ``breakage_sizes.png``   histogram of the diameters [mm] of the broken grains by cause (when
                           breakage.csv has rows)

Ageing (off-DEM stress relaxation or creep, ``"age"`` stages; drawn only when DIR/events.csv
exists). events.csv has one row per dynamic DEM phase: ``ageing_time_s`` (the ageing clock since
the boundary was frozen, 0 for the first phase), ``stage``, ``dynamic_phase`` and the time-series
columns of the end of that phase. The x axis is the ageing time [s] on a log scale, so only the
phases with ageing time > 0 are drawn (each phase a marker); the first phase (t = 0) gives the
reference values shown in the legends. Each age stage is its own curve, with its own t = 0. Dotted
vertical lines mark 1 h and 1 day when they lie within the ageing time reached:

* ``relaxation.png``          vertical stress sigma_v(t)/sigma_v(0) (sigma_v = mean of the
                              zmin/zmax wall stresses; sigma_v(0) in MPa in the legend; for a
                              relaxation with every wall fixed, sigma_v(t)/sigma_v(4 s) as in the
                              study, with its value at 1 day and the plausible band 0.70-0.97
                              there), one point per dynamic phase (t = 0 drawn open at the left
                              edge), and on a
                              second panel the deviator stress q [MPa] with the axial strain [%]
                              on a twin axis (which grows in creep, when the axial wall is
                              servo-controlled)
* ``relaxation_forces.png``   standard deviations of the contact normal and tangential forces
                              [N] (solid), with their means (dashed)
* ``relaxation_breakage.png`` cumulative breakages by cause (instant, crack) with the number of
                              particles on a second axis
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .analysis import DAY_S, HOUR_S, PLAUSIBLE_OEDOMETRIC_1DAY, T_REF_S, value_at

WALLS = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")
MPA = 1e-6


def read_timeseries(path: str) -> Dict[str, np.ndarray]:
    """Reads a CSV with a header row into {column: float64 array}; blanks become NaN."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path}: empty file")
    header = [h.strip() for h in rows[0]]
    data: Dict[str, List[float]] = {h: [] for h in header}
    for line_no, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(f"{path}:{line_no}: {len(row)} fields, the header has {len(header)}")
        for h, v in zip(header, row):
            v = v.strip()
            try:
                data[h].append(float(v) if v else math.nan)
            except ValueError:
                data[h].append(math.nan)
    return {h: np.asarray(v, dtype=np.float64) for h, v in data.items()}


def _has(d: Dict[str, np.ndarray], *cols: str) -> bool:
    return all(c in d and np.isfinite(d[c]).any() for c in cols)


def _time_axis(d: Dict[str, np.ndarray]):
    if _has(d, "time_s"):
        return d["time_s"], "time $t$ [s]"
    if _has(d, "step"):
        return d["step"], "step"
    n = len(next(iter(d.values()))) if d else 0
    return np.arange(n, dtype=np.float64), "row"


def _save(fig, out_dir: str, name: str, written: List[str]) -> None:
    path = os.path.join(out_dir, name)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    written.append(path)


def read_summary(run_dir: str) -> Dict[str, Any]:
    """DIR/summary.json as a dict; {} when it is missing or not valid JSON."""
    try:
        with open(os.path.join(run_dir, "summary.json")) as f:
            s = json.load(f)
    except (OSError, ValueError):
        return {}
    return s if isinstance(s, dict) else {}


def stages_from_config(run_dir: str) -> List[Dict[str, Any]]:
    """The stages (type and name) of DIR/config.toml, which a run writes when it starts: the
    stage types for a run still going or stopped before summary.json exists. [] when the file
    is missing, unreadable or has no [[stage]]."""
    import tomllib

    try:
        with open(os.path.join(run_dir, "config.toml"), "rb") as f:
            cfg = tomllib.load(f)
    except (OSError, ValueError):
        return []
    listed = cfg.get("stage")
    if not isinstance(listed, list):
        return []
    return [{"type": st.get("type"), "name": st.get("name")} for st in listed
            if isinstance(st, dict)]


def _num(x: Any) -> float:
    """A summary.json value as a float (NaN when missing or not a number)."""
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def _stages(d: Dict[str, np.ndarray],
            summary: Dict[str, Any]) -> List[Tuple[int, np.ndarray, Dict[str, Any]]]:
    """[(stage index, row mask, stage description from summary.json or {})] in stage order.

    Empty when the CSV has no ``stage`` column. A run writes the row at a stage boundary twice
    (last row of one stage, first row of the next), so consecutive stages share a point.
    """
    if not _has(d, "stage"):
        return []
    listed = summary.get("stages")
    listed = listed if isinstance(listed, list) else []
    s = d["stage"]
    out = []
    for k in sorted({int(v) for v in s[np.isfinite(s)]}):
        info = listed[k] if 0 <= k < len(listed) and isinstance(listed[k], dict) else {}
        out.append((k, s == k, info))
    return out


def _stage_name(k: int, info: Dict[str, Any]) -> str:
    name = info.get("name") or info.get("type") or ""
    return f"stage {k}: {name}" if name else f"stage {k}"


def _stage_color(k: int):
    import matplotlib.pyplot as plt

    cycle = plt.rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])
    return cycle[k % len(cycle)]


def _vertical_stress(d: Dict[str, np.ndarray]) -> Optional[np.ndarray]:
    """sigma_v: mean of the zmin and zmax wall stresses [Pa] (whichever exist)."""
    cols = [d[c] for c in ("wall_zmin_stress_Pa", "wall_zmax_stress_Pa") if _has(d, c)]
    if not cols:
        return None
    with np.errstate(all="ignore"):
        return np.nanmean(np.vstack(cols), axis=0)


def read_grading(run_dir: str) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """DIR/grading.csv as (sieve sizes [m] increasing, mass fraction passing [rows, sieves]).

    The sieve size is read from the column name ``passing_<d>_m``. None when the file is missing,
    unreadable or has no passing column or no row.
    """
    path = os.path.join(run_dir, "grading.csv")
    if not os.path.isfile(path):
        return None
    try:
        g = read_timeseries(path)
    except (OSError, ValueError):
        return None
    cols = []
    for name in g:
        if name.startswith("passing_") and name.endswith("_m"):
            try:
                size = float(name[len("passing_"):-len("_m")])
            except ValueError:
                continue
            if size > 0 and math.isfinite(size):
                cols.append((size, name))
    if not cols:
        return None
    cols.sort()
    passing = np.column_stack([g[name] for _, name in cols])
    if passing.shape[0] == 0:
        return None
    return np.asarray([size for size, _ in cols]), passing


def read_breakage(run_dir: str) -> List[Tuple[float, str]]:
    """(diameter [m], cause) of every breakage in DIR/breakage.csv; [] when there is none."""
    path = os.path.join(run_dir, "breakage.csv")
    out: List[Tuple[float, str]] = []
    try:
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                try:
                    dia = float(row.get("diameter_m") or "nan")
                except ValueError:
                    continue
                if math.isfinite(dia) and dia > 0:
                    out.append((dia, (row.get("cause") or "").strip() or "unknown"))
    except (OSError, ValueError, csv.Error):
        return []
    return out


def _legend_twin(ax, ax2, **kw) -> None:
    """One legend for the curves of an axis and its twin."""
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    if h1 or h2:
        ax.legend(h1 + h2, l1 + l2, **kw)


def _plain_log_ticks(ax) -> None:
    """Tick labels of a log x axis as plain numbers (0.1, 0.2, 1) instead of powers of ten."""
    from matplotlib.ticker import FuncFormatter

    fmt = FuncFormatter(lambda v, _pos: f"{v:g}")
    ax.xaxis.set_major_formatter(fmt)
    ax.xaxis.set_minor_formatter(FuncFormatter(
        lambda v, _pos: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""))


def make_plots(run_dir: str, out_dir: Optional[str] = None) -> List[str]:
    """Draws the figures for ``run_dir``/timeseries.csv; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    csv_path = os.path.join(run_dir, "timeseries.csv")
    d = read_timeseries(csv_path)
    summary = read_summary(run_dir)
    finished = bool(summary)  # summary.json is written when the run ends
    if not finished:
        # Still running, or stopped (a checkpoint waits for `crushdem resume`): the stage types
        # come from the configuration, the figures from the rows written so far.
        summary = {"stages": stages_from_config(run_dir)}
    out_dir = out_dir or run_dir
    os.makedirs(out_dir, exist_ok=True)
    t, t_label = _time_axis(d)
    written: List[str] = []
    title = os.path.basename(os.path.normpath(run_dir))
    stages = _stages(d, summary)

    # Wall stresses against time.
    wall_cols = [(w, f"wall_{w}_stress_Pa") for w in WALLS if _has(d, f"wall_{w}_stress_Pa")]
    if wall_cols or _has(d, "mean_stress_Pa"):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for w, c in wall_cols:
            ax.plot(t, d[c] * MPA, label=w)
        if _has(d, "mean_stress_Pa"):
            ax.plot(t, d["mean_stress_Pa"] * MPA, "k--", label="mean $p$")
        ax.set_xlabel(t_label)
        ax.set_ylabel("normal stress $\\sigma$ [MPa]")
        ax.set_title(f"{title}: wall stresses")
        ax.grid(True, alpha=0.3)
        ax.legend()
        _save(fig, out_dir, "stress_time.png", written)
        plt.close(fig)

    # Stress-strain.
    if _has(d, "axial_strain"):
        eps_a = d["axial_strain"] * 100.0
        stress_curves = []
        if _has(d, "deviator_stress_Pa"):
            stress_curves.append(("deviator $q$", d["deviator_stress_Pa"]))
        for w in ("zmax", "zmin"):
            c = f"wall_{w}_stress_Pa"
            if _has(d, c):
                stress_curves.append((f"axial $\\sigma_a$ ({w})", d[c]))
                break
        if stress_curves:
            with_vol = _has(d, "volumetric_strain")
            fig, axes = plt.subplots(2 if with_vol else 1, 1, figsize=(7, 7 if with_vol else 4.5),
                                     sharex=True, squeeze=False)
            ax = axes[0, 0]
            for label, s in stress_curves:
                ax.plot(eps_a, s * MPA, label=label)
            ax.set_ylabel("stress [MPa]")
            ax.set_title(f"{title}: stress against axial strain")
            ax.grid(True, alpha=0.3)
            ax.legend()
            if with_vol:
                ax2 = axes[1, 0]
                ax2.plot(eps_a, d["volumetric_strain"] * 100.0, color="tab:green")
                ax2.set_ylabel("volumetric strain $\\varepsilon_v$ [%]")
                ax2.grid(True, alpha=0.3)
            axes[-1, 0].set_xlabel("axial strain $\\varepsilon_a$ [%]")
            _save(fig, out_dir, "strain_stress.png", written)
            plt.close(fig)

    # Compression curve e - log p (one colour per stage in a staged test).
    if _has(d, "void_ratio"):
        p = None
        if _has(d, "mean_stress_Pa"):
            p = d["mean_stress_Pa"]
        elif wall_cols:
            p = np.nanmean(np.vstack([d[c] for _, c in wall_cols]), axis=0)
        if p is not None and np.any(p > 0):
            e = d["void_ratio"]
            fig, ax = plt.subplots(figsize=(6, 4.5))
            if stages:
                for k, rows, info in stages:
                    keep = rows & (p > 0) & np.isfinite(e)
                    if keep.any():
                        ax.semilogx(p[keep] * MPA, e[keep], "o-", ms=3, color=_stage_color(k),
                                    label=_stage_name(k, info))
                ax.legend()
            else:
                keep = p > 0
                ax.semilogx(p[keep] * MPA, e[keep], "o-", ms=3)
            ax.set_xlabel("mean stress $p$ [MPa] (log scale)")
            ax.set_ylabel("void ratio $e$ [-]")
            ax.set_title(f"{title}: compression curve $e$ - log $p$")
            ax.grid(True, which="both", alpha=0.3)
            _save(fig, out_dir, "void_ratio.png", written)
            plt.close(fig)

    # Triaxial stages: q and the change of volumetric strain against the stage's axial strain.
    triaxial = [(k, rows, info) for k, rows, info in stages
                if info.get("type") == "triaxial" and rows.any()]
    if triaxial and _has(d, "deviator_stress_Pa"):
        with_vol = _has(d, "volumetric_strain")
        fig, axes = plt.subplots(2 if with_vol else 1, 1, figsize=(7, 7.5 if with_vol else 4.5),
                                 sharex=True, squeeze=False)
        ax_q = axes[0, 0]
        for i, (k, rows, info) in enumerate(triaxial):
            color = _stage_color(k)
            idx = np.flatnonzero(rows)
            if _has(d, "stage_axial_strain"):
                eps = d["stage_axial_strain"][idx]
            elif _has(d, "axial_strain"):
                eps = d["axial_strain"][idx] - d["axial_strain"][idx[0]]
            else:
                continue
            q = d["deviator_stress_Pa"][idx]
            label = _stage_name(k, info)
            s3 = _num(info.get("sigma_3_at_q_max_Pa"))
            if math.isfinite(s3):
                label += f", $\\sigma_3$ = {s3 * MPA:.3g} MPa"
            ax_q.plot(eps * 100.0, q * MPA, "-", color=color, label=label)
            # Peak: summary.json tracks every step; fall back to the sampled rows.
            q_max = _num(info.get("q_max_Pa"))
            eps_peak = _num(info.get("axial_strain_at_q_max"))
            if not (math.isfinite(q_max) and math.isfinite(eps_peak)) and np.isfinite(q).any():
                j = int(np.nanargmax(q))
                q_max, eps_peak = float(q[j]), float(eps[j])
            if math.isfinite(q_max) and math.isfinite(eps_peak):
                ax_q.plot([eps_peak * 100.0], [q_max * MPA], "o", color=color, ms=7,
                          mfc="none", mew=2)
                text = (f"$q_{{max}}$ = {q_max * MPA:.3g} MPa"
                        f" at $\\varepsilon_a$ = {eps_peak * 100:.2f} %")
                phi = _num(info.get("friction_angle_peak_deg"))
                if math.isfinite(phi):
                    text += f"\n$\\varphi_{{peak}}$ = {phi:.1f}$^\\circ$"
                if info.get("warning"):
                    text += "\nwarning: " + str(info["warning"])[:60]
                ax_q.annotate(text, xy=(eps_peak * 100.0, q_max * MPA),
                              xytext=(0.35, 0.08 + 0.16 * i), textcoords="axes fraction",
                              color=color, fontsize=9,
                              arrowprops=dict(arrowstyle="->", color=color))
            if with_vol:
                ev = d["volumetric_strain"][idx]
                axes[1, 0].plot(eps * 100.0, (ev - ev[0]) * 100.0, "-", color=color,
                                label=_stage_name(k, info))
        ax_q.set_ylabel("deviator stress $q = \\sigma_1 - \\sigma_3$ [MPa]")
        ax_q.set_title(f"{title}: triaxial compression")
        ax_q.set_ylim(bottom=min(0.0, ax_q.get_ylim()[0]))
        ax_q.grid(True, alpha=0.3)
        ax_q.legend(loc="lower right", fontsize=9)
        if with_vol:
            ax_v = axes[1, 0]
            ax_v.axhline(0.0, color="0.5", lw=0.8)
            ax_v.set_ylabel("volumetric strain (compression +) [%]")
            ax_v.grid(True, alpha=0.3)
        axes[-1, 0].set_xlabel("axial strain of the stage $\\varepsilon_a$ [%]")
        _save(fig, out_dir, "triaxial.png", written)
        plt.close(fig)

    # Stress path q - p.
    if _has(d, "mean_stress_Pa", "deviator_stress_Pa"):
        p, q = d["mean_stress_Pa"] * MPA, d["deviator_stress_Pa"] * MPA
        fig, ax = plt.subplots(figsize=(6, 5))
        if stages:
            for k, rows, info in stages:
                ax.plot(p[rows], q[rows], "o-", ms=2.5, color=_stage_color(k),
                        label=_stage_name(k, info))
            ax.legend()
        else:
            ax.plot(p, q, "o-", ms=2.5)
        ax.set_xlabel("mean stress $p = (\\sigma_1 + \\sigma_2 + \\sigma_3)/3$ [MPa]")
        ax.set_ylabel("deviator stress $q$ [MPa]")
        ax.set_title(f"{title}: stress path")
        ax.grid(True, alpha=0.3)
        _save(fig, out_dir, "q_p_path.png", written)
        plt.close(fig)

    # Oedometric stages: e - log sigma_v.
    sigma_v = _vertical_stress(d)
    oedo = [(k, rows, info) for k, rows, info in stages
            if info.get("type") == "oedometric" and rows.any()]
    if oedo and sigma_v is not None and _has(d, "void_ratio"):
        e = d["void_ratio"]
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        drawn = False
        for k, rows, info in oedo:
            keep = rows & (sigma_v > 0) & np.isfinite(e)
            if not keep.any():
                continue
            sv = sigma_v[keep]
            label = _stage_name(k, info)
            if len(sv) > 1:
                label += ", loading" if sv[-1] >= sv[0] else ", unloading"
            k0 = _num(info.get("K0_end"))
            if math.isfinite(k0):
                label += f", $K_0$ = {k0:.3f}"
            ax.semilogx(sv * MPA, e[keep], "o-", ms=3, color=_stage_color(k), label=label)
            drawn = True
        if drawn:
            ax.set_xlabel("vertical stress $\\sigma_v$ [MPa] (log scale)")
            ax.set_ylabel("void ratio $e$ [-]")
            ax.set_title(f"{title}: oedometric compression")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=9)
            _save(fig, out_dir, "oedometer.png", written)
        plt.close(fig)

    # Inertial number against time (quasi-static when I < 1e-3).
    if _has(d, "inertial_number") and np.any(d["inertial_number"] > 0):
        inum = d["inertial_number"]
        limit = 1e-3
        fig, ax = plt.subplots(figsize=(7, 4))
        groups = stages if stages else [(0, np.ones(len(inum), dtype=bool), {})]
        for k, rows, info in groups:
            keep = rows & (inum > 0)
            if keep.any():
                ax.semilogy(t[keep], inum[keep], "-", color=_stage_color(k),
                            label=_stage_name(k, info) if stages else None)
        ax.axhline(limit, color="k", ls="--", lw=1.2, label="quasi-static limit")
        top = max(float(np.nanmax(inum)), limit)
        ax.set_ylim(top=top * 3.0)
        ax.set_xlabel(t_label)
        ax.set_ylabel("inertial number $I$ [-]")
        ax.set_title(f"{title}: inertial number")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=9)
        _save(fig, out_dir, "inertial_number.png", written)
        plt.close(fig)

    # Sample preparation: void ratio and preparation friction against time.
    if _has(d, "friction"):
        sample = summary.get("sample") if isinstance(summary.get("sample"), dict) else {}
        with_e = _has(d, "void_ratio")
        fig, axes = plt.subplots(2 if with_e else 1, 1, figsize=(7, 6.5 if with_e else 4),
                                 sharex=True, squeeze=False)
        if with_e:
            ax = axes[0, 0]
            ax.plot(t, d["void_ratio"], color="tab:blue", label="void ratio $e$")
            e_target = _num(sample.get("void_ratio_target"))
            if math.isfinite(e_target):
                ax.axhline(e_target, color="tab:red", ls="--", lw=1.2,
                           label=f"target $e$ = {e_target:.3g}")
            e_final = _num(sample.get("void_ratio"))
            if math.isfinite(e_final) and len(t):
                ax.plot([t[-1]], [e_final], "o", color="tab:blue",
                        label=f"prepared $e$ = {e_final:.4g}")
            ax.set_ylabel("void ratio $e$ [-]")
            ax.set_title(f"{title}: sample preparation")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=9)
        ax = axes[-1, 0]
        ax.plot(t, d["friction"], color="tab:orange", drawstyle="steps-post",
                label="grain friction $\\mu$")
        mu_prep = _num(sample.get("preparation_friction"))
        if math.isfinite(mu_prep):
            ax.axhline(mu_prep, color="0.4", ls=":", lw=1.2,
                       label=f"preparation friction = {mu_prep:.3g}")
        ax.set_ylabel("friction coefficient $\\mu$ [-]")
        ax.set_xlabel(t_label)
        if not with_e:
            ax.set_title(f"{title}: sample preparation")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=9)
        _save(fig, out_dir, "preparation.png", written)
        plt.close(fig)

    if _has(d, "coordination_number"):
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(t, d["coordination_number"])
        ax.set_xlabel(t_label)
        ax.set_ylabel("coordination number $Z$ [-]")
        ax.set_title(f"{title}: coordination number")
        ax.grid(True, alpha=0.3)
        _save(fig, out_dir, "coordination.png", written)
        plt.close(fig)

    if _has(d, "kinetic_energy_J"):
        ke = d["kinetic_energy_J"]
        fig, ax = plt.subplots(figsize=(7, 4))
        if np.any(ke > 0):
            ax.semilogy(t[ke > 0], ke[ke > 0])
        else:
            ax.plot(t, ke)
        ax.set_xlabel(t_label)
        ax.set_ylabel("kinetic energy [J]")
        ax.set_title(f"{title}: kinetic energy")
        ax.grid(True, which="both", alpha=0.3)
        _save(fig, out_dir, "kinetic_energy.png", written)
        plt.close(fig)

    _crushing_plots(d, summary, stages, run_dir, out_dir, title, t, t_label, written, finished)
    _ageing_plots(run_dir, summary, out_dir, title, written)
    return written


def _crushing_plots(d: Dict[str, np.ndarray], summary: Dict[str, Any],
                    stages: List[Tuple[int, np.ndarray, Dict[str, Any]]], run_dir: str,
                    out_dir: str, title: str, t: np.ndarray, t_label: str,
                    written: List[str], finished: bool = True) -> None:
    """grading.png, breakage.png and breakage_sizes.png, each when its data exist. A run not
    ``finished`` has its last grading labelled as such, not as the end of its stage."""
    import matplotlib.pyplot as plt

    crushing = summary.get("crushing") if isinstance(summary.get("crushing"), dict) else {}
    d_c = _num(crushing.get("d_c_m"))
    n_rows = len(t)
    br = d["relative_breakage_Br"] if _has(d, "relative_breakage_Br") else None

    # Grading curves: initial, end of every stage, final.
    grading = read_grading(run_dir)
    if grading is not None:
        sieves, passing = grading
        n = passing.shape[0]
        same_rows = n == n_rows
        # {row: label parts}; a row that ends a stage and is also the last row is drawn once.
        picks: Dict[int, List[str]] = {0: ["initial"]}
        if same_rows:
            for k, rows, info in stages:
                idx = np.flatnonzero(rows)
                # The stage still running has no end yet, only a last output.
                if idx.size and (finished or idx[-1] != n - 1):
                    picks.setdefault(int(idx[-1]), []).append("end of " + _stage_name(k, info))
        picks.setdefault(n - 1, []).insert(
            0, "final" if finished else "last output (run not finished)")
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
            ax.semilogx(sieves[keep] * 1e3, f[keep] * 100.0, fmt, ms=3, color=color,
                        label=label)
        if math.isfinite(d_c) and d_c > 0:
            ax.axvline(d_c * 1e3, color="0.4", ls=":", lw=1.2,
                       label=f"$d_c$ = {d_c * 1e3:.3g} mm")
        ax.set_ylim(0.0, 100.0)
        _plain_log_ticks(ax)
        ax.set_xlabel("particle size d [mm]")
        ax.set_ylabel("mass passing [%]")
        ax.set_title(f"{title}: grading")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
        _save(fig, out_dir, "grading.png", written)
        plt.close(fig)

    # Breakages, particle count, B_r and void ratios against axial strain (or time).
    counts = [(c, lab) for c, lab in (("breakages_instant", "instant failure"),
                                      ("breakages_crack", "crack"))
              if _has(d, c)]
    if counts or br is not None:
        x, x_label = t, t_label
        if _has(d, "axial_strain") and np.nanmax(np.abs(d["axial_strain"])) > 0:
            x, x_label = d["axial_strain"] * 100.0, "axial strain $\\varepsilon_a$ [%]"
        fig, (ax_top, ax_bot) = plt.subplots(2, 1, figsize=(7, 7.5), sharex=True)
        for (c, lab), color in zip(counts, ("tab:red", "tab:blue")):
            ax_top.plot(x, d[c], "-", color=color, label=f"breakages: {lab}")
        ax_top.set_ylabel("cumulative breakages [-]")
        ax_top.set_title(f"{title}: grain crushing")
        ax_top.grid(True, alpha=0.3)
        if _has(d, "n_particles"):
            ax_n = ax_top.twinx()
            ax_n.plot(x, d["n_particles"], "--", color="tab:green", label="particles")
            ax_n.set_ylabel("number of particles [-]", color="tab:green")
            _legend_twin(ax_top, ax_n, fontsize=9, loc="upper left")
        elif counts:
            ax_top.legend(fontsize=9, loc="upper left")
        if br is not None:
            ax_bot.plot(x, br, "-", color="tab:purple", label="relative breakage $B_r$")
        ax_bot.set_ylabel("relative breakage $B_r$ [-]")
        ax_bot.grid(True, alpha=0.3)
        voids = [(c, lab, color) for c, lab, color in (
            ("void_ratio", "void ratio $e$", "tab:blue"),
            ("void_ratio_with_fines", "void ratio with fines as solid", "tab:orange"))
            if _has(d, c)]
        if voids:
            ax_e = ax_bot.twinx()
            for c, lab, color in voids:
                ax_e.plot(x, d[c], "--", color=color, label=lab)
            ax_e.set_ylabel("void ratio $e$ [-]")
            _legend_twin(ax_bot, ax_e, fontsize=9, loc="center left")
        elif br is not None:
            ax_bot.legend(fontsize=9)
        ax_bot.set_xlabel(x_label)
        _save(fig, out_dir, "breakage.png", written)
        plt.close(fig)

    # Sizes of the broken grains by cause.
    broken = read_breakage(run_dir)
    if broken:
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
            _plain_log_ticks(ax)
        if math.isfinite(d_c) and d_c > 0:
            ax.axvline(d_c * 1e3, color="0.3", ls=":", lw=1.2,
                       label=f"$d_c$ = {d_c * 1e3:.3g} mm")
        d50 = _num(crushing.get("d50_initial_m"))
        if math.isfinite(d50) and d50 > 0:
            ax.axvline(d50 * 1e3, color="0.3", ls="--", lw=1.2,
                       label=f"initial $d_{{50}}$ = {d50 * 1e3:.3g} mm")
        ax.set_xlabel("diameter of the broken grain d [mm]")
        ax.set_ylabel("breakages [-]")
        ax.set_title(f"{title}: sizes of the broken grains ({dia.size})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=9)
        _save(fig, out_dir, "breakage_sizes.png", written)
        plt.close(fig)




def read_events(run_dir: str) -> Optional[Dict[str, np.ndarray]]:
    """DIR/events.csv (one row per dynamic phase of the "age" stages) as {column: array}.

    None when the file is missing, or unreadable (as it can be for a moment while a run is still
    writing it: a message goes to stderr and the ageing figures are left out).
    """
    path = os.path.join(run_dir, "events.csv")
    if not os.path.isfile(path):
        return None
    try:
        return read_timeseries(path)
    except (OSError, ValueError) as e:
        print(f"crushdem plot: {path} skipped: {e}", file=sys.stderr)
        return None


def _ageing_groups(ev: Dict[str, np.ndarray], summary: Dict[str, Any]
                   ) -> List[Tuple[str, np.ndarray, int]]:
    """[(label, row indices in ageing-time order, reference row)] for each age stage of events.

    The reference row is the stage's first dynamic phase (ageing time 0, or the earliest one).
    """
    t_age = ev["ageing_time_s"]
    n = len(t_age)
    listed = summary.get("stages")
    listed = listed if isinstance(listed, list) else []
    if _has(ev, "stage"):
        keys = sorted({int(v) for v in ev["stage"][np.isfinite(ev["stage"])]})
        groups = [(k, np.flatnonzero(ev["stage"] == k)) for k in keys]
    else:
        groups = [(-1, np.arange(n))]
    out = []
    for k, idx in groups:
        idx = idx[np.isfinite(t_age[idx])]
        if not idx.size:
            continue
        order = idx[np.argsort(t_age[idx], kind="stable")]
        if _has(ev, "dynamic_phase"):
            phase = ev["dynamic_phase"][order]
            ref = int(order[int(np.nanargmin(phase))]) if np.isfinite(phase).any() \
                else int(order[0])
        else:
            ref = int(order[0])
        if k < 0:
            label = "age"
        else:
            info = listed[k] if 0 <= k < len(listed) and isinstance(listed[k], dict) else {}
            label = _stage_name(k, info)
        out.append((label, order, ref))
    return out


def _walls_fixed(ev: Dict[str, np.ndarray], idx: np.ndarray) -> bool:
    """Whether every wall stood still over the phases ``idx`` (a relaxation with all walls
    fixed, as in the oedometric relaxation) rather than servo-controlled (creep, triaxial)."""
    cols = [f"wall_{w}_position_m" for w in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")]
    if len(idx) < 2 or not _has(ev, *cols):
        return False
    return all(np.ptp(ev[c][idx]) == 0.0 for c in cols)


def _time_marks(axes, label_ax=None) -> None:
    """Dotted vertical lines at 1 h and 1 day on log-time axes, where inside the data range."""
    for ax in axes:
        lo, hi = ax.get_xlim()
        for x, text in ((HOUR_S, "1 h"), (DAY_S, "1 day")):
            if lo <= x <= hi * 1.0001:
                ax.axvline(x, color="0.35", ls=":", lw=1.2)
                if ax is label_ax:
                    ax.text(x, 0.97, f"{text} ", transform=ax.get_xaxis_transform(),
                            rotation=90, ha="right", va="top", fontsize=8, color="0.25",
                            bbox=dict(facecolor="white", alpha=0.7, lw=0, pad=1))
        ax.set_xlim(lo, hi)


def _ageing_plots(run_dir: str, summary: Dict[str, Any], out_dir: str, title: str,
                  written: List[str]) -> None:
    """relaxation.png, relaxation_forces.png, relaxation_breakage.png from DIR/events.csv."""
    import matplotlib.pyplot as plt

    ev = read_events(run_dir)
    if ev is None or not _has(ev, "ageing_time_s"):
        return
    t_age = ev["ageing_time_s"]
    groups = _ageing_groups(ev, summary)
    # The log axis holds the phases with ageing time > 0 only; nothing to draw without one.
    groups = [(label, idx, ref) for label, idx, ref in groups if np.any(t_age[idx] > 0)]
    if not groups:
        return
    multi = len(groups) > 1
    markers = ("o", "s", "^", "D", "v")
    x_label = "ageing time $t$ [s] (log scale)"

    def pos(idx: np.ndarray) -> np.ndarray:
        return idx[t_age[idx] > 0]

    # Vertical stress relaxation, q and axial strain.
    sigma_v = _vertical_stress(ev)
    with_q = _has(ev, "deviator_stress_Pa")
    with_ea = _has(ev, "axial_strain")
    if sigma_v is not None:
        lower = with_q or with_ea
        fig, axes = plt.subplots(2 if lower else 1, 1, figsize=(7, 7.5 if lower else 4.5),
                                 sharex=True, squeeze=False)
        ax = axes[0, 0]
        band_drawn = False
        any_4s = False
        for i, (label, idx, ref) in enumerate(groups):
            p = pos(idx)
            # An oedometric relaxation (every wall fixed) is normalised as the study does, by
            # sigma_v at 4 s of ageing, and drawn with the plausible band at one day.
            s_ref, ref_text = sigma_v[ref], "$\\sigma_v(0)$"
            relaxation = _walls_fixed(ev, idx)
            if relaxation:
                s4, _ = value_at(t_age[idx], sigma_v[idx], T_REF_S)
                if math.isfinite(s4) and s4 != 0.0:
                    s_ref, ref_text, any_4s = s4, "$\\sigma_v$(4 s)", True
            text = f"{ref_text} = {s_ref * MPA:.2f} MPa"
            if relaxation and s_ref != sigma_v[ref]:
                r_day, _ = value_at(t_age[idx], sigma_v[idx] / s_ref, DAY_S)
                if math.isfinite(r_day):
                    text += f", 1 day: {r_day:.3f}"
            if math.isfinite(s_ref) and s_ref != 0.0:
                ax.semilogx(t_age[p], sigma_v[p] / s_ref, marker=markers[i % len(markers)],
                            ls="-", lw=0.8, ms=6, color=_stage_color(i),
                            label=f"{label}, {text}" if multi else text)
                # The state before the first jump (t = 0) has no place on a log axis: drawn
                # open at a tenth of the first ageing time, joined by a dotted line.
                if t_age[ref] <= 0 and p.size:
                    x0 = t_age[p[0]] / 10.0
                    ax.semilogx([x0, t_age[p[0]]], [sigma_v[ref] / s_ref, sigma_v[p[0]] / s_ref],
                                ls=":", lw=0.8, color=_stage_color(i))
                    ax.semilogx([x0], [sigma_v[ref] / s_ref], marker=markers[i % len(markers)],
                                ms=6, mfc="none", color=_stage_color(i), ls="none",
                                label="t = 0 (before the first jump), drawn at the left"
                                if i == 0 else None)
            if relaxation and any_4s and not band_drawn and np.nanmax(t_age[p]) >= DAY_S / 2:
                lo, hi = PLAUSIBLE_OEDOMETRIC_1DAY
                ax.fill_between([DAY_S / 1.3, DAY_S * 1.3], lo, hi, color="tab:green",
                                alpha=0.2, lw=0,
                                label=f"plausible at 1 day: {lo:.2f}-{hi:.2f} of $\\sigma_v$(4 s)")
                band_drawn = True
        ax.axhline(1.0, color="0.5", lw=0.8)
        ax.set_ylabel("$\\sigma_v(t) / \\sigma_v$(4 s) [-]" if any_4s and not multi
                      else "$\\sigma_v(t) / \\sigma_v$(reference) [-]" if any_4s
                      else "$\\sigma_v(t) / \\sigma_v(0)$ [-]")
        ax.set_title(f"{title}: ageing (relaxation / creep), vertical stress")
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=9, loc="lower left")
        if lower:
            ax_q = axes[1, 0]
            ax_e = ax_q.twinx() if with_ea else None
            for i, (label, idx, _ref) in enumerate(groups):
                p = pos(idx)
                m = markers[i % len(markers)]
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
                _legend_twin(ax_q, ax_e, fontsize=9, loc="best")
            else:
                ax_q.legend(fontsize=9)
        axes[-1, 0].set_xlabel(x_label)
        _time_marks([a[0] for a in axes], label_ax=axes[0, 0])
        _save(fig, out_dir, "relaxation.png", written)
        plt.close(fig)

    # Contact force statistics.
    force_cols = [(c, lab, color, ls) for c, lab, color, ls in (
        ("std_Fn_N", "std. dev. normal force $F_n$", "tab:blue", "-"),
        ("std_Ft_N", "std. dev. tangential force $F_t$", "tab:orange", "-"),
        ("mean_Fn_N", "mean normal force $F_n$", "tab:blue", "--"),
        ("mean_Ft_N", "mean tangential force $F_t$", "tab:orange", "--")) if _has(ev, c)]
    if force_cols:
        fig, ax = plt.subplots(figsize=(7, 4.8))
        for i, (label, idx, _ref) in enumerate(groups):
            p = pos(idx)
            m = markers[i % len(markers)]
            for c, lab, color, ls in force_cols:
                ax.semilogx(t_age[p], ev[c][p], marker=m, ls=ls, ms=4, color=color,
                            mfc=color if ls == "-" else "none",
                            label=f"{lab} ({label})" if multi else lab)
        ax.set_xlabel(x_label)
        ax.set_ylabel("contact force [N]")
        ax.set_title(f"{title}: ageing, contact forces")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        _time_marks([ax], label_ax=ax)
        _save(fig, out_dir, "relaxation_forces.png", written)
        plt.close(fig)

    # Breakages and particle count.
    counts = [(c, lab, color) for c, lab, color in (
        ("breakages_instant", "breakages: instant failure", "tab:red"),
        ("breakages_crack", "breakages: crack", "tab:blue")) if _has(ev, c)]
    with_n = _has(ev, "n_particles")
    if counts or with_n:
        fig, ax = plt.subplots(figsize=(7, 4.8))
        ax_n = ax.twinx() if with_n else None
        for i, (label, idx, _ref) in enumerate(groups):
            p = pos(idx)
            m = markers[i % len(markers)]
            suffix = f" ({label})" if multi else ""
            for c, lab, color in counts:
                ax.semilogx(t_age[p], ev[c][p], marker=m, ls="-", ms=4, color=color,
                            label=lab + suffix)
            if ax_n is not None:
                ax_n.semilogx(t_age[p], ev["n_particles"][p], marker=m, ls="--", ms=4,
                              mfc="none", color="tab:green", label="particles" + suffix)
        ax.set_xlabel(x_label)
        ax.set_ylabel("cumulative breakages [-]")
        ax.set_title(f"{title}: ageing, grain crushing")
        ax.grid(True, which="both", alpha=0.3)
        if ax_n is not None:
            ax_n.set_ylabel("number of particles [-]", color="tab:green")
            _legend_twin(ax, ax_n, fontsize=9, loc="best")
        else:
            ax.legend(fontsize=9, loc="best")
        _time_marks([ax], label_ax=ax)
        _save(fig, out_dir, "relaxation_breakage.png", written)
        plt.close(fig)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem plot DIR [--out OUT]``; returns the exit status."""
    parser = argparse.ArgumentParser(
        prog="crushdem plot",
        description="Draw the time series of a crushdem run (DIR/timeseries.csv) as PNG files.")
    parser.add_argument("dir", metavar="DIR", help="run directory containing timeseries.csv")
    parser.add_argument("--out", default=None, help="directory for the PNGs (default: DIR)")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        written = make_plots(args.dir, args.out)
    except (OSError, ValueError) as e:
        print(f"crushdem plot: error: {e}", file=sys.stderr)
        return 2
    if not written:
        print(f"crushdem plot: {os.path.join(args.dir, 'timeseries.csv')} has no column to plot",
              file=sys.stderr)
        return 1
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
