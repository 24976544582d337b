"""sigma_v(1 h) / sigma_v(4 s) and sigma_v(1 day) / sigma_v(4 s) of oedometric relaxation runs
against their number of grains (docs/reproduction.md, "Sample size").

    python scripts/size_figure.py RUN_DIR... [--out DIR]

Each RUN_DIR is a finished run with an age stage (events.csv, summary.json), for example the
runs of ``crushdem-sand sweep examples/sweeps/size_study.toml``. Writes DIR/size_relaxation.png (the
ratios against the grains, one point per run, with the band of +-0.05 around the largest
sample's value) and DIR/size_relaxation.csv (one row per run).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys

import numpy as np

from crushdem_sand.analysis import DAY_S, HOUR_S, T_REF_S, value_at
from crushdem_sand.rundir import read_events


def ratios(run_dir: str) -> dict:
    """The run's grains, N_break, seed and relaxation ratios (sigma_v: mean of the axial walls)."""
    ev = read_events(run_dir)
    if ev is None:
        raise ValueError(f"{run_dir}: no events.csv (not an ageing run)")
    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    t = ev["ageing_time_s"]
    sv = 0.5 * (ev["wall_zmin_stress_Pa"] + ev["wall_zmax_stress_Pa"])
    ref, _ = value_at(t, sv, T_REF_S)
    age = next(s for s in summary["stages"] if s["type"] == "age")
    with open(os.path.join(run_dir, "config.toml"), "rb") as f:
        import tomllib

        cfg = tomllib.load(f)
    n_break = next(s for s in cfg["stage"] if s["type"] == "age")["n_break"]
    return {"run": os.path.basename(os.path.normpath(run_dir)),
            "grains": summary["sample"]["grains"], "n_break": n_break,
            "seed": cfg["sample"]["seed"], "phases": age["dynamic_phases"],
            "ratio_1h": value_at(t, sv, HOUR_S)[0] / ref,
            "ratio_1day": value_at(t, sv, DAY_S)[0] / ref,
            "crack_failures": summary["crushing"]["breakages_crack"]}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", metavar="RUN_DIR")
    parser.add_argument("--out", default=".", metavar="DIR")
    args = parser.parse_args(argv)
    rows = sorted((ratios(d) for d in args.runs), key=lambda r: (r["grains"], r["seed"]))
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "size_relaxation.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 4.0))
    ax = fig.subplots()
    n = np.array([r["grains"] for r in rows], dtype=float)
    for key, label, marker in (("ratio_1day", "1 day", "o"), ("ratio_1h", "1 h", "s")):
        ax.plot(n, [r[key] for r in rows], marker, label=f"sigma_v({label}) / sigma_v(4 s)")
    largest = rows[int(np.argmax(n))]["ratio_1day"]
    ax.axhspan(largest - 0.05, largest + 0.05, color="0.85", zorder=0,
               label="largest sample's 1-day value +- 0.05")
    ax.set_xscale("log")
    ax.set_xlabel("grains")
    ax.set_ylabel("relaxation ratio")
    ax.set_title("Oedometric relaxation from 7.5 MPa against sample size")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "size_relaxation.png"), dpi=120)
    for r in rows:
        print(f"{r['run']}: {r['grains']} grains, N_break {r['n_break']}, seed {r['seed']}: "
              f"{r['ratio_1h']:.3f} at 1 h, {r['ratio_1day']:.3f} at 1 day")
    return 0


if __name__ == "__main__":
    sys.exit(main())
