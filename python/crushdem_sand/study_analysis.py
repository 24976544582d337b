"""The analysis of one reproduction's runs (``crushdem-sand reproduce``, docs/model.md 4.4 and 4.5):
q_max and the plateau of the triaxial shear, and each relaxation as the table its figure draws,
one row per dynamic phase against the ageing time t, with the values at 4 s, 1 h and 1 day and
the straight line in log t (:func:`crushdem_sand.analysis.fit_log_t`).

Each ``*_relaxation``, :func:`dynamic_phase` and :func:`force_statistics` returns a
:class:`FigureData`: the columns the figure draws (the CSV written beside it), the lines that say
how they were found (the CSV's ``#`` lines) and the key numbers (reproduce.json). The figures of
:mod:`crushdem_sand.figures.study` draw them; nothing here draws or writes."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .analysis import (DAY_S, HOUR_S, T_REF_S, age_rows, column, fit_log_t, has_values,
                       lateral_stress, value_at, vertical_stress)
from .rundir import read_events, read_phases, read_summary, read_timeseries

PLATEAU_FROM = 1.0 / 3.0  # the shear's plateau: from a third of its final axial strain
FIG2_PHASE = 3         # the study's Figure 2: the 4th dynamic phase (0-based in phases.csv)


@dataclass
class FigureData:
    """What one of the study's figures draws: ``columns`` (the rows of its CSV), ``notes`` (how
    they were found: the CSV's ``#`` lines), ``numbers`` (its key numbers for reproduce.json;
    ``{"skipped": reason}`` when there is nothing to draw) and ``fit`` (the straight line in
    log t, as :func:`crushdem_sand.analysis.fit_log_t` returns it, where the figure has one)."""

    columns: Dict[str, Any]
    notes: List[str]
    numbers: Dict[str, Any]
    fit: Dict[str, Any] = field(default_factory=dict)


def fit_caveat(fit: Mapping[str, Any]) -> str:
    """Why a fit has no R^2: two points lie on any line."""
    return "" if math.isfinite(fit["r2"]) else (
        f" (not judged: {fit['points']} phase(s) with t > 0, a line needs 3 to be tested)")


def fit_line(fit: Mapping[str, Any], t: np.ndarray) -> np.ndarray:
    """The fitted line at the phases' times (NaN at t = 0, off the log axis)."""
    return np.where(t > 0, fit["intercept"] + fit["slope"] * np.log10(np.where(t > 0, t, 1.0)),
                    math.nan)


def _phase_numbers(ev: Mapping[str, np.ndarray], idx: np.ndarray) -> np.ndarray:
    """The dynamic phase of each row (its position when events.csv has no such column)."""
    return column(ev, "dynamic_phase", idx).astype(np.int64) \
        if has_values(ev, "dynamic_phase") else np.arange(idx.size)


def oedometric_relaxation(run_dir: str) -> FigureData:
    """The oedometric relaxation of ``run_dir``/events.csv (study Figure 1): sigma_v(t) /
    sigma_v(4 s), sigma_v = mean of the two axial wall stresses at the end of each phase.
    sigma_v(4 s) is interpolated linearly in log t between the phases on either side of 4 s, or,
    when the first phase after t = 0 is later than 4 s, linearly in t from the t = 0 phase
    (:func:`crushdem_sand.analysis.value_at`). Raises ValueError without the columns."""
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
    notes = [
        "Oedometric stress relaxation (study Figure 1): one row per dynamic phase.",
        "sigma_v = mean of the zmin and zmax wall stresses at the end of the phase; "
        "sigma_v_ratio = sigma_v / sigma_v(4 s).",
        f"sigma_v(4 s) = {s_ref!r} Pa: {how}.",
        f"ratio at 1 h = {r_1h!r} ({how_1h}); at 1 day = {r_1d!r} ({how_1d}).",
        f"fit over the {fit['points']} phases with t > 0: sigma_v_ratio = {fit['intercept']!r} + "
        f"{fit['slope']!r} log10(t / 1 s); R^2 = {fit['r2']!r}{fit_caveat(fit)}",
        f"source: {os.path.join(run_dir, 'events.csv')}",
    ]
    columns = {
        "dynamic_phase": _phase_numbers(ev, idx),
        "ageing_time_s": t,
        "sigma_v_Pa": s,
        "sigma_v_ratio": ratio,
        "sigma_v_ratio_fit": fit_line(fit, t),
        "sigma_v_over_first_phase": s / s[0] if s.size and s[0] else np.full(s.size, math.nan),
        "breakages_instant": column(ev, "breakages_instant", idx),
        "breakages_crack": column(ev, "breakages_crack", idx),
        "n_particles": column(ev, "n_particles", idx),
    }
    numbers = {"sigma_v_start_Pa": float(s[0]) if s.size else math.nan,
               "sigma_v_4s_Pa": s_ref, "sigma_v_4s_method": how,
               "sigma_v_ratio_1h": r_1h, "sigma_v_ratio_1h_method": how_1h,
               "sigma_v_ratio_1day": r_1d, "sigma_v_ratio_1day_method": how_1d,
               "sigma_v_ratio_end": float(ratio[-1]) if ratio.size else math.nan,
               "ratio_slope_per_log10_t": fit["slope"], "ratio_intercept": fit["intercept"],
               "r2": fit["r2"], "fit_points": fit["points"]}
    return FigureData(columns, notes, numbers, fit)


