"""Tests of ``crushdem-sand plot`` (python/crushdem_sand/plot.py) on small synthetic run
directories: which figures a run gets, what each draws (its lines read back from the matplotlib
Figure against the run's time series, events.csv, grading.csv and summary.json), and that the PNGs
show a drawing.

Run with `python -m pytest tests/python` after `pip install .`. The plotting module needs only
NumPy and Matplotlib, not the compiled ``crushdem_sand._core``: when this file sits in the source
tree the module is loaded from python/crushdem_sand/plot.py (so the tests follow the checkout
without a rebuild), otherwise from the installed package.
"""

import csv
import json
import math
import os

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from _figures import (assert_drawn, assert_png_shows_a_drawing, labelled,  # noqa: E402
                      labelled_like, legend_texts)
from _source import load  # noqa: E402

plot = load("plot")
analysis = load("analysis")
figures = load("figures")
rundir = load("rundir")

WALLS = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")
MPA = 1e-6
OLD_FIGURES = {"stress_time.png", "strain_stress.png", "void_ratio.png", "coordination.png",
               "kinetic_energy.png"}
LAB_FIGURES = {"triaxial.png", "oedometer.png", "inertial_number.png", "preparation.png"}
CRUSHING_FIGURES = {"grading.png", "breakage.png", "breakage_sizes.png"}


def _row(t, sig_lat, sig_ax, eps_a, eps_v, e, **extra):
    """One time-series row with wall stresses (lateral walls sig_lat, z walls sig_ax) [Pa]."""
    r = {"time_s": t, "step": int(round(t * 1e8))}
    for w in WALLS:
        r[f"wall_{w}_stress_Pa"] = sig_ax if w.startswith("z") else sig_lat
        r[f"wall_{w}_position_m"] = 0.0 if w.endswith("min") else 1e-3
    r["mean_stress_Pa"] = (2.0 * sig_lat + sig_ax) / 3.0
    r["deviator_stress_Pa"] = sig_ax - sig_lat
    r["axial_strain"] = eps_a
    r["volumetric_strain"] = eps_v
    r["void_ratio"] = e
    r["coordination_number"] = 4.5
    r["kinetic_energy_J"] = 1e-9 * (1.0 + t * 1e3)
    r.update(extra)
    return r


def _write_run(path, rows, summary=None):
    os.makedirs(path, exist_ok=True)
    header = list(rows[0].keys())
    with open(os.path.join(path, "timeseries.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow(["" if isinstance(r[h], float) and math.isnan(r[h]) else r[h]
                        for h in header])
    if summary is not None:
        with open(os.path.join(path, "summary.json"), "w") as f:
            json.dump(summary, f)
    return str(path)


def _stage_summary(name, kind, **extra):
    s = {"name": name, "type": kind, "end": "target", "steps": 1000, "q_max_Pa": 0.0,
         "axial_strain_at_q_max": 0.0, "friction_angle_peak_deg": 0.0, "K0_end": 1.0,
         "max_inertial_number": 2e-4, "warning": ""}
    s.update(extra)
    return s


def _triaxial_run(path, with_summary=True):
    """Isotropic compression to 1 MPa, then triaxial compression to 5 % axial strain."""
    rows = []
    t = 0.0
    for p in np.linspace(0.1e6, 1.0e6, 10):
        eps = 0.003 * (p - 0.1e6) / 0.9e6
        rows.append(_row(t, p, p, eps, 3 * eps, 0.75 - 2 * eps, stage=0,
                         stage_axial_strain=eps, inertial_number=3e-4 - 1e-4 * eps / 0.003))
        t += 1e-5
    eps0, ev0 = rows[-1]["axial_strain"], rows[-1]["volumetric_strain"]
    for ea in np.linspace(0.0, 0.05, 21):
        q = 0.8e6 * ea / (0.005 + ea) * (1.0 + 0.2 * math.exp(-((ea - 0.02) / 0.008) ** 2))
        dev = 0.2 * ea - 8.0 * ea ** 2  # contraction, then dilation
        rows.append(_row(t, 1.0e6, 1.0e6 + q, eps0 + ea, ev0 + dev, 0.744 - 1.74 * dev, stage=1,
                         stage_axial_strain=ea, inertial_number=4e-4))
        t += 1e-5
    summary = None
    if with_summary:
        summary = {"steps": 31000, "stages": [
            _stage_summary("isotropic", "isotropic"),
            _stage_summary("triaxial", "triaxial", q_max_Pa=0.85e6, axial_strain_at_q_max=0.021,
                           sigma_3_at_q_max_Pa=1.0e6, friction_angle_peak_deg=17.2,
                           K0_end=0.55),
        ]}
    return _write_run(path, rows, summary)


def _oedometer_run(path):
    """Oedometric loading to 2 MPa, unloading to 1 MPa, then a hold (inertial number 0)."""
    rows = []
    t = 0.0
    k0_load, k0_unload = 0.6, 0.85
    for sv in np.geomspace(0.1e6, 2.0e6, 15):
        eps = 0.004 * math.log10(sv / 0.1e6)
        rows.append(_row(t, k0_load * sv, sv, eps, eps, 0.75 - 1.75 * eps, stage=0,
                         stage_axial_strain=eps, inertial_number=2e-4))
        t += 1e-5
    eps_top = rows[-1]["axial_strain"]
    for sv in np.geomspace(2.0e6, 1.0e6, 8):
        eps = eps_top - 0.001 * math.log10(2.0e6 / sv)
        rows.append(_row(t, k0_unload * sv, sv, eps, eps, 0.75 - 1.75 * eps, stage=1,
                         stage_axial_strain=eps - eps_top, inertial_number=1e-4))
        t += 1e-5
    last = dict(rows[-1])
    for _ in range(3):
        r = dict(last, time_s=t, stage=2, stage_axial_strain=0.0, inertial_number=0.0)
        rows.append(r)
        t += 1e-5
    summary = {"stages": [
        _stage_summary("oedometric", "oedometric", K0_end=k0_load),
        _stage_summary("oedometric", "oedometric", K0_end=k0_unload),
        _stage_summary("hold", "hold", K0_end=k0_unload, max_inertial_number=0.0),
    ]}
    return _write_run(path, rows, summary)


def _plain_run(path):
    """A run without laboratory stages: wall-driven compression, the old columns only."""
    rows = [_row(i * 1e-5, 0.5e6 * (i + 1), 0.6e6 * (i + 1), 0.001 * i, 0.002 * i,
                 0.8 - 0.002 * i) for i in range(12)]
    return _write_run(path, rows, {"steps": 1200})


def _names(paths):
    return {os.path.basename(p) for p in paths}


def _plots(run, out=None):
    """``crushdem-sand plot`` of ``run`` into ``out`` (default: the run directory): the names of the
    PNGs written there, each checked to show a drawing."""
    written = plot.make_plots(run, None if out is None else str(out))
    for p in written:
        assert os.path.dirname(os.path.abspath(p)) == os.path.abspath(out or run)
        assert_png_shows_a_drawing(p, 0.8 if p.endswith("stress_field.png") else 0.5)
    return _names(written)


def _close(fig):
    import matplotlib.pyplot as plt

    plt.close(fig)


