"""The pipeline of ``crushdem-sand reproduce``: the study's runs (the recipes of
:mod:`crushdem_sand.study`, each run by a function of :mod:`crushdem_sand.lab` into a run directory
of its own, skipped when finished and resumed when interrupted:
:func:`crushdem_sand.runs.run_step`), then what a reproduction directory holds: the study's figures
(:mod:`crushdem_sand.figures.study`), each PNG with the CSV of what it draws
(:mod:`crushdem_sand.study_analysis`), and ``reproduce.json``."""

from __future__ import annotations

import csv
import json
import math
import os
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

import numpy as np

from .figures.study import (figure_dynamic_phase, figure_force_statistics,
                            figure_oedometric_relaxation, figure_triaxial_relaxation)
from .rundir import has_stage_state, is_finished, read_summary
from .runs import run_step, set_threads, timing_record
from .study import (RUNS, TESTS, apply_overrides, settings, settings_changes, show_setting,
                    with_earlier_defaults)
from .study_analysis import (FigureData, age_counts, dynamic_phase, force_statistics,
                             oedometric_relaxation, shear_figures, triaxial_relaxation)


def run_sections(cfg: Mapping[str, Any], progress: bool) -> Dict[str, Any]:
    """The keyword arguments every run of the settings ``cfg`` gets from crushdem_sand.lab: the
    material, contact and output sections, the backend and the progress lines."""
    return {"material": cfg["material"], "contact": cfg["contact"], "output": cfg["output"],
            "backend": backend_of(cfg), "progress": progress}


def backend_of(cfg: Mapping[str, Any]) -> str:
    """The backend of the settings ``cfg`` ("cpu" unless recorded)."""
    return str(cfg.get("backend", "cpu"))


def resumer(backend: str) -> Callable[[str, bool], Any]:
    """``run_step``'s resume on ``backend``."""
    from . import _core

    return lambda run_dir, progress: _core.resume(run_dir, progress, backend)


def age_stage_keys(cfg: Mapping[str, Any]) -> Dict[str, Any]:
    """Keys for the age stage only: the settings' ``age_stage`` plus ``record_interval``."""
    age_stage = dict(cfg["age_stage"])
    if cfg["record_interval"]:
        age_stage["record_interval"] = cfg["record_interval"]
    return age_stage


def run_sample(cfg: Mapping[str, Any], run_dir: str, log: Callable[[str], None],
               record: Dict[str, Any], progress: bool = False) -> str:
    """The sample of the settings ``cfg`` prepared into ``run_dir`` as a ``run_step``; returns
    its particle file. progress: the engine's progress lines on stderr (every
    ``output.progress_seconds``)."""
    from . import lab

    run_step("sample", run_dir,
             lambda: lab.prepare_sample(run_dir, **run_sections(cfg, progress), **cfg["sample"]),
             log, record, resumer(backend_of(cfg)), progress)
    return os.path.join(run_dir, "sample.txt")


def run_oedometric_relaxation(cfg: Mapping[str, Any], run_dir: str, sample_file: str,
                              log: Callable[[str], None], record: Dict[str, Any],
                              name: str = "oedometric_relaxation",
                              progress: bool = False) -> None:
    """The study's oedometric relaxation with the settings ``cfg`` (see ``settings``) into
    ``run_dir``, as a ``run_step`` (skipped when finished, resumed when interrupted);
    progress: the engine's progress lines on stderr."""
    from . import lab

    oe = cfg["oedometric"]
    run_step(name, run_dir,
             lambda: lab.oedometric_relaxation(
                 run_dir, sample_file, stress=oe["stress"], strain_rate=oe["strain_rate"],
                 crushing=dict(cfg["crushing"]), age_stage=age_stage_keys(cfg), **cfg["age"],
                 **run_sections(cfg, progress)),
             log, record, resumer(backend_of(cfg)), progress)


