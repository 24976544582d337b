"""``crushdem reproduce --out DIR [--quick] [--threads N]``: the reference study's section 3
(stress relaxation of a crushable quartz sand) run end to end, with its four figures.

The study ("Discrete modelling of stress relaxation in crushable sands based on fracture
theory", section 3; docs/model.md 4.4 and 4.5) has one sample and three tests:

* an oedometric stress relaxation: load to sigma_v = 7.5 MPa with crushing on, fix the walls,
  age one day with the on-off scheme (dynamic phases of ``min_cycles`` steps alternating with
  off-DEM jumps that bring ``n_break`` grains to failure);
* a drained triaxial shear at sigma_3 = 10 MPa to 30 % axial strain, only to find q_max;
* a triaxial stress relaxation: the same shear stopped at q = 0.7 q_max, then the axial strain
  held (lateral walls servo-controlled at 10 MPa during dynamic phases) for one day of ageing.

Each run is an ordinary run directory under DIR (``sample/``, ``oedometric_relaxation/``,
``triaxial_shear/``, ``triaxial_relaxation/``), made by the functions of :mod:`crushdem.lab`, so
``crushdem plot DIR/<run>`` works on each. A run whose directory already holds ``summary.json``
(written last, when a run finishes) is not run again: a re-invocation after an interruption goes
on where it stopped (an interrupted run continues from its ``checkpoint.bin``; one that left
none starts over). ``DIR/settings.json`` records the settings of the first invocation; a later
one with other settings (``--quick`` against the study scale, another ``--sample``) stops rather
than mixing results.

Figures (PNG, with the CSV of what each draws; ``#`` lines at the top of a CSV say how it was
computed), all against the ageing time t (the relaxation clock, off-DEM jumps only) on a log axis,
one point per dynamic phase (the study's red dots):

* ``fig1_oedometric_relaxation``  sigma_v(t) / sigma_v(4 s), sigma_v = mean of the two axial wall
  stresses. sigma_v(4 s) is interpolated linearly in log t between the phases on either side of
  4 s; when the first phase after t = 0 is already later than 4 s (the first jumps can be long),
  linearly in t between the t = 0 phase and that one (the CSV header says which). With the
  straight line in log t fitted to the phases with t > 0 and its R^2 (not judged with fewer
  than 3 such phases: two points lie on any line).
* ``fig2_dynamic_phase4``  during the 4th dynamic phase of the triaxial relaxation: (a) the
  confining pressure fluctuation and (b) the volumetric strain generated, against the cycles of
  the phase, from the run's ``phases.csv`` (one row every ``record_interval`` steps of each
  phase). Left out, with a message, when the run has no ``phases.csv`` or fewer than 4 phases.
* ``fig3_triaxial_relaxation``  q against t with the straight line q = a + b log10 t fitted to
  the phases with t > 0 (b: the change of q per log cycle; R^2).
* ``fig4_force_statistics``  standard deviations of |F_n| (a) and |F_t| (b) over grain-grain
  contacts, triaxial and oedometric relaxation.

``DIR/reproduce.json`` holds the key numbers (sigma_v ratios at 1 h and 1 day, q_max, the fit,
phases, breakages, grains, wall-clock time of each run, and the crushdem version and commit of
the call that wrote it); a table of them is printed at the end.

``--quick`` runs the same pipeline on a 500-grain sample (e = 0.75: a cube that small packs
looser, docs/laboratory-tests.md) with short dynamic phases, to check the pipeline in a few
minutes; its numbers are not the study's.

Threads: ``--threads`` sets the OpenMP thread count of the engine (``crushdem.set_threads``);
each run's ``timing.json`` records the count used. Results do not depend on it.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .analysis import (BACKEND_TOLERANCE, DAY_S, HOUR_S, N_BREAK_TOLERANCE,  # noqa: F401
                       PLAUSIBLE_OEDOMETRIC_1DAY, T_REF_S, age_rows, column, compare_relaxation,
                       fit_log_t, has_values, lateral_stress, value_at, vertical_stress)
from .figures import MPA, mark_times, use_file_backend_without_display
from .rundir import read_events, read_phases, read_summary, read_timeseries  # noqa: F401
from .rundir import has_stage_state, is_finished
from .runs import run_step, set_threads, timing_record
from .study import (CONTACT, CRUSHING, MATERIAL, NE34,  # noqa: F401  (re-exported)
                    OEDOMETRIC_STRESS_PA, PARAMETER_SETS, SIGMA_3_PA, STUDY_Q_MAX_PA,
                    TABLE1_CONTACT, TABLE1_CRUSHING)

PLATEAU_FROM = 1.0 / 3.0  # the shear's plateau: from a third of its final axial strain
FIG2_PHASE = 3         # the study's Figure 2: the 4th dynamic phase (0-based in phases.csv)
RUNS = ("sample", "oedometric_relaxation", "triaxial_shear", "triaxial_relaxation")
TESTS = ("oedometric", "triaxial")  # --only: the runs of each besides the sample
TEST_RUNS = {"oedometric": ("oedometric_relaxation",),
             "triaxial": ("triaxial_shear", "triaxial_relaxation")}

def settings(quick: bool, parameters: str = "crushdem", backend: str = "cpu") -> Dict[str, Any]:
    """The parameters of every run, study scale or ``--quick``, with the named parameter set
    ``parameters`` (PARAMETER_SETS), as one JSON-able dict; ``backend`` (what advances the runs:
    "cpu", "cuda" or "emulated") is recorded when it is not the CPU, since the backends agree
    only statistically."""
    if parameters not in PARAMETER_SETS:
        raise ValueError(f"--parameters {parameters!r}: expected one of "
                         f"{', '.join(PARAMETER_SETS)}")
    contact, crushing, _ = PARAMETER_SETS[parameters]
    s: Dict[str, Any] = {
        "mode": "quick" if quick else "study",
        "material": dict(MATERIAL),
        "contact": dict(contact),
        "crushing": dict(crushing),
        "sample": {"side": 4e-3, "void_ratio": 0.65, "seed": 1, "stress": 100e3,
                   "grading": NE34},
        "oedometric": {"stress": OEDOMETRIC_STRESS_PA, "strain_rate": 10.0},
        "triaxial": {"sigma_3": SIGMA_3_PA, "strain_rate": 50.0, "axial_strain": 0.30},
        "relaxation": {"q_fraction": 0.7},
        # The study: dynamic phases of at least 150,000 cycles, N_break = 30, one day.
        "age": {"duration": 86400.0, "min_cycles": 150000, "n_break": 30},
        "age_stage": {},
        "record_interval": None,  # phases.csv rows: the C++ default (1000 steps)
        "output": {"interval": 20000, "progress_seconds": 60},
    }
    if parameters != "crushdem":
        s["parameters"] = parameters
    if backend != "cpu":
        s["backend"] = backend
    if quick:
        s["sample"] = {"count": 500, "void_ratio": 0.75, "seed": 3, "stress": 100e3,
                       "grading": NE34}
        # Faster loading and shearing: the inertial number stays below 1e-3 (about 8.6e-4 and
        # 7e-4, reported in summary.json); shear to 15 % only (q still rises slowly there).
        s["oedometric"]["strain_rate"] = 25.0
        s["triaxial"].update(strain_rate=100.0, axial_strain=0.15)
        s["age"].update(min_cycles=10000, n_break=3)
        # A phase must be long enough for the lateral servo to restore sigma_3 after the grains
        # of a jump break; the quick sample needs a few tenths of a percent of lateral strain.
        # At the default limit (10 /s) a 10,000-cycle phase (dt about 6.6e-9 s) allows 0.07 %
        # (the study's 150,000 cycles about 1 %); with 3,000 cycles even 100 /s left the walls at
        # their limit for the whole phase and sigma_3 16 % low. Hence 10,000 cycles and 100 /s
        # (inertial number below 4e-4), in the age stage only.
        s["age_stage"] = {"max_strain_rate": 100.0}
        s["record_interval"] = 500
        s["output"] = {"interval": 1000, "progress_seconds": 0}
    return s


def _write_csv(path: str, comments: Sequence[str], columns: Mapping[str, Sequence[Any]]) -> None:
    """A CSV with ``#`` comment lines first (read_timeseries skips them), then a header row."""
    names = list(columns)
    n = max((len(v) for v in columns.values()), default=0)
    with open(path, "w", newline="") as f:
        for c in comments:
            f.write(f"# {c}\n")
        w = csv.writer(f)
        w.writerow(names)
        for i in range(n):
            row = []
            for name in names:
                v = columns[name][i]
                if isinstance(v, (float, np.floating)):
                    row.append("" if not math.isfinite(float(v)) else repr(float(v)))
                elif isinstance(v, (int, np.integer)):
                    row.append(str(int(v)))
                else:
                    row.append(str(v))
            w.writerow(row)


