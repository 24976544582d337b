"""Tests of ``crushdem-sand reproduce``: its recipes (python/crushdem_sand/study.py), the analysis
of its runs (study_analysis.py, study_summary.py), its figures (figures/study.py), its pipeline
(study_pipeline.py) and the command (reproduce.py).

The figure and CSV code is tested on synthetic events.csv / phases.csv files with known answers
(the 4 s normalisation, the log-t fit), and each figure against the CSV written beside it; it
needs only NumPy and Matplotlib, and is loaded from python/crushdem_sand when this file sits in the
source tree (so the tests follow the checkout without a rebuild), otherwise from the installed
package. One end-to-end ``crushdem-sand reproduce --quick`` runs the real pipeline (about two
minutes on one core).
"""

import csv
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from _figures import (assert_drawn, assert_png_shows_a_drawing, labelled,  # noqa: E402
                      labelled_like, legend_texts, read_csv_with_comments)
from _source import load  # noqa: E402

rp, runs, analysis, study, sa, summary, pipeline, study_figures = (load(name) for name in (
    "reproduce", "runs", "analysis", "study", "study_analysis", "study_summary",
    "study_pipeline", "figures.study"))

WALLS = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")
MPA = 1e-6


def _write(path, rows):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(rows[0].keys()))
        for r in rows:
            w.writerow(list(r.values()))


def _event(t, phase, stage, sig_ax, sig_lat, std_fn, std_ft):
    r = {"ageing_time_s": t, "stage": stage, "dynamic_phase": phase, "time_s": 1e-3 + 1e-5 * phase,
         "step": 100000 + 1000 * phase, "n_particles": 1000 + 14 * phase}
    for w in WALLS:
        r[f"wall_{w}_stress_Pa"] = sig_ax if w.startswith("z") else sig_lat
    r["deviator_stress_Pa"] = sig_ax - sig_lat
    r["axial_strain"] = 0.05
    r["volumetric_strain"] = 0.02 + 1e-4 * phase
    r["mean_Fn_N"], r["std_Fn_N"] = 0.2, std_fn
    r["mean_Ft_N"], r["std_Ft_N"] = 0.03, std_ft
    r["breakages_instant"], r["breakages_crack"] = 10, 3 * phase
    return r


T_AGE = [0.0, 0.5, 2.0, 10.0, 100.0, 1000.0, 5000.0, 86400.0]


def _sigma_v(t):
    """sigma_v falling linearly in log t (exact for linear-in-log interpolation)."""
    return 7.0e6 - 0.3e6 * math.log10(t) if t > 0 else 7.5e6


def _q(t):
    return 5.0e6 - 0.25e6 * math.log10(t) if t > 0 else 5.2e6


def _oedometric_run(tmp_path, times=T_AGE):
    d = tmp_path / "oedometric_relaxation"
    rows = [_event(t, k, 1, _sigma_v(t), 0.6 * _sigma_v(t), 0.2 - 0.005 * k, 0.03 - 0.001 * k)
            for k, t in enumerate(times)]
    _write(str(d / "events.csv"), rows)
    return str(d)


def _triaxial_run(tmp_path):
    d = tmp_path / "triaxial_relaxation"
    rows = [_event(t, k, 2, 10e6 + _q(t), 10e6, 0.3 - 0.01 * k, 0.05 - 0.002 * k)
            for k, t in enumerate(T_AGE)]
    _write(str(d / "events.csv"), rows)
    return str(d)


def _written(out, name, data, fig):
    """Writes the figure and its CSV as ``crushdem-sand reproduce`` does; returns the CSV read back
    (its # lines, its rows)."""
    png = pipeline.write_figure(str(out), name, data, fig)
    assert png == os.path.join(str(out), name + ".png")
    assert_png_shows_a_drawing(png)
    return read_csv_with_comments(os.path.join(str(out), name + ".csv"))


def _column(rows, name, keep=None):
    return np.array([float(r[name]) if r[name] else math.nan for r in rows
                     if keep is None or keep(r)])


def _later(r):
    """A phase after t = 0: on the log axis."""
    return float(r["ageing_time_s"]) > 0


def test_value_at_interpolates_in_log_t_or_linear_t_before_the_first_phase():
    t = np.array([0.0, 1.0, 10.0, 100.0])
    y = np.array([9.0, 5.0, 4.0, 3.0])
    v, how = analysis.value_at(t, y, 4.0)
    assert v == pytest.approx(5.0 - math.log10(4.0))
    assert "log t" in how
    assert analysis.value_at(t, y, 10.0) == (4.0, "exact")
    # The first phase after t = 0 is later than 4 s: linear in t from the t = 0 phase.
    v, how = analysis.value_at(np.array([0.0, 100.0, 1000.0]), np.array([8.0, 6.0, 5.0]), 4.0)
    assert v == pytest.approx(8.0 + 0.04 * (6.0 - 8.0))
    assert "linear in t" in how
    v, how = analysis.value_at(t, y, 1000.0)
    assert math.isnan(v) and "beyond" in how


def test_compare_relaxation_reads_both_curves_at_common_log_times():
    # Two samplings of one curve that is straight in log t: no difference, whatever the phases.
    def line(t):
        return 7.0 * (1.0 - 0.05 * np.log10(t / 0.01))

    t_a = np.array([0.0, 0.1, 100.0, 1e4, 86400.0])
    t_b = np.array([0.0, 0.02, 3.0, 700.0, 5e4, 86400.0])
    y_a = np.concatenate([[7.0], line(t_a[1:])])
    y_b = np.concatenate([[7.0], line(t_b[1:])])
    same = analysis.compare_relaxation(t_a, y_a, t_b, y_b)
    assert same["max_abs_difference"] == pytest.approx(0.0, abs=1e-12)
    assert same["t_from_s"] == 0.1 and same["t_to_s"] == 86400.0
    # Normalised by the t = 0 value: a curve 0.02 lower (of 7) everywhere after t = 0.
    lower = analysis.compare_relaxation(t_a, y_a, t_b, y_b - np.array([0.0] + [0.14] * 5))
    assert lower["max_abs_difference"] == pytest.approx(0.02)
    assert lower["end_a"] - lower["end_b"] == pytest.approx(0.02)
    # A kink between the phases of the other run shows up where it is.
    y_kink = y_b.copy()
    y_kink[3] -= 0.35  # t = 700 s: 0.05 of sigma(0)
    kink = analysis.compare_relaxation(t_a, y_a, t_b, y_kink)
    assert kink["max_abs_difference"] == pytest.approx(0.05, rel=0.02)
    assert 300.0 < kink["at_t_s"] < 1500.0
    with pytest.raises(ValueError, match="t = 0"):
        analysis.compare_relaxation(t_a[1:], y_a[1:], t_b, y_b)