def _check_triaxial_figures(run):
    """triaxial.png: the shear's q [MPa] and volumetric strain change [%] against its axial
    strain [%], its peak from summary.json; q_p_path.png: each stage's q against p [MPa]."""
    data = rundir.read_run(run)
    d, shear = data.timeseries, data.timeseries["stage"] == 1
    fig = figures.figure_triaxial(data)
    ax_q, ax_v = fig.axes
    eps = d["stage_axial_strain"][shear] * 100.0
    assert_drawn(labelled(ax_q, "stage 1: triaxial, $\\sigma_3$ = 1 MPa"), eps,
                 d["deviator_stress_Pa"][shear] * MPA)
    (peak,) = [ln for ln in ax_q.get_lines() if len(ln.get_xdata()) == 1]
    assert_drawn(peak, [0.021 * 100.0], [0.85e6 * MPA])
    (note,) = [t.get_text() for t in ax_q.texts]
    assert "$q_{max}$ = 0.85 MPa at $\\varepsilon_a$ = 2.10 %" in note and "17.2" in note
    ev = d["volumetric_strain"][shear]
    assert_drawn(labelled(ax_v, "stage 1: triaxial"), eps, (ev - ev[0]) * 100.0)
    assert ax_q.get_ylabel().startswith("deviator stress") and "%" in ax_v.get_xlabel()
    _close(fig)
    fig = figures.figure_q_p_path(data)
    (ax,) = fig.axes
    for k, name in ((0, "isotropic"), (1, "triaxial")):
        rows = d["stage"] == k
        assert_drawn(labelled(ax, f"stage {k}: {name}"), d["mean_stress_Pa"][rows] * MPA,
                     d["deviator_stress_Pa"][rows] * MPA)
    _close(fig)


def test_triaxial_run_writes_lab_figures(tmp_path):
    run = _triaxial_run(tmp_path / "triaxial")
    names = _plots(run, tmp_path / "figs")
    assert OLD_FIGURES <= names
    assert {"triaxial.png", "q_p_path.png", "inertial_number.png"} <= names
    assert "oedometer.png" not in names
    assert "preparation.png" not in names
    _check_triaxial_figures(run)


def test_triaxial_without_summary_still_plots(tmp_path):
    # Without summary.json the stage types are unknown: no triaxial.png, but no failure either.
    run = _triaxial_run(tmp_path / "triaxial", with_summary=False)
    names = _plots(run, tmp_path / "figs")
    assert OLD_FIGURES <= names
    assert {"q_p_path.png", "inertial_number.png"} <= names
    assert "triaxial.png" not in names


def test_stopped_run_takes_its_stage_types_from_config_toml(tmp_path):
    # A run stopped with a checkpoint (or still going) has no summary.json, only config.toml.
    run = _oedometer_run(tmp_path / "stopped")
    os.remove(os.path.join(run, "summary.json"))
    assert "oedometer.png" not in _plots(run, tmp_path / "none")
    with open(os.path.join(run, "config.toml"), "w") as f:
        f.write('[[stage]]\ntype = "oedometric"\nname = "loading"\nstress = 2e6\n'
                '[[stage]]\ntype = "oedometric"\nname = "unloading"\nstress = 1e6\n'
                '[[stage]]\ntype = "hold"\nname = "hold"\nsteps = 10\n')
    assert plot.stages_from_config(run) == [{"type": "oedometric", "name": "loading"},
                                            {"type": "oedometric", "name": "unloading"},
                                            {"type": "hold", "name": "hold"}]
    assert "oedometer.png" in _plots(run, tmp_path / "figs")


def test_oedometer_run_writes_oedometer_figure(tmp_path):
    run = _oedometer_run(tmp_path / "oedometer")
    names = _plots(run)  # default: into the run directory
    assert {"oedometer.png", "void_ratio.png", "q_p_path.png", "inertial_number.png"} <= names
    assert "triaxial.png" not in names
    # e against sigma_v [MPa] of the two oedometric stages, each with its direction and K0; the
    # hold stage is no oedometric stage.
    d = rundir.read_run(run).timeseries
    fig = figures.figure_oedometer(run)
    (ax,) = fig.axes
    assert ax.get_xscale() == "log" and len(ax.get_lines()) == 2
    for k, label in ((0, "stage 0: oedometric, loading, $K_0$ = 0.600"),
                     (1, "stage 1: oedometric, unloading, $K_0$ = 0.850")):
        rows = d["stage"] == k
        assert_drawn(labelled(ax, label), d["wall_zmax_stress_Pa"][rows] * MPA,
                     d["void_ratio"][rows])
    _close(fig)


def test_preparation_run_writes_preparation_figure(tmp_path):
    rows = []
    for i in range(20):
        mu = 0.5 if i < 8 else (0.3 if i < 14 else 0.18)
        rows.append(_row(i * 1e-5, 1e3 * (i + 1), 1e3 * (i + 1), 0.01 * i, 0.03 * i,
                         3.0 - 0.11 * i, friction=mu if i < 19 else 0.5, phase=0 if i < 19 else 2))
    summary = {"sample": {"grains": 100, "void_ratio": 0.91, "void_ratio_target": 0.9,
                          "preparation_friction": 0.18, "warning": ""}}
    run = _write_run(tmp_path / "sample", rows, summary)
    names = _plots(run, tmp_path / "figs")
    assert "preparation.png" in names
    assert "triaxial.png" not in names and "oedometer.png" not in names
    # The void ratio with its target and the prepared value; the friction in steps, with the
    # preparation friction.
    d = rundir.read_run(run).timeseries
    fig = figures.figure_preparation(run)
    ax_e, ax_mu = fig.axes
    assert_drawn(labelled(ax_e, "void ratio $e$"), d["time_s"], d["void_ratio"])
    assert list(labelled(ax_e, "target $e$ = 0.9").get_ydata()) == [0.9, 0.9]
    assert_drawn(labelled(ax_e, "prepared $e$ = 0.91"), [d["time_s"][-1]], [0.91])
    mu = labelled(ax_mu, "grain friction $\\mu$")
    assert_drawn(mu, d["time_s"], d["friction"])
    assert mu.get_drawstyle() == "steps-post"
    assert list(labelled(ax_mu, "preparation friction = 0.18").get_ydata()) == [0.18, 0.18]
    _close(fig)


def test_plain_run_keeps_old_figures(tmp_path):
    run = _plain_run(tmp_path / "plain")
    names = _plots(run, tmp_path / "figs")
    assert OLD_FIGURES <= names
    assert not names & LAB_FIGURES
    # Each wall's stress and the mean stress [MPa] against time, a panel per axis (see
    # test_opposite_walls_are_both_visible); e against p on a log axis.
    d = rundir.read_run(run).timeseries
    fig = figures.figure_stress_time(run)
    assert [ax.get_title() for ax in fig.axes] == ["x walls", "y walls", "z walls"]
    for ax, axis in zip(fig.axes, "xyz"):
        for w in (axis + "min", axis + "max"):
            assert_drawn(labelled(ax, w), d["time_s"], d[f"wall_{w}_stress_Pa"] * MPA)
        assert_drawn(labelled(ax, "mean $p$"), d["time_s"], d["mean_stress_Pa"] * MPA)
        assert "[MPa]" in ax.get_ylabel()
    assert fig.axes[-1].get_xlabel() == "time $t$ [s]"
    _close(fig)
    fig = figures.figure_void_ratio(run)
    (ax,) = fig.axes
    (line,) = ax.get_lines()
    assert_drawn(line, d["mean_stress_Pa"] * MPA, d["void_ratio"])
    assert ax.get_xscale() == "log"
    _close(fig)


def test_plain_run_without_summary(tmp_path):
    run = _plain_run(tmp_path / "plain")
    os.remove(os.path.join(run, "summary.json"))
    assert OLD_FIGURES <= _plots(run, tmp_path / "figs")


