"""Pure analysis of a run's columns (NumPy only, no files, no figures; tested on synthetic
data): the time series split by stage, the rows whose contact measurements were not computed,
and relaxation and creep curves, one value per dynamic phase against ageing time. Used by
:mod:`crushdem_sand.rundir`, the figures (:mod:`crushdem_sand.figures`), ``crushdem-sand reproduce``
and the sweep tool.

A set of columns is a dict {column name: float64 array}, as :func:`crushdem_sand.rundir.read_csv`
returns it."""

from __future__ import annotations

import math
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

T_REF_S = 4.0  # the study normalises sigma_v by its value at 4 s of ageing
# sigma_v(1 day) / sigma_v(4 s) of an oedometric relaxation that a quartz sand can plausibly
# show (docs/model.md 5.1): the band a reproduction is checked against.
PLAUSIBLE_OEDOMETRIC_1DAY = (0.70, 0.97)
HOUR_S = 3600.0
DAY_S = 86400.0
WALLS = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")

Columns = Mapping[str, np.ndarray]


def has_values(d: Columns, *cols: str) -> bool:
    """Whether every column of ``cols`` exists in ``d`` with at least one finite value."""
    return all(c in d and np.isfinite(d[c]).any() for c in cols)


def as_float(x: Any) -> float:
    """A summary.json value as a float (NaN when missing or not a number)."""
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def column(d: Columns, name: str, idx: np.ndarray) -> np.ndarray:
    """Column ``name`` on rows ``idx`` (NaN when the column is missing)."""
    return d[name][idx] if name in d else np.full(np.asarray(idx).size, math.nan)


def _mean_of_walls(d: Columns, walls: Sequence[str]) -> Optional[np.ndarray]:
    cols = [d[f"wall_{w}_stress_Pa"] for w in walls if has_values(d, f"wall_{w}_stress_Pa")]
    if not cols:
        return None
    with np.errstate(all="ignore"):
        return np.nanmean(np.vstack(cols), axis=0)


def vertical_stress(d: Columns) -> Optional[np.ndarray]:
    """sigma_v: mean of the zmin and zmax wall stresses [Pa] (whichever exist); None without."""
    return _mean_of_walls(d, ("zmin", "zmax"))


def lateral_stress(d: Columns) -> Optional[np.ndarray]:
    """sigma_h: mean of the four lateral wall stresses [Pa] (whichever exist); None without."""
    return _mean_of_walls(d, ("xmin", "xmax", "ymin", "ymax"))


# Columns computed from the grain-grain contact list (experiments/measurements.cpp).
CONTACT_COLUMNS = ("n_contacts", "coordination_number", "mean_Fn_N", "std_Fn_N", "mean_Ft_N",
                   "std_Ft_N", "unbalanced_force_ratio", "love_xx_Pa", "love_yy_Pa",
                   "love_zz_Pa", "love_xy_Pa", "love_yz_Pa", "love_xz_Pa",
                   "love_mean_stress_Pa")


def unmeasured_contact_rows(d: Columns) -> np.ndarray:
    """Rows whose contact columns were written before the contact list was computed.

    The first row of a test that starts from a prepared sample has its wall stresses (the walls
    keep theirs) but every contact measurement 0: no contact, Z = 0, F_n = 0, Love-Weber stress
    0. Such a row is the first of its stage, has ``n_contacts`` 0 and a nonzero wall stress: a
    loaded sample in equilibrium has contacts. Elsewhere, n_contacts = 0 is a real measurement
    (grains not yet touching during preparation)."""
    n = len(next(iter(d.values()))) if d else 0
    if "n_contacts" not in d or n == 0:
        return np.zeros(n, dtype=bool)
    first_of_stage = np.zeros(n, dtype=bool)
    first_of_stage[0] = True
    if "stage" in d:
        st = d["stage"]
        first_of_stage[1:] = st[1:] != st[:-1]
    walls = [d[f"wall_{w}_stress_Pa"] for w in WALLS if f"wall_{w}_stress_Pa" in d]
    if not walls:
        return np.zeros(n, dtype=bool)
    loaded = np.any(np.abs(np.vstack(walls)) > 0, axis=0)
    return first_of_stage & (d["n_contacts"] == 0) & loaded


def mask_unmeasured_contacts(d: Columns) -> Dict[str, np.ndarray]:
    """A copy of ``d`` with the CONTACT_COLUMNS NaN on the unmeasured_contact_rows."""
    out = dict(d)
    rows = unmeasured_contact_rows(d)
    if rows.any():
        for c in CONTACT_COLUMNS:
            if c in out:
                out[c] = np.where(rows, math.nan, out[c])
    return out


StageRows = Tuple[int, np.ndarray, Dict[str, Any]]