def run_triaxial(cfg: Mapping[str, Any], dirs: Mapping[str, str], sample_file: str,
                 log: Callable[[str], None], runs: Dict[str, Any], progress: bool) -> float:
    """The triaxial shear (to find q_max), then the triaxial relaxation at q_fraction q_max,
    each a ``run_step`` into ``dirs[name]``; returns q_max."""
    from . import lab

    tx = cfg["triaxial"]
    run_step("triaxial_shear", dirs["triaxial_shear"],
             lambda: lab.triaxial_test(dirs["triaxial_shear"], sample_file,
                                       sigma_3=tx["sigma_3"], strain_rate=tx["strain_rate"],
                                       axial_strain=tx["axial_strain"],
                                       crushing=dict(cfg["crushing"]),
                                       **run_sections(cfg, progress)),
             log, runs, resumer(backend_of(cfg)), progress)
    q_max = record_shear(dirs["triaxial_shear"], runs)
    # The shear's isotropic compression is the relaxation's too: branch from its end.
    branch = dirs["triaxial_shear"] if has_stage_state(dirs["triaxial_shear"], 1) else None
    run_triaxial_relaxation(cfg, dirs["triaxial_relaxation"], sample_file,
                            cfg["relaxation"]["q_fraction"] * q_max, log, runs,
                            progress=progress, branch_from=branch)
    runs["triaxial_relaxation"].update(age_counts(dirs["triaxial_relaxation"]))
    return q_max


def run_triaxial_relaxation(cfg: Mapping[str, Any], run_dir: str, sample_file: str,
                            stop_q: float, log: Callable[[str], None], record: Dict[str, Any],
                            name: str = "triaxial_relaxation", progress: bool = False,
                            branch_from: Optional[str] = None) -> None:
    """The study's triaxial relaxation with the settings ``cfg``: the shear of the triaxial test
    stopped at ``stop_q`` (0.7 q_max), then one day of ageing, into ``run_dir`` as a
    ``run_step``. branch_from: a triaxial shear of the same settings and sample whose state
    after the isotropic compression this run starts from (same results, fewer steps)."""
    from . import lab

    tx = cfg["triaxial"]
    run_step(name, run_dir,
             lambda: lab.triaxial_relaxation(
                 run_dir, sample_file, sigma_3=tx["sigma_3"], stop_q=stop_q,
                 strain_rate=tx["strain_rate"], axial_strain=tx["axial_strain"],
                 crushing=dict(cfg["crushing"]), age_stage=age_stage_keys(cfg), **cfg["age"],
                 branch_from=branch_from, **run_sections(cfg, progress)),
             log, record, resumer(backend_of(cfg)), progress)


def record_shear(shear_dir: str, runs: Dict[str, Any]) -> float:
    """q_max of the finished triaxial shear in ``shear_dir``, its figures recorded in
    runs["triaxial_shear"] (:func:`crushdem_sand.study_analysis.shear_figures`)."""
    figures = shear_figures(shear_dir)
    runs.setdefault("triaxial_shear", {"skipped": True, **timing_record(shear_dir)})
    runs["triaxial_shear"].update(figures)
    return figures["q_max_Pa"]


def record_triaxial(dirs: Mapping[str, str], runs: Dict[str, Any]) -> float:
    """q_max and the records of a triaxial test that an earlier or another call finished."""
    q_max = record_shear(dirs["triaxial_shear"], runs)
    runs.setdefault("triaxial_relaxation",
                    {"skipped": True, **timing_record(dirs["triaxial_relaxation"])})
    runs["triaxial_relaxation"].update(age_counts(dirs["triaxial_relaxation"]))
    return q_max