def test_fit_log_t_slope_and_r2():
    t = np.array([0.0, 1.0, 10.0, 100.0, 1000.0])
    q = np.array([99.0, 10.0, 8.0, 6.0, 4.0])  # the t = 0 point is left out of the fit
    fit = analysis.fit_log_t(t, q)
    assert fit["slope"] == pytest.approx(-2.0)
    assert fit["intercept"] == pytest.approx(10.0)
    assert fit["r2"] == pytest.approx(1.0)
    assert fit["points"] == 4
    noisy = np.array([0.0, 10.0, 8.5, 5.5, 4.0])
    fit = analysis.fit_log_t(t, noisy)
    x, y = np.log10(t[1:]), noisy[1:]
    b, a = np.polyfit(x, y, 1)
    r2 = 1.0 - np.sum((y - a - b * x) ** 2) / np.sum((y - y.mean()) ** 2)
    assert fit["slope"] == pytest.approx(b) and fit["r2"] == pytest.approx(r2)
    assert fit["r2"] < 1.0


def test_oedometric_relaxation_normalises_at_4_s(tmp_path):
    run = _oedometric_run(tmp_path)
    data = sa.oedometric_relaxation(run)
    res = data.numbers
    s4 = _sigma_v(4.0)
    assert res["sigma_v_4s_Pa"] == pytest.approx(s4)
    assert res["sigma_v_ratio_1h"] == pytest.approx(_sigma_v(3600.0) / s4)
    assert res["sigma_v_ratio_1day"] == pytest.approx(_sigma_v(86400.0) / s4)
    fig = study_figures.figure_oedometric_relaxation(run)
    comments, rows = _written(tmp_path, "fig1_oedometric_relaxation", data, fig)
    assert any("sigma_v(4 s)" in c and "log t" in c for c in comments)
    assert len(rows) == len(T_AGE)
    for r, t in zip(rows, T_AGE):
        assert float(r["ageing_time_s"]) == t
        assert float(r["sigma_v_ratio"]) == pytest.approx(_sigma_v(t) / s4)
    # sigma_v falls linearly in log t: the fit over the phases with t > 0 finds it exactly.
    assert res["fit_points"] == len(T_AGE) - 1
    assert res["ratio_slope_per_log10_t"] == pytest.approx(-0.3e6 / s4)
    assert res["r2"] == pytest.approx(1.0)
    assert rows[0]["sigma_v_ratio_fit"] == ""  # t = 0 is off the log axis
    assert float(rows[4]["sigma_v_ratio_fit"]) == pytest.approx(_sigma_v(T_AGE[4]) / s4)
    assert any("R^2 = " in c for c in comments)
    # The figure draws the CSV's phases after t = 0, the fit with its slope, sigma_v(4 s) at 1.
    (ax,) = fig.axes
    assert ax.get_xscale() == "log" and "ageing time" in ax.get_xlabel()
    assert "4" in ax.get_ylabel() and "sigma_v" in ax.get_ylabel()
    assert_drawn(labelled(ax, "dynamic phases (end)"), _column(rows, "ageing_time_s", _later),
                 _column(rows, "sigma_v_ratio", _later))
    fit = labelled_like(ax, "fit: ")
    assert f"{res['ratio_slope_per_log10_t']:+.3g} per log cycle" in fit.get_label()
    assert "$R^2$ = 1.000" in fit.get_label()
    y_fit = np.asarray(fit.get_ydata())
    assert y_fit[0] == pytest.approx(_sigma_v(0.5) / s4) and y_fit[-1] == pytest.approx(
        _sigma_v(86400.0) / s4)
    assert_drawn(labelled_like(ax, "$\\sigma_v$(4 s) = 6.82 MPa"), [4.0], [1.0])
    assert f"{7.5:.3g} MPa" in ax.get_title()


def test_a_line_through_two_phases_is_not_judged(tmp_path):
    # Fewer than N_break grains fail after the first jump: one more phase, at one day.
    run = _oedometric_run(tmp_path, times=[0.0, 18.0, 86400.0])
    data = sa.oedometric_relaxation(run)
    res = data.numbers
    assert res["fit_points"] == 2 and math.isnan(res["r2"])
    assert math.isfinite(res["ratio_slope_per_log10_t"])
    comments, _ = _written(tmp_path, "fig1_oedometric_relaxation", data,
                           study_figures.figure_oedometric_relaxation(run))
    assert any("not judged: 2 phase(s) with t > 0" in c for c in comments)
    assert "(2 phases)" in rp.format_table({"oedometric_relaxation": res})
    fig = study_figures.figure_oedometric_relaxation(run)
    assert "$R^2$ = n/a (2 points)" in labelled_like(fig.axes[0], "fit: ").get_label()


def test_sigma_v_at_4_s_before_the_first_phase_after_t_0(tmp_path):
    run = _oedometric_run(tmp_path, times=[0.0, 50.0, 3000.0, 86400.0])
    data = sa.oedometric_relaxation(run)
    expect = 7.5e6 + 4.0 / 50.0 * (_sigma_v(50.0) - 7.5e6)
    assert data.numbers["sigma_v_4s_Pa"] == pytest.approx(expect)
    assert "linear in t" in data.numbers["sigma_v_4s_method"]
    comments, _ = _written(tmp_path, "fig1_oedometric_relaxation", data,
                           study_figures.figure_oedometric_relaxation(run))
    assert any("linear in t" in c for c in comments)


