"""``crushdem-sand pile`` (python/crushdem_sand/pile.py): the set-up fit returns the A of synthetic
capacities (and its uncertainty covers it under noise); the plan of runs follows the stages and
refuses a configuration out of order; the command on the 400-grain pile of tests/data (a main run
and one branch, about 20 s) writes the capacities, the fit and the figures, and called again
reuses its finished runs; stopped with SIGTERM, the command stops its run as the run's own stop
does (a checkpoint saved), and called again completes."""

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("pandas")

from crushdem_sand import pile  # noqa: E402
from crushdem_sand.figures import pile as pile_figures  # noqa: E402

from _data import DATA  # noqa: E402


def test_the_setup_fit_returns_the_factor_of_synthetic_capacities():
    t = np.array([3600.0, 86400.0, 604800.0, 2592000.0])
    for A in (0.0, 0.25, 0.6):
        Q = 120.0 * (1.0 + A * np.log10(t / 3600.0))
        f = pile.fit_setup(t, Q)
        assert f["A"] == pytest.approx(A, abs=1e-12)
        assert f["Q0_N"] == pytest.approx(120.0, rel=1e-12)
        assert f["A_std"] == pytest.approx(0.0, abs=1e-9)
        assert f["t0_s"] == 3600.0 and f["points"] == 4
    # Under noise the standard error covers the true factor (30 draws, 2 sigma: most of them).
    rng = np.random.default_rng(3)
    t = np.geomspace(3600.0, 2592000.0, 8)
    inside = 0
    for _ in range(30):
        Q = 100.0 * (1.0 + 0.4 * np.log10(t / 3600.0)) * (1.0 + 0.03 * rng.standard_normal(t.size))
        f = pile.fit_setup(t, Q)
        assert f["A_std"] > 0
        inside += abs(f["A"] - 0.4) < 2.0 * f["A_std"]
    assert inside >= 24
    # Two points give A without an uncertainty; one gives nothing; t = 0 is left out.
    f = pile.fit_setup([0.0, 3600.0, 36000.0], [5.0, 1.0, 1.5])
    assert f["points"] == 2 and f["A"] == pytest.approx(0.5) and math.isnan(f["A_std"])
    assert math.isnan(pile.fit_setup([3600.0], [1.0])["A"])


def _stage(kind, name, **keys):
    return {"type": kind, "name": name, **keys}


def test_the_plan_follows_the_stages_and_refuses_them_out_of_order():
    install = _stage("penetrate", "install", body="pile")
    ages = [_stage("age", f"a{i}", until=float(3600 * 10 ** i)) for i in range(3)]
    tests = [_stage("load_test", "comp"), _stage("load_test", "tens", direction="tension")]
    p = pile.plan({"stage": [install] + ages + tests})
    assert p["ages"] == [1, 2, 3] and p["tests"] == [4, 5]
    assert [s["name"] for s in p["main"]] == ["install", "a0", "a1", "a2", "comp"]
    names = [b[0] for b in p["branches"]]
    assert names == ["t0_comp", "t0_tens", "t1_comp", "t1_tens", "t2_tens"]
    # Each branch: the stages up to its age stage, then its test, from the stage after it.
    for name, stages, from_stage, a_pos, test in p["branches"]:
        assert [s["name"] for s in stages] == ["install"] + [f"a{i}" for i in
                                                             range(a_pos + 1)] + [test]
        assert from_stage == 1 + a_pos + 1
    for bad, said in [
        ([install] + tests, "no \"age\" stage"),
        ([install] + ages, "no \"load_test\""),
        ([install, ages[0], tests[0], ages[1], tests[1]], "stage[2] is a load test before"),
        ([install, tests[0]] + ages, "stage[1] is a load test before"),  # none after: this first
        ([install] + ages + tests + [_stage("hold", "h")], "stage[6] (hold) follows"),
        (ages + tests, "no \"penetrate\" stage"),
        # Two tests of one name (unnamed: both "load_test") would share their branches' folders.
        ([install] + ages + [_stage("load_test", None), _stage("load_test", None)],
         "stage[5].name = \"load_test\": expected a name of its own (stage[4]"),
    ]:
        with pytest.raises(ValueError, match=said.replace("[", r"\[").replace("(", r"\(")
                           .replace(")", r"\)")):
            pile.plan({"stage": bad})