def _pyplot():
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str, written: List[str]) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    written.append(path)


def _fit_caveat(fit: Mapping[str, Any]) -> str:
    """Why a fit has no R^2: two points lie on any line."""
    return "" if math.isfinite(fit["r2"]) else (
        f" (not judged: {fit['points']} phase(s) with t > 0, a line needs 3 to be tested)")


def _fit_line(fit: Mapping[str, Any], t: np.ndarray) -> np.ndarray:
    """The fitted line at the phases' times (NaN at t = 0, off the log axis)."""
    return np.where(t > 0, fit["intercept"] + fit["slope"] * np.log10(np.where(t > 0, t, 1.0)),
                    math.nan)


def _draw_fit(ax, fit: Mapping[str, Any], t: np.ndarray, scale: float, unit: str) -> None:
    """The straight line in log t over the phases with t > 0, dashed, with its slope and R^2."""
    if not math.isfinite(fit["slope"]):
        return
    pos = t > 0
    tt = np.geomspace(np.min(t[pos]), np.max(t[pos]), 50)
    r2 = f"{fit['r2']:.3f}" if math.isfinite(fit["r2"]) else f"n/a ({fit['points']} points)"
    ax.semilogx(tt, (fit["intercept"] + fit["slope"] * np.log10(tt)) * scale, "--", color="k",
                lw=1.2, label=f"fit: {fit['slope'] * scale:+.3g} {unit}, $R^2$ = {r2}")


def figure_oedometric(run_dir: str, out_dir: str, written: List[str]) -> Dict[str, Any]:
    """fig1_oedometric_relaxation.{png,csv} from ``run_dir``/events.csv; returns its numbers."""
    ev = read_events(run_dir)
    if ev is None or not has_values(ev, "ageing_time_s"):
        raise ValueError(f"{run_dir}: no events.csv with ageing_time_s (no age stage ran?)")
    idx = age_rows(ev)
    sigma_v = vertical_stress(ev)
    if sigma_v is None:
        raise ValueError(f"{run_dir}/events.csv: no axial wall stress column")
    t, s = ev["ageing_time_s"][idx], sigma_v[idx]
    s_ref, how = value_at(t, s, T_REF_S)
    ratio = s / s_ref if math.isfinite(s_ref) and s_ref != 0 else np.full(s.size, math.nan)
    r_1h, how_1h = value_at(t, ratio, HOUR_S)
    r_1d, how_1d = value_at(t, ratio, DAY_S)
    fit = fit_log_t(t, ratio)
    base = os.path.join(out_dir, "fig1_oedometric_relaxation")
    _write_csv(base + ".csv", [
        "Oedometric stress relaxation (study Figure 1): one row per dynamic phase.",
        "sigma_v = mean of the zmin and zmax wall stresses at the end of the phase; "
        "sigma_v_ratio = sigma_v / sigma_v(4 s).",
        f"sigma_v(4 s) = {s_ref!r} Pa: {how}.",
        f"ratio at 1 h = {r_1h!r} ({how_1h}); at 1 day = {r_1d!r} ({how_1d}).",
        f"fit over the {fit['points']} phases with t > 0: sigma_v_ratio = {fit['intercept']!r} + "
        f"{fit['slope']!r} log10(t / 1 s); R^2 = {fit['r2']!r}{_fit_caveat(fit)}",
        f"source: {os.path.join(run_dir, 'events.csv')}",
    ], {
        "dynamic_phase": column(ev, "dynamic_phase", idx).astype(np.int64)
        if has_values(ev, "dynamic_phase") else np.arange(idx.size),
        "ageing_time_s": t,
        "sigma_v_Pa": s,
        "sigma_v_ratio": ratio,
        "sigma_v_ratio_fit": _fit_line(fit, t),
        "sigma_v_over_first_phase": s / s[0] if s.size and s[0] else np.full(s.size, math.nan),
        "breakages_instant": column(ev, "breakages_instant", idx),
        "breakages_crack": column(ev, "breakages_crack", idx),
        "n_particles": column(ev, "n_particles", idx),
    })
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.8))
    pos = t > 0
    ax.semilogx(t[pos], ratio[pos], "-", color="0.3", lw=1.2, zorder=1, label="DEM")
    ax.semilogx(t[pos], ratio[pos], "o", color="red", ms=5, zorder=2,
                label="dynamic phases (end)")
    _draw_fit(ax, fit, t, 1.0, "per log cycle")
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
    _save(fig, base + ".png", written)
    plt.close(fig)
    return {"sigma_v_start_Pa": float(s[0]) if s.size else math.nan,
            "sigma_v_4s_Pa": s_ref, "sigma_v_4s_method": how,
            "sigma_v_ratio_1h": r_1h, "sigma_v_ratio_1h_method": how_1h,
            "sigma_v_ratio_1day": r_1d, "sigma_v_ratio_1day_method": how_1d,
            "sigma_v_ratio_end": float(ratio[-1]) if ratio.size else math.nan,
            "ratio_slope_per_log10_t": fit["slope"], "ratio_intercept": fit["intercept"],
            "r2": fit["r2"], "fit_points": fit["points"]}


def figure_dynamic_phase(run_dir: str, out_dir: str, written: List[str],
                         phase: int = FIG2_PHASE) -> Dict[str, Any]:
    """fig2_dynamic_phase4.{png,csv} from ``run_dir``/phases.csv.

    Returns {"skipped": reason} when there is nothing to draw (no phases.csv, or the phase is
    missing): the other figures do not depend on it.
    """
    ph = read_phases(run_dir)
    if ph is None:
        return {"skipped": f"{os.path.join(run_dir, 'phases.csv')} does not exist (this build "
                           "of crushdem does not write it)"}
    need = ("dynamic_phase", "cycle", "confining_fluctuation", "volumetric_strain_phase")
    missing = [c for c in need if c not in ph]
    if missing:
        return {"skipped": f"{run_dir}/phases.csv lacks the columns {', '.join(missing)}"}
    rows = np.arange(len(ph["cycle"]))
    if has_values(ph, "stage"):
        rows = np.flatnonzero(ph["stage"] == np.nanmin(ph["stage"]))
    rows = rows[ph["dynamic_phase"][rows] == phase]
    if not rows.size:
        n = int(np.nanmax(ph["dynamic_phase"])) + 1 if has_values(ph, "dynamic_phase") else 0
        return {"skipped": f"{run_dir}/phases.csv has no dynamic phase {phase + 1} "
                           f"(dynamic_phase == {phase}); the run had {n} phase(s)"}
    rows = rows[np.argsort(ph["cycle"][rows], kind="stable")]
    cyc = ph["cycle"][rows]
    fluct = ph["confining_fluctuation"][rows]
    vol = ph["volumetric_strain_phase"][rows]
    t_age = float(column(ph, "ageing_time_s", rows)[0])
    base = os.path.join(out_dir, "fig2_dynamic_phase4")
    _write_csv(base + ".csv", [
        f"Dynamic phase {phase + 1} (dynamic_phase == {phase}) of the triaxial relaxation "
        "(study Figure 2), from cycle 0 (just after the ageing jump).",
        "confining_fluctuation = lateral stress / reference - 1 (reference: the lateral servo "
        "target, or the lateral stress at cycle 0 without lateral servo); "
        "volumetric_strain_phase = 1 - V / V(cycle 0), compression positive.",
        f"ageing time of the phase: {t_age!r} s; source: {os.path.join(run_dir, 'phases.csv')}",
    ], {
        "cycle": cyc.astype(np.int64),
        "ageing_time_s": column(ph, "ageing_time_s", rows),
        "time_s": column(ph, "time_s", rows),
        "confining_fluctuation": fluct,
        "volumetric_strain_phase": vol,
        "lateral_stress_Pa": column(ph, "lateral_stress_Pa", rows),
        "axial_stress_Pa": column(ph, "axial_stress_Pa", rows),
        "deviator_stress_Pa": column(ph, "deviator_stress_Pa", rows),
        "breakages_instant": column(ph, "breakages_instant", rows),
        "breakages_crack": column(ph, "breakages_crack", rows),
        "n_particles": column(ph, "n_particles", rows),
    })
    plt = _pyplot()
    fig, (ax_a, ax_b) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    ax_a.plot(cyc, fluct * 100.0, "-", color="tab:blue", marker="o", ms=2.5)
    ax_a.axhline(0.0, color="0.5", lw=0.8)
    ax_a.set_ylabel("confining pressure fluctuation [%]")
    ax_a.set_title(f"(a) dynamic phase {phase + 1} of the triaxial relaxation "
                   f"(ageing time {t_age:.4g} s)")
    ax_a.grid(True, alpha=0.3)
    ax_b.plot(cyc, vol * 100.0, "-", color="tab:green", marker="o", ms=2.5)
    ax_b.axhline(0.0, color="0.5", lw=0.8)
    ax_b.set_ylabel("volumetric strain generated [%]")
    ax_b.set_xlabel("cycles within the dynamic phase")
    ax_b.set_title("(b) volumetric strain since cycle 0 (compression +)")
    ax_b.grid(True, alpha=0.3)
    _save(fig, base + ".png", written)
    plt.close(fig)
    return {"phase": phase + 1, "ageing_time_s": t_age, "cycles": float(np.nanmax(cyc)),
            "max_abs_confining_fluctuation": float(np.nanmax(np.abs(fluct))),
            "volumetric_strain_end": float(vol[-1])}