def dynamic_phase(run_dir: str, phase: int = FIG2_PHASE) -> FigureData:
    """Dynamic phase ``phase`` (0-based) of the first age stage in ``run_dir``/phases.csv
    (study Figure 2): the confining pressure fluctuation and the volumetric strain generated,
    against the cycles of the phase.

    Its numbers are {"skipped": reason} when there is nothing to draw (no phases.csv, or the
    phase is missing): the other figures do not depend on it.
    """
    ph = read_phases(run_dir)
    if ph is None:
        return _skipped(f"{os.path.join(run_dir, 'phases.csv')} does not exist (this build of "
                        "crushdem does not write it)")
    need = ("dynamic_phase", "cycle", "confining_fluctuation", "volumetric_strain_phase")
    missing = [c for c in need if c not in ph]
    if missing:
        return _skipped(f"{run_dir}/phases.csv lacks the columns {', '.join(missing)}")
    rows = np.arange(len(ph["cycle"]))
    if has_values(ph, "stage"):
        rows = np.flatnonzero(ph["stage"] == np.nanmin(ph["stage"]))
    rows = rows[ph["dynamic_phase"][rows] == phase]
    if not rows.size:
        n = int(np.nanmax(ph["dynamic_phase"])) + 1 if has_values(ph, "dynamic_phase") else 0
        return _skipped(f"{run_dir}/phases.csv has no dynamic phase {phase + 1} "
                        f"(dynamic_phase == {phase}); the run had {n} phase(s)")
    rows = rows[np.argsort(ph["cycle"][rows], kind="stable")]
    cyc = ph["cycle"][rows]
    fluct = ph["confining_fluctuation"][rows]
    vol = ph["volumetric_strain_phase"][rows]
    t_age = float(column(ph, "ageing_time_s", rows)[0])
    notes = [
        f"Dynamic phase {phase + 1} (dynamic_phase == {phase}) of the triaxial relaxation "
        "(study Figure 2), from cycle 0 (just after the ageing jump).",
        "confining_fluctuation = lateral stress / reference - 1 (reference: the lateral servo "
        "target, or the lateral stress at cycle 0 without lateral servo); "
        "volumetric_strain_phase = 1 - V / V(cycle 0), compression positive.",
        f"ageing time of the phase: {t_age!r} s; source: {os.path.join(run_dir, 'phases.csv')}",
    ]
    columns = {
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
    }
    numbers = {"phase": phase + 1, "ageing_time_s": t_age, "cycles": float(np.nanmax(cyc)),
               "max_abs_confining_fluctuation": float(np.nanmax(np.abs(fluct))),
               "volumetric_strain_end": float(vol[-1])}
    return FigureData(columns, notes, numbers)


def _skipped(reason: str) -> FigureData:
    return FigureData({}, [], {"skipped": reason})