def test_the_pile_command_tests_each_ageing_time_and_fits_the_setup(tmp_path):
    text = open(os.path.join(DATA, "pile_400.toml")).read().replace("@DATA@", DATA)
    cfg = tmp_path / "pile.toml"
    cfg.write_text(text)
    out = tmp_path / "out"
    said = []
    r = pile.pile(str(cfg), str(out), log=said.append)
    import pandas as pd

    # The main run (installation, both age stages, the test at 1 day) and the test at 1 hour.
    assert sorted(os.listdir(out / "configs")) == ["main.toml", "t0_compression.toml"]
    rows = r["capacity"]
    assert [(row["run"], row["ageing_time_s"]) for row in rows] == [("t0_compression", 3600.0),
                                                                    ("main", 86400.0)]
    for row in rows:
        assert row["capacity_N"] > 0
        assert row["capacity_N"] == pytest.approx(row["shaft_at_capacity_N"]
                                                  + row["base_at_capacity_N"], rel=1e-12)
    main = json.load(open(out / "main" / "summary.json"))
    assert main["stages"][-1]["capacity_N"] == rows[1]["capacity_N"]
    # A sweep's table of the pile case: the capacity and the installation's end resistance.
    from crushdem_sand import sweep

    fig = sweep.summary_figures(str(out / "main"))
    assert fig["compression.capacity_N"] == rows[1]["capacity_N"]
    assert fig["compression.shaft_at_capacity_N"] == rows[1]["shaft_at_capacity_N"]
    pen = pd.read_csv(out / "main" / "penetration.csv")
    end = pen[pen["travel_m"] >= 0.9 * pen["travel_m"].max()]
    assert fig["install.q_c_end_MPa"] == pytest.approx(end["q_c_Pa"].mean() / 1e6, rel=1e-12)
    assert fig["install.q_c_max_MPa"] >= fig["install.q_c_end_MPa"] > 0

    table = pd.read_csv(out / "pile_capacity.csv")
    assert list(table["ageing_time_s"]) == [3600.0, 86400.0]
    fit = json.load(open(out / "pile_setup.json"))["fits"]["compression"]
    q = table["capacity_N"].to_numpy()
    assert fit["A"] == pytest.approx((q[1] / q[0] - 1.0) / math.log10(24.0), rel=1e-9)
    assert fit["points"] == 2
    shaft = json.load(open(out / "pile_setup.json"))["fits"]["compression (shaft)"]
    assert shaft["points"] == 2 and math.isfinite(shaft["A"])
    for png in ("pile_setup.png", "main/pile_shaft.png", "main/pile_rings.png",
                "main/pile_forces.png"):
        assert (out / png).stat().st_size > 1000, png
    assert any("set-up 'compression'" in s for s in said)
    # Called again: every run has finished, the tables come back the same.
    again = pile.pile(str(cfg), str(out), log=lambda s: None)
    assert again["capacity"] == rows
    # A changed configuration is refused instead of mixed with the first one's runs.
    cfg.write_text(text.replace("n_break = 2", "n_break = 3", 1))
    with pytest.raises(ValueError, match="holds another configuration"):
        pile.pile(str(cfg), str(out), log=lambda s: None)

    # --from: that variant (the ageing changed) branched from the installed pile of the first.
    variant = tmp_path / "variant"
    r2 = pile.pile(str(cfg), str(variant), log=lambda s: None, branch=f"{out / 'main'}:age_1h")
    branch = json.load(open(variant / "main" / "branch.json"))
    assert os.path.realpath(branch["run"]) == os.path.realpath(out / "main")
    assert branch["stage"] == 2  # install, unload, then the first age stage
    # The installation is the first run's, to the byte; the ageing (n_break 3) is its own.
    for name in ("penetration.csv", "shaft_profile.csv"):
        assert (variant / "main" / name).read_bytes() == (out / "main" / name).read_bytes()
    assert [row["ageing_time_s"] for row in r2["capacity"]] == [3600.0, 86400.0]
    assert json.load(open(variant / "main" / "summary.json"))["stages"][2]["type"] == "age"
    # A RUN that is not there is named before anything is written.
    with pytest.raises(ValueError, match="is not a directory"):
        pile.pile(str(cfg), str(tmp_path / "nowhere"), log=lambda s: None,
                  branch=f"{tmp_path / 'none'}:age_1h")
    assert not (tmp_path / "nowhere").exists()
    # So are a directory that is not a run, and a stage the run does not have.
    for bad, said in ((f"{out}:age_1h", "not a crushdem-sand run directory"),
                      (f"{out / 'main'}:age_1y", "'age_1y' is not a stage of .* age_1h"),
                      (f"{out / 'main'}:9", "'9' is not a stage .* index below 5")):
        with pytest.raises(ValueError, match=said):
            pile.pile(str(cfg), str(tmp_path / "nowhere"), log=lambda s: None, branch=bad)
        assert not (tmp_path / "nowhere").exists()
    # Called again with another origin, or none, it refuses rather than mix two origins.
    for other in (None, f"{out / 't0_compression'}:0"):
        with pytest.raises(ValueError, match="was begun from"):
            pile.pile(str(cfg), str(variant), log=lambda s: None, branch=other)