def figure_triaxial(run_dir: str, out_dir: str, written: List[str],
                    q_max: float = math.nan) -> Dict[str, Any]:
    """fig3_triaxial_relaxation.{png,csv}: q against log t with its straight-line fit."""
    ev = read_events(run_dir)
    if ev is None or not has_values(ev, "ageing_time_s", "deviator_stress_Pa"):
        raise ValueError(f"{run_dir}: no events.csv with ageing_time_s and deviator_stress_Pa")
    idx = age_rows(ev)
    t, q = ev["ageing_time_s"][idx], ev["deviator_stress_Pa"][idx]
    fit = fit_log_t(t, q)
    q0 = float(q[0]) if q.size else math.nan
    ratio = q / q0 if math.isfinite(q0) and q0 != 0 else np.full(q.size, math.nan)
    r_1h, how_1h = value_at(t, ratio, HOUR_S)
    r_1d, how_1d = value_at(t, ratio, DAY_S)
    lateral = lateral_stress(ev)
    base = os.path.join(out_dir, "fig3_triaxial_relaxation")
    _write_csv(base + ".csv", [
        "Triaxial stress relaxation (study Figure 3): one row per dynamic phase; q = axial - "
        "lateral wall stress at the end of the phase.",
        f"fit over the {fit['points']} phases with t > 0: q = {fit['intercept']!r} + "
        f"{fit['slope']!r} log10(t / 1 s) [Pa]; slope per log10 cycle = {fit['slope']!r} Pa; "
        f"R^2 = {fit['r2']!r}{_fit_caveat(fit)}",
        f"q at the first phase (t = 0) = {q0!r} Pa; q_max of the shear = {q_max!r} Pa",
        f"q / q(t = 0) at 1 h = {r_1h!r} ({how_1h}); at 1 day = {r_1d!r} ({how_1d}).",
        f"source: {os.path.join(run_dir, 'events.csv')}",
    ], {
        "dynamic_phase": column(ev, "dynamic_phase", idx).astype(np.int64)
        if has_values(ev, "dynamic_phase") else np.arange(idx.size),
        "ageing_time_s": t,
        "deviator_stress_Pa": q,
        "q_fit_Pa": _fit_line(fit, t),
        "q_over_q_start": ratio,
        "q_over_q_max": q / q_max if math.isfinite(q_max) and q_max else np.full(q.size,
                                                                                 math.nan),
        "lateral_stress_Pa": lateral[idx] if lateral is not None else np.full(q.size, math.nan),
        "axial_strain": column(ev, "axial_strain", idx),
        "volumetric_strain": column(ev, "volumetric_strain", idx),
        "breakages_instant": column(ev, "breakages_instant", idx),
        "breakages_crack": column(ev, "breakages_crack", idx),
        "n_particles": column(ev, "n_particles", idx),
    })
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.8))
    pos = t > 0
    ax.semilogx(t[pos], q[pos] * MPA, "o-", color="tab:red", ms=5, label="dynamic phases (end)")
    if math.isfinite(q0):  # t = 0 has no place on the log axis: drawn as a level
        ax.axhline(q0 * MPA, color="tab:red", ls=":", lw=1.0,
                   label=f"q at t = 0: {q0 * MPA:.3g} MPa")
    _draw_fit(ax, fit, t, MPA, "MPa per log cycle")
    ax.set_xlabel("ageing time $t$ [s] (log scale)")
    ax.set_ylabel("deviator stress $q$ [MPa]")
    ax.set_title(f"Triaxial stress relaxation from q = {q0 * MPA:.3g} MPa" +
                 (f" ($q_{{max}}$ = {q_max * MPA:.3g} MPa)" if math.isfinite(q_max) else ""))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=9, loc="best")
    mark_times([ax], label_ax=ax)
    _save(fig, base + ".png", written)
    plt.close(fig)
    return {"q_start_Pa": q0, "q_end_Pa": float(q[-1]) if q.size else math.nan,
            "slope_Pa_per_log10_t": fit["slope"], "intercept_Pa": fit["intercept"],
            "r2": fit["r2"], "fit_points": fit["points"],
            "slope_per_log10_t_over_q_start": fit["slope"] / q0 if q0 else math.nan,
            "q_ratio_1h": r_1h, "q_ratio_1h_method": how_1h,
            "q_ratio_1day": r_1d, "q_ratio_1day_method": how_1d,
            "q_min_Pa": float(np.min(q)) if q.size else math.nan}


def figure_forces(runs: Sequence[Tuple[str, str]], out_dir: str,
                  written: List[str]) -> Dict[str, Any]:
    """fig4_force_statistics.{png,csv}: std of |F_n| and |F_t| against log t for each
    (label, run directory) that has them; returns {label: {first/last values}}."""
    cols = ("mean_Fn_N", "std_Fn_N", "mean_Ft_N", "std_Ft_N")
    data = []
    for label, run_dir in runs:
        ev = read_events(run_dir)
        if ev is None or not has_values(ev, "ageing_time_s", "std_Fn_N"):
            continue
        idx = age_rows(ev)
        data.append((label, ev["ageing_time_s"][idx], {c: column(ev, c, idx) for c in cols},
                     column(ev, "dynamic_phase", idx)))
    if not data:
        raise ValueError("no events.csv with std_Fn_N")
    base = os.path.join(out_dir, "fig4_force_statistics")
    table: Dict[str, List[Any]] = {"test": [], "dynamic_phase": [], "ageing_time_s": []}
    for c in cols:
        table[c] = []
    table["std_Fn_over_first_phase"], table["std_Ft_over_first_phase"] = [], []
    numbers: Dict[str, Any] = {}
    for label, t, v, phase in data:
        for i in range(t.size):
            table["test"].append(label)
            table["dynamic_phase"].append(int(phase[i]) if math.isfinite(phase[i]) else i)
            table["ageing_time_s"].append(float(t[i]))
            for c in cols:
                table[c].append(float(v[c][i]))
            table["std_Fn_over_first_phase"].append(float(v["std_Fn_N"][i] / v["std_Fn_N"][0]))
            table["std_Ft_over_first_phase"].append(float(v["std_Ft_N"][i] / v["std_Ft_N"][0]))
        numbers[label] = {f"{c}_{when}": float(v[c][k]) for c in ("std_Fn_N", "std_Ft_N")
                          for when, k in (("first", 0), ("last", -1))}
    _write_csv(base + ".csv", [
        "Contact force statistics during the relaxations (study Figure 4): mean and standard "
        "deviation of |F_n| and |F_t| over grain-grain contacts at the end of each dynamic phase.",
        "The figure draws the phases with t > 0 (log axis); the t = 0 values are in the legend.",
    ], table)
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(7, 7.5), sharex=True)
    colors = {"triaxial relaxation": "tab:red", "oedometric relaxation": "tab:blue"}
    markers = ("o", "s", "^")
    for k, (label, t, v, _phase) in enumerate(data):
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
    _save(fig, base + ".png", written)
    plt.close(fig)
    return numbers


# ----------------------------------------------------------------------------------------------
# Running.


def run_sample(cfg: Mapping[str, Any], run_dir: str, log: Callable[[str], None],
               record: Dict[str, Any], progress: bool = False) -> str:
    """The sample of the settings ``cfg`` prepared into ``run_dir`` as a ``run_step``; returns
    its particle file. progress: the engine's progress lines on stderr (every
    ``output.progress_seconds``)."""
    from . import lab

    run_step("sample", run_dir,
              lambda: lab.prepare_sample(run_dir, **run_sections(cfg, progress),
                                         **cfg["sample"]),
              log, record, resumer(backend_of(cfg)), progress)
    return os.path.join(run_dir, "sample.txt")


