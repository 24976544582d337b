"""``crushdem-sand reproduce --out DIR [--quick] [--threads N]``: the reference study's section 3
(stress relaxation of a crushable quartz sand) run end to end, with its four figures.

The study ("Discrete modelling of stress relaxation in crushable sands based on fracture
theory", section 3; docs/model.md 4.4 and 4.5) has one sample and three tests:

* an oedometric stress relaxation: load to sigma_v = 7.5 MPa with crushing on, fix the walls,
  age one day with the on-off scheme (dynamic phases of ``min_cycles`` steps alternating with
  off-DEM jumps that bring ``n_break`` grains to failure);
* a drained triaxial shear at sigma_3 = 10 MPa to 30 % axial strain, only to find q_max;
* a triaxial stress relaxation: the same shear stopped at q = 0.7 q_max, then the axial strain
  held (lateral walls servo-controlled at 10 MPa during dynamic phases) for one day of ageing.

Each run is an ordinary run directory under DIR (``sample/``, ``oedometric_relaxation/``,
``triaxial_shear/``, ``triaxial_relaxation/``), made by the functions of :mod:`crushdem_sand.lab`,
so ``crushdem-sand plot DIR/<run>`` works on each. A run whose directory already holds
``summary.json`` (written last, when a run finishes) is not run again: a re-invocation after an
interruption goes on where it stopped (an interrupted run continues from its ``checkpoint.bin``; one
that left none starts over). ``DIR/settings.json`` records the settings of the first invocation; a
later one with other settings (``--quick`` against the study scale, another ``--sample``) stops
rather than mixing results.

Figures (PNG, with the CSV of what each draws; ``#`` lines at the top of a CSV say how it was
computed), all against the ageing time t (the relaxation clock, off-DEM jumps only) on a log axis,
one point per dynamic phase (the study's red dots):

* ``fig1_oedometric_relaxation``  sigma_v(t) / sigma_v(4 s), sigma_v = mean of the two axial wall
  stresses. sigma_v(4 s) is interpolated linearly in log t between the phases on either side of
  4 s; when the first phase after t = 0 is already later than 4 s (the first jumps can be long),
  linearly in t between the t = 0 phase and that one (the CSV header says which). With the
  straight line in log t fitted to the phases with t > 0 and its R^2 (not judged with fewer
  than 3 such phases: two points lie on any line).
* ``fig2_dynamic_phase4``  during the 4th dynamic phase of the triaxial relaxation: (a) the
  confining pressure fluctuation and (b) the volumetric strain generated, against the cycles of
  the phase, from the run's ``phases.csv`` (one row every ``record_interval`` steps of each
  phase). Left out, with a message, when the run has no ``phases.csv`` or fewer than 4 phases.
* ``fig3_triaxial_relaxation``  q against t with the straight line q = a + b log10 t fitted to
  the phases with t > 0 (b: the change of q per log cycle; R^2).
* ``fig4_force_statistics``  standard deviations of |F_n| (a) and |F_t| (b) over grain-grain
  contacts, triaxial and oedometric relaxation.

``DIR/reproduce.json`` holds the key numbers (sigma_v ratios at 1 h and 1 day, q_max, the fit,
phases, breakages, grains, wall-clock time of each run, and the crushdem version and commit of
the call that wrote it); a table of them is printed at the end.

``--quick`` runs the same pipeline on a 500-grain sample (e = 0.75: a cube that small packs
looser, docs/laboratory-tests.md) with short dynamic phases, to check the pipeline in a few
minutes; its numbers are not the study's.

Threads: ``--threads`` sets the OpenMP thread count of the engine (``crushdem_sand.set_threads``);
each run's ``timing.json`` records the count used. Results do not depend on it.

This module is the command: its options and the tables it prints. The recipes are
:mod:`crushdem_sand.study`, the runs and the files they leave :mod:`crushdem_sand.study_pipeline`,
the numbers :mod:`crushdem_sand.study_analysis` (one reproduction) and
:mod:`crushdem_sand.study_summary` (``--summarize``, ``--against``), the figures
:mod:`crushdem_sand.figures.study`.
"""

