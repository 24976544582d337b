"""How far a run got and how fast, from its directory alone (a finished or a stopped run).

    python3 bench/run_progress.py RUN_DIR [LABEL]

Prints rows for bench/gpu_check.sh's table: the steps per second of each stage's progress lines
in run.log (median of the lines, as the run printed them), the preparation's last row (step,
phase, void ratio), a penetrate stage's travel and q_c averaged by half a body diameter of travel,
and timing.json's totals. Standard library only (the GPU machine's Python has no crushdem_sand).
"""

import csv
import json
import os
import re
import statistics
import sys

PROGRESS = re.compile(r"Z\s+(\S+)\s+step (\d+)\s+.*?([0-9.e+-]+) steps/s\s*$")


def row(label, value):
    print(f"{label:58s} {value}")


def rows(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main(directory, label):
    rates = {}
    last_step = {}
    log = os.path.join(directory, "run.log")
    if os.path.exists(log):
        for line in open(log):
            m = PROGRESS.search(line)
            if m:
                rates.setdefault(m.group(1), []).append(float(m.group(3)))
                last_step[m.group(1)] = int(m.group(2))
    for stage, r in rates.items():
        row(f"  {label} {stage}: steps/s (median of {len(r)} lines), last step",
            f"{statistics.median(r):.4g}, {last_step[stage]}")
    prep = rows(os.path.join(directory, "preparation.csv"))
    if prep:
        p = prep[-1]
        row(f"  {label} preparation: last step, phase, n, e",
            f"{p['step']}, {p.get('phase', '?')}, {p['n_particles']}, {float(p['void_ratio']):.4f}")
    for root, _, files in os.walk(directory):
        if "penetration.csv" not in files:
            continue
        pen = rows(os.path.join(root, "penetration.csv"))
        if not pen:
            continue
        last = pen[-1]
        row(f"  {label} {os.path.basename(root)}: records, travel [m], last q_c [MPa]",
            f"{len(pen)}, {float(last['travel_m']):.4g}, {float(last['q_c_Pa']) / 1e6:.4g}")
        # q_c averaged over bins of 0.5 cone diameters of travel (the body's diameter from its
        # config is not read here: 35.7 mm, examples/chamber_cpt.toml, unless CONE_D is set).
        d_c = float(os.environ.get("CONE_D", "0.0357"))
        bins = {}
        for r in pen:
            b = int(float(r["travel_m"]) / (0.5 * d_c))
            bins.setdefault(b, []).append(float(r["q_c_Pa"]))
        text = "; ".join(f"{0.5 * b:.1f}-{0.5 * (b + 1):.1f}: {statistics.mean(v) / 1e6:.3g}"
                         for b, v in sorted(bins.items()))
        row(f"  {label} q_c by travel [d_c: MPa]", text)
    timing = os.path.join(directory, "timing.json")
    if os.path.exists(timing):
        t = json.load(open(timing))
        row(f"  {label} timing: steps, wall s, particle-steps/s, rebuilds",
            f"{t['steps']}, {t['wall_seconds']:.1f}, {t['particle_steps_per_second']:.3e}, "
            f"{t.get('neighbor_builds', '?')}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: python3 bench/run_progress.py RUN_DIR [LABEL]")
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else os.path.basename(sys.argv[1]))
