"""``crushdem-sand sensitivity --out DIR --sample FILE``: the influence of the uncertain choices of
docs/model.md section 5 on the drained triaxial strength q_max.

Each variant changes one choice of the base settings (Table 1 and the documented defaults, as
``crushdem-sand reproduce`` uses them for its triaxial shear: crushing on, density scaling, no crack
growth) and runs the same test on the same prepared sample: isotropic compression to sigma_3,
then drained shear at ``strain_rate`` to ``axial_strain`` with the lateral walls at sigma_3.

The variants are a preset sweep (``crushdem-sand sweep``): ``DIR/sensitivity_base.toml`` is the test
on the sample, ``DIR/sensitivity_sweep.toml`` names each variant as a ``[[variant]]`` with the
keys it changes, and the sweep runs them as Dask tasks, ``--workers`` at a time (default: the
cores divided by ``--threads``), into ``DIR/runs/<variant>/`` (a run directory each), with
the sweep's ``DIR/results.csv`` beside the sensitivity tables. Writes ``DIR/qmax_sensitivity.csv``
and ``DIR/qmax_sensitivity.md`` (q_max, q_max / sigma_3, the axial strain at q_max, the peak
friction angle, breakages, B_r, grains and wall-clock time per variant, and which comes closest to
the study's 22.6 MPa) and ``DIR/sensitivity.json`` (the settings). A variant that has finished is
not run again and an interrupted one resumes from its checkpoint, so the command can be repeated
until every variant is done, or run on several machines with ``--only``. Variant directories
directly under ``DIR`` (an older layout) are read as well.

A name joined with ``+`` (``r_prime_2R_star+d0_2mm+rolling_0.3``) is a combination: it makes
every change of its parts at once (parts that set one key two ways are refused). The tables list
every variant with a run directory under ``DIR``, so runs made with different ``--only`` lists
end up in one table.
"""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import sys
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

import numpy as np

from ._cli import CommandParser
from .analysis import as_float
from .rundir import read_summary, read_timeseries, read_timing
from .study import (MATERIAL, SIGMA_3_PA, STUDY_Q_MAX_PA,  # noqa: F401  (re-exported)
                    TABLE1_CONTACT, TABLE1_CRUSHING, with_earlier_defaults)
from .study_analysis import triaxial_stage

# name: (what it changes, [contact] keys, [crushing] keys). One choice per variant, the rest as
# in "base"; docs/model.md section 5 lists the choices.
VARIANTS: Dict[str, tuple] = {
    "base": ("Table 1 with the documented defaults (r' = R*, d0 = d50, (k1, k2) = (0.05, 5), "
             "f normal)", {}, {}),
    "no_crushing": ("crushing off (the strength of the unbreakable spheres)", {},
                    {"enabled": False}),
    "r_prime_2R_star": ("r' = 2 R* (PFC's effective radius) instead of R*", {},
                        {"r_prime": "2R_star"}),
    "d0_2mm": ("d0 = 2 mm instead of d50 (a d50 grain (0.21 / 2)^(-3/m) = 1.76 times stronger)",
               {}, {"d0": 2e-3}),
    "d0_1mm": ("d0 = 1 mm instead of d50: a d50 grain breaks between platens at F / d^2 = "
               "0.47 GPa, near the top of the 0.05-0.5 GPa of real quartz grains (d50: 0.15 GPa)",
               {}, {"d0": 1e-3}),
    "k1k2_1_100": ("(k1, k2) = (1, 100), the original rough-law code's, instead of (0.05, 5)",
                   {"k1": 1.0, "k2": 100.0}, {}),
    "f_uniform": ("f uniform on [1 - var, 1 + var] instead of normal(1, var)", {},
                  {"distribution": "uniform"}),
    "blocked": ("rotation blocked: spins held at zero, contact moments ignored (Arroyo et al. "
                "2011; not in Table 1)", {"rotation": "blocked"}, {}),
}
# Rolling resistance (docs/model.md 1.5; PFC-style, not in Table 1) at the decision study's
# mu_r values.
for _mu_r in ("0.1", "0.2", "0.3", "0.4", "0.6", "1.0"):
    VARIANTS[f"rolling_{_mu_r}"] = (
        f"rolling resistance mu_r = {_mu_r} (k_r = k_t R*^2, |M_r| <= mu_r R* F_n)",
        {"rotation": "rolling", "rolling_friction": float(_mu_r)}, {})