from __future__ import annotations

import math
import os
import sys
from typing import Any, Mapping, Optional, Sequence

from ._cli import CommandParser
from .figures import MPA, use_file_backend_without_display
from .study import PARAMETER_SETS, RUNS, SETTABLE, TESTS, show_setting
from .study_pipeline import reproduce, write_json
from .study_summary import SAMPLE_FIGURES, compare_recipes, summarize_samples


def format_samples(result: Mapping[str, Any]) -> str:
    """summarize_samples' result as a Markdown table (MPa, %)."""

    def cell(v: Any, scale: float = 1.0, fmt: str = ".4g") -> str:
        return _number(v, scale, fmt, missing="")

    scales = {"q_max_Pa": (MPA, ".4g"), "axial_strain_at_q_max": (100.0, ".3g"),
              "friction_angle_peak_deg": (1.0, ".3g"), "q_plateau_Pa": (MPA, ".4g"),
              "q_ratio_1h": (1.0, ".3f"), "q_ratio_1day": (1.0, ".3f"), "r2": (1.0, ".3f"),
              "sigma_v_ratio_1day": (1.0, ".3f"), "oedometric_r2": (1.0, ".3f")}
    head = ("| directory | sample | grains | e | q_max [MPa] | eps_a at q_max [%] | phi' [deg] "
            "| q plateau [MPa] | q(1 h)/q(0) | q(1 day)/q(0) | q R^2 "
            "| sigma_v(1 day)/sigma_v(4 s) | sigma_v R^2 |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in result["samples"]:
        lines.append("| " + " | ".join(
            [r["dir"], r["sample"],
             cell(r["grains"], fmt=".0f"), cell(r["void_ratio"], fmt=".3f")] +
            [cell(r[k], *scales[k]) for k in SAMPLE_FIGURES]) + " |")
    for name, key in (("mean", "mean"), ("std", "std"), ("standard error", "sem")):
        lines.append("| " + " | ".join(
            [name, "", "", ""] +
            [cell(result["stats"][k][key], *scales[k]) for k in SAMPLE_FIGURES]) + " |")
    lines.append("")
    lines.append(f"mean q_max against the study's {result['study_q_max_Pa'] * MPA:g} MPa: "
                 f"{cell(result['q_max_mean_vs_study'], 100.0, '+.1f')} % "
                 f"(standard error {cell(result['q_max_sem_vs_study'], 100.0, '.2f')} %, "
                 f"{result['stats']['q_max_Pa']['n']} samples)")
    return "\n".join(lines)


def format_comparison(result: Mapping[str, Any]) -> str:
    """compare_recipes' result as Markdown: what changed, then the pairs and their mean
    difference with its standard error (MPa, %)."""
    lines = ["changed from the --against directories: " + ", ".join(
        f"{k} = {show_setting(a)} -> {show_setting(b)}"
        for k, (a, b) in result["changed"].items()), ""]
    head = ("| sample | q_max against [MPa] | q_max [MPa] | difference [MPa] "
            "| plateau against [MPa] | plateau [MPa] | difference [MPa] "
            "| eps_a at q_max against [%] | eps_a at q_max [%] |")
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    for p in result["pairs"]:
        lines.append("| " + " | ".join(
            [p["sample"], _number(p["base_q_max_Pa"], MPA, ".4g"),
             _number(p["q_max_Pa"], MPA, ".4g"), _number(p["delta_q_max_Pa"], MPA, "+.3f"),
             _number(p["base_q_plateau_Pa"], MPA, ".4g"), _number(p["q_plateau_Pa"], MPA, ".4g"),
             _number(p["delta_q_plateau_Pa"], MPA, "+.3f"),
             _number(p["base_axial_strain_at_q_max"], 100.0, ".3g"),
             _number(p["axial_strain_at_q_max"], 100.0, ".3g")]) + " |")
    st = result["stats"]
    lines.append("")
    for name, k in (("q_max", "delta_q_max_Pa"), ("plateau", "delta_q_plateau_Pa")):
        lines.append(f"{name}: mean difference {_number(st[k]['mean'], MPA, '+.3f')} MPa "
                     f"(standard error {_number(st[k]['sem'], MPA, '.3f')} MPa, "
                     f"{st[k]['n']} pairs)")
    v = result["variant"]
    lines.append(f"q_max against the study's {v['study_q_max_Pa'] * MPA:g} MPa: "
                 f"{_number(v['q_max_mean_vs_study'], 100.0, '+.1f')} % with the change, "
                 f"{_number(result['base']['q_max_mean_vs_study'], 100.0, '+.1f')} % without")
    return "\n".join(lines)


def _number(v: Any, scale: float = 1.0, fmt: str = ".4g", missing: str = "-") -> str:
    """v times scale formatted with fmt; ``missing`` when v is not a finite number."""
    try:
        f = float(v) * scale
    except (TypeError, ValueError):
        return missing
    return format(f, fmt) if math.isfinite(f) else missing


def _strain_range(r: Any) -> str:
    """"10-30 %" for [0.1, 0.3]; "-" when it is not two finite numbers."""
    try:
        lo, hi = (float(v) * 100.0 for v in r)
    except (TypeError, ValueError):
        return "-"
    return f"{lo:.3g}-{hi:.3g} %" if math.isfinite(lo) and math.isfinite(hi) else "-"


def format_table(result: Mapping[str, Any]) -> str:
    """The key numbers of reproduce.json as a short plain-text table."""

    num = _number
    oe = result.get("oedometric_relaxation") or {}
    tri = result.get("triaxial_relaxation") or {}
    dyn = result.get("dynamic_phase") or {}
    runs = result.get("runs") or {}
    lines = [f"crushdem-sand reproduce ({result.get('mode')}): study section 3",
             f"  {'sigma_v(4 s) [MPa]':<40}{num(oe.get('sigma_v_4s_Pa'), MPA)}",
             f"  {'sigma_v(1 h) / sigma_v(4 s)':<40}{num(oe.get('sigma_v_ratio_1h'))}",
             f"  {'sigma_v(1 day) / sigma_v(4 s)':<40}{num(oe.get('sigma_v_ratio_1day'))}"
             "   (plausible: 0.70-0.97)",
             f"  {'sigma_v fit R^2 (phases with t > 0)':<40}{num(oe.get('r2'), fmt='.3f')}"
             f"   ({num(oe.get('fit_points'), fmt='.0f')} phases)",
             f"  {'q_max [MPa]':<40}{num(tri.get('q_max_Pa'), MPA)}   (study: 22.6)",
             f"  {'q plateau, mean +- std [MPa]':<40}{num(tri.get('q_plateau_Pa'), MPA)}"
             f" +- {num(tri.get('q_plateau_std_Pa'), MPA, '.2g')}"
             f"   (axial strain {_strain_range(tri.get('plateau_axial_strain'))})",
             f"  {'0.7 q_max [MPa]':<40}{num(tri.get('stop_q_Pa'), MPA)}",
             f"  {'q at t = 0 / at the end [MPa]':<40}{num(tri.get('q_start_Pa'), MPA)}"
             f" / {num(tri.get('q_end_Pa'), MPA)}",
             f"  {'q(1 h) / q(0)':<40}{num(tri.get('q_ratio_1h'))}",
             f"  {'q(1 day) / q(0)':<40}{num(tri.get('q_ratio_1day'))}",
             f"  {'q slope [MPa per log10 cycle]':<40}{num(tri.get('slope_Pa_per_log10_t'), MPA)}",
             f"  {'q fit R^2 (phases with t > 0)':<40}{num(tri.get('r2'), fmt='.3f')}"
             f"   ({num(tri.get('fit_points'), fmt='.0f')} phases)"]
    if "skipped" in dyn:
        lines.append(f"  {'Figure 2':<40}left out: {dyn['skipped']}")
    else:
        lines.append(f"  {'phase 4: max |confining fluct.| [%]':<40}"
                     f"{num(dyn.get('max_abs_confining_fluctuation'), 100.0)}")
        lines.append(f"  {'phase 4: volumetric strain [%]':<40}"
                     f"{num(dyn.get('volumetric_strain_end'), 100.0)}")
    lines.append(f"  {'run':<24}{'wall [s]':>10}{'phases':>8}{'instant':>9}{'crack':>7}"
                 f"{'grains':>8}  most time in")
    for name in RUNS:
        r = runs.get(name) or {}
        wall = num(r.get("wall_s"), fmt=".1f") + ("*" if r.get("skipped") else " ")
        grains = r.get("grains_end", r.get("grains"))
        lines.append(f"  {name:<24}{wall:>10}{num(r.get('dynamic_phases'), fmt='.0f'):>8}"
                     f"{num(r.get('breakages_instant'), fmt='.0f'):>9}"
                     f"{num(r.get('breakages_crack'), fmt='.0f'):>7}"
                     f"{num(grains, fmt='.0f'):>8}  {r.get('dominant_part') or '-'}")
    lines.append(f"  total {num(result.get('wall_s_total'), fmt='.1f')} s in this call"
                 "   (* finished by an earlier call; a run's wall-clock sums all its calls)")
    return "\n".join(lines)


_DESCRIPTION = """\
Run the reference study's section 3 (oedometric and triaxial stress relaxation of crushable
quartz sand, one day of ageing each) and draw its four figures into DIR:
fig1_oedometric_relaxation, fig2_dynamic_phase4, fig3_triaxial_relaxation and
fig4_force_statistics (PNG, with the CSV of what each draws), plus DIR/reproduce.json with the key
numbers. Each run is a run directory of its own (DIR/sample, DIR/oedometric_relaxation,
DIR/triaxial_shear, DIR/triaxial_relaxation) that `crushdem-sand plot` can draw; the triaxial
relaxation starts from the shear's state after its isotropic compression (same results)."""

_EPILOG = """\
Restarting: a run whose directory already has summary.json (written when it finishes) is NOT
run again; its results are read back. So after an interruption the same command goes on with
the first unfinished run: from its checkpoint.bin when it left one,
otherwise from its beginning. To redo a run, delete its directory. DIR/settings.json records
the settings; a call with other settings (--quick or not, --sample, --parameters, --set) into
the same DIR stops
with an error instead of mixing results.

Study scale (default): the 4 mm REV of examples/sample_rev.toml (about 11,400 grains,
e = 0.65), Table 1 with rotation blocked and d0 = 1.07 mm (--parameters crushdem;
--parameters blocked_d0_1mm for the set with d0 = 1 mm, table1 for free rotation and d0 = d50),
crushing with crack growth (density scaling of small fragments), dynamic phases of 150,000
cycles, N_break = 30, triaxial shear at 50 /s to 30 %: about 2.5-3 hours of one core for the
triaxial test and 30 minutes for the oedometric one (--only, side by side on two cores).
--quick: 500 grains at e = 0.75, 10,000-cycle phases, N_break = 3, shear at 100 /s to 15 %:
a few minutes on one core, to check the pipeline (its numbers are not the study's)."""


_SUMMARIZE = (
    "run nothing: put the triaxial figures (q_max, its strain and phi', the plateau, "
    "q(1 h)/q(0), q(1 day)/q(0), R^2) of these finished reproduce directories (samples of one "
    "recipe, e.g. --set sample.seed=K) side by side with their mean, standard deviation and "
    "standard error, and the mean q_max against the study's")
_AGAINST = (
    "with --summarize: finished reproduce directories of another recipe on the same samples "
    "(e.g. the default set, where the --summarize ones change one key, each run with --sample "
    "BASE/sample/sample.txt or the same sample.seed): each pair's difference in q_max, plateau "
    "and strain at q_max, and the mean difference with its standard error; writes "
    "comparison.json and comparison.md with --out")


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand reproduce --out DIR [--quick] [--threads N] [--sample FILE]``."""
    parser = CommandParser("reproduce", _DESCRIPTION + "\n\n" + _EPILOG)
    parser.add_argument("--out", metavar="DIR", help="directory for everything (required "
                        "unless --summarize; with it, where samples.json and samples.md go)")
    parser.add_argument("--quick", action="store_true",
                        help="small sample and short phases (minutes), to check the pipeline")
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="OpenMP threads for the runs (default: the OpenMP default, "
                             "usually every core); results do not depend on it")
    parser.add_argument("--sample", default=None, metavar="FILE",
                        help="use this prepared sample.txt (e.g. runs/sample_rev/sample.txt) "
                             "instead of preparing one in DIR/sample")
    parser.add_argument("--parameters", default="crushdem", choices=list(PARAMETER_SETS),
                        help="named parameter set: " + "; ".join(  # argparse %-formats help
                            f"{k}: {v[2]}" for k, v in PARAMETER_SETS.items()).replace("%", "%%")
                        + " (default: crushdem)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="change one setting, e.g. --set contact.rotation=free, --set "
                             "crushing.r_prime=2R_star or --set sample.seed=2 (another sample "
                             "of the same recipe) (repeatable; sections: "
                             f"{', '.join(SETTABLE)}); recorded in DIR/settings.json")
    parser.add_argument("--only", default=",".join(TESTS), metavar="TEST[,TEST]",
                        help="run only these tests (" + ", ".join(TESTS) + "; default: both), "
                             "e.g. two processes side by side, one per test, into one DIR once "
                             "the sample is prepared; the figures cover what has finished")
    parser.add_backend("what advances the runs: cpu (default), cuda (a GPU, in a build with CUDA) "
                       "or emulated (the GPU's step on the host); recorded in DIR/settings.json, "
                       "as the backends agree only statistically")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress lines (by default the engine prints one on stderr "
                             "every minute at study scale: stage, stresses, share done, ETA)")
    for option, text in (("--summarize", _SUMMARIZE), ("--against", _AGAINST)):
        parser.add_argument(option, nargs="+", default=None, metavar="DIR", help=text)
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    if args.threads is not None and args.threads < 1:
        parser.error("--threads must be >= 1")
    if args.against is not None and args.summarize is None:
        parser.error("--against needs --summarize DIR...")
    if args.summarize is not None:
        return _summarize_main(args.summarize, args.out, args.against)
    if args.out is None:
        parser.error("the following arguments are required: --out")

    def log(msg: str) -> None:
        print(f"crushdem-sand reproduce: {msg}", flush=True)

    use_file_backend_without_display()

    try:
        result = reproduce(args.out, quick=args.quick, threads=args.threads, sample=args.sample,
                           log=log, overrides=args.set, parameters=args.parameters,
                           tests=[t.strip() for t in args.only.split(",") if t.strip()],
                           backend=args.backend, progress=not args.quiet)
    except (OSError, ValueError, RuntimeError) as e:
        print(f"crushdem-sand reproduce: error: {e}", file=sys.stderr)
        return 2
    for name in result.get("figures", []):
        print(os.path.join(args.out, name))
    print(os.path.join(args.out, "reproduce.json"))
    print(format_table(result))
    return 0


def _summarize_main(dirs: Sequence[str], out: Optional[str],
                    against: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand reproduce --summarize DIR... [--against DIR...] [--out DIR]``."""
    try:
        if against is None:
            result = summarize_samples(dirs)
            table, name = format_samples(result), "samples"
        else:
            result = compare_recipes(dirs, against)
            table, name = format_comparison(result), "comparison"
    except (OSError, ValueError) as e:
        print(f"crushdem-sand reproduce: error: {e}", file=sys.stderr)
        return 2
    if out is not None:
        os.makedirs(out, exist_ok=True)
        write_json(os.path.join(out, f"{name}.json"), result)
        with open(os.path.join(out, f"{name}.md"), "w") as f:
            f.write(table + "\n")
        print(os.path.join(out, f"{name}.json"))
        print(os.path.join(out, f"{name}.md"))
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