def run_sections(cfg: Mapping[str, Any], progress: bool) -> Dict[str, Any]:
    """The keyword arguments every run of the settings ``cfg`` gets from crushdem.lab: the
    material, contact and output sections, the backend and the progress lines."""
    return {"material": cfg["material"], "contact": cfg["contact"], "output": cfg["output"],
            "backend": backend_of(cfg), "progress": progress}


def backend_of(cfg: Mapping[str, Any]) -> str:
    """The backend of the settings ``cfg`` ("cpu" unless recorded)."""
    return str(cfg.get("backend", "cpu"))


def resumer(backend: str) -> Callable[[str, bool], Any]:
    """``run_step``'s resume on ``backend``."""
    from . import _core

    return lambda run_dir, progress: _core.resume(run_dir, progress, backend)


def age_stage_keys(cfg: Mapping[str, Any]) -> Dict[str, Any]:
    """Keys for the age stage only: the settings' ``age_stage`` plus ``record_interval``."""
    age_stage = dict(cfg["age_stage"])
    if cfg["record_interval"]:
        age_stage["record_interval"] = cfg["record_interval"]
    return age_stage


def run_oedometric_relaxation(cfg: Mapping[str, Any], run_dir: str, sample_file: str,
                              log: Callable[[str], None], record: Dict[str, Any],
                              name: str = "oedometric_relaxation",
                              progress: bool = False) -> None:
    """The study's oedometric relaxation with the settings ``cfg`` (see ``settings``) into
    ``run_dir``, as a ``run_step`` (skipped when finished, resumed when interrupted);
    progress: the engine's progress lines on stderr."""
    from . import lab

    oe = cfg["oedometric"]
    run_step(name, run_dir,
              lambda: lab.oedometric_relaxation(
                  run_dir, sample_file, stress=oe["stress"], strain_rate=oe["strain_rate"],
                  crushing=dict(cfg["crushing"]), age_stage=age_stage_keys(cfg), **cfg["age"],
                  **run_sections(cfg, progress)),
              log, record, resumer(backend_of(cfg)), progress)


def triaxial_stage_index(summary: Mapping[str, Any]) -> Optional[int]:
    """The index (the ``stage`` column of timeseries.csv) of the first triaxial stage of a
    summary.json dict; None when there is none."""
    return next((k for k, st in enumerate(summary.get("stages") or [])
                 if isinstance(st, dict) and st.get("type") == "triaxial"), None)


def triaxial_stage(summary: Mapping[str, Any]) -> Dict[str, Any]:
    """The first triaxial stage of a summary.json dict (q_max_Pa, axial_strain_at_q_max, ...);
    {} when there is none."""
    index = triaxial_stage_index(summary)
    return {} if index is None else summary["stages"][index]


def _age_counts(run_dir: str) -> Dict[str, Any]:
    """Phases, breakages (total and during the age stage) and grains at the end of a run."""
    summary = read_summary(run_dir)
    crushing = summary.get("crushing") or {}
    out: Dict[str, Any] = {
        "grains_end": summary.get("particles"),
        "breakages_instant": crushing.get("breakages_instant"),
        "breakages_crack": crushing.get("breakages_crack"),
        "relative_breakage_Br": crushing.get("relative_breakage_Br"),
    }
    for st in summary.get("stages") or []:
        if isinstance(st, dict) and st.get("type") == "age":
            out["dynamic_phases"] = st.get("dynamic_phases")
            out["ageing_time_s"] = st.get("ageing_time_s")
            out["age_steps"] = st.get("steps")
            out["age_warning"] = st.get("warning", "")
            break
    ev = read_events(run_dir)
    if ev is not None and has_values(ev, "n_particles"):
        idx = age_rows(ev)
        out["grains_first_phase"] = float(ev["n_particles"][idx[0]])
    return out


# Sections of settings() that --set may change, and whether it may add keys to them (the
# configuration sections are checked by the engine's reader, which names a bad key).
SETTABLE = {"material": True, "contact": True, "crushing": True, "age_stage": True,
            "sample": False, "oedometric": False, "triaxial": False, "relaxation": False,
            "age": False}


def apply_overrides(cfg: Dict[str, Any], overrides: Sequence[str]) -> Dict[str, Any]:
    """``cfg`` with each "SECTION.KEY=VALUE" of ``overrides`` set; VALUE is read as a TOML value
    (``0.3``, ``true``, ``"blocked"``), or taken as a string when it is not one."""
    import tomllib

    for item in overrides:
        target, sep, text = item.partition("=")
        section, dot, key = target.strip().partition(".")
        if not sep or not dot or not key:
            raise ValueError(f"--set {item!r}: expected SECTION.KEY=VALUE "
                             "(e.g. contact.rotation=blocked)")
        if section not in SETTABLE:
            raise ValueError(f"--set {item!r}: unknown section '{section}' (expected one of "
                             f"{', '.join(SETTABLE)})")
        if not SETTABLE[section] and key not in cfg[section]:
            raise ValueError(f"--set {item!r}: unknown key '{key}' in '{section}' (expected one "
                             f"of {', '.join(cfg[section])})")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        cfg[section][key] = value
    return cfg


def reproduce(out: str, quick: bool = False, threads: Optional[int] = None,
              sample: Optional[str] = None, log: Callable[[str], None] = print,
              overrides: Sequence[str] = (), parameters: str = "crushdem",
              tests: Sequence[str] = TESTS, backend: str = "cpu",
              progress: bool = False) -> Dict[str, Any]:
    """Runs the study's section 3 into ``out`` and draws its figures; returns reproduce.json.
    parameters: a named parameter set (PARAMETER_SETS); overrides: "SECTION.KEY=VALUE" changes
    of the settings on top of it (apply_overrides); backend: what advances every run ("cpu",
    "cuda" or "emulated"); tests: which of TESTS to run ("oedometric":
    the oedometric relaxation; "triaxial": the shear and the triaxial relaxation), so that two
    processes can run them side by side into one ``out`` (the sample first, by either); the
    figures and reproduce.json then cover the tests whose runs have finished. progress: the
    engine's progress lines on stderr, one every ``output.progress_seconds`` (60 s at study
    scale, none with ``quick``), with the stage, q and the share done."""
    unknown = [t for t in tests if t not in TESTS]
    if unknown or not tests:
        raise ValueError(f"--only {','.join(tests)}: expected one or more of {', '.join(TESTS)}")
    cfg = apply_overrides(settings(quick, parameters, backend), overrides)
    if sample is not None:
        if not os.path.isfile(sample):
            raise ValueError(f"--sample {sample}: no such file")
        prepared = [o for o in overrides if o.strip().startswith("sample.")]
        if prepared:
            raise ValueError(f"--set {prepared[0]}: the sample is read from --sample {sample}, "
                             "so its preparation settings do not apply; give one or the other")
        cfg["sample"] = {"file": os.path.abspath(sample)}
    os.makedirs(out, exist_ok=True)
    settings_path = os.path.join(out, "settings.json")
    if os.path.isfile(settings_path):
        with open(settings_path) as f:
            before = json.load(f)
        changed = settings_changes(before, json.loads(json.dumps(cfg)))
        if changed:
            differ = "; ".join(f"{k} = {_show_setting(a)} there, {_show_setting(b)} in this call"
                               for k, (a, b) in changed.items())
            raise ValueError(f"{out} holds results made with other settings ({settings_path}: "
                             f"{differ}); give the same --parameters, --set and --sample as "
                             "the call that made them, another --out, or delete that "
                             "directory")
    else:
        with open(settings_path, "w") as f:
            json.dump(cfg, f, indent=2)
            f.write("\n")
    used_threads = set_threads(threads) if threads else None

    t_start = time.perf_counter()
    runs: Dict[str, Any] = {}
    dirs = {name: os.path.join(out, name) for name in RUNS}

    # 1. The sample (or a given sample file), prepared once and read by every test.
    if sample is not None:
        sample_file = os.path.abspath(sample)
        runs["sample"] = {"skipped": True, "wall_s": 0.0, "file": sample_file}
    else:
        sample_file = run_sample(cfg, dirs["sample"], log, runs, progress)
        info = read_summary(dirs["sample"]).get("sample") or {}
        runs["sample"].update(grains=info.get("grains"), void_ratio=info.get("void_ratio"))

    # 2. Oedometric relaxation.
    if "oedometric" in tests:
        run_oedometric_relaxation(cfg, dirs["oedometric_relaxation"], sample_file, log, runs,
                                  progress=progress)
    if is_finished(dirs["oedometric_relaxation"]):
        runs.setdefault("oedometric_relaxation", {"skipped": True,
                                                  **timing_record(dirs["oedometric_relaxation"])})
        runs["oedometric_relaxation"].update(_age_counts(dirs["oedometric_relaxation"]))

    q_max = math.nan
    if "triaxial" in tests:
        q_max = _run_triaxial(cfg, dirs, sample_file, log, runs, progress)
    elif is_finished(dirs["triaxial_relaxation"]):
        q_max = _read_triaxial(dirs, runs)

    # Figures of the tests that have finished (a test that another process still runs is left
    # out here and drawn by the call that finishes it, or by a later one).
    written: List[str] = []
    result: Dict[str, Any] = {"mode": cfg["mode"], "threads": used_threads,
                              "settings": "settings.json", **_made_by(), "runs": runs}
    relaxations = []
    if is_finished(dirs["oedometric_relaxation"]):
        result["oedometric_relaxation"] = figure_oedometric(dirs["oedometric_relaxation"], out,
                                                            written)
    else:
        log("oedometric relaxation: not finished, its figure is left out")
    if math.isfinite(q_max):
        result["dynamic_phase"] = figure_dynamic_phase(dirs["triaxial_relaxation"], out, written)
        if "skipped" in result["dynamic_phase"]:
            log(f"Figure 2 left out: {result['dynamic_phase']['skipped']}")
        tri = figure_triaxial(dirs["triaxial_relaxation"], out, written, q_max)
        shear = runs["triaxial_shear"]
        tri.update(q_max_Pa=q_max, stop_q_Pa=cfg["relaxation"]["q_fraction"] * q_max,
                   q_fraction=cfg["relaxation"]["q_fraction"],
                   **{k: shear[k] for k in ("q_plateau_Pa", "q_plateau_std_Pa",
                                            "plateau_axial_strain")})
        result["triaxial_relaxation"] = tri
        relaxations.append(("triaxial relaxation", dirs["triaxial_relaxation"]))
    else:
        log("triaxial relaxation: not finished, its figures are left out")
    if is_finished(dirs["oedometric_relaxation"]):
        relaxations.append(("oedometric relaxation", dirs["oedometric_relaxation"]))
    if relaxations:
        result["force_statistics"] = figure_forces(relaxations, out, written)
    result["figures"] = [os.path.basename(p) for p in written]
    result["wall_s_total"] = time.perf_counter() - t_start
    with open(os.path.join(out, "reproduce.json"), "w") as f:
        json.dump(_json_safe(result), f, indent=2)
        f.write("\n")
    return result