def test_a_bad_key_is_named_with_the_pile_file(tmp_path):
    cfg = tmp_path / "pile.toml"
    text = open(os.path.join(DATA, "pile_400.toml")).read().replace("@DATA@", DATA)
    cfg.write_text(text.replace("depth = 0.6e-3", "dept = 0.6e-3", 1))
    with pytest.raises(ValueError, match=f"{cfg}: .*'stage\\[0\\]\\.dept'"):
        pile.pile(str(cfg), str(tmp_path / "out"), log=lambda s: None)
    assert not (tmp_path / "out" / "main").exists()


def test_a_stopped_pile_command_lets_its_run_save_its_checkpoint(tmp_path):
    """SIGTERM to crushdem-sand pile during the installation: its run gets SIGTERM too and saves
    its checkpoint (the installation stage has no other before its end); the command exits with
    128 + SIGTERM, and called again resumes the run and completes."""
    cfg = tmp_path / "pile.toml"
    cfg.write_text(open(os.path.join(DATA, "pile_400.toml")).read().replace("@DATA@", DATA))
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "crushdem_sand", "pile", str(cfg), "--out",
                          str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    log = out / "main" / "run.log"
    deadline = time.monotonic() + 120
    while not (log.is_file() and "install  step" in log.read_text()):
        assert p.poll() is None and time.monotonic() < deadline, "the installation never began"
        time.sleep(0.05)
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=120) == 128 + signal.SIGTERM
    assert (out / "main" / "checkpoint.bin").is_file()
    assert "stopped by signal" in log.read_text()
    r = pile.pile(str(cfg), str(out), log=lambda s: None)
    assert [row["ageing_time_s"] for row in r["capacity"]] == [3600.0, 86400.0]
    assert json.load(open(out / "main" / "timing.json"))["resumed"] is True


def test_each_capacity_and_each_stage_has_a_column_of_its_own(tmp_path):
    from crushdem_sand import sweep_results

    # Ageing times below a second keep their digits: 0.2 s and 0.4 s are two columns.
    with open(tmp_path / "pile_capacity.csv", "w") as f:
        f.write("run,age,ageing_time_s,test,capacity_N,shaft_at_capacity_N,base_at_capacity_N\n"
                "main,0,0.2,compression,1.0,0.5,0.5\nt1,1,0.4,compression,2.0,1.0,1.0\n"
                "t2,2,3600,compression,3.0,1.5,1.5\n")
    figs = sweep_results.pile_figures(str(tmp_path))
    assert figs["compression.capacity_N@0.2s"] == 1.0
    assert figs["compression.capacity_N@0.4s"] == 2.0
    assert figs["compression.capacity_N@3600s"] == 3.0
    # Two stages of one name: each keeps its figures, under its index.
    with open(tmp_path / "summary.json", "w") as f:
        json.dump({"stages": [{"name": "age", "type": "age", "K0_end": 0.9},
                              {"name": "age", "type": "age", "K0_end": 0.8},
                              {"name": "test", "type": "load_test", "capacity_N": 4.0}]}, f)
    figs = sweep_results.summary_figures(str(tmp_path))
    assert figs["age[0].K0_end"] == 0.9 and figs["age[1].K0_end"] == 0.8
    assert "age.K0_end" not in figs and figs["test.capacity_N"] == 4.0


def test_a_pile_experiment_counts_as_done_only_with_its_figures(tmp_path, monkeypatch):
    from crushdem_sand import plot, sweep_results

    (tmp_path / "main").mkdir()
    (tmp_path / "main" / "timeseries.csv").write_text("time_s\n0\n")
    rows = [{"run": "main", "age": 0, "ageing_time_s": t, "test": "compression",
             "capacity_N": 1.0 + np.log10(t / 3600.0) * 0.1, "shaft_at_capacity_N": 0.5,
             "base_at_capacity_N": 0.5} for t in (3600.0, 86400.0, 604800.0)]
    monkeypatch.setattr(pile, "capacity_rows", lambda out, p: rows)

    def stopped(run_dir, out=None):
        raise KeyboardInterrupt

    monkeypatch.setattr(plot, "make_plots", stopped)
    p = {"test_names": ["compression"]}
    with pytest.raises(KeyboardInterrupt):
        pile.write_results(str(tmp_path), p, log=lambda s: None)
    assert not sweep_results.finished(str(tmp_path), "pile")
    monkeypatch.setattr(plot, "make_plots", lambda run_dir, out=None: [])
    pile.write_results(str(tmp_path), p, log=lambda s: None)
    assert sweep_results.finished(str(tmp_path), "pile")
    fit = json.loads((tmp_path / "pile_setup.json").read_text())["fits"]["compression"]
    assert fit["A"] == pytest.approx(0.1, rel=1e-9)


