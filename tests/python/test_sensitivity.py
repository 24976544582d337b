"""Tests of ``crushdem-sand sensitivity`` (python/crushdem_sand/sensitivity.py): each variant
changes one choice only, every variant is a valid configuration, and the table reads finished runs
(here synthetic run directories with known figures) and names the one closest to the study."""

import csv
import json
import os

import pytest

from crushdem_sand import _core, sensitivity


def _markdown(out):
    with open(os.path.join(out, "qmax_sensitivity.md")) as f:
        return f.read()


def test_each_variant_changes_one_choice_only():
    base = sensitivity.settings()
    assert base["crushing"]["crack_growth"] is False
    for name, (_, contact, crushing) in sensitivity.VARIANTS.items():
        s = sensitivity.variant_settings(base, name)
        changed = {("contact", k) for k in s["contact"]
                   if s["contact"][k] != base["contact"].get(k)}
        changed |= {("crushing", k) for k in s["crushing"]
                    if s["crushing"][k] != base["crushing"].get(k)}
        assert changed == {("contact", k) for k in contact} | {("crushing", k) for k in crushing}
        assert len(changed) <= 2, name  # (k1, k2) is one choice of two keys
    assert sensitivity.variant_settings(base, "base") == base
    # The base settings are not modified by making a variant.
    assert "rolling_friction" not in base["contact"]
    with pytest.raises(ValueError, match="unknown variant 'nonsense'"):
        sensitivity.variant_settings(base, "nonsense")


def test_every_variant_is_a_valid_configuration(tmp_path):
    sample = tmp_path / "sample.txt"
    lines = [f"# box_{a}{m}={0.0 if m == 'min' else 1e-3}" for a in "xyz" for m in ("min", "max")]
    lines += ["0 0.0003 0.0005 0.0005 0.0001", "1 0.0007 0.0005 0.0005 0.0001"]
    sample.write_text("\n".join(lines) + "\n")
    base = sensitivity.settings()
    for name in sensitivity.VARIANTS:
        s = sensitivity.variant_settings(base, name)
        cfg = {"material": s["material"], "contact": s["contact"], "crushing": s["crushing"],
               "particles": {"file": str(sample)},
               "stage": [{"type": "triaxial", "name": "shear", "sigma_3": 10e6,
                          "strain_rate": 50.0, "axial_strain": 0.3}]}
        text = _core.resolved_run_config(cfg, str(tmp_path))
        if name == "rolling_0.3":
            assert "rolling_friction = 0.3" in text
        if name == "r_prime_2R_star":
            assert 'r_prime = "2R_star"' in text


def _fake_run(directory, q_max, breakages=None):
    os.makedirs(directory)
    summary = {"particles": 1500 + (breakages or 0) * 13,
               "stages": [{"type": "isotropic", "q_max_Pa": 5e4},
                          {"type": "triaxial", "q_max_Pa": q_max, "axial_strain_at_q_max": 0.12,
                           "friction_angle_peak_deg": 20.0}]}
    if breakages is not None:
        summary["crushing"] = {"breakages_instant": breakages, "breakages_crack": 0,
                               "relative_breakage_Br": 0.1}
    with open(os.path.join(directory, "summary.json"), "w") as f:
        json.dump(summary, f)
    with open(os.path.join(directory, "timing.json"), "w") as f:
        json.dump({"wall_seconds": 123.0}, f)