def _marker_positions(line):
    """The x of the points of ``line`` that carry a marker (its ``markevery``)."""
    x = np.asarray(line.get_xdata(), dtype=float)
    every = line.get_markevery()
    if every is None:
        return x
    start, step = every if isinstance(every, tuple) else (0, every)
    return x[start::step]


def test_opposite_walls_are_both_visible(tmp_path):
    # The walls of an axis carry the same stress in these runs (and nearly so in most): each
    # pair is drawn so that both show, solid and dashed, with markers of other shapes and fills
    # at other points, and the pairs of the three axes in panels of their own.
    import matplotlib.colors as mcolors

    for run in (_plain_run(tmp_path / "plain"), _oedometer_run(tmp_path / "oedometer")):
        fig = figures.figure_stress_time(run)
        assert len(fig.axes) == 3
        for ax, axis in zip(fig.axes, "xyz"):
            low, high = labelled(ax, axis + "min"), labelled(ax, axis + "max")
            np.testing.assert_array_equal(low.get_ydata(), high.get_ydata())  # on each other
            assert low.get_linestyle() == "-" and high.get_linestyle() == "--"
            assert low.get_linewidth() > high.get_linewidth()  # the solid one shows around
            assert low.get_marker() != high.get_marker()
            assert mcolors.to_hex(low.get_color()) == mcolors.to_hex(high.get_color())
            assert high.get_markerfacecolor() == "none" != low.get_markerfacecolor()
            assert not set(_marker_positions(low)) & set(_marker_positions(high))
            assert {axis + "min", axis + "max", "mean $p$"} <= set(legend_texts(ax))
            # The other axes' walls are not on this panel.
            assert not [ln for ln in ax.get_lines() if ln.get_label()[:1] in set("xyz") - {axis}]
        _close(fig)
    # Many rows: markers spread along the curve, a dozen or so, still alternating.
    rows = [_row(i * 1e-6, 1e6, 2e6, 0.0, 0.0, 0.7) for i in range(240)]
    fig = figures.figure_stress_time(_write_run(tmp_path / "long", rows))
    low, high = labelled(fig.axes[0], "xmin"), labelled(fig.axes[0], "xmax")
    assert 10 <= len(_marker_positions(low)) <= 14
    assert not set(_marker_positions(low)) & set(_marker_positions(high))
    _close(fig)


def test_oedometric_strain_stress_is_the_stress_path(tmp_path):
    # An oedometer's volumetric strain is its axial strain (the lateral walls do not move): a
    # 1:1 line says nothing. Its strain_stress.png draws sigma_v and sigma_h against the axial
    # strain and the stress path sigma_h against sigma_v, with each stage's K0 line.
    run = _oedometer_run(tmp_path / "oedometer")
    data = rundir.read_run(run)
    d = data.timeseries
    assert [k for k, _, _ in figures.oedometric_stages(data)] == [0, 1, 2]
    fig = figures.figure_strain_stress(data)
    ax_e, ax_p = fig.axes
    assert ax_e.get_xlabel() == "axial strain $\\varepsilon_a$ [%]"
    assert ax_p.get_xlabel() == "vertical stress $\\sigma_v$ [MPa]"
    assert ax_p.get_ylabel() == "lateral stress $\\sigma_h$ [MPa]"
    assert not any("volumetric" in ax.get_ylabel() for ax in fig.axes)
    sigma_v = analysis.vertical_stress(d) * MPA
    sigma_h = analysis.lateral_stress(d) * MPA
    for k, label in ((0, "stage 0: oedometric, loading, $K_0$ = 0.600"),
                     (1, "stage 1: oedometric, unloading, $K_0$ = 0.850")):
        rows = d["stage"] == k
        assert_drawn(labelled(ax_p, label), sigma_v[rows], sigma_h[rows])
        assert_drawn(labelled(ax_e, label), d["axial_strain"][rows] * 100.0, sigma_v[rows])
    # The K0 lines, from the origin to the largest sigma_v, and the isotropic line.
    top = float(np.max(sigma_v))
    k0_lines = sorted(tuple(ln.get_ydata()) for ln in ax_p.get_lines()
                      if ln.get_linestyle() == "--")
    assert k0_lines == [(0.0, 0.6 * top), (0.0, 0.85 * top)]
    assert list(labelled(ax_p, "$\\sigma_h = \\sigma_v$ (isotropic)").get_ydata()) == [0.0, top]
    _close(fig)
    # A triaxial test keeps q against axial strain with its volumetric strain.
    tri = rundir.read_run(_triaxial_run(tmp_path / "triaxial"))
    assert figures.oedometric_stages(tri) == []
    fig = figures.figure_strain_stress(tri)
    ax_q, ax_v = fig.axes
    assert ax_v.get_ylabel().startswith("volumetric strain")
    assert labelled(ax_q, "deviator $q$") is not None
    _close(fig)


def _crushing_run(path, breakages=True):
    """Isotropic compression then triaxial compression with grain crushing: the time series with
    the crushing columns, grading.csv (one row per time-series row), breakage.csv, summary.json."""
    rng = np.random.default_rng(7)
    sieves = np.geomspace(1e-5, 1e-3, 16)
    d50, n0 = 0.6e-3, 400
    rows, grading, broken = [], [], []
    t, n_inst, n_crack, n_part, removed = 0.0, 0, 0, n0, 0.0
    plan = [(0, ea) for ea in np.linspace(0.0, 0.004, 8)] + \
           [(1, 0.004 + ea) for ea in np.linspace(0.0, 0.08, 25)]
    for i, (stage, ea) in enumerate(plan):
        new_inst = int(rng.poisson(3.0 * ea / 0.08 * 10)) if i else 0
        new_crack = int(rng.poisson(2.0 * ea / 0.08 * 10)) if i else 0
        for cause, count in (("instant", new_inst), ("crack", new_crack)):
            for _ in range(count):
                dia = d50 * math.exp(rng.normal(0.0, 0.25)) * (0.5 if cause == "crack" else 1.0)
                broken.append([t, int(t * 1e8), len(broken), dia, cause, 4e9, 3.8e9, 14, 3,
                               " ".join(str(n_part + k) for k in range(14)), 1e-3, 2e-3,
                               3e-3])
        n_inst += new_inst
        n_crack += new_crack
        n_part += 11 * (new_inst + new_crack)
        removed += 1e-12 * (new_inst + new_crack)
        br = min(1.0, 0.35 * ea / 0.084)
        e = 0.75 - 0.5 * ea
        sig_lat = 0.2e6 + 0.8e6 * min(ea / 0.004, 1.0)
        rows.append(_row(t, sig_lat, sig_lat + (1.2e6 * (ea - 0.004) / 0.02 if stage else 0.0),
                         ea, 1.5 * ea, e, stage=stage, stage_axial_strain=ea - (0.004 * stage),
                         n_particles=n_part, breakages_instant=n_inst, breakages_crack=n_crack,
                         removed_volume_m3=removed, removed_mass_kg=2650.0 * removed,
                         void_ratio_with_fines=e - 0.02 * br, relative_breakage_Br=br))
        # Grading: the initial log-normal curve shifted towards the fines as B_r grows.
        f0 = 0.5 * (1.0 + np.vectorize(math.erf)(np.log(sieves / d50) / (0.25 * math.sqrt(2))))
        fines = br * (np.log(sieves / 1e-5) / np.log(1e-3 / 1e-5)) ** 2
        grading.append([t, int(t * 1e8)] + list(np.clip(f0 + (1.0 - f0) * fines, 0.0, 1.0)))
        t += 1e-5
    run = _write_run(path, rows, {
        "stages": [_stage_summary("isotropic", "isotropic"),
                   _stage_summary("triaxial", "triaxial", q_max_Pa=4.8e6,
                                  axial_strain_at_q_max=0.08, sigma_3_at_q_max_Pa=1.0e6)],
        "crushing": {"d50_initial_m": d50, "d0_m": 1e-3, "d_c_m": 0.55 * d50,
                     "breakages_instant": n_inst, "breakages_crack": n_crack,
                     "removed_volume_m3": removed, "relative_breakage_Br": rows[-1][
                         "relative_breakage_Br"]}})
    with open(os.path.join(run, "grading.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time_s", "step"] + [f"passing_{s:.4e}_m" for s in sieves])
        w.writerows(grading)
    with open(os.path.join(run, "breakage.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time_s", "step", "id", "diameter_m", "cause", "sigma_Pa", "sigma_lim_Pa",
                    "fragments", "removed_fragments", "fragment_ids", "x_m", "y_m", "z_m"])
        if breakages:
            w.writerows(broken)
    return run


