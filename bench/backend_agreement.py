"""Do the CPU engine and the device step (its emulation, which has the GPU's bits) agree on the
triaxial shear, or is one of them biased? Paired runs: each sample seed is prepared once on the
CPU, then sheared on both backends with the settings of `crushdem-sand reproduce --quick` (500
grains, crushdem's set with crushing, sigma_3 = 10 MPa, 100 /s to 15 %); the two runs of a pair
drift apart by the order of the force sums, as two samples do, so only the mean of many pairs can
show a bias. Prints each pair and the mean relative difference of q_max and of the plateau (the mean
q from 5 to 15 % axial strain) with their standard errors (docs/performance.md, "Backends").

    python bench/backend_agreement.py OUT [--seeds 3-26] [--backend emulated]

A run already finished in OUT is read, not repeated, so the script can be stopped and started
again. About 2 minutes a seed on one core (the CPU run 40-60 s, the emulated one 50-80 s).
"""
import argparse
import json
import math
import os
import statistics
import sys
from typing import Dict, List


def shear(run_dir: str) -> Dict[str, float]:
    """q_max, the plateau and the breakages of a finished triaxial test in run_dir."""
    import pandas as pd

    with open(os.path.join(run_dir, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    stage = next(s for s in summary["stages"] if s["type"] == "triaxial")
    rows = pd.read_csv(os.path.join(run_dir, "timeseries.csv"), comment="#")
    plateau = rows[(rows.stage == stage_index(summary)) & (rows.stage_axial_strain >= 0.05)]
    crushing = summary.get("crushing") or {}
    return {"q_max": stage["q_max_Pa"], "plateau": float(plateau.deviator_stress_Pa.mean()),
            "breakages": crushing.get("breakages_instant", 0) + crushing.get("breakages_crack", 0)}


def stage_index(summary: Dict) -> int:
    return next(k for k, s in enumerate(summary["stages"]) if s["type"] == "triaxial")


def run_pair(out: str, seed: int, backend: str) -> Dict[str, Dict[str, float]]:
    from crushdem_sand import lab, study

    cfg = study.settings(quick=True)
    cfg["sample"]["seed"] = seed
    sections = dict(material=cfg["material"], contact=cfg["contact"], output=cfg["output"],
                    progress=False)
    sample = os.path.join(out, f"seed{seed}", "sample")
    if not os.path.exists(os.path.join(sample, "summary.json")):
        lab.prepare_sample(sample, **sections, **cfg["sample"])
    tx = cfg["triaxial"]
    result = {}
    for b in ("cpu", backend):
        d = os.path.join(out, f"seed{seed}", b)
        if not os.path.exists(os.path.join(d, "summary.json")):
            lab.triaxial_test(d, os.path.join(sample, "sample.txt"), sigma_3=tx["sigma_3"],
                              strain_rate=tx["strain_rate"], axial_strain=tx["axial_strain"],
                              crushing=dict(cfg["crushing"]), backend=b, **sections)
        result[b] = shear(d)
    return result


def mean_se(values: List[float]) -> str:
    m = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else math.nan
    return f"{m:+.4f} +- {se:.4f} (mean / se = {m / se:+.2f})"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="directory for the runs (kept; finished runs are reused)")
    ap.add_argument("--seeds", default="3-26", help="sample seeds, FIRST-LAST (default 3-26)")
    ap.add_argument("--backend", default="emulated", help="the backend set beside the CPU")
    a = ap.parse_args()
    first, _, last = a.seeds.partition("-")
    seeds = range(int(first), int(last or first) + 1)
    d_q, d_plateau, d_breakages = [], [], []
    print("seed  q_max cpu  q_max dev [MPa]  plateau cpu  plateau dev [MPa]  breakages cpu dev")
    for seed in seeds:
        r = run_pair(a.out, seed, a.backend)
        c, d = r["cpu"], r[a.backend]
        d_q.append(d["q_max"] / c["q_max"] - 1.0)
        d_plateau.append(d["plateau"] / c["plateau"] - 1.0)
        d_breakages.append(d["breakages"] - c["breakages"])
        print(f"{seed:4d}  {c['q_max'] / 1e6:9.3f}  {d['q_max'] / 1e6:9.3f}        "
              f"{c['plateau'] / 1e6:9.3f}    {d['plateau'] / 1e6:9.3f}          "
              f"{c['breakages']:5.0f} {d['breakages']:5.0f}", flush=True)
    print(f"{len(d_q)} pairs, {a.backend} against cpu:")
    print(f"  q_max   relative difference {mean_se(d_q)}")
    print(f"  plateau relative difference {mean_se(d_plateau)}")
    print(f"  breakages difference        {mean_se([float(x) for x in d_breakages])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