def settings(sigma_3: float = SIGMA_3_PA, strain_rate: float = 50.0,
             axial_strain: float = 0.30) -> Dict[str, Any]:
    """The base settings of every variant, as one JSON-able dict."""
    crushing = dict(TABLE1_CRUSHING)
    crushing["crack_growth"] = False  # q_max is a short-term strength
    return {"material": dict(MATERIAL), "contact": dict(TABLE1_CONTACT), "crushing": crushing,
            "triaxial": {"sigma_3": sigma_3, "strain_rate": strain_rate,
                         "axial_strain": axial_strain},
            "output": {"interval": 20000, "progress_seconds": 60}}


def variant_parts(name: str) -> List[str]:
    """The single variants of ``name`` (one, or several joined with '+')."""
    parts = [p.strip() for p in name.split("+")]
    for p in parts:
        if p not in VARIANTS:
            raise ValueError(f"unknown variant '{p}' in '{name}': expected one of "
                             f"{', '.join(VARIANTS)}, or several joined with '+'")
    if len(parts) > 1 and "base" in parts:
        raise ValueError(f"variant '{name}': 'base' changes nothing, leave it out of a "
                         "combination")
    if len(set(parts)) != len(parts):
        raise ValueError(f"variant '{name}': a part appears twice")
    return parts


def describe(name: str) -> str:
    """What variant ``name`` changes, in words."""
    return "; ".join(VARIANTS[p][0] for p in variant_parts(name))


def variant_settings(base: Mapping[str, Any], name: str) -> Dict[str, Any]:
    """``base`` with the changes of variant ``name`` (every part's, for a combination)."""
    s = copy.deepcopy(dict(base))
    set_by: Dict[tuple, str] = {}
    for part in variant_parts(name):
        _, contact, crushing = VARIANTS[part]
        for section, changes in (("contact", contact), ("crushing", crushing)):
            for key, value in changes.items():
                other = set_by.get((section, key))
                if other is not None and s[section][key] != value:
                    raise ValueError(f"variant '{name}': '{other}' and '{part}' set "
                                     f"{section}.{key} differently")
                set_by[(section, key)] = part
                s[section][key] = value
    return s


def run_dir(out: str, name: str) -> str:
    """The run directory of variant ``name`` under ``out``: DIR/runs/NAME (the sweep's), or
    DIR/NAME where an older layout left it."""
    old = os.path.join(out, name)
    new = os.path.join(out, "runs", name)
    return old if os.path.isdir(old) and not os.path.isdir(new) else new


def known_runs(out: str) -> List[str]:
    """Variant names with a run directory under ``out``: single variants in the order of
    VARIANTS, then combinations in name order."""
    found = set()
    for where in (out, os.path.join(out, "runs")):
        if not os.path.isdir(where):
            continue
        for entry in sorted(os.listdir(where)):
            if not os.path.isdir(os.path.join(where, entry)):
                continue
            try:
                variant_parts(entry)
            except ValueError:
                continue
            found.add(entry)
    singles = [n for n in VARIANTS if n in found]
    return singles + sorted(n for n in found if n not in VARIANTS)


