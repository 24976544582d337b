"""The installation's rate (docs/pile.md, "The installation's rate"): what a pile's installation
gives against the inertial number of the grains it pushes aside, from a sweep over its velocity
and the sample's seed.

    python scripts/rate_figure.py SWEEP_DIR [--stage install] [--out DIR]

SWEEP_DIR is the output of ``crushdem-sand sweep`` over ``stage.STAGE.velocity`` (and any other
key, say ``sample.seed``, whose runs are then repeats), for example
``crushdem-sand sweep examples/sweeps/pile_rate.toml --out runs/pile_rate``. For each velocity
the inertial number is I = (v / D) d50 / sqrt(p / rho): D the pushed body's diameter (its
``radius`` x 2), d50 the mass median of the sample's grading (times the upscaling factor), p the
stage's ``lateral_stress`` and rho ``material.density`` (MiDi 2004, with v / D the shear rate
about the tip). Writes DIR/pile_rate.csv (per velocity: I, the runs, and the mean and standard
error over them of each figure and of the breakages, and q_c's ratio to the same sample's at
the slowest velocity) and DIR/pile_rate.png (the mean and the
largest q_c, the shaft's load and its radial stress against I).
"""

from __future__ import annotations

import argparse
import os
import sys
import tomllib
from typing import Dict, List, Tuple

import numpy as np

FIGURES = (("q_c_mean_MPa", "q_c, last half of the travel [MPa]"),
           ("q_c_max_MPa", "largest q_c [MPa]"),
           ("shaft_load_end_N", "shaft load at the end [N]"),
           ("sigma_r_shaft_end_kPa", "shaft's sigma_r at the end [kPa]"))


def inertial_number(config_path: str, stage: str, velocity: float) -> float:
    """I = (v / D) d50 / sqrt(p / rho) of the run whose configuration is ``config_path``."""
    with open(config_path, "rb") as f:
        cfg = tomllib.load(f)
    st = next((s for s in cfg.get("stage", []) if s.get("name") == stage), None)
    if st is None:
        raise ValueError(f"{config_path}: no stage named '{stage}' (--stage)")
    body = next((b for b in cfg.get("body", []) if b.get("name") == st.get("body")), None)
    if body is None:
        raise ValueError(f"{config_path}: stage '{stage}' pushes no [[body]] of this file")
    grading = cfg["sample"]["grading"]
    d50 = float(np.interp(0.5, grading["passing"], grading["diameter"]))
    d50 *= float(cfg.get("upscaling", {}).get("factor", 1.0))
    p = float(st.get("lateral_stress") or cfg["sample"]["stress"])
    rho = float(cfg.get("material", {}).get("density", 2650.0))
    return velocity / (2.0 * float(body["radius"])) * d50 / np.sqrt(p / rho)


def _columns(stage: str) -> List[Tuple[str, str]]:
    """(name in pile_rate.csv, column of results.csv) of each figure, and the breakages."""
    return [(key, f"{stage}.{key}") for key, _ in FIGURES] + [("breakages", "breakages")]


def by_velocity(rows: List[Dict[str, float]], stage: str) -> List[Dict[str, float]]:
    """One row per velocity (increasing): its inertial number, the number of runs, the mean and
    standard error of each figure (nan where fewer than two runs have it) and, where the runs
    carry a ``sample.seed``, the mean and standard deviation over the samples of q_c's ratio to
    the same sample's at the slowest velocity (the samples' own scatter paired out)."""
    out = []
    slowest = min(r["velocity"] for r in rows)
    q_col = f"{stage}.q_c_mean_MPa"
    reference = {r.get("sample.seed"): r.get(q_col) for r in rows if r["velocity"] == slowest}
    for v in sorted({r["velocity"] for r in rows}):
        runs = [r for r in rows if r["velocity"] == v]
        row = {"velocity_m_s": v, "inertial_number": runs[0]["I"], "runs": len(runs)}
        ratios = np.array([r[q_col] / reference[r["sample.seed"]] for r in runs
                           if "sample.seed" in r and q_col in r
                           and reference.get(r["sample.seed"])])
        row["q_c_mean_ratio_mean"] = float(ratios.mean()) if len(ratios) else float("nan")
        row["q_c_mean_ratio_sd"] = (float(ratios.std(ddof=1)) if len(ratios) > 1
                                    else float("nan"))
        for key, col in _columns(stage):
            vals = np.array([r[col] for r in runs if col in r and np.isfinite(r[col])])
            row[f"{key}_mean"] = float(vals.mean()) if len(vals) else float("nan")
            row[f"{key}_se"] = (float(vals.std(ddof=1) / np.sqrt(len(vals))) if len(vals) > 1
                                else float("nan"))
        out.append(row)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sweep_dir")
    ap.add_argument("--stage", default="install", help="the penetrate stage's name")
    ap.add_argument("--out", default=None, help="output directory (default: SWEEP_DIR)")
    a = ap.parse_args(argv)
    import pandas as pd

    df = pd.read_csv(os.path.join(a.sweep_dir, "results.csv"))
    vcol = f"stage.{a.stage}.velocity"
    if vcol not in df:
        print(f"{a.sweep_dir}/results.csv: no column {vcol} (a sweep over the velocity)",
              file=sys.stderr)
        return 2
    done = df[df["status"] == "done"]
    rows = []
    for _, r in done.iterrows():
        config = os.path.join(a.sweep_dir, "configs", f"{r['variant']}.toml")
        rec = {k: float(v) for k, v in r.items() if isinstance(v, (int, float))}
        rec["velocity"] = float(r[vcol])
        try:
            rec["I"] = inertial_number(config, a.stage, rec["velocity"])
        except (OSError, ValueError, KeyError) as e:
            print(f"{a.sweep_dir}: {e}", file=sys.stderr)
            return 2
        rows.append(rec)
    if not rows:
        print(f"{a.sweep_dir}: no finished run", file=sys.stderr)
        return 2
    table = by_velocity(rows, a.stage)
    out = a.out or a.sweep_dir
    os.makedirs(out, exist_ok=True)
    pd.DataFrame(table).to_csv(os.path.join(out, "pile_rate.csv"), index=False)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(2, 2, figsize=(9, 6.5))
    for ax, (key, label) in zip(axes.flat, FIGURES):
        col = f"{a.stage}.{key}"
        pts = [(r["I"], r[col]) for r in rows if col in r and np.isfinite(r[col])]
        if pts:
            ax.plot(*zip(*pts), "o", color="0.7", ms=4, label="runs")
        ax.errorbar([t["inertial_number"] for t in table], [t[f"{key}_mean"] for t in table],
                    yerr=[t[f"{key}_se"] for t in table], fmt="s-", color="C0", capsize=3,
                    label="mean +- standard error")
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("inertial number I = (v / D) d50 / sqrt(p / rho)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "pile_rate.png"), dpi=110)
    for t in table:
        print(f"v = {t['velocity_m_s']:g} m/s  I = {t['inertial_number']:.2e}  runs {t['runs']}  "
              f"q_c ratio {t['q_c_mean_ratio_mean']:.3f} +- {t['q_c_mean_ratio_sd']:.3f}  " +
              "  ".join(f"{k} {t[f'{k}_mean']:.4g} +- {t[f'{k}_se']:.2g}"
                        for k, _ in _columns(a.stage)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
