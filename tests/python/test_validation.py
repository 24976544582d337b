"""Study-scale validation runs (opt-in: hours on a workstation, never in the default suite).

Set CRUSHDEM_VALIDATION_DIR to a directory; runs that have finished there (summary.json) are
reused, interrupted ones are resumed from their checkpoint, missing ones are run. The sample is
CRUSHDEM_VALIDATION_SAMPLE (a particle file, e.g. runs/sample_rev/sample.txt) or is prepared
into DIR/sample with the settings of ``crushdem-sand reproduce``. With CRUSHDEM_VALIDATION_REPRODUCE
set to the directory of a study-scale ``crushdem-sand reproduce``, its oedometric relaxation is the
N_break = 30 run and its sample the sample (nothing is run twice).

    CRUSHDEM_VALIDATION_DIR=runs/validation CRUSHDEM_VALIDATION_REPRODUCE=runs/reproduce_rev \
        .venv/bin/python -m pytest -q tests/python/test_validation.py

The N_break = 10 run branches from the N_break = 30 run at the start of its ageing (the same
loading, not repeated).
"""

import json
import os

import pytest

DIR = os.environ.get("CRUSHDEM_VALIDATION_DIR")
REPRODUCE = os.environ.get("CRUSHDEM_VALIDATION_REPRODUCE")
pytestmark = pytest.mark.skipif(not DIR, reason="opt-in: set CRUSHDEM_VALIDATION_DIR")


def _sample(pipeline):
    given = os.environ.get("CRUSHDEM_VALIDATION_SAMPLE")
    if given:
        return os.path.abspath(given)
    if REPRODUCE:
        return os.path.join(os.path.abspath(REPRODUCE), "sample", "sample.txt")
    from crushdem_sand.study import settings

    return pipeline.run_sample(settings(quick=False), os.path.join(DIR, "sample"), print, {})


def _reproduce_settings():
    """The settings of the reproduce directory (its own parameter set), or reproduce's."""
    if REPRODUCE:
        with open(os.path.join(REPRODUCE, "settings.json")) as f:
            cfg = json.load(f)
        assert cfg["mode"] == "study", f"{REPRODUCE}: a --quick reproduce"
        return cfg
    from crushdem_sand.study import settings

    return settings(quick=False)


def test_n_break_10_and_30_give_the_same_oedometric_relaxation():
    from crushdem_sand import lab
    from crushdem_sand import study_pipeline as pipeline
    from crushdem_sand.analysis import (N_BREAK_TOLERANCE, age_rows, compare_relaxation,
                                        vertical_stress)
    from crushdem_sand.rundir import read_events
    from crushdem_sand.runs import run_step

    os.makedirs(DIR, exist_ok=True)
    sample = _sample(pipeline)
    cfg = _reproduce_settings()
    runs = {30: os.path.join(REPRODUCE, "oedometric_relaxation") if REPRODUCE
            else os.path.join(DIR, "oedometric_relaxation_nbreak30"),
            10: os.path.join(DIR, "oedometric_relaxation_nbreak10")}
    cfg30 = json.loads(json.dumps(cfg))
    cfg30["age"]["n_break"] = 30
    pipeline.run_oedometric_relaxation(cfg30, runs[30], sample, print, {}, name="n_break 30")
    # N_break = 10: the same loading, so a branch of the N_break = 30 run at its ageing.
    oe = cfg["oedometric"]
    age = dict(cfg["age"], n_break=10)
    run_step("n_break 10", runs[10],
             lambda: lab.oedometric_relaxation(
                 runs[10], sample, stress=oe["stress"], strain_rate=oe["strain_rate"],
                 crushing=dict(cfg["crushing"]), age_stage=pipeline.age_stage_keys(cfg), **age,
                 material=cfg["material"], contact=cfg["contact"], output=cfg["output"],
                 branch_from=runs[30]),
             print, {}, pipeline.resumer(pipeline.backend_of(cfg)))
    curves = {}
    for n_break, out in runs.items():
        ev = read_events(out)
        idx = age_rows(ev)
        curves[n_break] = (ev["ageing_time_s"][idx], vertical_stress(ev)[idx])
    # Identical up to the first jump: the same state at t = 0.
    assert curves[10][1][0] == curves[30][1][0]
    cmp = compare_relaxation(*curves[10], *curves[30])
    print(f"N_break 10 against 30: {cmp}")
    assert cmp["t_to_s"] == pytest.approx(86400.0)
    assert cmp["max_abs_difference"] <= N_BREAK_TOLERANCE, cmp