def test_a_run_without_events_has_no_relaxation_figure(tmp_path):
    empty = str(tmp_path / "nothing")
    os.makedirs(empty)
    with pytest.raises(ValueError, match="no events.csv with ageing_time_s"):
        sa.oedometric_relaxation(empty)
    with pytest.raises(ValueError, match="no events.csv with ageing_time_s and deviator"):
        sa.triaxial_relaxation(empty)
    assert study_figures.figure_oedometric_relaxation(empty) is None
    assert study_figures.figure_triaxial_relaxation(empty) is None
    assert study_figures.figure_force_statistics([("x", empty)]) is None


def test_triaxial_relaxation_fit(tmp_path):
    run = _triaxial_run(tmp_path)
    data = sa.triaxial_relaxation(run, q_max=7.5e6)
    res = data.numbers
    assert res["slope_Pa_per_log10_t"] == pytest.approx(-0.25e6)
    assert res["r2"] == pytest.approx(1.0)
    assert res["fit_points"] == len(T_AGE) - 1
    assert res["q_start_Pa"] == pytest.approx(5.2e6)
    # q / q(t = 0) at 1 h (between the phases at 1000 s and 5000 s, linear in log t: exact
    # here) and at 1 day (a phase)
    assert res["q_ratio_1h"] == pytest.approx(_q(3600.0) / 5.2e6)
    assert "linear in log t" in res["q_ratio_1h_method"]
    assert res["q_ratio_1day"] == pytest.approx(_q(86400.0) / 5.2e6)
    assert res["q_ratio_1day_method"] == "exact"
    assert res["q_min_Pa"] == pytest.approx(_q(86400.0))
    fig = study_figures.figure_triaxial_relaxation(run, q_max=7.5e6)
    comments, rows = _written(tmp_path, "fig3_triaxial_relaxation", data, fig)
    assert float(rows[-1]["q_over_q_start"]) == pytest.approx(_q(86400.0) / 5.2e6)
    assert float(rows[-1]["q_over_q_max"]) == pytest.approx(_q(86400.0) / 7.5e6)
    assert any("R^2" in c for c in comments)
    assert rows[0]["q_fit_Pa"] == ""  # no fit value at t = 0
    assert float(rows[3]["q_fit_Pa"]) == pytest.approx(_q(T_AGE[3]))
    assert float(rows[1]["lateral_stress_Pa"]) == pytest.approx(10e6)
    # The figure: q [MPa] of the CSV's phases after t = 0, q(t = 0) as a level, the fit's slope
    # in MPa per log cycle, q_max in the title.
    (ax,) = fig.axes
    assert ax.get_xscale() == "log" and ax.get_ylabel() == "deviator stress $q$ [MPa]"
    assert_drawn(labelled(ax, "dynamic phases (end)"), _column(rows, "ageing_time_s", _later),
                 _column(rows, "deviator_stress_Pa", _later) * MPA)
    level = labelled(ax, "q at t = 0: 5.2 MPa")
    assert list(level.get_ydata()) == [5.2e6 * MPA] * 2
    assert "-0.25 MPa per log cycle" in labelled_like(ax, "fit: ").get_label()
    assert "$q_{max}$ = 7.5 MPa" in ax.get_title()


def test_force_statistics(tmp_path):
    tri, oed = _triaxial_run(tmp_path), _oedometric_run(tmp_path)
    relaxations = [("triaxial relaxation", tri), ("oedometric relaxation", oed)]
    data = sa.force_statistics(relaxations)
    res = data.numbers
    assert res["triaxial relaxation"]["std_Fn_N_first"] == pytest.approx(0.3)
    assert res["oedometric relaxation"]["std_Ft_N_last"] == pytest.approx(0.03 - 0.007)
    fig = study_figures.figure_force_statistics(relaxations)
    _, rows = _written(tmp_path, "fig4_force_statistics", data, fig)
    assert len(rows) == 2 * len(T_AGE)
    assert {r["test"] for r in rows} == {"triaxial relaxation", "oedometric relaxation"}
    # Each panel: one curve per test, the CSV's phases after t = 0, the t = 0 value in the
    # legend.
    ax_n, ax_t = fig.axes
    for ax, col in ((ax_n, "std_Fn_N"), (ax_t, "std_Ft_N")):
        assert len(legend_texts(ax)) == 2
        for label, _ in relaxations:
            def of_test(r, label=label):
                return r["test"] == label and _later(r)
            first = next(float(r[col]) for r in rows if r["test"] == label)
            assert_drawn(labelled(ax, f"{label} (t = 0: {first:.3g} N)"),
                         _column(rows, "ageing_time_s", of_test), _column(rows, col, of_test))
    assert "|F_n|" in ax_n.get_ylabel() and "|F_t|" in ax_t.get_ylabel()


def _phases(run, n_phases, cycles=3000, interval=250):
    rows = []
    for k in range(n_phases):
        for c in range(0, cycles + 1, interval):
            rows.append({"stage": 2, "dynamic_phase": k, "cycle": c, "ageing_time_s": 10.0 * k,
                         "time_s": 1e-3 + 1e-8 * c, "axial_stress_Pa": 15e6,
                         "lateral_stress_Pa": 10e6 * (1 + 0.01 * k * math.exp(-c / 500.0)),
                         "deviator_stress_Pa": 5e6,
                         "confining_fluctuation": 0.01 * k * math.exp(-c / 500.0),
                         "volumetric_strain_phase": 1e-5 * k * c / cycles,
                         "breakages_instant": 0, "breakages_crack": 3 * k + (3 if c else 0),
                         "n_particles": 1000 + 39 * k})
    _write(os.path.join(run, "phases.csv"), rows)


