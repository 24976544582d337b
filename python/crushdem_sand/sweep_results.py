"""The table of a sweep (``crushdem-sand sweep``): the summary figures of each run or pile
experiment, one row per variant in results.csv and results.parquet, and results.png."""

from __future__ import annotations

import csv
import json
import math
import os
from typing import TYPE_CHECKING, Any, Dict, Mapping, Optional, Sequence

import numpy as np

from ._optional import require
from .analysis import DAY_S, HOUR_S, T_REF_S, as_float, value_at
from .rundir import read_events, read_penetration, read_shaft_profile, read_summary, read_timing

if TYPE_CHECKING:
    import pandas as pd

# What one variant runs: ``crushdem-sand run`` or ``crushdem-sand pile`` (a pile experiment:
# DIR/main, the load tests branched at every ageing time and the set-up fit).
EXPERIMENTS = ("run", "pile")


def finished(run_dir: str, experiment: str = "run") -> bool:
    """Whether the variant in ``run_dir`` is done: its summary.json (a run), or its
    pile_setup.json, written after its last load test and its figures (a pile experiment)."""
    return os.path.isfile(os.path.join(run_dir, "pile_setup.json" if experiment == "pile"
                                       else "summary.json"))


def ageing_label(t: float) -> str:
    """An ageing time [s] in a column name: its whole seconds ("3600"), or its digits when it
    has a fraction ("0.2"), so that two times never share a column."""
    return f"{t:.0f}" if math.isfinite(t) and t == round(t) else f"{t:.15g}"


