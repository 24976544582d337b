"""The figures of laboratory tests (``crushdem-sand plot``): stress against strain, the compression
curves, the triaxial and oedometric stages, the stress path, the inertial number and the sample
preparation."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..analysis import (WALLS, as_float, has_values, lateral_stress, stage_label, stage_rows,
                        vertical_stress)
from ..rundir import RunData, read_run_table
from .common import (MPA, Run, as_run, label_axes, pyplot, stacked_axes, stage_color,
                     time_axis, unique_legend)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


# The stage kinds that keep the lateral walls fixed: a run of these alone (one oedometric at
# least) is an oedometric test, whose volumetric strain is its axial strain.
_LATERALLY_FIXED = {"oedometric", "hold", "age"}


def oedometric_stages(run: RunData) -> List[Tuple[int, np.ndarray, Dict[str, Any]]]:
    """The stages of ``run`` with rows (:func:`~crushdem_sand.analysis.stage_rows`) when it is an
    oedometric test: every stage oedometric, hold or age (its type from summary.json, or
    config.toml for a run still going), one oedometric at least; [] otherwise."""
    stages = [(k, rows, info) for k, rows, info in stage_rows(run.timeseries, run.summary)
              if rows.any()]
    types = {info.get("type") for _, _, info in stages}
    return stages if "oedometric" in types and types <= _LATERALLY_FIXED else []


def figure_strain_stress(run: Run) -> Optional[Figure]:
    """strain_stress.png: deviator stress q (or the axial wall stress) [MPa] against axial
    strain [%], with the volumetric strain [%] on a second panel when present. For an
    oedometric test (:func:`oedometric_stages`), whose volumetric strain is its axial strain,
    the vertical and lateral stress [MPa] against axial strain [%] and the stress path sigma_h
    against sigma_v [MPa] with each oedometric stage's K0 line instead."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "axial_strain"):
        return None
    oedometric = oedometric_stages(run)
    sigma_v, sigma_h = vertical_stress(d), lateral_stress(d)
    if oedometric and sigma_v is not None and sigma_h is not None:
        return _oedometric_strain_stress(run, oedometric, sigma_v, sigma_h)
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
    fig, axes = stacked_axes(has_values(d, "volumetric_strain"), 7)
    with_vol = len(axes) == 2
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


def _oedometric_strain_stress(run: RunData, stages: List[Tuple[int, np.ndarray, Dict[str, Any]]],
                              sigma_v: np.ndarray, sigma_h: np.ndarray) -> Figure:
    """strain_stress.png of an oedometric test: sigma_v (solid) and sigma_h (dashed) [MPa]
    against axial strain [%], and the stress path sigma_h against sigma_v [MPa], a colour per
    stage, with the K0 line of each oedometric stage (dashed) and the isotropic line
    (dotted)."""
    eps = run.timeseries["axial_strain"] * 100.0
    sv, sh = sigma_v * MPA, sigma_h * MPA
    drawn = np.zeros(len(sv), dtype=bool)
    for _, rows, _ in stages:
        drawn |= rows
    top = float(np.nanmax(sv[drawn], initial=0.0))
    plt = pyplot()
    fig, (ax_e, ax_p) = plt.subplots(1, 2, figsize=(11, 4.8))
    for k, rows, info in stages:
        color = stage_color(k)
        oedometric = info.get("type") == "oedometric"
        label = oedometer_label(k, info, sv[rows]) if oedometric else stage_label(k, info)
        ax_e.plot(eps[rows], sv[rows], "-", color=color, label=label)
        ax_e.plot(eps[rows], sh[rows], "--", color=color)
        ax_p.plot(sv[rows], sh[rows], "o-", ms=2.5, color=color, label=label)
        k0 = as_float(info.get("K0_end"))
        if oedometric and math.isfinite(k0) and top > 0:
            ax_p.plot([0.0, top], [0.0, k0 * top], "--", lw=0.9, color=color)
    ax_e.plot([], [], "-", color="0.3", label="vertical $\\sigma_v$ (solid)")
    ax_e.plot([], [], "--", color="0.3", label="lateral $\\sigma_h$ (dashed)")
    label_axes(ax_e, "axial strain $\\varepsilon_a$ [%]", "stress [MPa]",
               "stress against axial strain", fontsize=8)
    if top > 0:
        ax_p.plot([0.0, top], [0.0, top], ":", color="0.5", lw=1.0,
                  label="$\\sigma_h = \\sigma_v$ (isotropic)")
    ax_p.set_xlim(left=0.0)
    ax_p.set_ylim(bottom=0.0)
    label_axes(ax_p, "vertical stress $\\sigma_v$ [MPa]", "lateral stress $\\sigma_h$ [MPa]",
               "stress path (dashed: $\\sigma_h = K_0\\,\\sigma_v$ of the stage)", fontsize=8)
    fig.suptitle(f"{run.title}: oedometric test, stresses")
    fig.tight_layout()
    return fig