def test_dynamic_phase(tmp_path):
    run = _triaxial_run(tmp_path)
    res = sa.dynamic_phase(run).numbers
    assert "skipped" in res and "phases.csv" in res["skipped"]  # missing: skipped, no crash
    assert study_figures.figure_dynamic_phase(run) is None
    _phases(run, 3)
    res = sa.dynamic_phase(run).numbers
    assert "skipped" in res and "3 phase" in res["skipped"]
    assert study_figures.figure_dynamic_phase(run) is None
    _phases(run, 6)
    data = sa.dynamic_phase(run)
    res = data.numbers
    assert res["phase"] == 4 and res["ageing_time_s"] == pytest.approx(30.0)
    assert res["max_abs_confining_fluctuation"] == pytest.approx(0.03)
    assert res["volumetric_strain_end"] == pytest.approx(3e-5)
    fig = study_figures.figure_dynamic_phase(run)
    _, rows = _written(tmp_path, "fig2_dynamic_phase4", data, fig)
    assert [int(r["cycle"]) for r in rows] == list(range(0, 3001, 250))
    assert float(rows[0]["confining_fluctuation"]) == pytest.approx(0.03)
    # (a) the fluctuation and (b) the volumetric strain, in %, at the CSV's cycles.
    ax_a, ax_b = fig.axes
    cycles = _column(rows, "cycle")
    (fluct,) = [ln for ln in ax_a.get_lines() if len(ln.get_xdata()) > 2]
    assert_drawn(fluct, cycles, _column(rows, "confining_fluctuation") * 100.0)
    (vol,) = [ln for ln in ax_b.get_lines() if len(ln.get_xdata()) > 2]
    assert_drawn(vol, cycles, _column(rows, "volumetric_strain_phase") * 100.0)
    assert "dynamic phase 4" in ax_a.get_title() and "30 s" in ax_a.get_title()
    assert ax_b.get_xlabel() == "cycles within the dynamic phase"


def test_run_step_skips_finished_runs_and_resumes_interrupted_ones(tmp_path):
    calls, log = [], []
    record = {}
    run = tmp_path / "run"
    run.mkdir()

    def start():
        calls.append("start")
        run.mkdir(exist_ok=True)  # as a run does: into a new directory

    def resume(d, progress):
        calls.append(("resume", d, progress))

    def failing_resume(d, progress):
        raise RuntimeError("checkpoint of another build")

    runs.run_step("r", str(run), start, log.append, record, resume)  # nothing there: runs
    assert calls == ["start"] and record["r"]["skipped"] is False
    (run / "checkpoint.bin").write_bytes(b"x")
    (run / "timing.json").write_text('{"wall_seconds": 300.0}')  # summed over the run's calls
    runs.run_step("r", str(run), start, log.append, record, resume)
    assert calls[-1] == ("resume", str(run), False) and record["r"]["resumed"] is True
    assert record["r"]["wall_s"] == 300.0 and record["r"]["wall_s_this_call"] < 300.0
    runs.run_step("r", str(run), start, log.append, record, resume, progress=True)
    assert calls[-1] == ("resume", str(run), True)  # the caller's progress reaches the engine
    (run / "timing.json").unlink()
    runs.run_step("r", str(run), start, log.append, record, failing_resume)
    assert calls[-1] == "start" and record["r"]["resumed"] is False
    assert any("starting over" in m for m in log)
    assert not (run / "checkpoint.bin").exists()  # the unfinished run was removed first
    runs.run_step("r", str(run), start, log.append, record, None)  # no resume in this build
    assert calls[-1] == "start"
    (run / "summary.json").write_text("{}")
    (run / "timing.json").write_text('{"wall_seconds": 12.5}')
    n = len(calls)
    runs.run_step("r", str(run), start, log.append, record, resume)
    assert len(calls) == n and record["r"]["skipped"] and record["r"]["wall_s"] == 12.5


def _reproduce_dir(out, seed, q_plateau, q_peak, q_ratio_1day=None, rotation="blocked",
                   d0=None, sample_file=None, void_ratio=0.65, sigma_v_ratio_1day=None):
    """A reproduce directory with a finished triaxial shear: isotropic rows (stage 0, large
    strains that must not count), then the shear (stage 1) at q_peak up to 10 % axial strain
    and q_plateau +- 0.5 MPa, alternating, from 10 % to 30 % (200 rows). With q_ratio_1day, a
    finished triaxial relaxation whose reproduce.json gives it. With d0, crushing.d0 set; with
    sample_file, run on that prepared sample (--sample) instead of its own of seed ``seed``
    (prepared to ``void_ratio``)."""
    os.makedirs(out)
    settings = {"mode": "study", "contact": {"rotation": rotation},
                "sample": ({"seed": seed, "void_ratio": void_ratio} if sample_file is None
                           else {"file": str(sample_file)})}
    if d0 is not None:
        settings["crushing"] = {"d0": d0}
    with open(out / "settings.json", "w") as f:
        json.dump(settings, f)
    if sample_file is None:
        os.makedirs(out / "sample")
        with open(out / "sample" / "summary.json", "w") as f:
            json.dump({"sample": {"grains": 11000 + seed, "void_ratio": 0.652}}, f)
        with open(out / "sample" / "sample.txt", "w") as f:
            f.write(f"# a sample of seed {seed}\n")
    shear = out / "triaxial_shear"
    rows = [{"stage": 0, "stage_axial_strain": 0.25, "deviator_stress_Pa": 0.0}] * 10
    for k in range(300):
        strain = (k + 0.5) * 1e-3
        q = q_peak if strain < 0.1 else q_plateau + (0.5e6 if k % 2 else -0.5e6)
        rows.append({"stage": 1, "stage_axial_strain": strain, "deviator_stress_Pa": q})
    _write(str(shear / "timeseries.csv"), rows)
    with open(shear / "summary.json", "w") as f:
        json.dump({"particles": 30000, "stages": [
            {"type": "isotropic", "q_max_Pa": 1e5},
            {"type": "triaxial", "q_max_Pa": q_peak, "axial_strain_at_q_max": 0.05,
             "friction_angle_peak_deg": 31.0}]}, f)
    drawn = {}
    if q_ratio_1day is not None:
        drawn["triaxial_relaxation"] = {"q_ratio_1h": 0.6, "q_ratio_1day": q_ratio_1day,
                                        "r2": 0.99}
    if sigma_v_ratio_1day is not None:
        drawn["oedometric_relaxation"] = {"sigma_v_ratio_1day": sigma_v_ratio_1day, "r2": 0.98}
    for run in drawn:
        os.makedirs(out / run)
        with open(out / run / "summary.json", "w") as f:
            json.dump({}, f)
    if drawn:
        with open(out / "reproduce.json", "w") as f:
            json.dump(drawn, f)
    return str(out)