def test_crushing_run_writes_crushing_figures(tmp_path):
    run = _crushing_run(tmp_path / "crushing")
    names = _plots(run, tmp_path / "figs")
    assert CRUSHING_FIGURES <= names
    assert {"triaxial.png", "void_ratio.png"} <= names
    data = rundir.read_run(run)
    d, (sieves, passing) = data.timeseries, data.grading
    # grading.png: the initial and final curves [%] against d [mm], each with B_r, and d_c.
    fig = figures.figure_grading(data)
    (ax,) = fig.axes
    assert_drawn(labelled(ax, "initial, $B_r$ = 0.000"), sieves * 1e3, passing[0] * 100.0)
    final = labelled_like(ax, "final")
    assert_drawn(final, sieves * 1e3, passing[-1] * 100.0)
    assert final.get_label().endswith(f"$B_r$ = {d['relative_breakage_Br'][-1]:.3f}")
    assert "$d_c$ = 0.33 mm" in legend_texts(ax)
    _close(fig)
    # breakage.png: the cumulative breakages by cause and the particles against axial strain.
    fig = figures.figure_breakage(data)
    ax_top, ax_bottom = fig.axes[:2]
    eps = d["axial_strain"] * 100.0
    assert_drawn(labelled(ax_top, "breakages: instant failure"), eps, d["breakages_instant"])
    assert_drawn(labelled(ax_top, "breakages: crack"), eps, d["breakages_crack"])
    assert_drawn(labelled(ax_bottom, "relative breakage $B_r$"), eps, d["relative_breakage_Br"])
    _close(fig)
    # breakage_sizes.png: every broken grain counted once, by cause.
    fig = figures.figure_breakage_sizes(data)
    (ax,) = fig.axes
    counts = {c: sum(1 for _, cause in data.breakage if cause == c) for c in ("instant", "crack")}
    assert sum(p.get_height() for p in ax.patches) == len(data.breakage) > 10
    assert legend_texts(ax)[:2] == [f"instant ({counts['instant']})", f"crack ({counts['crack']})"]
    assert ax.get_title().endswith(f"({len(data.breakage)})")
    _close(fig)


def test_crushing_run_without_breakages_has_no_size_histogram(tmp_path):
    # breakage.csv with its header only: grading and breakage curves, but no histogram.
    run = _crushing_run(tmp_path / "crushing", breakages=False)
    names = _plots(run, tmp_path / "figs")
    assert {"grading.png", "breakage.png"} <= names
    assert "breakage_sizes.png" not in names


def test_crushing_grading_with_mismatched_rows(tmp_path):
    # grading.csv shorter than the time series: only the first and last curves, no failure.
    run = _crushing_run(tmp_path / "crushing")
    path = os.path.join(run, "grading.csv")
    with open(path) as f:
        lines = f.readlines()
    with open(path, "w") as f:
        f.writelines(lines[:-3])
    assert "grading.png" in _plots(run, tmp_path / "figs")


def test_crushing_reads_grading_and_breakage(tmp_path):
    run = _crushing_run(tmp_path / "crushing")
    sieves, passing = plot.read_grading(run)
    assert sieves.shape == (16,) and np.all(np.diff(sieves) > 0)
    assert sieves[0] == pytest.approx(1e-5) and sieves[-1] == pytest.approx(1e-3)
    assert passing.shape[1] == 16 and np.all((passing >= 0) & (passing <= 1))
    broken = plot.read_breakage(run)
    assert broken and {c for _, c in broken} <= {"instant", "crack"}
    assert all(dia > 0 for dia, _ in broken)


def test_run_without_crushing_has_no_crushing_figures(tmp_path):
    for run in (_plain_run(tmp_path / "plain"), _triaxial_run(tmp_path / "triaxial"),
                _oedometer_run(tmp_path / "oedometer")):
        names = _plots(run, tmp_path / "figs" / os.path.basename(run))
        assert names and not names & CRUSHING_FIGURES


def test_main_prints_written_paths(tmp_path, capsys):
    run = _oedometer_run(tmp_path / "oedometer")
    out = tmp_path / "figs"
    assert plot.main([run, "--out", str(out)]) == 0
    printed = capsys.readouterr().out.split()
    assert os.path.join(str(out), "oedometer.png") in printed
    assert all(os.path.isfile(p) for p in printed)


def test_main_missing_directory(tmp_path, capsys):
    assert plot.main([str(tmp_path / "missing")]) == 2
    assert "error" in capsys.readouterr().err


AGEING_FIGURES = {"relaxation.png", "relaxation_forces.png", "relaxation_breakage.png"}


