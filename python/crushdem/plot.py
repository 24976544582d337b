"""``crushdem plot DIR``: figures of a run's DIR/timeseries.csv.

The CSV has one header row whose column names carry their SI unit (``time_s``,
``wall_zmax_stress_Pa``, ``kinetic_energy_J``, ...). Every figure is drawn only when the columns
it needs exist, so the command works for any experiment. Figures written (PNG, into DIR unless
``--out`` is given):

* ``stress_time.png``      wall normal stresses (and mean stress p) [MPa] against time [s]
* ``strain_stress.png``    deviator stress q (or axial wall stress) [MPa] against axial strain [%],
                           with volumetric strain [%] on a second panel when present
* ``void_ratio.png``       void ratio e against mean stress p [MPa] on a log axis
* ``coordination.png``     coordination number against time
* ``kinetic_energy.png``   kinetic energy [J] against time (log axis)
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
from typing import Dict, List, Optional, Sequence

import numpy as np

WALLS = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")
MPA = 1e-6


def read_timeseries(path: str) -> Dict[str, np.ndarray]:
    """Reads a CSV with a header row into {column: float64 array}; blanks become NaN."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path}: empty file")
    header = [h.strip() for h in rows[0]]
    data: Dict[str, List[float]] = {h: [] for h in header}
    for line_no, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(f"{path}:{line_no}: {len(row)} fields, the header has {len(header)}")
        for h, v in zip(header, row):
            v = v.strip()
            try:
                data[h].append(float(v) if v else math.nan)
            except ValueError:
                data[h].append(math.nan)
    return {h: np.asarray(v, dtype=np.float64) for h, v in data.items()}


def _has(d: Dict[str, np.ndarray], *cols: str) -> bool:
    return all(c in d and np.isfinite(d[c]).any() for c in cols)


def _time_axis(d: Dict[str, np.ndarray]):
    if _has(d, "time_s"):
        return d["time_s"], "time $t$ [s]"
    if _has(d, "step"):
        return d["step"], "step"
    n = len(next(iter(d.values()))) if d else 0
    return np.arange(n, dtype=np.float64), "row"


def _save(fig, out_dir: str, name: str, written: List[str]) -> None:
    path = os.path.join(out_dir, name)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    written.append(path)


def make_plots(run_dir: str, out_dir: Optional[str] = None) -> List[str]:
    """Draws the figures for ``run_dir``/timeseries.csv; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    csv_path = os.path.join(run_dir, "timeseries.csv")
    d = read_timeseries(csv_path)
    out_dir = out_dir or run_dir
    os.makedirs(out_dir, exist_ok=True)
    t, t_label = _time_axis(d)
    written: List[str] = []
    title = os.path.basename(os.path.normpath(run_dir))

    # Wall stresses against time.
    wall_cols = [(w, f"wall_{w}_stress_Pa") for w in WALLS if _has(d, f"wall_{w}_stress_Pa")]
    if wall_cols or _has(d, "mean_stress_Pa"):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for w, c in wall_cols:
            ax.plot(t, d[c] * MPA, label=w)
        if _has(d, "mean_stress_Pa"):
            ax.plot(t, d["mean_stress_Pa"] * MPA, "k--", label="mean $p$")
        ax.set_xlabel(t_label)
        ax.set_ylabel("normal stress $\\sigma$ [MPa]")
        ax.set_title(f"{title}: wall stresses")
        ax.grid(True, alpha=0.3)
        ax.legend()
        _save(fig, out_dir, "stress_time.png", written)
        plt.close(fig)

    # Stress-strain.
    if _has(d, "axial_strain"):
        eps_a = d["axial_strain"] * 100.0
        stress_curves = []
        if _has(d, "deviator_stress_Pa"):
            stress_curves.append(("deviator $q$", d["deviator_stress_Pa"]))
        for w in ("zmax", "zmin"):
            c = f"wall_{w}_stress_Pa"
            if _has(d, c):
                stress_curves.append((f"axial $\\sigma_a$ ({w})", d[c]))
                break
        if stress_curves:
            with_vol = _has(d, "volumetric_strain")
            fig, axes = plt.subplots(2 if with_vol else 1, 1, figsize=(7, 7 if with_vol else 4.5),
                                     sharex=True, squeeze=False)
            ax = axes[0, 0]
            for label, s in stress_curves:
                ax.plot(eps_a, s * MPA, label=label)
            ax.set_ylabel("stress [MPa]")
            ax.set_title(f"{title}: stress against axial strain")
            ax.grid(True, alpha=0.3)
            ax.legend()
            if with_vol:
                ax2 = axes[1, 0]
                ax2.plot(eps_a, d["volumetric_strain"] * 100.0, color="tab:green")
                ax2.set_ylabel("volumetric strain $\\varepsilon_v$ [%]")
                ax2.grid(True, alpha=0.3)
            axes[-1, 0].set_xlabel("axial strain $\\varepsilon_a$ [%]")
            _save(fig, out_dir, "strain_stress.png", written)
            plt.close(fig)

    # Compression curve e - log p.
    if _has(d, "void_ratio"):
        p = None
        if _has(d, "mean_stress_Pa"):
            p = d["mean_stress_Pa"]
        elif wall_cols:
            p = np.nanmean(np.vstack([d[c] for _, c in wall_cols]), axis=0)
        if p is not None and np.any(p > 0):
            keep = p > 0
            fig, ax = plt.subplots(figsize=(6, 4.5))
            ax.semilogx(p[keep] * MPA, d["void_ratio"][keep], "o-", ms=3)
            ax.set_xlabel("mean stress $p$ [MPa] (log scale)")
            ax.set_ylabel("void ratio $e$ [-]")
            ax.set_title(f"{title}: compression curve")
            ax.grid(True, which="both", alpha=0.3)
            _save(fig, out_dir, "void_ratio.png", written)
            plt.close(fig)

    if _has(d, "coordination_number"):
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(t, d["coordination_number"])
        ax.set_xlabel(t_label)
        ax.set_ylabel("coordination number $Z$ [-]")
        ax.set_title(f"{title}: coordination number")
        ax.grid(True, alpha=0.3)
        _save(fig, out_dir, "coordination.png", written)
        plt.close(fig)

    if _has(d, "kinetic_energy_J"):
        ke = d["kinetic_energy_J"]
        fig, ax = plt.subplots(figsize=(7, 4))
        if np.any(ke > 0):
            ax.semilogy(t[ke > 0], ke[ke > 0])
        else:
            ax.plot(t, ke)
        ax.set_xlabel(t_label)
        ax.set_ylabel("kinetic energy [J]")
        ax.set_title(f"{title}: kinetic energy")
        ax.grid(True, which="both", alpha=0.3)
        _save(fig, out_dir, "kinetic_energy.png", written)
        plt.close(fig)

    return written


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem plot DIR [--out OUT]``; returns the exit status."""
    parser = argparse.ArgumentParser(
        prog="crushdem plot",
        description="Draw the time series of a crushdem run (DIR/timeseries.csv) as PNG files.")
    parser.add_argument("dir", help="run directory containing timeseries.csv")
    parser.add_argument("--out", default=None, help="directory for the PNGs (default: DIR)")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        written = make_plots(args.dir, args.out)
    except (OSError, ValueError) as e:
        print(f"crushdem plot: error: {e}", file=sys.stderr)
        return 2
    if not written:
        print(f"crushdem plot: {os.path.join(args.dir, 'timeseries.csv')} has no column to plot",
              file=sys.stderr)
        return 1
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