def test_shear_plateau_averages_the_shear_from_a_third_of_its_strain(tmp_path):
    d = _reproduce_dir(tmp_path / "a", 1, q_plateau=19e6, q_peak=21e6)
    p = sa.shear_plateau(os.path.join(d, "triaxial_shear"))
    assert p["plateau_rows"] == 200
    assert p["q_plateau_Pa"] == pytest.approx(19e6, rel=1e-12)
    assert p["q_plateau_std_Pa"] == pytest.approx(0.5e6, rel=1e-12)
    assert p["plateau_axial_strain"] == pytest.approx([0.2995 / 3, 0.2995])
    # A run without rows of a triaxial stage has no plateau.
    assert math.isnan(sa.shear_plateau(str(tmp_path))["q_plateau_Pa"])


def test_summarize_samples_gives_mean_spread_and_the_gap_to_the_study(tmp_path):
    dirs = [_reproduce_dir(tmp_path / "s1", 1, 19e6, 21e6, q_ratio_1day=0.5),
            _reproduce_dir(tmp_path / "s2", 2, 20e6, 22e6, q_ratio_1day=0.4,
                           sigma_v_ratio_1day=0.95),
            _reproduce_dir(tmp_path / "s3", 3, 21e6, 23e6, sigma_v_ratio_1day=0.93)]
    res = summary.summarize_samples(dirs)
    q = res["stats"]["q_max_Pa"]
    assert q["n"] == 3 and q["mean"] == pytest.approx(22e6)
    assert q["std"] == pytest.approx(1e6) and q["sem"] == pytest.approx(1e6 / math.sqrt(3))
    assert res["q_max_mean_vs_study"] == pytest.approx(22.0 / 22.6 - 1.0)
    assert res["stats"]["q_plateau_Pa"]["mean"] == pytest.approx(20e6)
    # The relaxation figures of the samples whose relaxation finished only.
    day = res["stats"]["q_ratio_1day"]
    assert day["n"] == 2 and day["mean"] == pytest.approx(0.45)
    assert math.isnan(res["samples"][2]["q_ratio_1day"])
    oed = res["stats"]["sigma_v_ratio_1day"]
    assert oed["n"] == 2 and oed["mean"] == pytest.approx(0.94)
    assert math.isnan(res["samples"][0]["sigma_v_ratio_1day"])
    assert res["samples"][2]["oedometric_r2"] == pytest.approx(0.98)
    assert math.isnan(res["samples"][2]["r2"])  # its triaxial relaxation has not run
    assert [r["seed"] for r in res["samples"]] == [1, 2, 3]
    text = rp.format_samples(res)
    assert "| mean |" in text and "22" in text and "3 samples" in text
    # The command writes both files and prints the table.
    assert rp.main(["--summarize", *dirs, "--out", str(tmp_path / "sum")]) == 0
    with open(tmp_path / "sum" / "samples.json") as f:
        assert json.load(f)["stats"]["q_max_Pa"]["n"] == 3


def test_summarize_samples_refuses_unfinished_shears_and_other_recipes(tmp_path):
    a = _reproduce_dir(tmp_path / "a", 1, 19e6, 21e6)
    os.makedirs(tmp_path / "empty")
    with pytest.raises(ValueError, match="no finished triaxial shear"):
        summary.summarize_samples([a, str(tmp_path / "empty")])
    free = _reproduce_dir(tmp_path / "free", 2, 9e6, 10e6, rotation="free")
    with pytest.raises(ValueError, match="other settings"):
        summary.summarize_samples([a, free])
    assert rp.main(["--summarize", a, free]) == 2


def test_against_pairs_two_recipes_by_sample_and_averages_the_differences(tmp_path):
    """A change of one key on the samples of the base recipe: each run paired with the base run
    on its sample (its file given by --sample, or the same seed), the differences averaged."""
    b1 = _reproduce_dir(tmp_path / "b1", 1, 19.8e6, 21.0e6)
    b2 = _reproduce_dir(tmp_path / "b2", 2, 19.9e6, 21.4e6)
    # Run with --sample on b2's prepared file.
    v2 = _reproduce_dir(tmp_path / "v2", None, 20.0e6, 21.6e6, d0=1.07e-3,
                        sample_file=tmp_path / "b2" / "sample" / "sample.txt")
    res = summary.compare_recipes([v2], [b1, b2])
    assert res["changed"] == {"crushing.d0": [None, 1.07e-3]}
    assert [p["base_dir"] for p in res["pairs"]] == [b2]
    assert res["pairs"][0]["delta_q_max_Pa"] == pytest.approx(0.2e6)
    # One run on b1's file, whichever order the base directories come in.
    v1 = _reproduce_dir(tmp_path / "v1", None, 19.9e6, 21.3e6, d0=1.07e-3,
                        sample_file=tmp_path / "b1" / "sample" / "sample.txt")
    res = summary.compare_recipes([v1, v2], [b2, b1])
    assert [p["base_dir"] for p in res["pairs"]] == [b1, b2]
    d = res["stats"]["delta_q_max_Pa"]
    assert d["n"] == 2 and d["mean"] == pytest.approx(0.25e6)
    assert d["sem"] == pytest.approx(0.05e6)
    assert res["stats"]["delta_q_plateau_Pa"]["mean"] == pytest.approx(0.1e6)
    text = rp.format_comparison(res)
    assert "crushing.d0 = (unset) -> 0.00107" in text and "+0.250" in text
    assert "2 pairs" in text
    # By seed: a variant that prepared its own sample of seed 2 (the same packing) pairs with
    # b2, beside one on b1's file.
    own = _reproduce_dir(tmp_path / "own2", 2, 20.1e6, 21.9e6, d0=1.07e-3)
    res = summary.compare_recipes([v1, own], [b1, b2])
    assert [p["base_dir"] for p in res["pairs"]] == [b1, b2]
    assert res["pairs"][1]["delta_q_max_Pa"] == pytest.approx(0.5e6)
    # Another sample recipe: a seed is another packing, so only files pair.
    other = _reproduce_dir(tmp_path / "other2", 2, 20.1e6, 21.9e6, d0=1.07e-3, void_ratio=0.7)
    with pytest.raises(ValueError, match="no directory of --against ran on its sample"):
        summary.compare_recipes([other], [b1, b2])
    # The command writes comparison.json and comparison.md.
    out = tmp_path / "cmp"
    assert rp.main(["--summarize", v1, v2, "--against", b1, b2, "--out", str(out)]) == 0
    with open(out / "comparison.json") as f:
        assert json.load(f)["stats"]["delta_q_max_Pa"]["n"] == 2
    assert os.path.getsize(out / "comparison.md") > 100