def _ageing_run(path, creep=False, events=True):
    """Oedometric loading to 7.5 MPa, then an "age" stage of one day: timeseries.csv with the
    ``stage`` and ``ageing_time_s`` columns, events.csv with one row per dynamic phase (ageing
    time 0, then growing jumps), summary.json. In creep the vertical stress is held and the axial
    strain grows; in relaxation the strain is fixed and the vertical stress decays."""
    rows, phases = [], []
    t = 0.0
    for sv in np.geomspace(0.1e6, 7.5e6, 10):
        eps = 0.01 * math.log10(sv / 0.1e6)
        rows.append(_row(t, 0.55 * sv, sv, eps, eps, 0.72 - 1.72 * eps, stage=0,
                         ageing_time_s=0.0, n_particles=1500, breakages_instant=0,
                         breakages_crack=0))
        t += 1e-5
    eps0 = rows[-1]["axial_strain"]
    ages = [0.0] + list(np.geomspace(2.0, 86400.0, 14))
    n_inst, n_crack, n_part = 3, 0, 1500
    for j, age in enumerate(ages):
        decay = 1.0 - 0.03 * math.log10(1.0 + age)
        sv = 7.5e6 if creep else 7.5e6 * decay
        eps = eps0 + (0.002 * math.log10(1.0 + age) if creep else 0.0)
        if j:
            n_crack += 10
            n_inst += j % 2
            n_part += 11 * (10 + j % 2)
        extra = dict(stage=1, ageing_time_s=age, n_particles=n_part, breakages_instant=n_inst,
                     breakages_crack=n_crack, mean_Fn_N=2.0 * decay, std_Fn_N=2.5 * decay ** 2,
                     mean_Ft_N=0.4 * decay ** 3, std_Ft_N=0.5 * decay ** 4,
                     removed_volume_m3=0.0, removed_mass_kg=0.0, void_ratio_with_fines=0.6,
                     relative_breakage_Br=0.01 * j)
        r = _row(t, 0.55 * sv, sv, eps, eps, 0.72 - 1.72 * eps, **extra)
        rows.append({k: v for k, v in r.items() if k in rows[0]})
        phases.append(dict({"ageing_time_s": age, "stage": 1, "dynamic_phase": j},
                           **{k: v for k, v in r.items() if k != "stage"
                              and k != "ageing_time_s"}))
        t += 2e-4
    summary = {"stages": [
        _stage_summary("loading", "oedometric", K0_end=0.55),
        _stage_summary("relaxation", "age", dynamic_phases=len(ages), ageing_time_s=ages[-1]),
    ]}
    run = _write_run(path, rows, summary)
    if events:
        with open(os.path.join(run, "events.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(list(phases[0].keys()))
            for ph in phases:
                w.writerow(list(ph.values()))
    return run


def test_ageing_run_writes_relaxation_figures(tmp_path):
    run = _ageing_run(tmp_path / "relaxation")
    names = _plots(run, tmp_path / "figs")
    assert AGEING_FIGURES <= names
    assert "oedometer.png" in names
    # relaxation.png: every wall fixed, so sigma_v / sigma_v(4 s) at the phases after t = 0,
    # with its value at one day and the plausible band there.
    ev = rundir.read_events(run)
    t, later = ev["ageing_time_s"], ev["ageing_time_s"] > 0
    s4, _ = analysis.value_at(t, ev["wall_zmax_stress_Pa"], 4.0)
    fig = figures.figure_relaxation(run)
    ax = fig.axes[0]
    curve = labelled_like(ax, f"$\\sigma_v$(4 s) = {s4 * MPA:.2f} MPa, 1 day: ")
    assert_drawn(curve, t[later], ev["wall_zmax_stress_Pa"][later] / s4)
    assert any("plausible at 1 day: 0.70-0.97" in text for text in legend_texts(ax))
    assert ax.get_ylabel() == "$\\sigma_v(t) / \\sigma_v$(4 s) [-]"
    _close(fig)
    # relaxation_forces.png: the force statistics of events.csv at the same phases, each over
    # its value at t = 0 (given in N in the legend).
    fig = figures.figure_relaxation_forces(run)
    (ax,) = fig.axes
    for col, label in (("std_Fn_N", "std. dev. normal force $F_n$"),
                       ("mean_Ft_N", "mean tangential force $F_t$")):
        f0 = ev[col][0]
        line = labelled(ax, f"{label}, $F(0)$ = {f0:.3g} N")
        assert_drawn(line, t[later], ev[col][later] / f0)
    _close(fig)


def test_relaxation_forces_show_a_change_of_a_percent(tmp_path):
    # Forces that change by about 1 % in a day: on an axis from 0 to the largest force the
    # curves would be flat lines; over their values at t = 0, on an axis that spans what they
    # reach, the change fills most of the height.
    run = _ageing_run(tmp_path / "relaxation")
    path = os.path.join(run, "events.csv")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        drop = 0.01 * math.log10(1.0 + float(r["ageing_time_s"])) / math.log10(86401.0)
        r["mean_Fn_N"] = repr(2.0 * (1.0 - drop))
        r["std_Fn_N"] = repr(2.5 * (1.0 - 1.2 * drop))
        r["mean_Ft_N"] = repr(0.4 * (1.0 - 0.5 * drop))
        r["std_Ft_N"] = repr(0.5 * (1.0 - 0.8 * drop))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    fig = figures.figure_relaxation_forces(run)
    (ax,) = fig.axes
    curves = [ln for ln in ax.get_lines() if "$F(0)$" in str(ln.get_label())]
    assert len(curves) == 4
    y = np.concatenate([ln.get_ydata() for ln in curves])
    lo, hi = ax.get_ylim()
    assert lo <= y.min() and y.max() <= hi  # every point on the axis
    assert lo > 0.9  # not from 0
    # The 1.2 % drop of the normal force's spread takes most of the axis height.
    assert (1.0 - y.min()) / (hi - lo) > 0.6
    assert ax.get_ylabel() == "contact force $F(t) / F(0)$ [-]"
    _close(fig)


def test_creep_run_writes_relaxation_figures(tmp_path):
    run = _ageing_run(tmp_path / "creep", creep=True)
    assert AGEING_FIGURES <= _plots(run, tmp_path / "figs")
    # relaxation_breakage.png: the cumulative breakages by cause and the particles per phase.
    ev = rundir.read_events(run)
    later = ev["ageing_time_s"] > 0
    fig = figures.figure_relaxation_breakage(run)
    ax, ax_n = fig.axes
    assert_drawn(labelled(ax, "breakages: crack"), ev["ageing_time_s"][later],
                 ev["breakages_crack"][later])
    assert_drawn(labelled(ax_n, "particles"), ev["ageing_time_s"][later],
                 ev["n_particles"][later])
    _close(fig)


def test_ageing_figures_need_events_csv(tmp_path):
    # The same run without events.csv: no ageing figure, the others still drawn.
    run = _ageing_run(tmp_path / "relaxation", events=False)
    names = _plots(run, tmp_path / "figs")
    assert names and not names & AGEING_FIGURES
    assert "oedometer.png" in names
    for run in (_plain_run(tmp_path / "plain"), _triaxial_run(tmp_path / "triaxial"),
                _crushing_run(tmp_path / "crushing")):
        names = _plots(run, tmp_path / "figs" / os.path.basename(run))
        assert names and not names & AGEING_FIGURES


def test_ageing_events_with_only_the_first_phase_or_header(tmp_path):
    # A run still in its first dynamic phase: events.csv empty, header only or one row at t = 0
    # has nothing for the log time axis, so no ageing figure and no failure.
    run = _ageing_run(tmp_path / "relaxation")
    path = os.path.join(run, "events.csv")
    with open(path) as f:
        lines = f.readlines()
    for keep in (lines[:2], lines[:1], []):
        with open(path, "w") as f:
            f.writelines(keep)
        names = _plots(run, tmp_path / "figs")
        assert "oedometer.png" in names and not names & AGEING_FIGURES


def test_ageing_reads_events(tmp_path):
    run = _ageing_run(tmp_path / "relaxation")
    ev = plot.read_events(run)
    assert ev["ageing_time_s"][0] == 0.0 and np.all(np.diff(ev["ageing_time_s"]) > 0)
    assert list(ev["dynamic_phase"]) == list(range(15))
    groups = analysis.ageing_groups(ev, plot.read_summary(run))
    assert len(groups) == 1
    label, idx, ref = groups[0]
    assert "relaxation" in label and ref == 0 and len(idx) == 15
    assert plot.read_events(_plain_run(tmp_path / "plain")) is None


def test_relaxation_with_every_wall_fixed_is_told_from_creep(tmp_path):
    # Relaxation (walls fixed) is normalised by sigma_v(4 s) and gets the plausible band; in
    # creep the axial wall is servo-controlled and moves, and sigma_v(0) stays the reference.
    for creep in (False, True):
        run = _ageing_run(tmp_path / ("creep" if creep else "relaxation"), creep=creep)
        path = os.path.join(run, "events.csv")
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        if creep:
            for r in rows:  # the top wall follows the axial strain
                r["wall_zmax_position_m"] = repr(1e-3 * (1.0 - float(r["axial_strain"])))
            with open(path, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(rows[0]))
                w.writeheader()
                w.writerows(rows)
        ev = plot.read_events(run)
        (_, idx, _), = analysis.ageing_groups(ev, plot.read_summary(run))
        assert analysis.walls_fixed(ev, idx) is (not creep)
        assert not analysis.walls_fixed(ev, idx[:1])  # one phase says nothing
        assert AGEING_FIGURES <= _plots(run, tmp_path / "figs")


# --- the figure functions ------------------------------------------------------------------------


def _labels(fig):
    """The legend labels of every axes of ``fig``, one list per legend."""
    out = []
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None:
            out.append([t.get_text() for t in leg.get_texts()])
    return out


def test_figure_functions_return_figures_without_switching_the_backend(tmp_path):
    import matplotlib
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    before = matplotlib.get_backend()
    matplotlib.use("svg")  # a backend that is not Agg, as a notebook's inline one is not
    try:
        run = _triaxial_run(tmp_path / "triaxial")
        data = rundir.read_run(run)
        drawn = {}
        for name, make in figures.FIGURES.items():
            fig = make(data)
            if fig is not None:
                assert isinstance(fig, Figure), name
                drawn[name] = fig
        assert {"stress_time.png", "triaxial.png", "coordination.png"} <= set(drawn)
        assert isinstance(plot.figure_stress_time(run), Figure)  # a path works too
        assert _plots(run, tmp_path / "figs") == set(drawn)
        assert matplotlib.get_backend() == "svg"
        plt.close("all")
    finally:
        matplotlib.use(before)


def test_cli_selects_agg_only_without_a_display(tmp_path, monkeypatch, capsys):
    import matplotlib

    before = matplotlib.get_backend()
    run = _plain_run(tmp_path / "plain")
    try:
        monkeypatch.setattr(figures, "display_available", lambda: True)
        matplotlib.use("svg")
        assert plot.main([run, "--out", str(tmp_path / "a")]) == 0
        assert matplotlib.get_backend() == "svg"
        monkeypatch.setattr(figures, "display_available", lambda: False)
        assert plot.main([run, "--out", str(tmp_path / "b")]) == 0
        assert matplotlib.get_backend().lower() == "agg"
    finally:
        matplotlib.use(before)
    capsys.readouterr()


def test_stress_time_of_an_age_run_is_against_ageing_time(tmp_path):
    import matplotlib.pyplot as plt

    run = _ageing_run(tmp_path / "relaxation")
    fig = figures.figure_stress_time(run)
    # A row per axis: DEM time on the left, ageing time on the right.
    assert [ax.get_xscale() for ax in fig.axes] == ["linear", "log"] * 3
    log_axes, dem_axes = fig.axes[1::2], fig.axes[0::2]
    ev = plot.read_events(run)
    for ax, axis in zip(log_axes, "xyz"):
        x_age = np.concatenate([ln.get_xdata() for ln in ax.get_lines()
                                if len(ln.get_xdata()) > 2])
        assert np.nanmax(x_age) > 1000.0 and np.nanmax(x_age) == pytest.approx(86400.0)
        # Both walls of the axis, at the phases after t = 0 (the walls' own markers).
        later = ev["ageing_time_s"] > 0
        ys = [ln.get_ydata() for ln in ax.get_lines() if len(ln.get_xdata()) > 2]
        for w in (axis + "min", axis + "max"):
            want = ev[f"wall_{w}_stress_Pa"][later] * MPA
            assert any(np.array_equal(y, want) for y in ys), w
        assert {ln.get_marker() for ln in ax.get_lines() if len(ln.get_xdata()) > 2} >= {"o", "s"}
    # The DEM-time panels hold the loading stage, up to the age stage's first row (in a run,
    # the same state as the loading's last row).
    d = plot.read_timeseries(run)
    age_rows = np.flatnonzero(d["stage"] == 1)
    for ax in dem_axes:
        x_dem = np.concatenate([ln.get_xdata()[np.isfinite(ln.get_ydata())]
                                for ln in ax.get_lines() if len(ln.get_xdata())])
        assert np.nanmax(x_dem) == d["time_s"][age_rows[0]] < d["time_s"][age_rows[1]]
    plt.close(fig)
    # Without an age stage: panels against DEM time only.
    fig = figures.figure_stress_time(_oedometer_run(tmp_path / "oedometer"))
    assert [ax.get_xscale() for ax in fig.axes] == ["linear"] * 3
    plt.close(fig)
    # One panel for a figure of one curve.
    fig = figures.figure_coordination(_oedometer_run(tmp_path / "oedometer2"))
    assert [ax.get_xscale() for ax in fig.axes] == ["linear"]
    plt.close(fig)


def test_no_legend_repeats_a_label(tmp_path):
    import matplotlib.pyplot as plt

    run = _oedometer_run(tmp_path / "oedometer")
    with open(os.path.join(run, "summary.json")) as f:
        summary = json.load(f)
    summary["stages"][0]["name"], summary["stages"][1]["name"] = "loading", "unloading"
    with open(os.path.join(run, "summary.json"), "w") as f:
        json.dump(summary, f)
    runs = [run, _ageing_run(tmp_path / "relaxation"), _crushing_run(tmp_path / "crushing")]
    for r in runs:
        for name, fig in figures.draw_all(r):
            for labels in _labels(fig):
                assert len(labels) == len(set(labels)), (r, name, labels)
                assert not any("loading, loading" in lab for lab in labels), (name, labels)
            plt.close(fig)
    fig = figures.figure_oedometer(run)
    (labels,) = _labels(fig)
    assert labels[0].startswith("stage 0: loading, $K_0$")
    assert labels[1].startswith("stage 1: unloading, $K_0$")
    plt.close(fig)
    # A stage drawn in two segments has one legend entry.
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1], label="stage 0: loading")
    ax.plot([2, 3], [1, 2], label="stage 0: loading")
    ax.plot([2, 3], [0, 0], label="limit")
    assert [t.get_text() for t in figures.unique_legend(ax).get_texts()] == [
        "stage 0: loading", "limit"]
    plt.close(fig)