def pile_figures(out: str) -> Dict[str, float]:
    """A pile experiment's results (``crushdem-sand pile``'s DIR): per load test the set-up
    factor A with its standard error, the fit's Q0 and its reference time t0 (``setup.TEST.A``,
    ``setup.TEST.A_std``, ``setup.TEST.Q0_N``, ``setup.TEST.t0_s``; the shaft's own as
    ``setup.TEST (shaft).A``), and each capacity by its
    ageing time (``TEST.capacity_N@3600s``, with the shaft's load at it)."""
    out_figs: Dict[str, float] = {}
    try:
        with open(os.path.join(out, "pile_setup.json")) as f:
            fits = json.load(f).get("fits") or {}
    except (OSError, ValueError):
        fits = {}
    for test, fit in fits.items():
        for key in ("A", "A_std", "Q0_N", "t0_s"):
            out_figs[f"setup.{test}.{key}"] = as_float(fit.get(key))
    try:
        with open(os.path.join(out, "pile_capacity.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError:
        rows = []
    for r in rows:
        at = f"@{ageing_label(as_float(r.get('ageing_time_s')))}s"
        out_figs[f"{r.get('test')}.capacity_N{at}"] = as_float(r.get("capacity_N"))
        out_figs[f"{r.get('test')}.shaft_at_capacity_N{at}"] = as_float(
            r.get("shaft_at_capacity_N"))
    return out_figs

def _shaft_sigma_r_end(profile: Optional[Dict[str, Any]], stage: int) -> Optional[float]:
    """The mean radial stress [Pa] over the shaft's bins that touch grains, at stage ``stage``'s
    last record of shaft_profile.csv; None without such a record or bin."""
    if profile is None or not {"stage", "time_s", "sigma_r_Pa", "contacts"} <= set(profile):
        return None
    rows = profile["stage"] == stage
    if not rows.any():
        return None
    last = rows & (profile["time_s"] == profile["time_s"][rows].max())
    touching = last & (profile["contacts"] > 0)
    return float(np.mean(profile["sigma_r_Pa"][touching])) if touching.any() else None


def summary_figures(run_dir: str) -> Dict[str, float]:
    """The summary figures of a finished run: per stage (named by the stage's name, with its index
    where stages share a name: ``age[2].K0_end``) q_max, the
    peak friction angle, K0, and for age stages sigma_v and q at 1 h and 1 day over their value
    at 4 s of ageing and the axial strain at 1 day; for a penetrate stage the cone resistance at
    its end (q_c averaged over the records of the last 10 % of its travel), the largest, the mean
    over the last half of the travel, the tip's and the shaft's loads at the end (last 10 %) and
    the shaft's radial stress at the end (sigma_r_shaft_end_kPa: the mean over the shaft's bins
    that touch grains, at the stage's last record of shaft_profile.csv); for
    a load test the capacity with the shaft and base loads at it (a pile sweep's result);
    breakages, B_r, the final void ratio, coordination number, stresses and volumetric strain,
    grains and steps."""
    s = read_summary(run_dir)
    out: Dict[str, float] = {}
    if not s:
        return out
    ev = read_events(run_dir)
    pen = profile = None
    stages = s.get("stages") or []
    given = [st.get("name") or f"stage{k}" for k, st in enumerate(stages)]
    for k, st in enumerate(stages):
        # A name that two stages share gets the stage's index: "age[2]" (no column overwritten).
        name = given[k] if given.count(given[k]) == 1 else f"{given[k]}[{k}]"
        kind = st.get("type")
        if kind == "load_test":
            for key in ("capacity_N", "shaft_at_capacity_N", "base_at_capacity_N"):
                out[f"{name}.{key}"] = as_float(st.get(key))
        if kind == "penetrate":
            pen = read_penetration(run_dir) if pen is None else pen
            rows = (pen["stage"] == k) if pen is not None and "stage" in pen else None
            if rows is not None and rows.any():
                travel, q_c = pen["travel_m"][rows], pen["q_c_Pa"][rows]
                end = travel >= 0.9 * travel.max()
                out[f"{name}.q_c_end_MPa"] = float(np.mean(q_c[end])) / 1e6
                out[f"{name}.q_c_max_MPa"] = float(np.max(q_c)) / 1e6
                half = travel >= 0.5 * travel.max()
                out[f"{name}.q_c_mean_MPa"] = float(np.mean(q_c[half])) / 1e6
                for load in ("tip_load_N", "shaft_load_N"):
                    if load in pen:
                        out[f"{name}.{load[:-2]}_end_N"] = float(np.mean(pen[load][rows][end]))
                profile = read_shaft_profile(run_dir) if profile is None else profile
                sigma_r = _shaft_sigma_r_end(profile, k)
                if sigma_r is not None:
                    out[f"{name}.sigma_r_shaft_end_kPa"] = sigma_r / 1e3
        if kind == "triaxial":
            out[f"{name}.q_max_MPa"] = as_float(st.get("q_max_Pa")) / 1e6
            out[f"{name}.friction_angle_peak_deg"] = as_float(st.get("friction_angle_peak_deg"))
        if kind in ("oedometric", "isotropic", "triaxial", "age"):
            out[f"{name}.K0_end"] = as_float(st.get("K0_end"))
        if kind == "age" and ev is not None and "ageing_time_s" in ev:
            rows = np.arange(len(ev["ageing_time_s"]))
            if "stage" in ev:
                rows = rows[ev["stage"][rows] == k]
            t = ev["ageing_time_s"][rows]
            series = {}
            walls = [ev[c][rows] for c in ("wall_zmin_stress_Pa", "wall_zmax_stress_Pa") if c in ev]
            if walls:
                series["sigma_v"] = np.mean(np.vstack(walls), axis=0)
            if "deviator_stress_Pa" in ev:
                series["q"] = ev["deviator_stress_Pa"][rows]
            for label, y in series.items():
                y_ref, _ = value_at(t, y, T_REF_S)
                for tag, t_at in (("1h", HOUR_S), ("1day", DAY_S)):
                    y_at, _ = value_at(t, y, t_at)
                    out[f"{name}.{label}_ratio_{tag}"] = y_at / y_ref if y_ref else math.nan
            if "axial_strain" in ev:
                out[f"{name}.axial_strain_1day"] = value_at(t, ev["axial_strain"][rows], DAY_S)[0]
    crushing = s.get("crushing") or {}
    if crushing:
        out["breakages"] = as_float(crushing.get("breakages_instant", 0)) + as_float(
            crushing.get("breakages_crack", 0))
        out["relative_breakage_Br"] = as_float(crushing.get("relative_breakage_Br"))
    final = s.get("final") or {}
    for k in ("void_ratio", "coordination_number", "mean_stress_Pa", "deviator_stress_Pa",
              "volumetric_strain"):
        if k in final:
            out[f"final.{k}"] = as_float(final[k])
    out["grains_end"] = as_float(s.get("particles"))
    out["steps"] = as_float(s.get("steps"))
    return out


def results_table(out: str, listed: Sequence[Dict[str, Any]], keys: Sequence[str],
                  errors: Mapping[str, str], experiment: str = "run") -> pd.DataFrame:
    """The pandas DataFrame of the sweep (one row per variant), written to results.csv and
    results.parquet. A pile experiment's row has DIR/main's summary figures, its pile_figures()
    and the wall-clock of all its runs."""
    import pandas as pd

    rows = []
    for v in listed:
        run_dir = os.path.join(out, "runs", v["name"])
        row: Dict[str, Any] = {"variant": v["name"]}
        row.update({k: v["values"].get(k) for k in keys})
        done = finished(run_dir, experiment)
        row["status"] = "done" if done else ("failed" if v["name"] in errors else "not run")
        # A finished variant's error too: its command failed after its results (a figure).
        row["error"] = errors.get(v["name"], "")
        row["run_dir"] = run_dir
        if experiment == "pile":
            runs = [os.path.join(run_dir, d) for d in (sorted(os.listdir(run_dir))
                                                       if os.path.isdir(run_dir) else [])]
            walls = [as_float(read_timing(d).get("wall_seconds")) for d in runs
                     if os.path.isfile(os.path.join(d, "timing.json"))]
            row["wall_s"] = float(np.sum(walls)) if walls else math.nan
            figures = summary_figures(os.path.join(run_dir, "main"))
            figures.update(pile_figures(run_dir))
        else:
            row["wall_s"] = as_float(read_timing(run_dir).get("wall_seconds"))
            figures = summary_figures(run_dir)
        row.update(figures)
        rows.append(row)
    df = pd.DataFrame(rows)
    df.to_csv(os.path.join(out, "results.csv"), index=False)
    try:
        df.astype({k: str for k in keys if df[k].dtype == object}).to_parquet(
            os.path.join(out, "results.parquet"), index=False)
    except ImportError:  # no pyarrow: sweep() says so
        pass
    return df


def figure(df: pd.DataFrame, keys: Sequence[str], path: str) -> Optional[str]:
    """Each summary figure against each varied key (numeric keys only), one panel each."""
    from pandas.api.types import is_numeric_dtype  # pandas' own string columns too

    skip = {"variant", "status", "error", "run_dir", "wall_s", *keys}
    done = df[df["status"] == "done"] if "status" in df else df
    # A set-up fit's t0 is the first ageing time, a setting rather than a result: not drawn.
    figures = [c for c in df.columns if c not in skip and is_numeric_dtype(df[c].dtype)
               and not c.endswith(".t0_s")
               and np.isfinite(done[c].to_numpy(dtype=float)).any()] if len(done) else []
    numeric = [k for k in keys if is_numeric_dtype(df[k].dtype)]
    if not figures or not numeric:
        return None
    # No pyplot: no backend is chosen for the caller.
    Figure = require("matplotlib.figure", "crushdem_sand.sweep.figure").Figure
    fig = Figure(figsize=(3.6 * len(numeric), 2.6 * len(figures)))
    axes = fig.subplots(len(figures), len(numeric), squeeze=False)
    for i, f in enumerate(figures):
        for j, k in enumerate(numeric):
            ax = axes[i, j]
            ax.plot(done[k], done[f], "o")
            ax.set_xlabel(k)
            ax.set_ylabel(f, fontsize=8)
            ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