def test_table_reads_finished_runs_and_names_the_closest(tmp_path):
    out = str(tmp_path)
    _fake_run(os.path.join(out, "base"), 8.5e6, breakages=100)
    _fake_run(os.path.join(out, "no_crushing"), 10.2e6)
    _fake_run(os.path.join(out, "rolling_0.3"), 19.0e6, breakages=300)
    names = ["base", "no_crushing", "rolling_0.3", "d0_2mm"]  # d0_2mm: not run
    rows = sensitivity.table(out, names, 10e6)
    by = {r["variant"]: r for r in rows}
    assert by["base"]["q_max_MPa"] == pytest.approx(8.5)
    assert by["rolling_0.3"]["q_max_over_sigma_3"] == pytest.approx(1.9)
    assert by["no_crushing"]["breakages"] == 0 and by["base"]["breakages"] == 100
    assert not by["d0_2mm"]["finished"]
    with open(os.path.join(out, "qmax_sensitivity.csv")) as f:
        got = list(csv.DictReader(f))
    assert [r["variant"] for r in got] == names
    assert float(got[2]["q_max_MPa"]) == pytest.approx(19.0)
    md = _markdown(out)
    assert "Closest to the study: rolling_0.3 (19.00 MPa" in md
    assert "| d0_2mm | (not finished)" in md


def test_a_combination_makes_every_change_of_its_parts():
    base = sensitivity.settings()
    s = sensitivity.variant_settings(base, "r_prime_2R_star+d0_2mm+rolling_0.3")
    assert s["crushing"]["r_prime"] == "2R_star" and s["crushing"]["d0"] == 2e-3
    assert s["contact"]["rolling_friction"] == 0.3
    assert s["contact"]["k1"] == base["contact"]["k1"]  # untouched
    assert "d0 = 2 mm" in sensitivity.describe("r_prime_2R_star+d0_2mm")
    with pytest.raises(ValueError, match="set contact.rolling_friction differently"):
        sensitivity.variant_settings(base, "rolling_0.1+rolling_0.3")
    with pytest.raises(ValueError, match="unknown variant 'nope' in 'd0_2mm\\+nope'"):
        sensitivity.variant_settings(base, "d0_2mm+nope")
    with pytest.raises(ValueError, match="appears twice"):
        sensitivity.variant_settings(base, "d0_2mm+d0_2mm")


def test_rotation_variants_cannot_be_combined_with_each_other():
    base = sensitivity.settings()
    s = sensitivity.variant_settings(base, "no_crushing+blocked")
    assert s["contact"]["rotation"] == "blocked" and s["crushing"]["enabled"] is False
    with pytest.raises(ValueError, match="set contact.rotation differently"):
        sensitivity.variant_settings(base, "blocked+rolling_0.3")


def test_the_table_lists_every_variant_run_in_the_directory(tmp_path):
    out = str(tmp_path)
    _fake_run(os.path.join(out, "base"), 8.5e6, breakages=100)
    _fake_run(os.path.join(out, "rolling_0.3+d0_2mm"), 13.0e6, breakages=200)
    os.makedirs(os.path.join(out, "not_a_variant"))
    # A later call that names only one other variant keeps the earlier ones in the table.
    rows = sensitivity.table(out, ["f_uniform"], 10e6)
    assert [r["variant"] for r in rows] == ["base", "rolling_0.3+d0_2mm", "f_uniform"]
    assert rows[1]["q_max_MPa"] == pytest.approx(13.0)
    assert "Closest to the study: rolling_0.3+d0_2mm (13.00 MPa" in _markdown(out)


def test_a_directory_is_not_shared_between_samples(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "sensitivity.json").write_text(json.dumps({"sample": "/elsewhere/sample.txt",
                                                      "base": {}, "variants": {}}))
    sample = tmp_path / "sample.txt"
    sample.write_text("# box_xmin=0\n")
    with pytest.raises(ValueError, match="holds variants run on /elsewhere/sample.txt"):
        sensitivity.run_sensitivity(str(out), str(sample), ["base"])