def test_triaxial_warning_is_below_the_axes(tmp_path):
    import matplotlib.pyplot as plt

    run = _triaxial_run(tmp_path / "triaxial")
    with open(os.path.join(run, "summary.json")) as f:
        summary = json.load(f)
    summary["stages"][1]["warning"] = ("the inertial number reached 2.3e-3, above the "
                                       "quasi-static limit 1e-3: lower the strain rate") * 2
    with open(os.path.join(run, "summary.json"), "w") as f:
        json.dump(summary, f)
    fig = figures.figure_triaxial(run)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    assert not any("warning" in t.get_text() for ax in fig.axes for t in ax.texts)
    notes = [t for t in fig.texts if t.get_text()]
    assert notes and "warning" in notes[0].get_text()
    boxes = [ax.get_tightbbox(renderer) for ax in fig.axes]
    boxes += [ax.get_legend().get_window_extent(renderer) for ax in fig.axes
              if ax.get_legend() is not None]
    for t in notes:
        tb = t.get_window_extent(renderer)
        assert tb.x0 >= 0 and tb.y0 >= 0 and tb.x1 <= fig.bbox.width
        assert not any(tb.overlaps(b) for b in boxes), t.get_text()
    plt.close(fig)


def _prepared_sample_test_run(path):
    """A test from a prepared sample: its first row has the wall stresses (0.1 MPa) but every
    contact column 0, as the engine writes it; later rows are measured."""
    rows = []
    for i in range(6):
        sig = 0.1e6 * (1 + i)
        contacts = 0 if i == 0 else 1000 + 10 * i
        rows.append(_row(i * 1e-5, sig, sig, 0.001 * i, 0.003 * i, 0.7 - 0.002 * i, stage=0,
                         n_contacts=contacts, mean_Fn_N=0.0 if i == 0 else 0.01 * i,
                         love_mean_stress_Pa=0.0 if i == 0 else sig))
        rows[-1]["coordination_number"] = 0.0 if i == 0 else 4.4
    return _write_run(path, rows, {"stages": [_stage_summary("isotropic", "isotropic")]})