def stage_rows(d: Columns, summary: Mapping[str, Any]) -> List[StageRows]:
    """[(stage index, row mask, stage description from summary["stages"] or {})] in stage
    order; empty when the CSV has no ``stage`` column. A run writes the row at a stage boundary
    twice (last row of one stage, first row of the next), so consecutive stages share a point.
    """
    if not has_values(d, "stage"):
        return []
    listed = summary.get("stages")
    listed = listed if isinstance(listed, list) else []
    s = d["stage"]
    out = []
    for k in sorted({int(v) for v in s[np.isfinite(s)]}):
        info = listed[k] if 0 <= k < len(listed) and isinstance(listed[k], dict) else {}
        out.append((k, s == k, info))
    return out


def stage_label(k: int, info: Mapping[str, Any]) -> str:
    """"stage K: NAME" (the stage's name, else its type)."""
    name = info.get("name") or info.get("type") or ""
    return f"stage {k}: {name}" if name else f"stage {k}"


def age_stage_indices(summary: Mapping[str, Any], events: Optional[Columns]) -> List[int]:
    """The indices of the "age" stages: those typed so in summary["stages"], and those with
    rows in events.csv (which only age stages write)."""
    listed = summary.get("stages")
    found = {k for k, st in enumerate(listed if isinstance(listed, list) else [])
             if isinstance(st, dict) and st.get("type") == "age"}
    if events is not None and has_values(events, "stage"):
        found |= {int(v) for v in events["stage"][np.isfinite(events["stage"])]}
    return sorted(found)


def age_rows(ev: Columns) -> np.ndarray:
    """Row indices of the first age stage in events.csv / phases.csv, in ageing-time order."""
    n = len(next(iter(ev.values()))) if ev else 0
    idx = np.arange(n)
    if has_values(ev, "stage"):
        st = ev["stage"]
        idx = np.flatnonzero(st == np.nanmin(st))
    if has_values(ev, "ageing_time_s"):
        idx = idx[np.isfinite(ev["ageing_time_s"][idx])]
        idx = idx[np.argsort(ev["ageing_time_s"][idx], kind="stable")]
    return idx


def ageing_groups(ev: Columns, summary: Mapping[str, Any]) -> List[Tuple[str, np.ndarray, int]]:
    """[(label, row indices in ageing-time order, reference row)] for each age stage of the
    events (events.csv columns). The reference row is the stage's first dynamic phase (ageing
    time 0, or the earliest one)."""
    t_age = ev["ageing_time_s"]
    n = len(t_age)
    listed = summary.get("stages")
    listed = listed if isinstance(listed, list) else []
    if has_values(ev, "stage"):
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
        if has_values(ev, "dynamic_phase"):
            phase = ev["dynamic_phase"][order]
            ref = int(order[int(np.nanargmin(phase))]) if np.isfinite(phase).any() \
                else int(order[0])
        else:
            ref = int(order[0])
        if k < 0:
            label = "age"
        else:
            info = listed[k] if 0 <= k < len(listed) and isinstance(listed[k], dict) else {}
            label = stage_label(k, info)
        out.append((label, order, ref))
    return out


def walls_fixed(ev: Columns, idx: np.ndarray) -> bool:
    """Whether every wall stood still over the phases ``idx`` (a relaxation with all walls
    fixed, as in the oedometric relaxation) rather than servo-controlled (creep, triaxial)."""
    cols = [f"wall_{w}_position_m" for w in WALLS]
    if len(idx) < 2 or not has_values(ev, *cols):
        return False
    return all(np.ptp(ev[c][idx]) == 0.0 for c in cols)


def value_at(t: np.ndarray, y: np.ndarray, t_target: float) -> Tuple[float, str]:
    """y at ageing time ``t_target`` from one value per dynamic phase, and how it was found.

    Between two phases with t > 0 the value is interpolated linearly in log t (the curves are
    near straight there). Before the first phase with t > 0 log t has no left end, so the value
    is interpolated linearly in t from the t = 0 phase. Beyond the last phase it is NaN (the
    curve is not extrapolated).
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    keep = np.isfinite(t) & np.isfinite(y)
    t, y = t[keep], y[keep]
    if t.size == 0 or not (math.isfinite(t_target) and t_target > 0):
        return math.nan, "no data"
    order = np.argsort(t, kind="stable")
    t, y = t[order], y[order]
    exact = np.flatnonzero(t == t_target)
    if exact.size:
        return float(y[exact[0]]), "exact"
    if t_target > t[-1]:
        return math.nan, f"beyond the last phase (t = {t[-1]:.6g} s)"
    pos = np.flatnonzero(t > 0)
    if pos.size and t_target > t[pos[0]]:
        j = int(np.searchsorted(t, t_target))  # t[j-1] < t_target < t[j], both > 0
        lt0, lt1 = math.log(t[j - 1]), math.log(t[j])
        w = (math.log(t_target) - lt0) / (lt1 - lt0)
        return float(y[j - 1] + w * (y[j] - y[j - 1])), (
            f"linear in log t between phases at t = {t[j - 1]:.6g} s and {t[j]:.6g} s")
    zero = np.flatnonzero(t <= 0)
    if not zero.size or not pos.size:
        return math.nan, "no phase at t = 0 before the first phase with t > 0"
    i0, i1 = int(zero[-1]), int(pos[0])
    w = (t_target - t[i0]) / (t[i1] - t[i0])
    return float(y[i0] + w * (y[i1] - y[i0])), (
        f"linear in t between the t = 0 phase and the first later phase at t = {t[i1]:.6g} s "
        f"(> {t_target:g} s)")


def fit_log_t(t: np.ndarray, y: np.ndarray) -> Dict[str, float]:
    """Least-squares line y = intercept + slope log10(t) over the points with t > 0.

    ``slope`` is the change of y per log cycle (per factor 10 of ageing time); ``r2`` the
    coefficient of determination (NaN with fewer than 3 points: two always fit exactly).
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    keep = np.isfinite(t) & np.isfinite(y) & (t > 0)
    x, y = np.log10(t[keep]), y[keep]
    out = {"slope": math.nan, "intercept": math.nan, "r2": math.nan, "points": int(x.size)}
    if x.size < 2 or np.ptp(x) == 0:
        return out
    slope, intercept = np.polyfit(x, y, 1)
    out["slope"], out["intercept"] = float(slope), float(intercept)
    if x.size >= 3:
        ss_res = float(np.sum((y - (intercept + slope * x)) ** 2))
        ss_tot = float(np.sum((y - y.mean()) ** 2))
        out["r2"] = 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan
    return out