def test_the_table_reads_the_shear_end_deleted_volume_and_loaded_share(tmp_path):
    out = str(tmp_path / "out")
    run = os.path.join(out, "blocked")
    _fake_run(run, 20e6, breakages=7)
    with open(os.path.join(run, "summary.json")) as f:
        summary = json.load(f)
    summary["crushing"]["removed_volume_m3"] = 2.5e-12
    summary["stages"][0]["loaded_share"] = {"0.7": 0.05, "0.72": 0.031}
    with open(os.path.join(run, "summary.json"), "w") as f:
        json.dump(summary, f)
    # Stage 0 (isotropic), then the shear from eps_v = 0.010 to 0.004 ending at q = 18 MPa.
    with open(os.path.join(run, "timeseries.csv"), "w") as f:
        f.write("step,stage,deviator_stress_Pa,volumetric_strain\n"
                "0,0,0,0.000\n10,0,1e5,0.010\n20,1,5e6,0.010\n30,1,2e7,0.012\n40,1,1.8e7,0.004\n")
    sample = tmp_path / "sample.txt"
    sample.write_text("# box_xmin=0\n0 0 0 0 1e-4\n1 1 1 1 2e-4\n")  # diameters
    solids = sensitivity.solid_volume(str(sample))
    assert solids == pytest.approx(3.141592653589793 / 6.0 * (1e-12 + 8e-12))
    row = sensitivity.table(out, ["blocked"], 10e6, solids)[0]
    assert row["q_end_MPa"] == pytest.approx(18.0)
    assert row["eps_v_shear"] == pytest.approx(-0.006)
    assert row["removed_volume_share"] == pytest.approx(2.5e-12 / solids)
    assert row["loaded_share_072_isotropic"] == pytest.approx(0.031)
    md = _markdown(out)
    assert "| 18.00 | -0.60 % | 7 |" in md
    assert "| 3.10 % |" in md


DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data")
LATTICE = os.path.join(DATA, "lattice_64.txt")


def test_the_preset_sweep_makes_each_variant_s_configuration(tmp_path):
    """The sweep file that ``crushdem-sand sensitivity`` writes gives, for every variant, the same
    resolved configuration as the variant's settings applied to the base test directly."""
    from crushdem_sand import sweep

    out = str(tmp_path)
    base = sensitivity.settings()
    names = list(sensitivity.VARIANTS) + ["r_prime_2R_star+d0_2mm+rolling_0.3"]
    path = sensitivity.write_sweep(out, LATTICE, names, base)
    listed = sweep.variants(sweep.read_sweep(path))
    assert [v["name"] for v in listed] == names
    for v in listed:
        direct = sensitivity.base_config(sensitivity.variant_settings(base, v["name"]), LATTICE)
        assert (_core.resolved_run_config(v["config"], out)
                == _core.resolved_run_config(direct, out)), v["name"]
    no_crushing = next(v for v in listed if v["name"] == "no_crushing")
    assert "[crushing]" not in _core.resolved_run_config(no_crushing["config"], out)


def test_sensitivity_runs_its_variants_as_a_sweep(tmp_path):
    """Two variants on the 64-grain lattice, two workers: each is a run of the sweep under
    DIR/runs, the table has both, and the blocked variant ran with rotation blocked."""
    pytest.importorskip("distributed")
    out = str(tmp_path / "sens")
    rows = sensitivity.run_sensitivity(out, LATTICE, ["base", "blocked"], threads=1,
                                       sigma_3=1e6, strain_rate=50.0, axial_strain=0.005,
                                       log=lambda m: None, workers=2)
    by = {r["variant"]: r for r in rows}
    assert set(by) == {"base", "blocked"}
    assert all(r["finished"] and r["q_max_MPa"] > 0 for r in rows), rows
    with open(os.path.join(out, "runs", "blocked", "config.toml")) as f:
        assert 'rotation = "blocked"' in f.read()
    assert os.path.isfile(os.path.join(out, "results.csv"))
    with open(os.path.join(out, "qmax_sensitivity.csv")) as f:
        assert [r["variant"] for r in csv.DictReader(f)] == ["base", "blocked"]
    # Run again: nothing left to run, the same table.
    again = sensitivity.run_sensitivity(out, LATTICE, ["base", "blocked"], threads=1,
                                        sigma_3=1e6, strain_rate=50.0, axial_strain=0.005,
                                        log=lambda m: None, workers=2)
    assert [r["q_max_MPa"] for r in again] == [r["q_max_MPa"] for r in rows]