def test_rows_without_contact_measurements_are_not_drawn_as_zero(tmp_path):
    import matplotlib.pyplot as plt

    run = _prepared_sample_test_run(tmp_path / "from_sample")
    d = rundir.read_run(run).timeseries
    for c in ("n_contacts", "coordination_number", "mean_Fn_N", "love_mean_stress_Pa"):
        assert math.isnan(d[c][0]) and np.all(np.isfinite(d[c][1:])), c
    assert d["wall_zmax_stress_Pa"][0] == 0.1e6  # the walls' own measurement stays
    fig = figures.figure_coordination(run)
    (line,) = fig.axes[0].get_lines()
    assert np.nanmin(line.get_ydata()) == pytest.approx(4.4)
    plt.close(fig)


def test_unmeasured_contact_rows_are_the_first_rows_of_stages_under_load():
    n = 6
    d = {"stage": np.array([0, 0, 0, 1, 1, 1], dtype=float),
         "n_contacts": np.array([0, 0, 5, 0, 7, 0], dtype=float),
         "wall_zmax_stress_Pa": np.array([0.0, 1e3, 1e5, 1e5, 1e5, 1e5])}
    # Row 0: no load, so a real 0; row 1: grains not yet touching in the middle of a stage;
    # row 3: first row of stage 1 under load without contacts: not computed; row 5: a real 0.
    assert list(analysis.unmeasured_contact_rows(d)) == [False, False, False, True, False,
                                                         False]
    masked = analysis.mask_unmeasured_contacts(d)
    assert math.isnan(masked["n_contacts"][3]) and masked["n_contacts"][5] == 0
    assert d["n_contacts"][3] == 0  # the input is not changed
    assert not analysis.unmeasured_contact_rows({"time_s": np.zeros(n)}).any()


def test_rundir_readers_are_the_ones_plot_exports(tmp_path):
    run = _crushing_run(tmp_path / "crushing")
    assert plot.read_timeseries is rundir.read_timeseries
    by_dir, by_file = plot.read_timeseries(run), plot.read_timeseries(
        os.path.join(run, "timeseries.csv"))
    assert by_dir.keys() == by_file.keys()
    assert all(np.array_equal(by_dir[k], by_file[k], equal_nan=True) for k in by_dir)
    data = rundir.read_run(run)
    assert data.finished and data.title == "crushing" and data.grading is not None
    assert data.breakage and data.events is None


def _penetration_run(path):
    """A run with a penetrate stage (stage 1): penetration.csv and shaft_profile.csv (3 bins)."""
    rows = [_row(i * 1e-5, 0.2e6, 0.2e6, 0.0, 0.0, 0.7, stage=min(i, 1)) for i in range(8)]
    run = _write_run(path, rows, {"stages": [_stage_summary("iso", "isotropic"),
                                             _stage_summary("cpt", "penetrate")]})
    travel = np.linspace(0.0, 0.7e-3, 8)
    q_c = np.where(travel > 0.2e-3, 2e7 * (travel - 0.2e-3), 0.0)
    with open(os.path.join(run, "penetration.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stage", "travel_m", "q_c_Pa", "f_s_Pa", "time_s", "tip_x_m", "tip_y_m",
                    "tip_z_m", "wall_zmax_position_m"])
        for t, q in zip(travel, q_c):
            w.writerow([1, float(t), float(q), float(0.01 * q), float(t / 2.0), 1e-3, 0.0,
                        float(1.2e-3 - t), 1.0e-3])
    with open(os.path.join(run, "shaft_profile.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stage", "travel_m", "bin", "height_m", "sigma_r_Pa", "tau_Pa", "contacts"])
        for t in travel:
            for b in range(3):
                w.writerow([1, float(t), b, (b + 0.5) * 1e-4, float(1e5 * (b + 1) * t / 7e-4),
                            0.0, 2])
    return run, travel, q_c


def test_penetration_run_draws_q_c_f_s_and_the_shaft_stress(tmp_path):
    run, travel, q_c = _penetration_run(tmp_path / "cpt")
    assert {"penetration.png", "shaft_stress.png"} <= _plots(run)
    data = rundir.read_run(run)
    fig = figures.figure_penetration(data)
    ax_q, ax_f = fig.axes
    assert_drawn(labelled(ax_q, "stage 1"), q_c * MPA, travel * 1e3)
    assert_drawn(labelled(ax_f, "stage 1"), 0.01 * q_c * 1e-3, travel * 1e3)
    assert ax_q.yaxis_inverted()  # depth downwards
    _close(fig)
    fig = figures.figure_shaft_stress(data)
    (ax,) = fig.axes
    # Four travels picked evenly from the eight, the first and the last among them.
    lines = ax.get_lines()
    assert [ln.get_label() for ln in lines][0] == "travel 0 mm"
    assert lines[-1].get_label() == "travel 0.7 mm"
    assert_drawn(lines[-1], [100.0, 200.0, 300.0], (np.arange(3) + 0.5) * 1e-4 * 1e3)
    assert len(lines) == 4
    _close(fig)


def test_the_stress_field_about_the_cone_is_drawn_at_its_last_record(tmp_path):
    run, travel, _ = _penetration_run(tmp_path / "cpt")
    assert "stress_field.png" not in _plots(run)  # no penetration_field.csv
    # Two records of 2 rings (0.1 mm wide) by 3 slices; at the last, sigma_rr = 10 (ring + 1)
    # (bin + 1) kPa, and ring 0's lowest slice is empty (inside the body).
    with open(os.path.join(run, "penetration_field.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stage", "time_s", "travel_m", "tip_z_m", "ring", "bin", "r_in_m", "r_out_m",
                    "z_m", "sigma_rr_Pa", "sigma_tt_Pa", "sigma_zz_Pa", "tau_rz_Pa", "grains"])
        for k, t in ((0, 0.0), (1, 3.5e-4)):
            for ring in range(2):
                for b in range(3):
                    s = 1e4 * (ring + 1) * (b + 1) * k
                    w.writerow([1, t, 2 * t, 1.2e-3 - 2 * t, ring, b, ring * 1e-4,
                                (ring + 1) * 1e-4, (b + 0.5) * 4e-4, s, 0.5 * s, 2 * s, 0.0,
                                0 if (ring, b) == (0, 0) else 3])
    assert "stress_field.png" in _plots(run, tmp_path / "field")
    fig = figures.figure_stress_field(rundir.read_run(run))
    ax = fig.axes[0]
    mesh = ax.collections[0]
    grid = np.ma.masked_array(mesh.get_array()).reshape(3, 2)  # slices by rings
    assert np.ma.getmaskarray(grid)[0, 0] and not np.ma.getmaskarray(grid)[1, 0]
    np.testing.assert_allclose(grid[1:, :], [[20.0, 40.0], [30.0, 60.0]])
    np.testing.assert_allclose(grid[0, 1], 20.0)
    # The cells' edges: rings from the axis, slices about their middles.
    coords = mesh.get_coordinates()
    np.testing.assert_allclose(coords[0, :, 0], [0.0, 0.1, 0.2])
    np.testing.assert_allclose(coords[:, 0, 1], [0.0, 0.4, 0.8, 1.2])
    assert "0.7 mm" in fig.texts[0].get_text()
    _close(fig)