def test_against_refuses_unpaired_samples_and_identical_recipes(tmp_path, capsys):
    b1 = _reproduce_dir(tmp_path / "b1", 1, 19.8e6, 21.0e6)
    b2 = _reproduce_dir(tmp_path / "b2", 2, 19.9e6, 21.4e6)
    v3 = _reproduce_dir(tmp_path / "v3", 3, 20.0e6, 21.6e6, d0=1.07e-3)
    with pytest.raises(ValueError, match="no directory of --against ran on its sample"):
        summary.compare_recipes([v3], [b1, b2])
    with pytest.raises(ValueError, match="same settings"):
        summary.compare_recipes([b1], [b2])
    twin = _reproduce_dir(tmp_path / "twin", 1, 19.0e6, 21.0e6)
    with pytest.raises(ValueError, match="both ran on"):
        summary.compare_recipes([v3], [b1, twin])
    loose = _reproduce_dir(tmp_path / "loose", 5, 19.0e6, 21.0e6, void_ratio=0.7)
    with pytest.raises(ValueError, match="prepares its sample otherwise"):
        summary.summarize_samples([b1, loose])
    assert rp.main(["--summarize", v3, "--against", b1, b2]) == 2
    assert "v3" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        rp.main(["--against", b1])  # --against alone


def test_format_table_handles_missing_numbers():
    text = rp.format_table({"mode": "quick", "dynamic_phase": {"skipped": "no phases.csv"}})
    assert "left out" in text and "q_max" in text


def _finite(x):
    return isinstance(x, (int, float)) and math.isfinite(x)


@pytest.fixture(scope="module")
def quick_cpu(tmp_path_factory):
    """``crushdem-sand reproduce --quick`` on the CPU, one test per call (--only), as two processes
    side by side would run it: the directory and the two calls' outputs."""
    pytest.importorskip("crushdem_sand._core")
    out = tmp_path_factory.mktemp("reproduce") / "rq"
    calls = []
    for only in ("oedometric", "triaxial"):
        calls.append(subprocess.run([sys.executable, "-m", "crushdem_sand", "reproduce", "--quick",
                                     "--out", str(out), "--threads", "1", "--only", only],
                                    capture_output=True, text=True, timeout=900))
        if only == "oedometric" and calls[0].returncode == 0:
            # The first call ran the oedometric test alone.
            assert not os.path.exists(out / "triaxial_shear")
            assert os.path.isfile(out / "fig1_oedometric_relaxation.png")
            assert not os.path.exists(out / "fig3_triaxial_relaxation.png")
            with open(out / "reproduce.json") as f:
                assert "triaxial_relaxation" not in json.load(f)
    return out, calls