def reproduce(out: str, quick: bool = False, threads: Optional[int] = None,
              sample: Optional[str] = None, log: Callable[[str], None] = print,
              overrides: Sequence[str] = (), parameters: str = "crushdem",
              tests: Sequence[str] = TESTS, backend: str = "cpu",
              progress: bool = False) -> Dict[str, Any]:
    """Runs the study's section 3 into ``out`` and draws its figures; returns reproduce.json.
    parameters: a named parameter set (PARAMETER_SETS); overrides: "SECTION.KEY=VALUE" changes
    of the settings on top of it (apply_overrides); backend: what advances every run ("cpu",
    "cuda" or "emulated"); tests: which of TESTS to run ("oedometric":
    the oedometric relaxation; "triaxial": the shear and the triaxial relaxation), so that two
    processes can run them side by side into one ``out`` (the sample first, by either); the
    figures and reproduce.json then cover the tests whose runs have finished. progress: the
    engine's progress lines on stderr, one every ``output.progress_seconds`` (60 s at study
    scale, none with ``quick``), with the stage, q and the share done."""
    unknown = [t for t in tests if t not in TESTS]
    if unknown or not tests:
        raise ValueError(f"--only {','.join(tests)}: expected one or more of {', '.join(TESTS)}")
    cfg = apply_overrides(settings(quick, parameters, backend), overrides)
    if sample is not None:
        if not os.path.isfile(sample):
            raise ValueError(f"--sample {sample}: no such file")
        prepared = [o for o in overrides if o.strip().startswith("sample.")]
        if prepared:
            raise ValueError(f"--set {prepared[0]}: the sample is read from --sample {sample}, "
                             "so its preparation settings do not apply; give one or the other")
        cfg["sample"] = {"file": os.path.abspath(sample)}
    os.makedirs(out, exist_ok=True)
    _keep_settings(out, cfg)
    used_threads = set_threads(threads) if threads else None

    t_start = time.perf_counter()
    runs: Dict[str, Any] = {}
    dirs = {name: os.path.join(out, name) for name in RUNS}

    # 1. The sample (or a given sample file), prepared once and read by every test.
    if sample is not None:
        sample_file = os.path.abspath(sample)
        runs["sample"] = {"skipped": True, "wall_s": 0.0, "file": sample_file}
    else:
        sample_file = run_sample(cfg, dirs["sample"], log, runs, progress)
        info = read_summary(dirs["sample"]).get("sample") or {}
        runs["sample"].update(grains=info.get("grains"), void_ratio=info.get("void_ratio"))

    # 2. Oedometric relaxation.
    if "oedometric" in tests:
        run_oedometric_relaxation(cfg, dirs["oedometric_relaxation"], sample_file, log, runs,
                                  progress=progress)
    if is_finished(dirs["oedometric_relaxation"]):
        runs.setdefault("oedometric_relaxation", {"skipped": True,
                                                  **timing_record(dirs["oedometric_relaxation"])})
        runs["oedometric_relaxation"].update(age_counts(dirs["oedometric_relaxation"]))

    # 3. Triaxial shear and relaxation.
    q_max = math.nan
    if "triaxial" in tests:
        q_max = run_triaxial(cfg, dirs, sample_file, log, runs, progress)
    elif is_finished(dirs["triaxial_relaxation"]):
        q_max = record_triaxial(dirs, runs)

    result: Dict[str, Any] = {"mode": cfg["mode"], "threads": used_threads,
                              "settings": "settings.json", **made_by(), "runs": runs}
    written = draw_figures(out, dirs, cfg, q_max, result, log)
    result["figures"] = [os.path.basename(p) for p in written]
    result["wall_s_total"] = time.perf_counter() - t_start
    write_json(os.path.join(out, "reproduce.json"), result)
    return result


def _keep_settings(out: str, cfg: Mapping[str, Any]) -> None:
    """Writes ``out``/settings.json, or, when it exists, refuses settings other than its
    own (ValueError naming each key that differs)."""
    settings_path = os.path.join(out, "settings.json")
    if os.path.isfile(settings_path):
        with open(settings_path) as f:
            before = with_earlier_defaults(json.load(f))
        changed = settings_changes(before, json.loads(json.dumps(cfg)))
        if changed:
            differ = "; ".join(f"{k} = {show_setting(a)} there, {show_setting(b)} in this call"
                               for k, (a, b) in changed.items())
            raise ValueError(f"{out} holds results made with other settings ({settings_path}: "
                             f"{differ}); give the same --parameters, --set and --sample as "
                             "the call that made them, another --out, or delete that "
                             "directory")
    else:
        with open(settings_path, "w") as f:
            json.dump(cfg, f, indent=2)
            f.write("\n")