def triaxial_relaxation(run_dir: str, q_max: float = math.nan) -> FigureData:
    """The triaxial relaxation of ``run_dir``/events.csv (study Figure 3): q against t with the
    straight line q = a + b log10 t fitted to the phases with t > 0 (b: the change of q per log
    cycle), and q / q(t = 0) at 1 h and 1 day; ``q_max`` (the shear's) for q / q_max. Raises
    ValueError without the columns."""
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
    notes = [
        "Triaxial stress relaxation (study Figure 3): one row per dynamic phase; q = axial - "
        "lateral wall stress at the end of the phase.",
        f"fit over the {fit['points']} phases with t > 0: q = {fit['intercept']!r} + "
        f"{fit['slope']!r} log10(t / 1 s) [Pa]; slope per log10 cycle = {fit['slope']!r} Pa; "
        f"R^2 = {fit['r2']!r}{fit_caveat(fit)}",
        f"q at the first phase (t = 0) = {q0!r} Pa; q_max of the shear = {q_max!r} Pa",
        f"q / q(t = 0) at 1 h = {r_1h!r} ({how_1h}); at 1 day = {r_1d!r} ({how_1d}).",
        f"source: {os.path.join(run_dir, 'events.csv')}",
    ]
    columns = {
        "dynamic_phase": _phase_numbers(ev, idx),
        "ageing_time_s": t,
        "deviator_stress_Pa": q,
        "q_fit_Pa": fit_line(fit, t),
        "q_over_q_start": ratio,
        "q_over_q_max": q / q_max if math.isfinite(q_max) and q_max else np.full(q.size,
                                                                                 math.nan),
        "lateral_stress_Pa": lateral[idx] if lateral is not None else np.full(q.size, math.nan),
        "axial_strain": column(ev, "axial_strain", idx),
        "volumetric_strain": column(ev, "volumetric_strain", idx),
        "breakages_instant": column(ev, "breakages_instant", idx),
        "breakages_crack": column(ev, "breakages_crack", idx),
        "n_particles": column(ev, "n_particles", idx),
    }
    numbers = {"q_start_Pa": q0, "q_end_Pa": float(q[-1]) if q.size else math.nan,
               "slope_Pa_per_log10_t": fit["slope"], "intercept_Pa": fit["intercept"],
               "r2": fit["r2"], "fit_points": fit["points"],
               "slope_per_log10_t_over_q_start": fit["slope"] / q0 if q0 else math.nan,
               "q_ratio_1h": r_1h, "q_ratio_1h_method": how_1h,
               "q_ratio_1day": r_1d, "q_ratio_1day_method": how_1d,
               "q_min_Pa": float(np.min(q)) if q.size else math.nan}
    return FigureData(columns, notes, numbers, fit)


FORCE_COLUMNS = ("mean_Fn_N", "std_Fn_N", "mean_Ft_N", "std_Ft_N")


def force_statistics(runs: Sequence[Tuple[str, str]]) -> FigureData:
    """The contact force statistics (study Figure 4) of each (label, run directory) whose
    events.csv has them: mean and standard deviation of |F_n| and |F_t| at the end of each
    dynamic phase, one row per phase of each run (column ``test``: its label); numbers
    {label: first and last standard deviations}. Raises ValueError when no run has them."""
    data = []
    for label, run_dir in runs:
        ev = read_events(run_dir)
        if ev is None or not has_values(ev, "ageing_time_s", "std_Fn_N"):
            continue
        idx = age_rows(ev)
        data.append((label, ev["ageing_time_s"][idx],
                     {c: column(ev, c, idx) for c in FORCE_COLUMNS},
                     column(ev, "dynamic_phase", idx)))
    if not data:
        raise ValueError("no events.csv with std_Fn_N")
    table: Dict[str, List[Any]] = {"test": [], "dynamic_phase": [], "ageing_time_s": []}
    for c in FORCE_COLUMNS:
        table[c] = []
    table["std_Fn_over_first_phase"], table["std_Ft_over_first_phase"] = [], []
    numbers: Dict[str, Any] = {}
    for label, t, v, phase in data:
        for i in range(t.size):
            table["test"].append(label)
            table["dynamic_phase"].append(int(phase[i]) if math.isfinite(phase[i]) else i)
            table["ageing_time_s"].append(float(t[i]))
            for c in FORCE_COLUMNS:
                table[c].append(float(v[c][i]))
            table["std_Fn_over_first_phase"].append(float(v["std_Fn_N"][i] / v["std_Fn_N"][0]))
            table["std_Ft_over_first_phase"].append(float(v["std_Ft_N"][i] / v["std_Ft_N"][0]))
        numbers[label] = {f"{c}_{when}": float(v[c][k]) for c in ("std_Fn_N", "std_Ft_N")
                          for when, k in (("first", 0), ("last", -1))}
    notes = [
        "Contact force statistics during the relaxations (study Figure 4): mean and standard "
        "deviation of |F_n| and |F_t| over grain-grain contacts at the end of each dynamic phase.",
        "The figure draws the phases with t > 0 (log axis); the t = 0 values are in the legend.",
    ]
    return FigureData(table, notes, numbers)


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


def shear_figures(shear_dir: str) -> Dict[str, Any]:
    """q_max, the axial strain there, the largest inertial number, the grains at the end and
    the plateau (:func:`shear_plateau`) of the finished triaxial shear in ``shear_dir``. Raises
    ValueError when its summary.json has no positive q_max."""
    summary = read_summary(shear_dir)
    shear = triaxial_stage(summary)
    q_max = float(shear.get("q_max_Pa", math.nan))
    if not (math.isfinite(q_max) and q_max > 0):
        raise ValueError(f"{shear_dir}/summary.json: no positive q_max_Pa")
    return {"q_max_Pa": q_max, "axial_strain_at_q_max": shear.get("axial_strain_at_q_max"),
            "max_inertial_number": shear.get("max_inertial_number"),
            "grains_end": summary.get("particles"), **shear_plateau(shear_dir)}


def age_counts(run_dir: str) -> Dict[str, Any]:
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