def test_reproduce_quick_end_to_end(quick_cpu):
    """The whole pipeline on the quick settings (about two minutes on one core)."""
    out, calls = quick_cpu
    for res in calls:
        assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    res = calls[1]
    assert "oedometric_relaxation: running" not in res.stdout
    assert "q_max" in res.stdout
    for run in study.RUNS:
        assert os.path.isfile(out / run / "summary.json"), run
    # The quick settings record phases.csv every 500 steps, and the triaxial relaxation has
    # more than four dynamic phases: all four figures, each with its CSV.
    assert os.path.isfile(out / "triaxial_relaxation" / "phases.csv")
    figures = ["fig1_oedometric_relaxation", "fig2_dynamic_phase4", "fig3_triaxial_relaxation",
               "fig4_force_statistics"]
    csv_rows = {}
    for name in figures:
        assert_png_shows_a_drawing(str(out / f"{name}.png"))
        csv_rows[name] = read_csv_with_comments(str(out / f"{name}.csv"))[1]
    with open(out / "reproduce.json") as f:
        rj = json.load(f)
    oe, tri = rj["oedometric_relaxation"], rj["triaxial_relaxation"]
    for v in (oe["sigma_v_4s_Pa"], oe["sigma_v_ratio_1h"], oe["sigma_v_ratio_1day"],
              tri["q_max_Pa"], tri["stop_q_Pa"], tri["slope_Pa_per_log10_t"], tri["r2"]):
        assert _finite(v)
    assert tri["stop_q_Pa"] == pytest.approx(0.7 * tri["q_max_Pa"])
    # The plateau: the shear's last two thirds, below its highest point.
    assert 0 < tri["q_plateau_Pa"] < tri["q_max_Pa"] and tri["q_plateau_std_Pa"] > 0
    assert tri["plateau_axial_strain"][1] == pytest.approx(3 * tri["plateau_axial_strain"][0])
    assert oe["sigma_v_ratio_1day"] > 0
    assert oe["fit_points"] >= 1
    import crushdem_sand
    assert rj["crushdem_version"] == crushdem_sand.__version__
    assert rj["crushdem_commit"] == crushdem_sand.__commit__
    for name in ("oedometric_relaxation", "triaxial_relaxation"):
        r = rj["runs"][name]
        assert r["dynamic_phases"] >= 2 and r["grains_end"] > 0 and _finite(r["wall_s"])
        # The ageing broke grains by crack growth (the point of an age stage).
        assert r["breakages_crack"] > 0 and r["threads"] == 1
    assert rj["figures"] == [f"{name}.png" for name in figures]
    # One CSV row per dynamic phase; Figure 2: phase 4 from cycle 0 to min_cycles, one row per
    # record_interval.
    phases = {name: rj["runs"][name]["dynamic_phases"]
              for name in ("oedometric_relaxation", "triaxial_relaxation")}
    assert len(csv_rows["fig1_oedometric_relaxation"]) == phases["oedometric_relaxation"]
    assert len(csv_rows["fig3_triaxial_relaxation"]) == phases["triaxial_relaxation"] >= 4
    assert len(csv_rows["fig4_force_statistics"]) == sum(phases.values())
    quick = study.settings(quick=True)
    assert [int(r["cycle"]) for r in csv_rows["fig2_dynamic_phase4"]] == list(
        range(0, quick["age"]["min_cycles"] + 1, quick["record_interval"]))
    dyn = rj["dynamic_phase"]
    assert dyn["phase"] == 4 and dyn["cycles"] == quick["age"]["min_cycles"]
    assert _finite(dyn["max_abs_confining_fluctuation"]) and _finite(dyn["volumetric_strain_end"])
    assert tri["q_max_Pa"] == rj["runs"]["triaxial_shear"]["q_max_Pa"]
    # A second call finds every run finished: nothing is run again.
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "reproduce", "--quick", "--out",
                          str(out), "--threads", "1"], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.count("not run again") == len(study.RUNS), res.stdout
    with open(out / "reproduce.json") as f:
        again = json.load(f)
    assert again["triaxial_relaxation"]["q_max_Pa"] == rj["triaxial_relaxation"]["q_max_Pa"]
    # Other settings into the same directory: refused.
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "reproduce", "--out", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "other settings" in res.stderr
    assert 'mode = "quick" there, "study" in this call' in res.stderr


def test_the_triaxial_relaxation_branches_from_the_shear_with_the_same_results(quick_cpu,
                                                                                tmp_path):
    """The relaxation starts from the shear run's state after the isotropic compression
    instead of compressing again, and its files are those of the unbranched run, byte for
    byte (the branch only skips work)."""
    out, calls = quick_cpu
    assert all(c.returncode == 0 for c in calls)
    relaxation = out / "triaxial_relaxation"
    with open(relaxation / "summary.json") as f:
        summary = json.load(f)
    assert summary["branched_from"]["stage"] == 1
    assert os.path.samefile(summary["branched_from"]["run"], out / "triaxial_shear")
    with open(out / "settings.json") as f:
        cfg = json.load(f)
    with open(out / "reproduce.json") as f:
        stop_q = json.load(f)["triaxial_relaxation"]["stop_q_Pa"]
    unbranched = tmp_path / "unbranched"
    record = {}
    installed = pytest.importorskip("crushdem_sand.study_pipeline")  # runs need the compiled engine
    installed.run_triaxial_relaxation(cfg, str(unbranched), str(out / "sample" / "sample.txt"),
                                      stop_q, lambda _msg: None, record)
    with open(unbranched / "summary.json") as f:
        assert "branched_from" not in json.load(f)
    for name in ("timeseries.csv", "events.csv", "breakage.csv", "phases.csv"):
        if os.path.isfile(relaxation / name) or os.path.isfile(unbranched / name):
            with open(relaxation / name, "rb") as a, open(unbranched / name, "rb") as b:
                assert a.read() == b.read(), name


def test_reproduce_quick_on_the_emulated_device(quick_cpu, tmp_path):
    """The whole pipeline on the device step (its host emulation: the GPU's bits without a
    GPU), from the CPU run's sample: every run finishes on that backend and lands within the
    stated statistical tolerances of the CPU's (analysis.BACKEND_TOLERANCE)."""
    cpu_out, calls = quick_cpu
    assert all(c.returncode == 0 for c in calls)
    out = tmp_path / "rq_emulated"
    sample = cpu_out / "sample" / "sample.txt"
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "reproduce", "--quick", "--out",
                          str(out), "--threads", "1", "--backend", "emulated", "--sample",
                          str(sample)], capture_output=True, text=True, timeout=1500)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    with open(cpu_out / "reproduce.json") as f:
        cpu = json.load(f)
    with open(out / "reproduce.json") as f:
        emu = json.load(f)
    for run in study.RUNS[1:]:
        with open(out / run / "timing.json") as f:
            assert json.load(f)["backend"] == "emulated", run
        assert emu["runs"][run]["grains_end"] > 0
    with open(out / "settings.json") as f:
        assert json.load(f)["backend"] == "emulated"
    tol = analysis.BACKEND_TOLERANCE
    oc, oe = cpu["oedometric_relaxation"], emu["oedometric_relaxation"]
    assert oe["sigma_v_4s_Pa"] == pytest.approx(oc["sigma_v_4s_Pa"],
                                                rel=tol["sigma_v_4s_relative"])
    assert abs(oe["sigma_v_ratio_1day"] - oc["sigma_v_ratio_1day"]) <= tol["sigma_v_ratio_1day"]
    tc, te = cpu["triaxial_relaxation"], emu["triaxial_relaxation"]
    assert te["q_max_Pa"] == pytest.approx(tc["q_max_Pa"], rel=tol["q_max_relative"])
    # The ageing broke grains by crack growth on the device too.
    for name in ("oedometric_relaxation", "triaxial_relaxation"):
        assert emu["runs"][name]["breakages_crack"] > 0
        assert emu["runs"][name]["dynamic_phases"] >= 2
    # The same directory on another backend: refused (the backends agree only statistically).
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "reproduce", "--quick", "--out",
                          str(out), "--sample", str(sample)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "other settings" in res.stderr
    assert 'backend = "emulated" there, (unset) in this call' in res.stderr