def _made_by() -> Dict[str, str]:
    """The crushdem version and commit of this call (every run's summary.json has the engine's
    too; a directory advanced by several calls shows the last)."""
    from . import _core  # the compiled module, imported only when something runs
    return {"crushdem_version": _core.__version__, "crushdem_commit": _core.__commit__}


def _run_triaxial(cfg: Mapping[str, Any], dirs: Mapping[str, str], sample_file: str,
                  log: Callable[[str], None], runs: Dict[str, Any], progress: bool) -> float:
    """The triaxial shear (to find q_max), then the triaxial relaxation at q_fraction q_max,
    each a ``run_step``; returns q_max."""
    from . import lab

    tx = cfg["triaxial"]
    run_step("triaxial_shear", dirs["triaxial_shear"],
              lambda: lab.triaxial_test(dirs["triaxial_shear"], sample_file,
                                        sigma_3=tx["sigma_3"], strain_rate=tx["strain_rate"],
                                        axial_strain=tx["axial_strain"],
                                        crushing=dict(cfg["crushing"]),
                                        **run_sections(cfg, progress)),
              log, runs, resumer(backend_of(cfg)), progress)
    q_max = _shear_q_max(dirs["triaxial_shear"], runs)
    # The shear's isotropic compression is the relaxation's too: branch from its end.
    branch = dirs["triaxial_shear"] if has_stage_state(dirs["triaxial_shear"], 1) else None
    run_triaxial_relaxation(cfg, dirs["triaxial_relaxation"], sample_file,
                            cfg["relaxation"]["q_fraction"] * q_max, log, runs,
                            progress=progress, branch_from=branch)
    runs["triaxial_relaxation"].update(_age_counts(dirs["triaxial_relaxation"]))
    return q_max


def run_triaxial_relaxation(cfg: Mapping[str, Any], run_dir: str, sample_file: str,
                            stop_q: float, log: Callable[[str], None], record: Dict[str, Any],
                            name: str = "triaxial_relaxation", progress: bool = False,
                            branch_from: Optional[str] = None) -> None:
    """The study's triaxial relaxation with the settings ``cfg``: the shear of the triaxial test
    stopped at ``stop_q`` (0.7 q_max), then one day of ageing, into ``run_dir`` as a
    ``run_step``. branch_from: a triaxial shear of the same settings and sample whose state
    after the isotropic compression this run starts from (same results, fewer steps)."""
    from . import lab

    tx = cfg["triaxial"]
    run_step(name, run_dir,
              lambda: lab.triaxial_relaxation(
                  run_dir, sample_file, sigma_3=tx["sigma_3"], stop_q=stop_q,
                  strain_rate=tx["strain_rate"], axial_strain=tx["axial_strain"],
                  crushing=dict(cfg["crushing"]), age_stage=age_stage_keys(cfg), **cfg["age"],
                  branch_from=branch_from, **run_sections(cfg, progress)),
              log, record, resumer(backend_of(cfg)), progress)


def _shear_q_max(shear_dir: str, runs: Dict[str, Any]) -> float:
    """q_max of the finished triaxial shear in ``shear_dir`` (recorded in
    runs["triaxial_shear"])."""
    summary = read_summary(shear_dir)
    shear = triaxial_stage(summary)
    q_max = float(shear.get("q_max_Pa", math.nan))
    if not (math.isfinite(q_max) and q_max > 0):
        raise ValueError(f"{shear_dir}/summary.json: no positive q_max_Pa")
    runs.setdefault("triaxial_shear", {"skipped": True, **timing_record(shear_dir)})
    runs["triaxial_shear"].update(q_max_Pa=q_max,
                                  axial_strain_at_q_max=shear.get("axial_strain_at_q_max"),
                                  max_inertial_number=shear.get("max_inertial_number"),
                                  grains_end=summary.get("particles"),
                                  **shear_plateau(shear_dir))
    return q_max


def shear_plateau(shear_dir: str, start_fraction: float = PLATEAU_FROM) -> Dict[str, Any]:
    """Mean and standard deviation of q over the shear's rows from ``start_fraction`` of its
    final axial strain to the end (10-30 % at study scale), from ``shear_dir``'s timeseries.csv.

    A sample sheared to critical state holds a plateau there, and q_max is its highest
    fluctuation; the mean says where the curve lies. Rows are evenly spaced in time and the
    strain rate is constant, so the mean over rows is the mean over strain. NaN entries when
    the run has no rows of its triaxial stage."""
    none = {"q_plateau_Pa": math.nan, "q_plateau_std_Pa": math.nan,
            "plateau_axial_strain": [math.nan, math.nan], "plateau_rows": 0}
    index = triaxial_stage_index(read_summary(shear_dir))
    path = os.path.join(shear_dir, "timeseries.csv")
    if index is None or not os.path.isfile(path):
        return none
    ts = read_timeseries(path)
    if not has_values(ts, "stage", "stage_axial_strain", "deviator_stress_Pa"):
        return none
    in_stage = ts["stage"] == index
    strain = ts["stage_axial_strain"][in_stage]
    if strain.size == 0 or not np.isfinite(strain).any():
        return none
    end = float(np.nanmax(strain))
    q = ts["deviator_stress_Pa"][in_stage][strain >= start_fraction * end]
    q = q[np.isfinite(q)]
    if q.size == 0:
        return none
    return {"q_plateau_Pa": float(np.mean(q)), "q_plateau_std_Pa": float(np.std(q)),
            "plateau_axial_strain": [start_fraction * end, end], "plateau_rows": int(q.size)}


def _read_triaxial(dirs: Mapping[str, str], runs: Dict[str, Any]) -> float:
    """q_max and the records of a triaxial test that an earlier or another call finished."""
    q_max = _shear_q_max(dirs["triaxial_shear"], runs)
    runs.setdefault("triaxial_relaxation",
                    {"skipped": True, **timing_record(dirs["triaxial_relaxation"])})
    runs["triaxial_relaxation"].update(_age_counts(dirs["triaxial_relaxation"]))
    return q_max