def toml_value(v: Any) -> str:
    """A scalar as TOML (strings quoted, booleans lower case, numbers that read back exactly)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (int, float)):
        return repr(v)
    raise ValueError(f"not a TOML scalar: {v!r}")


def base_config(s: Mapping[str, Any], sample: str) -> Dict[str, Any]:
    """The test every variant runs: isotropic compression to sigma_3, then drained shear, on the
    prepared ``sample``, with the sections of settings ``s``."""
    tri = s["triaxial"]
    return {"material": dict(s["material"]), "contact": dict(s["contact"]),
            "crushing": dict(s["crushing"]), "output": dict(s["output"]),
            "particles": {"file": os.path.abspath(sample)},
            "stage": [{"type": "isotropic", "name": "isotropic", "stress": tri["sigma_3"]},
                      {"type": "triaxial", "name": "shear", "sigma_3": tri["sigma_3"],
                       "strain_rate": tri["strain_rate"], "axial_strain": tri["axial_strain"]}]}


def write_sweep(out: str, sample: str, names: Sequence[str], base: Mapping[str, Any]) -> str:
    """Writes DIR/sensitivity_base.toml (the resolved base test) and DIR/sensitivity_sweep.toml
    (one [[variant]] per name with the keys it changes); returns the sweep file's path."""
    from . import _core

    text = _core.resolved_run_config(base_config(base, sample), out)
    with open(os.path.join(out, "sensitivity_base.toml"), "w") as f:
        f.write(text)
    lines = ["# crushdem-sand sensitivity: each variant changes the base test's choices below",
             'base = "sensitivity_base.toml"', ""]
    for name in names:
        changed = variant_settings(base, name)
        lines += ["[[variant]]", f"name = {toml_value(name)}"]
        for section in ("contact", "crushing"):
            for key, value in changed[section].items():
                if base[section].get(key, None) != value or key not in base[section]:
                    lines.append(f'"{section}.{key}" = {toml_value(value)}')
        lines.append("")
    path = os.path.join(out, "sensitivity_sweep.toml")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    return path


def solid_volume(sample: str) -> float:
    """The grains' volume of a sample file (rows "id x y z d", d the diameter) [m^3]."""
    volume = 0.0
    with open(sample) as f:
        for line in f:
            fields = line.split()
            if fields and not fields[0].startswith("#"):
                volume += math.pi / 6.0 * float(fields[4]) ** 3
    return volume


def shear_end(run_dir: str) -> Dict[str, float]:
    """q and the volumetric strain of the shear (from its first row) at the end of the
    triaxial stage, from DIR/timeseries.csv (NaN when it cannot be read)."""
    out = {"q_end_MPa": math.nan, "eps_v_shear": math.nan}
    try:
        d = read_timeseries(os.path.join(run_dir, "timeseries.csv"))
    except (OSError, ValueError):
        return out
    stage = d.get("stage")
    if stage is None or not len(stage):
        return out
    rows = np.flatnonzero(stage == stage.max())
    if len(rows):
        out["q_end_MPa"] = d["deviator_stress_Pa"][rows[-1]] / 1e6
        out["eps_v_shear"] = d["volumetric_strain"][rows[-1]] - d["volumetric_strain"][rows[0]]
    return out


def read_variant(run_dir: str, sigma_3: float, solids_m3: float = math.nan) -> Dict[str, Any]:
    """The figures of one finished variant run (NaN where the run has not finished).
    solids_m3: the sample's grain volume, for the share of it that breakage deleted."""
    nan = math.nan
    row: Dict[str, Any] = {"q_max_MPa": nan, "q_max_over_sigma_3": nan,
                           "axial_strain_at_q_max": nan, "friction_angle_peak_deg": nan,
                           "q_end_MPa": nan, "eps_v_shear": nan,
                           "breakages": nan, "relative_breakage_Br": nan,
                           "removed_volume_share": nan, "loaded_share_072_isotropic": nan,
                           "grains_end": nan, "wall_s": nan, "finished": False}
    summary = read_summary(run_dir)
    if not summary:
        return row
    shear = triaxial_stage(summary)
    q = as_float(shear.get("q_max_Pa"))
    row.update(finished=True, q_max_MPa=q / 1e6, q_max_over_sigma_3=q / sigma_3,
               axial_strain_at_q_max=as_float(shear.get("axial_strain_at_q_max")),
               friction_angle_peak_deg=as_float(shear.get("friction_angle_peak_deg")),
               grains_end=summary.get("particles", nan),
               wall_s=as_float(read_timing(run_dir).get("wall_seconds")))
    row.update(shear_end(run_dir))
    crushing = summary.get("crushing") or {}
    if crushing:
        row["breakages"] = (crushing.get("breakages_instant", 0) or 0) + (
            crushing.get("breakages_crack", 0) or 0)
        row["relative_breakage_Br"] = crushing.get("relative_breakage_Br", nan)
        row["removed_volume_share"] = as_float(crushing.get("removed_volume_m3")) / solids_m3
        first = (summary.get("stages") or [{}])[0]
        row["loaded_share_072_isotropic"] = as_float((first.get("loaded_share") or {}).get("0.72"))
    else:
        row["breakages"], row["relative_breakage_Br"], row["removed_volume_share"] = 0, 0.0, 0.0
    return row