def figure_void_ratio(run: Run) -> Optional[Figure]:
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
    plt = pyplot()
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
    label_axes(ax, "mean stress $p$ [MPa] (log scale)", "void ratio $e$ [-]",
               f"{run.title}: compression curve $e$ - log $p$")
    fig.tight_layout()
    return fig


def figure_triaxial(run: Run) -> Optional[Figure]:
    """triaxial.png: for each triaxial stage, q [MPa] (peak marked with q_max and the peak
    friction angle) and the change of volumetric strain [%] against the stage's axial strain
    [%]. A stage's warning (summary.json) is figure text below the axes."""
    run = as_run(run)
    d = run.timeseries
    triaxial = [(k, rows, info) for k, rows, info in stage_rows(d, run.summary)
                if info.get("type") == "triaxial" and rows.any()]
    if not triaxial or not has_values(d, "deviator_stress_Pa"):
        return None
    fig, axes = stacked_axes(has_values(d, "volumetric_strain"), 7.5)
    with_vol = len(axes) == 2
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


def figure_q_p_path(run: Run) -> Optional[Figure]:
    """q_p_path.png: the stress path q [MPa] against p [MPa], one colour per stage."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "mean_stress_Pa", "deviator_stress_Pa"):
        return None
    plt = pyplot()
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


def figure_oedometer(run: Run) -> Optional[Figure]:
    """oedometer.png: for oedometric stages, void ratio e against the vertical stress sigma_v
    [MPa] (log axis), each stage labelled loading or unloading, with its K0."""
    run = as_run(run)
    d = run.timeseries
    sigma_v = vertical_stress(d)
    oedo = [(k, rows, info) for k, rows, info in stage_rows(d, run.summary)
            if info.get("type") == "oedometric" and rows.any()]
    if not oedo or sigma_v is None or not has_values(d, "void_ratio"):
        return None
    plt = pyplot()
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
    label_axes(ax, "vertical stress $\\sigma_v$ [MPa] (log scale)", "void ratio $e$ [-]",
               f"{run.title}: oedometric compression", fontsize=9)
    fig.tight_layout()
    return fig


def figure_inertial_number(run: Run) -> Optional[Figure]:
    """inertial_number.png: the inertial number I against DEM time (log axis) with the
    quasi-static limit I = 1e-3 dashed."""
    run = as_run(run)
    d = run.timeseries
    if not (has_values(d, "inertial_number") and np.any(d["inertial_number"] > 0)):
        return None
    plt = pyplot()
    t, t_label = time_axis(d)
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
    label_axes(ax, t_label, "inertial number $I$ [-]", f"{run.title}: inertial number",
               fontsize=9)
    fig.tight_layout()
    return fig


def figure_preparation(run: Run) -> Optional[Figure]:
    """preparation.png: void ratio (with the target) and the preparation friction coefficient
    against time (a ``friction`` column)."""
    run = as_run(run)
    d = run.timeseries
    if not has_values(d, "friction"):
        return None
    t, t_label = time_axis(d)
    summary = run.summary
    sample = summary.get("sample") if isinstance(summary.get("sample"), dict) else {}
    with_e = has_values(d, "void_ratio")
    fig, axes = stacked_axes(with_e, 6.5, 4)
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


def figure_stress_profile(run: Run) -> Optional[Figure]:
    """stress_profile.png: a chamber sample's stress with depth at the end of its last hold that
    wrote one (``profile_bins``: stress_profile.csv): the vertical, radial and hoop stress [kPa]
    of the core's grains against the depth below the top platen [mm], and K = sigma_rr /
    sigma_zz beside it (a chamber at rest: K0 by depth)."""
    run = as_run(run)
    p = read_run_table(run.directory, "stress_profile.csv")
    if p is None or "depth_m" not in p:
        return None
    last = (p["stage"] == p["stage"][-1]) & (p["time_s"] == p["time_s"][-1])
    depth = p["depth_m"][last] * 1e3
    plt = pyplot()
    fig, (a_s, a_k) = plt.subplots(1, 2, figsize=(9, 5.5), sharey=True,
                                   gridspec_kw={"width_ratios": [2, 1]})
    for key, label, style in (("sigma_zz_Pa", r"$\sigma_{zz}$ (vertical)", "o-"),
                              ("sigma_rr_Pa", r"$\sigma_{rr}$ (radial)", "s-"),
                              ("sigma_tt_Pa", r"$\sigma_{\theta\theta}$ (hoop)", "^-")):
        a_s.plot(p[key][last] * 1e-3, depth, style, ms=3, lw=1.2, label=label)
    a_k.plot(p["K"][last], depth, "o-", ms=3, lw=1.2, color="k")
    a_s.invert_yaxis()
    core = p["core_radius_m"][last][0] * 1e3
    label_axes(a_s, "stress [kPa]", "depth below the top platen [mm]",
               f"{run.title}: within {core:.3g} mm of the axis", fontsize=8)
    label_axes(a_k, r"$K = \sigma_{rr} / \sigma_{zz}$", "", "K")
    fig.tight_layout()
    return fig