SAMPLE_FIGURES = ("q_max_Pa", "axial_strain_at_q_max", "friction_angle_peak_deg",
                  "q_plateau_Pa", "q_ratio_1h", "q_ratio_1day", "r2", "sigma_v_ratio_1day",
                  "oedometric_r2")
# The relaxation figures --summarize reads from a directory's reproduce.json once the run has
# finished there: run -> {column: key in reproduce.json's entry of that run}.
RELAXATION_FIGURES = {
    "triaxial_relaxation": {"q_ratio_1h": "q_ratio_1h", "q_ratio_1day": "q_ratio_1day",
                            "r2": "r2"},
    "oedometric_relaxation": {"sigma_v_ratio_1day": "sigma_v_ratio_1day",
                              "oedometric_r2": "r2"}}


def _sample_of(d: str, cfg: Mapping[str, Any]) -> Dict[str, Any]:
    """The sample a reproduce directory ran on: the real path of its particle file
    (``sample_file``), its ``seed`` (None for a ``--sample`` file), a short ``label`` and the
    sample run's summary entry (``info``: grains, e). The file is DIR/sample/sample.txt, or the
    ``--sample`` file the settings name (its summary then the one beside it)."""
    sample = cfg.get("sample") or {}
    given = sample.get("file")
    path = os.path.realpath(given or os.path.join(d, "sample", "sample.txt"))
    info: Dict[str, Any] = {}
    if os.path.isfile(os.path.join(os.path.dirname(path), "summary.json")):
        info = read_summary(os.path.dirname(path)).get("sample") or {}
    seed = None if given else sample.get("seed")
    label = given or (f"seed {seed}" if seed is not None else path)
    return {"sample_file": path, "seed": seed, "label": label, "info": info}


def _recipe(cfg: Mapping[str, Any]) -> Dict[str, Any]:
    """The settings apart from the sample: what a test does to whichever sample it gets."""
    return {k: v for k, v in cfg.items() if k != "sample"}


def _sample_recipe(cfg: Mapping[str, Any]) -> Optional[Dict[str, Any]]:
    """How the directory prepared its own sample, apart from the seed (None for a --sample
    file, made elsewhere)."""
    sample = cfg.get("sample") or {}
    if "file" in sample:
        return None
    return {k: v for k, v in sample.items() if k != "seed"}


def settings_changes(before: Mapping[str, Any], after: Mapping[str, Any]
                     ) -> Dict[str, List[Any]]:
    """The dotted keys whose values differ between two settings dicts: {key: [before, after]}
    (None where a key is absent), sorted by key."""
    fa, fb = _flat(before), _flat(after)
    return {k: [fa.get(k), fb.get(k)] for k in sorted(set(fa) | set(fb))
            if fa.get(k) != fb.get(k)}


def _flat(cfg: Mapping[str, Any], prefix: str = "") -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for k, v in cfg.items():
        if isinstance(v, Mapping):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def summarize_samples(out_dirs: Sequence[str]) -> Dict[str, Any]:
    """The triaxial figures of several ``crushdem reproduce`` directories (samples of one
    recipe: ``--set sample.seed=K``, or prepared samples given by ``--sample``) side by side,
    with their mean, standard deviation (n - 1) and standard error, and the mean q_max against
    the study's.

    Each directory needs a finished triaxial shear; the relaxation figures (q(1 h)/q(0),
    q(1 day)/q(0), R^2) come from its reproduce.json when the triaxial relaxation has finished
    there, and are left empty otherwise. Raises ValueError naming a directory without a
    finished shear, or directories made with different settings apart from the sample."""
    if not out_dirs:
        raise ValueError("--summarize: expected one or more reproduce directories")
    rows: List[Dict[str, Any]] = []
    recipe = None
    sample_recipe = None
    for d in out_dirs:
        shear_dir = os.path.join(d, "triaxial_shear")
        if not is_finished(shear_dir):
            raise ValueError(f"{d}: no finished triaxial shear ({shear_dir}/summary.json)")
        settings_path = os.path.join(d, "settings.json")
        cfg: Dict[str, Any] = {}
        if os.path.isfile(settings_path):
            with open(settings_path) as f:
                cfg = json.load(f)
        same = _recipe(cfg)
        if recipe is None:
            recipe = (d, same, cfg)
        elif same != recipe[1]:
            raise ValueError(f"{d}: made with other settings than {recipe[0]} (settings.json "
                             "differs in more than the sample); compare samples of one "
                             "recipe, or two recipes with --against")
        made = _sample_recipe(cfg)
        if made is not None:
            if sample_recipe is None:
                sample_recipe = (d, made)
            elif made != sample_recipe[1]:
                raise ValueError(f"{d}: prepares its sample otherwise than {sample_recipe[0]} "
                                 "(settings.json sample differs in more than the seed)")
        summary = read_summary(shear_dir)
        shear = triaxial_stage(summary)
        used = _sample_of(d, cfg)
        info = used["info"]
        row: Dict[str, Any] = {
            "dir": d, "sample": used["label"], "sample_file": used["sample_file"],
            "seed": used["seed"],
            "grains": info.get("grains"), "void_ratio": info.get("void_ratio"),
            "q_max_Pa": shear.get("q_max_Pa", math.nan),
            "axial_strain_at_q_max": shear.get("axial_strain_at_q_max", math.nan),
            "friction_angle_peak_deg": shear.get("friction_angle_peak_deg", math.nan),
            **shear_plateau(shear_dir)}
        drawn: Dict[str, Any] = {}
        try:
            with open(os.path.join(d, "reproduce.json")) as f:
                drawn = json.load(f)
        except (OSError, ValueError):
            drawn = {}
        for run, figures in RELAXATION_FIGURES.items():
            found = (drawn.get(run) or {}) if is_finished(os.path.join(d, run)) else {}
            for column_name, key in figures.items():
                v = found.get(key)
                row[column_name] = float(v) if isinstance(v, (int, float)) else math.nan
        rows.append(row)
    q = _stats(rows, SAMPLE_FIGURES)
    return {"samples": rows, "stats": q, "settings": recipe[2] if recipe else {},
            "sample_recipe": sample_recipe[1] if sample_recipe else None,
            "study_q_max_Pa": STUDY_Q_MAX_PA,
            "q_max_mean_vs_study": q["q_max_Pa"]["mean"] / STUDY_Q_MAX_PA - 1.0,
            "q_max_sem_vs_study": q["q_max_Pa"]["sem"] / STUDY_Q_MAX_PA}