def test_the_ring_profile_averages_the_slices_per_event_and_ring():
    rings = {"ageing_time_s": np.array([0, 0, 0, 0, 5, 5, 5, 5], float),
             "ring": np.array([0, 0, 1, 1, 0, 0, 1, 1], float),
             "bin": np.array([0, 1, 0, 1, 0, 1, 0, 1], float),
             "height_m": np.array([1, 3, 1, 3, 1, 3, 1, 3], float),
             "r_in_m": np.array([1, 1, 2, 2, 1, 1, 2, 2], float),
             "r_out_m": np.array([2, 2, 4, 4, 2, 2, 4, 4], float)}
    for k, base in (("sigma_rr_Pa", 10.0), ("sigma_tt_Pa", 20.0), ("sigma_zz_Pa", 30.0)):
        rings[k] = base + np.arange(8, dtype=float)
    prof = pile_figures.ring_profile(rings)
    assert list(prof["ageing_time_s"]) == [0, 0, 5, 5]
    assert list(prof["r_mid_m"]) == [1.5, 3.0, 1.5, 3.0]
    assert list(prof["sigma_rr_Pa"]) == [10.5, 12.5, 14.5, 16.5]
    low = pile_figures.ring_profile(rings, shaft_top=2.0)
    assert list(low["sigma_tt_Pa"]) == [20.0, 22.0, 24.0, 26.0]
    # A slice without grains (beyond the chamber's wall) is left out; a ring without any, too.
    rings["grains"] = np.array([3, 0, 5, 5, 3, 3, 0, 0], float)
    some = pile_figures.ring_profile(rings)
    assert list(some["ageing_time_s"]) == [0, 0, 5]
    assert list(some["sigma_rr_Pa"]) == [10.0, 12.5, 14.5]


def test_the_breakage_map_outlines_the_pile_where_its_degree_of_freedom_puts_it(tmp_path):
    """The outline of pile_breakage.png: from the tip up the cone to the shaft's radius and up the
    shaft, the tip at origin + q direction (q: head_position_m); none for a pile off the z axis
    or a run whose age stages name no pile."""
    def write(body, stage_body="pile"):
        (tmp_path / "config.toml").write_text(
            "[[body]]\n" + body + "\n[[stage]]\ntype = \"penetrate\"\nbody = \"pile\"\n"
            f"[[stage]]\ntype = \"age\"\nbody = \"{stage_body}\"\n")
        return pile_figures.pile_outline(str(tmp_path), 0.004)

    cone = ('name = "pile"\nshape = "pile"\norigin = [0.0, 0.0, 0.05]\nradius = 3e-4\n'
            'length = 5e-3\nhalf_angle = 30.0')
    o = write(cone)
    rise = 3e-4 / math.tan(math.radians(30.0))
    assert np.allclose(o, [[0.0, 0.046], [3e-4, 0.046 + rise], [3e-4, 0.046 + 5e-3]])
    o = write(cone + '\ntip = "flat"\ndirection = [0.0, 0.0, -2.0]')
    assert np.allclose(o, [[0.0, 0.046], [3e-4, 0.046], [3e-4, 0.051]])
    assert write(cone.replace("[0.0, 0.0, 0.05]", "[1e-3, 0.0, 0.05]")) is None
    assert write(cone + "\naxis = [1.0, 0.0, 0.0]") is None
    assert write(cone, stage_body="other") is None


def test_the_pile_command_passes_keep_columns_to_every_run(tmp_path, monkeypatch):
    """`crushdem-sand pile ... --keep-columns`: DIR/main and each branch are run (and, when
    interrupted, resumed) with keep_columns; without the option, none is."""
    from crushdem_sand import sweep

    calls = []

    def fake_run_variant(cfg, run_dir, threads, branch=None, backend="cpu", experiment="run",
                         keep_columns=False):
        calls.append((os.path.basename(run_dir), keep_columns))
        return {"skipped": True}

    monkeypatch.setattr(sweep, "run_variant", fake_run_variant)
    monkeypatch.setattr(pile, "write_results", lambda out, p, log: {})
    config = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "pile_small.toml")
    for flag in (["--keep-columns"], []):
        calls.clear()
        assert pile.main([config, "--out", str(tmp_path / "out"), *flag]) == 0
        assert len(calls) >= 2 and calls[0][0] == "main", calls
        assert all(keep == bool(flag) for _, keep in calls), calls