COLUMNS = ("variant", "q_max_MPa", "q_max_over_sigma_3", "axial_strain_at_q_max",
           "friction_angle_peak_deg", "q_end_MPa", "eps_v_shear", "breakages",
           "relative_breakage_Br", "removed_volume_share", "loaded_share_072_isotropic",
           "grains_end", "wall_s", "changes")


def table(out: str, names: Sequence[str], sigma_3: float,
          solids_m3: float = math.nan) -> List[Dict[str, Any]]:
    """Reads the runs of ``names`` and of every other variant run under ``out``; writes
    qmax_sensitivity.csv and .md; returns the rows. solids_m3: the sample's grain volume."""
    rows = []
    listed = known_runs(out)
    for name in listed + [n for n in names if n not in listed]:
        row = read_variant(run_dir(out, name), sigma_3, solids_m3)
        row["variant"], row["changes"] = name, describe(name)
        rows.append(row)
    with open(os.path.join(out, "qmax_sensitivity.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([r[c] for c in COLUMNS])
    done = [r for r in rows if r["finished"] and math.isfinite(r["q_max_MPa"])]
    lines = [f"q_max at sigma_3 = {sigma_3 / 1e6:g} MPa, one choice varied at a time "
             f"(study: {STUDY_Q_MAX_PA / 1e6:g} MPa)", "",
             "| variant | q_max [MPa] | q_max / sigma_3 | eps_a at q_max | phi_peak [deg] | "
             "q at end [MPa] | eps_v of the shear | breakages | B_r | volume deleted | "
             "grains >= 0.72 sigma_lim after isotropic | grains | wall [s] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r["finished"]:
            lines.append(f"| {r['variant']} | (not finished) |" + " |" * 11)
            continue
        lines.append(
            f"| {r['variant']} | {r['q_max_MPa']:.2f} | {r['q_max_over_sigma_3']:.3f} | "
            f"{100 * r['axial_strain_at_q_max']:.1f} % | {r['friction_angle_peak_deg']:.1f} | "
            f"{r['q_end_MPa']:.2f} | {100 * r['eps_v_shear']:.2f} % | {r['breakages']} | "
            f"{r['relative_breakage_Br']:.3f} | {100 * r['removed_volume_share']:.2f} % | "
            f"{100 * r['loaded_share_072_isotropic']:.2f} % | {r['grains_end']} | "
            f"{r['wall_s']:.0f} |")
    if done:
        best = min(done, key=lambda r: abs(r["q_max_MPa"] * 1e6 - STUDY_Q_MAX_PA))
        lines += ["", f"Closest to the study: {best['variant']} ({best['q_max_MPa']:.2f} MPa: "
                      f"{best['changes']})."]
    lines += ["", "Variants:"] + [f"- {r['variant']}: {r['changes']}" for r in rows]
    with open(os.path.join(out, "qmax_sensitivity.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    return rows


def run_sensitivity(out: str, sample: str, names: Optional[Sequence[str]] = None,
                    threads: Optional[int] = None, sigma_3: float = SIGMA_3_PA,
                    strain_rate: float = 50.0, axial_strain: float = 0.30,
                    log: Callable[[str], None] = print,
                    workers: Optional[int] = None) -> List[Dict[str, Any]]:
    """Runs the variants ``names`` (default: all) on the prepared ``sample`` into ``out``, as a
    sweep of ``workers`` runs at a time with ``threads`` threads each."""
    from . import sweep

    names = list(names or VARIANTS)
    base = settings(sigma_3, strain_rate, axial_strain)
    chosen = {n: variant_settings(base, n) for n in names}  # bad names fail before anything runs
    if not os.path.isfile(sample):
        raise ValueError(f"--sample '{sample}': no such file (a prepared sample.txt)")
    os.makedirs(out, exist_ok=True)
    # The settings of every variant ever run here, so that runs with other --only lists keep
    # theirs.
    json_path = os.path.join(out, "sensitivity.json")
    variants: Dict[str, Any] = {}
    if os.path.isfile(json_path):
        with open(json_path) as f:
            before = json.load(f)
        if before.get("sample") not in (None, os.path.abspath(sample)):
            raise ValueError(f"--sample '{sample}': {out} holds variants run on "
                             f"{before['sample']}; use that sample or another --out")
        earlier = before.get("base")
        if earlier is not None:
            earlier = with_earlier_defaults(earlier)
        if earlier not in (None, json.loads(json.dumps(base))):
            raise ValueError(f"{out} holds variants run with other base settings (sigma_3, "
                             "strain rate, axial strain or defaults); use another --out")
        variants = before.get("variants", {})
    for n, s in chosen.items():
        variants[n] = {"changes": describe(n), "contact": s["contact"],
                       "crushing": s["crushing"]}
    with open(json_path, "w") as f:
        json.dump({"sample": os.path.abspath(sample), "base": base, "variants": variants}, f,
                  indent=1)
    solids = solid_volume(sample)
    # Variants finished in the older layout (DIR/NAME) are not run again.
    todo = [n for n in names
            if not os.path.isfile(os.path.join(run_dir(out, n), "summary.json"))]
    if todo:
        path = write_sweep(out, sample, todo, base)
        threads_per_run = threads or 1
        try:
            sweep.sweep(path, out, workers=workers, threads_per_run=threads_per_run, log=log)
        finally:
            table(out, names, sigma_3, solids)  # finished work is never lost
    return table(out, names, sigma_3, solids)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand sensitivity --out DIR --sample FILE [--only A,B] [--axial-strain E]``."""
    parser = CommandParser("sensitivity", __doc__)
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="directory for the variants' runs and the tables")
    parser.add_argument("--sample", required=True, metavar="FILE",
                        help="a prepared sample.txt (e.g. runs/sample_rev/sample.txt)")
    parser.add_argument("--only", default=None, metavar="A,B",
                        help=f"variants to run, comma-separated (default all: "
                             f"{', '.join(VARIANTS)}); join names with '+' to combine "
                             f"their changes")
    parser.add_argument("--axial-strain", type=float, default=0.30, metavar="E",
                        help="axial strain the shear ends at (default 0.30)")
    parser.add_argument("--strain-rate", type=float, default=50.0, metavar="R",
                        help="axial strain rate of the shear, 1/s (default 50)")
    parser.add_argument("--sigma-3", type=float, default=SIGMA_3_PA, metavar="PA",
                        help="confining stress, Pa (default: the study's 10 MPa)")
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="OpenMP threads of each variant run (default 1)")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="variants run at once (default: the cores divided by --threads)")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    names = [n.strip() for n in args.only.split(",")] if args.only else None

    def log(msg: str) -> None:
        print(f"crushdem-sand sensitivity: {msg}", flush=True)

    try:
        run_sensitivity(args.out, args.sample, names, args.threads, args.sigma_3,
                        args.strain_rate, args.axial_strain, log, args.workers)
    except (OSError, ValueError, RuntimeError) as e:
        print(f"crushdem-sand sensitivity: error: {e}", file=sys.stderr)
        return 2
    with open(os.path.join(args.out, "qmax_sensitivity.md")) as f:
        print(f.read())
    return 0


if __name__ == "__main__":
    sys.exit(main())