def test_set_overrides_change_settings_and_name_what_is_wrong():
    cfg = study.apply_overrides(study.settings(quick=True),
                                ["contact.rotation=blocked", "crushing.r_prime=\"2R_star\"",
                                 "age.n_break=5", "contact.rolling_friction=0"])
    assert cfg["contact"]["rotation"] == "blocked"  # a bare word is a string
    assert cfg["crushing"]["r_prime"] == "2R_star"
    assert cfg["age"]["n_break"] == 5 and isinstance(cfg["age"]["n_break"], int)
    assert cfg["contact"]["rolling_friction"] == 0
    with pytest.raises(ValueError, match="expected SECTION.KEY=VALUE"):
        study.apply_overrides(study.settings(quick=True), ["rotation=blocked"])
    with pytest.raises(ValueError, match="unknown section 'walls'"):
        study.apply_overrides(study.settings(quick=True), ["walls.x=1"])
    with pytest.raises(ValueError, match="unknown key 'cycles' in 'age'"):
        study.apply_overrides(study.settings(quick=True), ["age.cycles=1"])
    # another sample of the same recipe: its seed, and nothing the recipe lacks
    seeded = study.apply_overrides(study.settings(quick=False), ["sample.seed=2"])
    assert seeded["sample"]["seed"] == 2
    with pytest.raises(ValueError, match="unknown key 'seeds' in 'sample'"):
        study.apply_overrides(study.settings(quick=False), ["sample.seeds=2"])


def test_sample_settings_and_a_sample_file_exclude_each_other(tmp_path):
    sample = tmp_path / "sample.txt"
    sample.write_text("")
    with pytest.raises(ValueError, match="--set sample.seed=2: the sample is read from --sample"):
        pipeline.reproduce(str(tmp_path / "out"), quick=True, sample=str(sample),
                     overrides=["sample.seed=2"], log=lambda m: None)
    assert not (tmp_path / "out").exists()


def test_a_directory_of_other_settings_is_refused_naming_what_differs(tmp_path):
    out = tmp_path / "out"
    os.makedirs(out)
    with open(out / "settings.json", "w") as f:
        json.dump(study.settings(quick=True, parameters="blocked_d0_1mm"), f)
    with pytest.raises(ValueError, match="other settings") as err:
        pipeline.reproduce(str(out), quick=True, log=lambda m: None)
    msg = str(err.value)
    assert "crushing.d0 = 0.001 there, 0.00107 in this call" in msg
    assert 'parameters = "blocked_d0_1mm" there, (unset) in this call' in msg
    assert "mode" not in msg  # only what differs
    # The same settings again: accepted up to the run (here: the check only).
    assert study.apply_overrides(study.settings(quick=True), ["crushing.d0=1e-3"])["crushing"] == \
        study.settings(quick=True, parameters="blocked_d0_1mm")["crushing"]


def test_parameter_sets_are_table1_plus_the_decision_study_choice():
    chosen = study.settings(quick=False)
    table1 = study.settings(quick=False, parameters="table1")
    assert chosen["contact"]["rotation"] == "blocked" and chosen["crushing"]["d0"] == 1.07e-3
    # The set before d0 = 1.07 mm, kept by name: only d0 differs.
    before = study.settings(quick=False, parameters="blocked_d0_1mm")
    assert before["crushing"] == {**chosen["crushing"], "d0": 1e-3}
    assert before["contact"] == chosen["contact"]
    # Table 1 as printed: free rotation and d0 = d50, named (the engine's default set blocks
    # rotation and sets d0 = 1.07 mm), and recorded by name.
    assert table1["contact"]["rotation"] == "free" and table1["crushing"]["d0"] == 0.0
    assert table1["parameters"] == "table1" and "parameters" not in chosen
    # Apart from those two choices the sets are the same Table 1.
    for section in ("contact", "crushing"):
        def rest(s):
            return {k: v for k, v in s.items() if k not in ("rotation", "d0")}
        assert rest(chosen[section]) == rest(table1[section])
    with pytest.raises(ValueError, match="expected one of crushdem, blocked_d0_1mm, table1"):
        study.settings(quick=True, parameters="pfc")
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "reproduce", "--out", "x",
                          "--parameters", "pfc"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "--parameters" in res.stderr


def test_only_names_what_is_wrong(tmp_path):
    with pytest.raises(ValueError, match="expected one or more of oedometric, triaxial"):
        pipeline.reproduce(str(tmp_path / "x"), quick=True, tests=["shear"])


def test_a_run_another_process_writes_is_neither_resumed_nor_removed(tmp_path):
    """run_step leaves a directory alone while another crushdem run holds its .lock."""
    import fcntl

    run_dir = tmp_path / "busy"
    run_dir.mkdir()
    (run_dir / "checkpoint.bin").write_bytes(b"x")
    fd = os.open(run_dir / ".lock", os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # as a running crushdem holds it
        called = []
        with pytest.raises(RuntimeError, match="being written by another crushdem process"):
            runs.run_step("busy", str(run_dir), lambda: called.append(1), lambda m: None, {},
                          resume=lambda d, p: called.append(2))
        assert not called and (run_dir / "checkpoint.bin").exists()
    finally:
        os.close(fd)
    # Once the holder is gone the run is resumed as usual.
    resumed = []
    runs.run_step("busy", str(run_dir), lambda: None, lambda m: None, {},
                  resume=lambda d, p: resumed.append(d))
    assert resumed == [str(run_dir)]