def test_breakage_around_the_cone_is_drawn_by_distance_from_its_axis(tmp_path):
    run, travel, _ = _penetration_run(tmp_path / "cpt")
    # Three grains broke during the push (time = travel / 2: the first at its start), one after
    # the stage ended (not drawn).
    events = [(0.0, 2e-4, 1e-3 + 3e-4, 0.0, 0.9e-3), (2e-4, 1e-4, 1e-3, 4e-4, 0.7e-3),
              (3.5e-4, 2e-4, 1e-3, 0.0, 0.5e-3), (1.0, 2e-4, 1e-3, 0.0, 0.1e-3)]
    with open(os.path.join(run, "breakage.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time_s", "step", "id", "diameter_m", "cause", "sigma_Pa", "sigma_lim_Pa",
                    "fragments", "removed_fragments", "fragment_ids", "x_m", "y_m", "z_m"])
        for k, (t, d, x, y, z) in enumerate(events):
            w.writerow([t, k, k, d, "instant", 1e9, 1e9, 14, 0, "1 2", x, y, z])
    assert "breakage_field.png" in _plots(run)
    data = rundir.read_run(run)
    assert data.breakage_positions["x_m"].size == 4
    fig = figures.figure_breakage_field(data)
    ax = fig.axes[0]
    offsets = ax.collections[0].get_offsets()
    # r from the axis through the tip's last x, y (1 mm, 0), z as written, in mm.
    np.testing.assert_allclose(offsets[:, 0], [0.3, 0.4, 0.0], atol=1e-12)
    np.testing.assert_allclose(offsets[:, 1], [0.9, 0.7, 0.5], atol=1e-12)
    np.testing.assert_allclose(ax.collections[0].get_array(), [0.0, 0.4, 0.7], atol=1e-12)
    assert "3 breakages" in ax.get_title()
    _close(fig)
    # A breakage.csv without positions (a run begun by an older version): no field figure.
    with open(os.path.join(run, "breakage.csv"), "w", newline="") as f:
        csv.writer(f).writerow(["time_s", "step", "id", "diameter_m", "cause"])
    assert rundir.read_breakage_positions(run) is None
    assert "breakage_field.png" not in _plots(run, tmp_path / "again")


def test_a_run_without_penetration_has_no_penetration_figures(tmp_path):
    names = _plots(_plain_run(tmp_path / "plain"))
    assert not {"penetration.png", "shaft_stress.png"} & names


def test_figures_join_the_runs_manifest(tmp_path):
    """Figures drawn into a run directory are listed in its manifest.json (so --overwrite removes
    them with the run); a folder without a manifest gets none."""
    run = _triaxial_run(tmp_path / "triaxial")
    with open(os.path.join(run, "manifest.json"), "w") as f:
        json.dump({"crushdem_run": True, "entries": ["config.toml", "timeseries.csv"]}, f)
    written = plot.make_plots(run)
    with open(os.path.join(run, "manifest.json")) as f:
        entries = json.load(f)["entries"]
    assert entries[:2] == ["config.toml", "timeseries.csv"]
    assert sorted(entries[2:]) == sorted(os.path.basename(p) for p in written)
    plot.make_plots(run)  # drawn again: listed once
    with open(os.path.join(run, "manifest.json")) as f:
        assert len(json.load(f)["entries"]) == len(entries)
    other = _plain_run(tmp_path / "plain")
    plot.make_plots(other)
    assert not os.path.exists(os.path.join(other, "manifest.json"))


def test_log_time_axes_label_the_minor_ticks_only_when_they_have_room():
    """2 and 5 between the decades are labelled on an axis of at most two decades; on a wider
    one their plain labels (20000, 50000) would run into each other."""
    from crushdem_sand.figures.common import plain_log_ticks, pyplot

    plt = pyplot()
    for span, labelled in (((1.0, 100.0), True), ((1e2, 1e6), False)):
        fig, ax = plt.subplots()
        ax.set_xscale("log")
        ax.plot(span, [0, 1])
        ax.set_xlim(*span)
        plain_log_ticks(ax)
        fig.canvas.draw()
        minor = [t.get_text() for t in ax.get_xticklabels(minor=True) if t.get_text()]
        major = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
        assert bool(minor) == labelled, (span, minor)
        assert "100" in major, major
        # A month of ageing in seconds: 10^6, not Python's 1e+06.
        assert not any("e+" in t for t in major + minor), major
        if span[1] >= 1e6:
            assert "$10^{6}$" in major, major
        plt.close(fig)


def test_tick_numbers_are_plain_to_1e5_and_powers_of_ten_beyond():
    from crushdem_sand.figures.common import tick_number

    assert [tick_number(v) for v in (0.0, 0.001, 0.2, 3600.0, 86400.0)] == [
        "0", "0.001", "0.2", "3600", "86400"]
    assert tick_number(1e6) == "$10^{6}$"
    assert tick_number(2.592e6) == "$2.59\\times10^{6}$"
    assert tick_number(1e-5) == "$10^{-5}$"


def test_a_chamber_at_rest_draws_its_stress_profile_with_depth(tmp_path):
    # stress_profile.csv of two holds (hold stage 1 wrote the earlier profile): the last one's
    # four slices are drawn, from the bottom platen up, against the depth downwards.
    run = _write_run(tmp_path / "k0", [_row(0.0, 1e4, 1e4, 0.0, 0.0, 0.70),
                                       _row(1e-3, 1e4, 2e4, 1e-3, 1e-3, 0.69)])
    depth = np.array([3.5e-3, 2.5e-3, 1.5e-3, 0.5e-3])
    with open(os.path.join(run, "stress_profile.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stage", "time_s", "bin", "z_m", "depth_m", "core_radius_m", "sigma_rr_Pa",
                    "sigma_tt_Pa", "sigma_zz_Pa", "tau_rz_Pa", "K", "grains"])
        for stage, scale in ((1, 0.5), (2, 1.0)):
            for b in range(4):
                zz = scale * (10e3 + 20e3 * depth[b] / 4e-3)
                w.writerow([stage, 1e-3 * stage, b, 4e-3 - depth[b], depth[b], 1.5e-3, 0.6 * zz,
                            0.5 * zz, zz, 0.0, 0.6, 100])
    assert "stress_profile.png" in _plots(run)
    fig = figures.figure_stress_profile(rundir.read_run(run))
    ax_s, ax_k = fig.axes
    zz = 10.0 + 20.0 * depth / 4e-3
    assert_drawn(labelled_like(ax_s, r"$\sigma_{zz}$"), zz, depth * 1e3)
    assert_drawn(labelled_like(ax_s, r"$\sigma_{rr}$"), 0.6 * zz, depth * 1e3)
    assert_drawn(ax_k.get_lines()[0], [0.6] * 4, depth * 1e3)
    assert ax_s.yaxis_inverted()  # depth downwards
    assert "1.5 mm of the axis" in ax_s.get_title()
    _close(fig)
    assert "stress_profile.png" not in _plots(_plain_run(tmp_path / "plain"))