def _stats(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> Dict[str, Dict[str, Any]]:
    """Per key: n, mean, standard deviation (n - 1) and standard error over the finite
    values."""
    stats: Dict[str, Dict[str, Any]] = {}
    for k in keys:
        v = np.array([float(r[k]) if r.get(k) is not None else math.nan for r in rows])
        v = v[np.isfinite(v)]
        std = float(np.std(v, ddof=1)) if v.size > 1 else math.nan
        stats[k] = {"n": int(v.size), "mean": float(np.mean(v)) if v.size else math.nan,
                    "std": std, "sem": std / math.sqrt(v.size) if v.size > 1 else math.nan}
    return stats


PAIRED_FIGURES = ("q_max_Pa", "q_plateau_Pa", "axial_strain_at_q_max")


def compare_recipes(variant_dirs: Sequence[str], base_dirs: Sequence[str]) -> Dict[str, Any]:
    """Two recipes on the same samples: each directory of ``variant_dirs`` is paired with the
    one of ``base_dirs`` that ran on the same sample (the same particle file: a base's own
    DIR/sample/sample.txt given to the variant by ``--sample``, or the same seed), and the
    differences variant - base of q_max, the plateau and the strain at q_max are averaged with
    their standard error. On one packing the sample-to-sample scatter cancels, so a change of
    a choice shows with fewer runs. Raises ValueError for a variant without a base on its
    sample, or when the two recipes have the same settings."""
    variant = summarize_samples(variant_dirs)
    base = summarize_samples(base_dirs)
    changed = settings_changes(_recipe(base["settings"]), _recipe(variant["settings"]))
    if not changed:
        raise ValueError("--against: the two groups were made with the same settings; "
                         "--summarize them together instead")
    # One seed of one sample recipe is one packing (preparation is deterministic).
    same_recipe = (variant["sample_recipe"] is not None and
                   variant["sample_recipe"] == base["sample_recipe"])

    def keys(r: Mapping[str, Any]) -> List[Tuple[str, Any]]:
        out: List[Tuple[str, Any]] = [("file", r["sample_file"])]
        if same_recipe and r["seed"] is not None:
            out.append(("seed", r["seed"]))
        return out

    by_sample: Dict[Tuple[str, Any], Mapping[str, Any]] = {}
    for r in base["samples"]:
        for k in keys(r):
            if k in by_sample:
                raise ValueError(f"{r['dir']} and {by_sample[k]['dir']}: both ran on "
                                 f"{r['sample']}; give one directory per sample")
            by_sample[k] = r
    pairs: List[Dict[str, Any]] = []
    for r in variant["samples"]:
        b = next((by_sample[k] for k in keys(r) if k in by_sample), None)
        if b is None:
            raise ValueError(f"{r['dir']}: no directory of --against ran on its sample "
                             f"({r['sample']})")
        if any(p["base_dir"] == b["dir"] for p in pairs):
            raise ValueError(f"{r['dir']}: another directory ran on its sample "
                             f"({r['sample']}); give one directory per sample")
        pair: Dict[str, Any] = {"sample": b["sample"], "base_dir": b["dir"], "dir": r["dir"]}
        for k in PAIRED_FIGURES:
            pair[f"base_{k}"], pair[k] = b[k], r[k]
            pair[f"delta_{k}"] = float(r[k]) - float(b[k])
        pairs.append(pair)
    return {"changed": changed, "pairs": pairs,
            "stats": _stats(pairs, [f"delta_{k}" for k in PAIRED_FIGURES]),
            "variant": variant, "base": base}


def format_samples(result: Mapping[str, Any]) -> str:
    """summarize_samples' result as a Markdown table (MPa, %)."""

    def cell(v: Any, scale: float = 1.0, fmt: str = ".4g") -> str:
        return _number(v, scale, fmt, missing="")

    scales = {"q_max_Pa": (MPA, ".4g"), "axial_strain_at_q_max": (100.0, ".3g"),
              "friction_angle_peak_deg": (1.0, ".3g"), "q_plateau_Pa": (MPA, ".4g"),
              "q_ratio_1h": (1.0, ".3f"), "q_ratio_1day": (1.0, ".3f"), "r2": (1.0, ".3f"),
              "sigma_v_ratio_1day": (1.0, ".3f"), "oedometric_r2": (1.0, ".3f")}
    head = ("| directory | sample | grains | e | q_max [MPa] | eps_a at q_max [%] | phi' [deg] "
            "| q plateau [MPa] | q(1 h)/q(0) | q(1 day)/q(0) | q R^2 "
            "| sigma_v(1 day)/sigma_v(4 s) | sigma_v R^2 |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in result["samples"]:
        lines.append("| " + " | ".join(
            [r["dir"], r["sample"],
             cell(r["grains"], fmt=".0f"), cell(r["void_ratio"], fmt=".3f")] +
            [cell(r[k], *scales[k]) for k in SAMPLE_FIGURES]) + " |")
    for name, key in (("mean", "mean"), ("std", "std"), ("standard error", "sem")):
        lines.append("| " + " | ".join(
            [name, "", "", ""] +
            [cell(result["stats"][k][key], *scales[k]) for k in SAMPLE_FIGURES]) + " |")
    lines.append("")
    lines.append(f"mean q_max against the study's {result['study_q_max_Pa'] * MPA:g} MPa: "
                 f"{cell(result['q_max_mean_vs_study'], 100.0, '+.1f')} % "
                 f"(standard error {cell(result['q_max_sem_vs_study'], 100.0, '.2f')} %, "
                 f"{result['stats']['q_max_Pa']['n']} samples)")
    return "\n".join(lines)


def format_comparison(result: Mapping[str, Any]) -> str:
    """compare_recipes' result as Markdown: what changed, then the pairs and their mean
    difference with its standard error (MPa, %)."""
    lines = ["changed from the --against directories: " + ", ".join(
        f"{k} = {_show_setting(a)} -> {_show_setting(b)}"
        for k, (a, b) in result["changed"].items()), ""]
    head = ("| sample | q_max against [MPa] | q_max [MPa] | difference [MPa] "
            "| plateau against [MPa] | plateau [MPa] | difference [MPa] "
            "| eps_a at q_max against [%] | eps_a at q_max [%] |")
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    for p in result["pairs"]:
        lines.append("| " + " | ".join(
            [p["sample"], _number(p["base_q_max_Pa"], MPA, ".4g"),
             _number(p["q_max_Pa"], MPA, ".4g"), _number(p["delta_q_max_Pa"], MPA, "+.3f"),
             _number(p["base_q_plateau_Pa"], MPA, ".4g"), _number(p["q_plateau_Pa"], MPA, ".4g"),
             _number(p["delta_q_plateau_Pa"], MPA, "+.3f"),
             _number(p["base_axial_strain_at_q_max"], 100.0, ".3g"),
             _number(p["axial_strain_at_q_max"], 100.0, ".3g")]) + " |")
    st = result["stats"]
    lines.append("")
    for name, k in (("q_max", "delta_q_max_Pa"), ("plateau", "delta_q_plateau_Pa")):
        lines.append(f"{name}: mean difference {_number(st[k]['mean'], MPA, '+.3f')} MPa "
                     f"(standard error {_number(st[k]['sem'], MPA, '.3f')} MPa, "
                     f"{st[k]['n']} pairs)")
    v = result["variant"]
    lines.append(f"q_max against the study's {v['study_q_max_Pa'] * MPA:g} MPa: "
                 f"{_number(v['q_max_mean_vs_study'], 100.0, '+.1f')} % with the change, "
                 f"{_number(result['base']['q_max_mean_vs_study'], 100.0, '+.1f')} % without")
    return "\n".join(lines)


def _show_setting(v: Any) -> str:
    return "(unset)" if v is None else json.dumps(v)


def _json_safe(x: Any) -> Any:
    """NaN and infinities become null (strict JSON); NumPy scalars become Python numbers."""
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def _number(v: Any, scale: float = 1.0, fmt: str = ".4g", missing: str = "-") -> str:
    """v times scale formatted with fmt; ``missing`` when v is not a finite number."""
    try:
        f = float(v) * scale
    except (TypeError, ValueError):
        return missing
    return format(f, fmt) if math.isfinite(f) else missing


def _strain_range(r: Any) -> str:
    """"10-30 %" for [0.1, 0.3]; "-" when it is not two finite numbers."""
    try:
        lo, hi = (float(v) * 100.0 for v in r)
    except (TypeError, ValueError):
        return "-"
    return f"{lo:.3g}-{hi:.3g} %" if math.isfinite(lo) and math.isfinite(hi) else "-"


def format_table(result: Mapping[str, Any]) -> str:
    """The key numbers of reproduce.json as a short plain-text table."""

    num = _number
    oe = result.get("oedometric_relaxation") or {}
    tri = result.get("triaxial_relaxation") or {}
    dyn = result.get("dynamic_phase") or {}
    runs = result.get("runs") or {}
    lines = [f"crushdem reproduce ({result.get('mode')}): study section 3",
             f"  {'sigma_v(4 s) [MPa]':<40}{num(oe.get('sigma_v_4s_Pa'), MPA)}",
             f"  {'sigma_v(1 h) / sigma_v(4 s)':<40}{num(oe.get('sigma_v_ratio_1h'))}",
             f"  {'sigma_v(1 day) / sigma_v(4 s)':<40}{num(oe.get('sigma_v_ratio_1day'))}"
             "   (plausible: 0.70-0.97)",
             f"  {'sigma_v fit R^2 (phases with t > 0)':<40}{num(oe.get('r2'), fmt='.3f')}"
             f"   ({num(oe.get('fit_points'), fmt='.0f')} phases)",
             f"  {'q_max [MPa]':<40}{num(tri.get('q_max_Pa'), MPA)}   (study: 22.6)",
             f"  {'q plateau, mean +- std [MPa]':<40}{num(tri.get('q_plateau_Pa'), MPA)}"
             f" +- {num(tri.get('q_plateau_std_Pa'), MPA, '.2g')}"
             f"   (axial strain {_strain_range(tri.get('plateau_axial_strain'))})",
             f"  {'0.7 q_max [MPa]':<40}{num(tri.get('stop_q_Pa'), MPA)}",
             f"  {'q at t = 0 / at the end [MPa]':<40}{num(tri.get('q_start_Pa'), MPA)}"
             f" / {num(tri.get('q_end_Pa'), MPA)}",
             f"  {'q(1 h) / q(0)':<40}{num(tri.get('q_ratio_1h'))}",
             f"  {'q(1 day) / q(0)':<40}{num(tri.get('q_ratio_1day'))}",
             f"  {'q slope [MPa per log10 cycle]':<40}{num(tri.get('slope_Pa_per_log10_t'), MPA)}",
             f"  {'q fit R^2 (phases with t > 0)':<40}{num(tri.get('r2'), fmt='.3f')}"
             f"   ({num(tri.get('fit_points'), fmt='.0f')} phases)"]
    if "skipped" in dyn:
        lines.append(f"  {'Figure 2':<40}left out: {dyn['skipped']}")
    else:
        lines.append(f"  {'phase 4: max |confining fluct.| [%]':<40}"
                     f"{num(dyn.get('max_abs_confining_fluctuation'), 100.0)}")
        lines.append(f"  {'phase 4: volumetric strain [%]':<40}"
                     f"{num(dyn.get('volumetric_strain_end'), 100.0)}")
    lines.append(f"  {'run':<24}{'wall [s]':>10}{'phases':>8}{'instant':>9}{'crack':>7}"
                 f"{'grains':>8}  most time in")
    for name in RUNS:
        r = runs.get(name) or {}
        wall = num(r.get("wall_s"), fmt=".1f") + ("*" if r.get("skipped") else " ")
        grains = r.get("grains_end", r.get("grains"))
        lines.append(f"  {name:<24}{wall:>10}{num(r.get('dynamic_phases'), fmt='.0f'):>8}"
                     f"{num(r.get('breakages_instant'), fmt='.0f'):>9}"
                     f"{num(r.get('breakages_crack'), fmt='.0f'):>7}"
                     f"{num(grains, fmt='.0f'):>8}  {r.get('dominant_part') or '-'}")
    lines.append(f"  total {num(result.get('wall_s_total'), fmt='.1f')} s in this call"
                 "   (* finished by an earlier call; a run's wall-clock sums all its calls)")
    return "\n".join(lines)


_DESCRIPTION = """\
Run the reference study's section 3 (oedometric and triaxial stress relaxation of crushable
quartz sand, one day of ageing each) and draw its four figures into DIR:
fig1_oedometric_relaxation, fig2_dynamic_phase4, fig3_triaxial_relaxation and
fig4_force_statistics (PNG, with the CSV of what each draws), plus DIR/reproduce.json with the key
numbers. Each run is a run directory of its own (DIR/sample, DIR/oedometric_relaxation,
DIR/triaxial_shear, DIR/triaxial_relaxation) that `crushdem plot` can draw; the triaxial
relaxation starts from the shear's state after its isotropic compression (same results)."""

_EPILOG = """\
Restarting: a run whose directory already has summary.json (written when it finishes) is NOT
run again; its results are read back. So after an interruption the same command goes on with
the first unfinished run: from its checkpoint.bin when it left one,
otherwise from its beginning. To redo a run, delete its directory. DIR/settings.json records
the settings; a call with other settings (--quick or not, --sample, --parameters, --set) into
the same DIR stops
with an error instead of mixing results.

Study scale (default): the 4 mm REV of examples/sample_rev.toml (about 11,400 grains,
e = 0.65), Table 1 with rotation blocked and d0 = 1.07 mm (--parameters crushdem;
--parameters blocked_d0_1mm for the set with d0 = 1 mm, table1 for free rotation and d0 = d50),
crushing with crack growth (density scaling of small fragments), dynamic phases of 150,000
cycles, N_break = 30, triaxial shear at 50 /s to 30 %: about 2.5-3 hours of one core for the
triaxial test and 30 minutes for the oedometric one (--only, side by side on two cores).
--quick: 500 grains at e = 0.75, 10,000-cycle phases, N_break = 3, shear at 100 /s to 15 %:
a few minutes on one core, to check the pipeline (its numbers are not the study's)."""


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem reproduce --out DIR [--quick] [--threads N] [--sample FILE]``."""
    parser = argparse.ArgumentParser(prog="crushdem reproduce", description=_DESCRIPTION,
                                     epilog=_EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", metavar="DIR", help="directory for everything (required "
                        "unless --summarize; with it, where samples.json and samples.md go)")
    parser.add_argument("--quick", action="store_true",
                        help="small sample and short phases (minutes), to check the pipeline")
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="OpenMP threads for the runs (default: the OpenMP default, "
                             "usually every core); results do not depend on it")
    parser.add_argument("--sample", default=None, metavar="FILE",
                        help="use this prepared sample.txt (e.g. runs/sample_rev/sample.txt) "
                             "instead of preparing one in DIR/sample")
    parser.add_argument("--parameters", default="crushdem", choices=list(PARAMETER_SETS),
                        help="named parameter set: " + "; ".join(  # argparse %-formats help
                            f"{k}: {v[2]}" for k, v in PARAMETER_SETS.items()).replace("%", "%%")
                        + " (default: crushdem)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="change one setting, e.g. --set contact.rotation=free, --set "
                             "crushing.r_prime=2R_star or --set sample.seed=2 (another sample "
                             "of the same recipe) (repeatable; sections: "
                             f"{', '.join(SETTABLE)}); recorded in DIR/settings.json")
    parser.add_argument("--only", default=",".join(TESTS), metavar="TEST[,TEST]",
                        help="run only these tests (" + ", ".join(TESTS) + "; default: both), "
                             "e.g. two processes side by side, one per test, into one DIR once "
                             "the sample is prepared; the figures cover what has finished")
    parser.add_argument("--backend", default="cpu", choices=("cpu", "cuda", "emulated"),
                        help="what advances the runs: cpu (default), cuda (a GPU, in a build with "
                             "CUDA) or emulated (the GPU's step on the host); recorded in "
                             "DIR/settings.json, as the backends agree only statistically")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress lines (by default the engine prints one on stderr "
                             "every minute at study scale: stage, stresses, share done, ETA)")
    parser.add_argument("--summarize", nargs="+", default=None, metavar="DIR",
                        help="run nothing: put the triaxial figures (q_max, its strain and "
                             "phi', the plateau, q(1 h)/q(0), q(1 day)/q(0), R^2) of these "
                             "finished reproduce directories (samples of one recipe, e.g. "
                             "--set sample.seed=K) side by side with their mean, standard "
                             "deviation and standard error, and the mean q_max against the "
                             "study's")
    parser.add_argument("--against", nargs="+", default=None, metavar="DIR",
                        help="with --summarize: finished reproduce directories of another "
                             "recipe on the same samples (e.g. the default set, where the "
                             "--summarize ones change one key, each run with --sample "
                             "BASE/sample/sample.txt or the same sample.seed): each pair's "
                             "difference in q_max, plateau and strain at q_max, and the mean "
                             "difference with its standard error; writes comparison.json and "
                             "comparison.md with --out")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    if args.threads is not None and args.threads < 1:
        parser.error("--threads must be >= 1")
    if args.against is not None and args.summarize is None:
        parser.error("--against needs --summarize DIR...")
    if args.summarize is not None:
        return _summarize_main(args.summarize, args.out, args.against)
    if args.out is None:
        parser.error("the following arguments are required: --out")

    def log(msg: str) -> None:
        print(f"crushdem reproduce: {msg}", flush=True)

    use_file_backend_without_display()

    try:
        result = reproduce(args.out, quick=args.quick, threads=args.threads, sample=args.sample,
                           log=log, overrides=args.set, parameters=args.parameters,
                           tests=[t.strip() for t in args.only.split(",") if t.strip()],
                           backend=args.backend, progress=not args.quiet)
    except (OSError, ValueError, RuntimeError) as e:
        print(f"crushdem reproduce: error: {e}", file=sys.stderr)
        return 2
    for name in result.get("figures", []):
        print(os.path.join(args.out, name))
    print(os.path.join(args.out, "reproduce.json"))
    print(format_table(result))
    return 0


def _summarize_main(dirs: Sequence[str], out: Optional[str],
                    against: Optional[Sequence[str]] = None) -> int:
    """``crushdem reproduce --summarize DIR... [--against DIR...] [--out DIR]``."""
    try:
        if against is None:
            result = summarize_samples(dirs)
            table, name = format_samples(result), "samples"
        else:
            result = compare_recipes(dirs, against)
            table, name = format_comparison(result), "comparison"
    except (OSError, ValueError) as e:
        print(f"crushdem reproduce: error: {e}", file=sys.stderr)
        return 2
    if out is not None:
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, f"{name}.json"), "w") as f:
            json.dump(_json_safe(result), f, indent=2)
            f.write("\n")
        with open(os.path.join(out, f"{name}.md"), "w") as f:
            f.write(table + "\n")
        print(os.path.join(out, f"{name}.json"))
        print(os.path.join(out, f"{name}.md"))
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
