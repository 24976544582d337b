"""``crushdem-sand calibrate`` (python/crushdem_sand/calibrate.py) on a cheap synthetic target: the
isotropic stress that brings the 64-grain lattice of tests/data to a void ratio of 0.910 (the
void ratio falls monotonically with the stress: 0.924 at 0.4 MPa, 0.903 at 3 MPa)."""

import json
import os

import pytest

pytest.importorskip("distributed")
pytest.importorskip("scipy")

from crushdem_sand import calibrate, sweep  # noqa: E402

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data")


def _write(tmp_path, body):
    path = tmp_path / "calibration.toml"
    path.write_text(f'base = "{os.path.join(DATA, "isotropic_lattice.toml")}"\n' + body)
    return str(path)


def test_converges_within_tolerance_in_few_evaluations(tmp_path):
    path = _write(tmp_path, 'tolerance = 5e-4\nmax_evaluations = 10\n'
                            '[parameters]\n"stage.isotropic.stress" = [4e5, 3e6]\n'
                            '[targets]\n"final.void_ratio" = 0.910\n')
    out = tmp_path / "out"
    result = calibrate.calibrate(path, str(out), workers=2, log=lambda m: None)
    assert result["converged"], result
    assert result["evaluations"] <= 10
    stress = result["calibrated"]["stage.isotropic.stress"]
    assert 1e6 < stress < 3e6
    # The calibrated configuration, run on its own, meets the target.
    assert "stress = " in (out / "calibrated.toml").read_text()
    best = [d for d in os.listdir(out / "runs")
            if d == sweep.variant_name({"stage.isotropic.stress": stress})]
    assert best
    e = sweep.summary_figures(str(out / "runs" / best[0]))["final.void_ratio"]
    assert abs(e - 0.910) / 0.910 <= 5e-4
    rows = (out / "evaluations.csv").read_text().splitlines()
    assert len(rows) == result["evaluations"] + 1
    assert (out / "convergence.png").is_file()
    assert json.loads((out / "calibration.json").read_text())["converged"]
    # Again: the same path through the finished runs, the same answer.
    again = calibrate.calibrate(path, str(out), workers=2, log=lambda m: None)
    assert again["calibrated"] == result["calibrated"]


def test_bounds_that_do_not_bracket_the_target_are_named(tmp_path):
    path = _write(tmp_path, '[parameters]\n"stage.isotropic.stress" = [4e5, 1e6]\n'
                            '[targets]\n"final.void_ratio" = 0.85\n')
    with pytest.raises(ValueError, match="does not bracket"):
        calibrate.calibrate(path, str(tmp_path / "out"), workers=2, log=lambda m: None)


def test_the_file_is_checked(tmp_path):
    with pytest.raises(ValueError, match="one or two keys"):
        calibrate.read_calibration(_write(tmp_path, '[targets]\n"final.void_ratio" = 0.9\n'))
    with pytest.raises(ValueError, match="low < high"):
        calibrate.read_calibration(_write(tmp_path, '[parameters]\n"material.friction" = [0.5, '
                                                    '0.1]\n[targets]\n"a" = 1.0\n'))
    # One stage's key by its index and by its name: the second would overwrite the first.
    with pytest.raises(ValueError, match="both set stress of stage 0"):
        calibrate.read_calibration(_write(tmp_path, '[parameters]\n"stage.0.stress" = [1e5, 1e6]\n'
                                                    '"stage.isotropic.stress" = [1e5, 1e6]\n'
                                                    '[targets]\n"final.void_ratio" = 0.9\n'))