def draw_figures(out: str, dirs: Mapping[str, str], cfg: Mapping[str, Any], q_max: float,
                 result: Dict[str, Any], log: Callable[[str], None]) -> List[str]:
    """The figures of the tests that have finished, into ``out`` (a test that another process
    still runs is left out here and drawn by the call that finishes it, or by a later one),
    each PNG with the CSV of what it draws; their numbers go into ``result``. Returns the PNG
    paths written."""
    written: List[str] = []
    oedometric = dirs["oedometric_relaxation"]
    relaxations = []
    if is_finished(oedometric):
        data = oedometric_relaxation(oedometric)
        written.append(write_figure(out, "fig1_oedometric_relaxation", data,
                                    figure_oedometric_relaxation(oedometric)))
        result["oedometric_relaxation"] = data.numbers
    else:
        log("oedometric relaxation: not finished, its figure is left out")
    if math.isfinite(q_max):
        triaxial = dirs["triaxial_relaxation"]
        data = dynamic_phase(triaxial)
        if "skipped" in data.numbers:
            log(f"Figure 2 left out: {data.numbers['skipped']}")
        else:
            written.append(write_figure(out, "fig2_dynamic_phase4", data,
                                        figure_dynamic_phase(triaxial)))
        result["dynamic_phase"] = data.numbers
        data = triaxial_relaxation(triaxial, q_max)
        written.append(write_figure(out, "fig3_triaxial_relaxation", data,
                                    figure_triaxial_relaxation(triaxial, q_max)))
        tri = data.numbers
        shear = result["runs"]["triaxial_shear"]
        tri.update(q_max_Pa=q_max, stop_q_Pa=cfg["relaxation"]["q_fraction"] * q_max,
                   q_fraction=cfg["relaxation"]["q_fraction"],
                   **{k: shear[k] for k in ("q_plateau_Pa", "q_plateau_std_Pa",
                                            "plateau_axial_strain")})
        result["triaxial_relaxation"] = tri
        relaxations.append(("triaxial relaxation", triaxial))
    else:
        log("triaxial relaxation: not finished, its figures are left out")
    if is_finished(oedometric):
        relaxations.append(("oedometric relaxation", oedometric))
    if relaxations:
        data = force_statistics(relaxations)
        written.append(write_figure(out, "fig4_force_statistics", data,
                                    figure_force_statistics(relaxations)))
        result["force_statistics"] = data.numbers
    return written


def write_figure(out: str, name: str, data: FigureData, fig: Any) -> str:
    """``out``/name.csv (the notes and columns of ``data``: what the figure draws) and
    ``out``/name.png (``fig``, then closed); returns the PNG's path."""
    from ._optional import require

    plt = require("matplotlib.pyplot", "crushdem-sand reproduce")
    write_csv(os.path.join(out, name + ".csv"), data.notes, data.columns)
    path = os.path.join(out, name + ".png")
    try:
        fig.savefig(path, dpi=150)
    finally:
        plt.close(fig)
    return path


def write_csv(path: str, comments: Sequence[str], columns: Mapping[str, Sequence[Any]]) -> None:
    """A CSV with ``#`` comment lines first (read_timeseries skips them), then a header row;
    non-finite floats are written empty."""
    names = list(columns)
    n = max((len(v) for v in columns.values()), default=0)
    with open(path, "w", newline="") as f:
        for c in comments:
            f.write(f"# {c}\n")
        w = csv.writer(f)
        w.writerow(names)
        for i in range(n):
            row = []
            for name in names:
                v = columns[name][i]
                if isinstance(v, (float, np.floating)):
                    row.append("" if not math.isfinite(float(v)) else repr(float(v)))
                elif isinstance(v, (int, np.integer)):
                    row.append(str(int(v)))
                else:
                    row.append(str(v))
            w.writerow(row)


def json_safe(x: Any) -> Any:
    """NaN and infinities become null (strict JSON); NumPy scalars become Python numbers."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def write_json(path: str, data: Any) -> None:
    """``data`` as indented strict JSON (:func:`json_safe`) with a final newline."""
    with open(path, "w") as f:
        json.dump(json_safe(data), f, indent=2)
        f.write("\n")


def made_by() -> Dict[str, str]:
    """The crushdem version and commit of this call (every run's summary.json has the engine's
    too; a directory advanced by several calls shows the last)."""
    from . import _core  # the compiled module, imported only when something runs
    return {"crushdem_version": _core.__version__, "crushdem_commit": _core.__commit__}