# N_break = 10 and 30: the two relaxation curves, each normalised by its value at the
# end of phase 0 (the same state for both: the runs are identical up to the first jump), may
# differ by at most this much anywhere between the later of the two first jumps and the end.
# Stated before the comparison was run: 0.03, about a tenth of the 1-day relaxation of the
# study-scale oedometer (sigma_v / sigma_v(0) = 0.66 at one day with N_break = 30).
N_BREAK_TOLERANCE = 0.03

# How far a run on another backend (the GPU, or its emulation) may land from the CPU's on the
# quick settings of `crushdem-sand reproduce` (500 grains; docs/performance.md, "Backends"). The two
# follow each other to rounding at first and then as two samples would, so the bounds are those
# of the sample-to-sample scatter measured on the CPU (sample seeds 3, 4, 5: q_max 22.75, 20.06,
# 20.46 MPa, sd 7 %; sigma_v(1 day) / sigma_v(4 s) 0.943, 0.884, 0.968, sd 0.04), about 2.5
# standard deviations of the difference of two such runs; sigma_v(4 s) is held by the loading's
# target. Measured between backends (same seeds): q_max -3.9 % and +4.5 %, the ratio -0.078 and
# +0.054.
BACKEND_TOLERANCE = {"q_max_relative": 0.15, "sigma_v_ratio_1day": 0.15,
                     "sigma_v_4s_relative": 0.02}


def compare_relaxation(t_a: np.ndarray, y_a: np.ndarray, t_b: np.ndarray, y_b: np.ndarray,
                       points: int = 60) -> Dict[str, Any]:
    """How far two relaxation curves (one value per dynamic phase, t = 0 first) are apart.

    Each curve is divided by its t = 0 value and read with ``value_at`` (linear in log t between
    phases) at ``points`` log-spaced times from the later of the two first phases with t > 0 to
    the earlier of the two last phases. Returns the largest absolute difference, where it is, and
    both curves' values at the common end.
    """
    def norm(t: np.ndarray, y: np.ndarray) -> Tuple[np.ndarray, np.ndarray, float]:
        t = np.asarray(t, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        zero = np.flatnonzero(t <= 0)
        if not zero.size or not (y[zero[0]] != 0 and math.isfinite(y[zero[0]])):
            raise ValueError("a relaxation curve needs its t = 0 phase")
        return t, y / y[zero[0]], float(t[t > 0].min()) if np.any(t > 0) else math.nan

    t_a, n_a, first_a = norm(t_a, y_a)
    t_b, n_b, first_b = norm(t_b, y_b)
    lo, hi = max(first_a, first_b), min(float(t_a.max()), float(t_b.max()))
    out: Dict[str, Any] = {"t_from_s": lo, "t_to_s": hi, "max_abs_difference": math.nan,
                           "at_t_s": math.nan, "end_a": math.nan, "end_b": math.nan}
    if not (math.isfinite(lo) and math.isfinite(hi) and hi >= lo):
        return out
    times = np.geomspace(lo, hi, points) if hi > lo else np.array([lo])
    diff = np.array([value_at(t_a, n_a, t)[0] - value_at(t_b, n_b, t)[0] for t in times])
    k = int(np.nanargmax(np.abs(diff)))
    out.update(max_abs_difference=float(abs(diff[k])), at_t_s=float(times[k]),
               end_a=value_at(t_a, n_a, hi)[0], end_b=value_at(t_b, n_b, hi)[0])
    return out
