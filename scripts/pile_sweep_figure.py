"""A sweep of pile experiments (``experiment = "pile"``, docs/pile.md): each variant's capacity
against its ageing time, with the set-up fit Q(t) = Q0 (1 + A log10(t / t0)) (Skov and Denver
1988) that ``crushdem-sand pile`` made, for the whole pile and for its shaft.

    python scripts/pile_sweep_figure.py SWEEP_DIR [--test compression] [--out DIR]

SWEEP_DIR is the output of ``crushdem-sand sweep`` of a file with ``experiment = "pile"``, for
example ``crushdem-sand sweep examples/sweeps/pile_n_break.toml --out runs/pile_n_break``.
Writes DIR/pile_sweep.csv (a row per variant and ageing time: the varied values, the capacity and
the shaft's load at it, the variant's A, its standard error and Q0 for both) and DIR/pile_sweep.png,
and prints the table.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from typing import Any, Dict, List, Optional

import numpy as np


def _sweep_json(sweep_dir: str) -> Dict[str, Any]:
    with open(os.path.join(sweep_dir, "sweep.json")) as f:
        return json.load(f)


def varied_keys(sweep_dir: str) -> List[str]:
    """The sweep's varied keys (its sweep.json)."""
    return _sweep_json(sweep_dir)["keys"]


def short_names(sweep_dir: str) -> Dict[str, str]:
    """The sweep file's [names] (its sweep.json; none in a sweep written before them)."""
    return _sweep_json(sweep_dir).get("names") or {}


def _show(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def rows(sweep_dir: str, test: str) -> List[Dict[str, Any]]:
    """A row per finished variant and ageing time of results.csv: the variant, its varied values,
    t, the capacity and the shaft's load, and the variant's fits (A, A_std, Q0_N, t0_s; shaft_A
    and so on); ValueError without a finished variant."""
    import pandas as pd

    df = pd.read_csv(os.path.join(sweep_dir, "results.csv"))
    keys = varied_keys(sweep_dir)
    at = re.compile(re.escape(f"{test}.capacity_N@") + r"(\d+)s$")
    times = sorted(int(m.group(1)) for c in df.columns if (m := at.match(c)))
    if not times:
        raise ValueError(f"{sweep_dir}/results.csv has no capacities of load test '{test}' "
                         "(a sweep with experiment = \"pile\"; --test names the load test)")
    done = df[df["status"] == "done"]
    if done.empty:
        raise ValueError(f"{sweep_dir}/results.csv has no finished variant (run the sweep again "
                         "to complete it)")
    out = []
    for _, r in done.iterrows():
        for t in times:
            row = {"variant": r["variant"], **{k: r[k] for k in keys}, "ageing_time_s": float(t),
                   "capacity_N": r[f"{test}.capacity_N@{t}s"],
                   "shaft_at_capacity_N": r[f"{test}.shaft_at_capacity_N@{t}s"]}
            for tag, fit in (("", test), ("shaft_", f"{test} (shaft)")):
                for key in ("A", "A_std", "Q0_N", "t0_s"):
                    row[f"{tag}{key}"] = r.get(f"setup.{fit}.{key}", math.nan)
            out.append(row)
    return out


def figure(table: List[Dict[str, Any]], keys: List[str], path: str,
           names: Optional[Dict[str, str]] = None) -> None:
    """Capacity and shaft load against ageing time, one line of points per variant, with its
    fitted line Q0 (1 + A log10(t / t0)), t0 the fit's (its first ageing time with a capacity);
    each labelled by the values of ``keys`` that differ between variants (a key by its entry in
    ``names``, the sweep file's [names], where it has one), or by its directory name where more
    than two differ (named variants, whose keys the name stands for)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2)
    variants = list(dict.fromkeys(r["variant"] for r in table))
    differ = [k for k in keys if len({str(r[k]) for r in table}) > 1]
    for v in variants:
        sel = [r for r in table if r["variant"] == v]
        label = (", ".join(f"{(names or {}).get(k, k)} = {_show(sel[0][k])}" for k in differ)
                 if 0 < len(differ) <= 2 else v)
        t = np.array([r["ageing_time_s"] for r in sel])
        for ax, col, tag in ((axes[0], "capacity_N", ""), (axes[1], "shaft_at_capacity_N",
                                                           "shaft_")):
            q = np.array([r[col] for r in sel])
            A, A_std, Q0, t0 = (sel[0].get(f"{tag}{k}", math.nan)
                                for k in ("A", "A_std", "Q0_N", "t0_s"))
            line = ax.plot(t, q, "o", label=f"{label}: A = {A:.3f} +- {A_std:.3f}")[0]
            if not np.isfinite(t0):  # a results.csv of a sweep before t0 was tabulated
                t0 = t[np.isfinite(q)].min() if np.isfinite(q).any() else math.nan
            if np.isfinite(A) and np.isfinite(Q0) and np.isfinite(t0):
                tt = np.geomspace(t0, t.max(), 50)
                ax.plot(tt, Q0 * (1.0 + A * np.log10(tt / t0)), "-",
                        color=line.get_color(), alpha=0.6)
    for ax, what in zip(axes, ("capacity", "shaft's load at capacity")):
        ax.set_xscale("log")
        ax.set_xlabel("ageing time [s]")
        ax.set_ylabel(f"{what} [N]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: List[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sweep_dir")
    ap.add_argument("--test", default="compression", help="the load test's name")
    ap.add_argument("--out", help="where to write (default: SWEEP_DIR)")
    args = ap.parse_args(argv)
    out = args.out or args.sweep_dir
    try:
        table = rows(args.sweep_dir, args.test)
    except (OSError, ValueError, KeyError) as e:
        print(f"pile_sweep_figure: {e}", file=sys.stderr)
        return 2
    import pandas as pd

    df = pd.DataFrame(table)
    os.makedirs(out, exist_ok=True)
    df.to_csv(os.path.join(out, "pile_sweep.csv"), index=False)
    figure(table, varied_keys(args.sweep_dir), os.path.join(out, "pile_sweep.png"),
           short_names(args.sweep_dir))
    # Printed: the values that differ between variants (a named variant's keys are its name).
    same = [c for c in df.columns[1:df.columns.get_loc("ageing_time_s")]
            if df[c].nunique(dropna=False) == 1]
    with pd.option_context("display.width", 140, "display.max_columns", 20):
        print(df.drop(columns=same).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
