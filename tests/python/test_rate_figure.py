"""scripts/rate_figure.py: the inertial number of a pile installation from its configuration, and
the figures of a velocity sweep grouped by velocity (means and standard errors over the seeds),
on a sweep directory written here (no run needed)."""

import math
import os
import shutil

import pytest

pd = pytest.importorskip("pandas")
pytest.importorskip("matplotlib")

from _source import load_script  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
rate_figure = load_script("rate_figure")
PILE = os.path.join(ROOT, "examples", "pile_small.toml")


def test_inertial_number_of_the_small_pile():
    # v / D = 0.2 / 0.6e-3; d50 = 0.21 mm (the grading's 50 % passing); sqrt(100e3 / 2650).
    expected = 0.2 / 0.6e-3 * 0.21e-3 / math.sqrt(100e3 / 2650.0)
    assert rate_figure.inertial_number(PILE, "install", 0.2) == pytest.approx(expected, rel=1e-12)
    assert rate_figure.inertial_number(PILE, "install", 0.4) == pytest.approx(2 * expected)


def test_a_sweep_is_grouped_by_velocity(tmp_path):
    (tmp_path / "configs").mkdir()
    rows = []
    for v in (0.1, 0.2):
        for seed, q in ((1, 2.0), (2, 4.0)):
            name = f"v{v}_s{seed}"
            shutil.copy(PILE, tmp_path / "configs" / f"{name}.toml")
            rows.append({"variant": name, "status": "done", "stage.install.velocity": v,
                         "sample.seed": seed, "install.q_c_mean_MPa": q * v,
                         "install.tip_load_end_N": 1.0, "install.shaft_load_end_N": 0.1,
                         "install.sigma_r_shaft_end_kPa": 200.0, "breakages": seed})
    rows.append({"variant": "broken", "status": "failed", "stage.install.velocity": 0.4})
    pd.DataFrame(rows).to_csv(tmp_path / "results.csv", index=False)
    assert rate_figure.main([str(tmp_path), "--out", str(tmp_path / "fig")]) == 0
    table = pd.read_csv(tmp_path / "fig" / "pile_rate.csv")
    assert list(table["velocity_m_s"]) == [0.1, 0.2] and list(table["runs"]) == [2, 2]
    assert table["q_c_mean_MPa_mean"].tolist() == pytest.approx([0.3, 0.6])
    # Standard error of two values a, b: |a - b| / 2.
    assert table["q_c_mean_MPa_se"].tolist() == pytest.approx([0.1, 0.2])
    assert table["breakages_mean"].tolist() == pytest.approx([1.5, 1.5])
    # Each sample's q_c against its own at the slowest velocity: 2 for both here.
    assert table["q_c_mean_ratio_mean"].tolist() == pytest.approx([1.0, 2.0])
    assert table["q_c_mean_ratio_sd"].tolist() == pytest.approx([0.0, 0.0])
    assert (table["inertial_number"][1] / table["inertial_number"][0]) == pytest.approx(2.0)
    assert os.path.getsize(tmp_path / "fig" / "pile_rate.png") > 0
    # A stage the configurations do not have is refused by name.
    assert rate_figure.main([str(tmp_path), "--stage", "push", "--out", str(tmp_path)]) == 2
    # A sweep over something else is refused by name.
    pd.DataFrame([{"variant": "a", "status": "done"}]).to_csv(tmp_path / "results.csv",
                                                            index=False)
    assert rate_figure.main([str(tmp_path)]) == 2
