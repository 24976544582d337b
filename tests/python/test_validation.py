"""Study-scale validation runs (opt-in: hours on a workstation, never in the default suite).

Set CRUSHDEM_VALIDATION_DIR to a directory; runs that have finished there (summary.json) are
reused, interrupted ones are resumed from their checkpoint, missing ones are run. The sample is
CRUSHDEM_VALIDATION_SAMPLE (a particle file, e.g. runs/sample_rev/sample.txt) or is prepared
into DIR/sample with the settings of ``crushdem reproduce``.

    CRUSHDEM_VALIDATION_DIR=runs/validation CRUSHDEM_VALIDATION_SAMPLE=runs/sample_rev/sample.txt \
        .venv/bin/python -m pytest -q tests/python/test_validation.py
"""

import os

import pytest

DIR = os.environ.get("CRUSHDEM_VALIDATION_DIR")
pytestmark = pytest.mark.skipif(not DIR, reason="opt-in: set CRUSHDEM_VALIDATION_DIR")


def _sample(rp):
    given = os.environ.get("CRUSHDEM_VALIDATION_SAMPLE")
    if given:
        return os.path.abspath(given)
    return rp.run_sample(rp.settings(quick=False), os.path.join(DIR, "sample"), print, {})


def test_n_break_10_and_30_give_the_same_oedometric_relaxation():
    from crushdem import reproduce as rp
    from crushdem.analysis import age_rows, vertical_stress
    from crushdem.rundir import read_events

    os.makedirs(DIR, exist_ok=True)
    sample = _sample(rp)
    curves = {}
    for n_break in (30, 10):
        # The reproduce settings with this N_break.
        cfg = rp.settings(quick=False)
        cfg["age"]["n_break"] = n_break
        out = os.path.join(DIR, f"oedometric_relaxation_nbreak{n_break}")
        rp.run_oedometric_relaxation(cfg, out, sample, print, {}, name=f"n_break {n_break}")
        ev = read_events(out)
        idx = age_rows(ev)
        curves[n_break] = (ev["ageing_time_s"][idx], vertical_stress(ev)[idx])
    # Identical up to the first jump: the same state at t = 0.
    assert curves[10][1][0] == curves[30][1][0]
    cmp = rp.compare_relaxation(*curves[10], *curves[30])
    print(f"N_break 10 against 30: {cmp}")
    assert cmp["t_to_s"] == pytest.approx(86400.0)
    assert cmp["max_abs_difference"] <= rp.N_BREAK_TOLERANCE, cmp
