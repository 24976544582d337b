"""scripts/pile_sweep_figure.py: the capacities of a sweep of pile experiments by variant and
ageing time, with each variant's fits, on a sweep directory written here (no run needed)."""

import json
import math
import os

import pytest

pd = pytest.importorskip("pandas")
pytest.importorskip("matplotlib")

from _source import load_script  # noqa: E402

pile_sweep_figure = load_script("pile_sweep_figure")


def _sweep_dir(tmp_path):
    rows = []
    for n, A in ((1, -0.05), (2, -0.08)):
        row = {"variant": f"nb{n}", "status": "done", "stage.*.n_break": n, "sample.stress": 5e6,
               "setup.compression.A": A, "setup.compression.A_std": 0.01,
               "setup.compression.Q0_N": 17.0, "setup.compression.t0_s": 3600.0,
               "setup.compression (shaft).A": A / 2,
               "setup.compression (shaft).A_std": 0.02, "setup.compression (shaft).Q0_N": 3.0}
        for t in (3600, 86400):
            row[f"compression.capacity_N@{t}s"] = 17.0 * (1 + A * (t > 3600))
            row[f"compression.shaft_at_capacity_N@{t}s"] = 3.0
        rows.append(row)
    rows.append({"variant": "nb4", "status": "failed", "stage.*.n_break": 4,
                 "sample.stress": 5e6})
    pd.DataFrame(rows).to_csv(tmp_path / "results.csv", index=False)
    (tmp_path / "sweep.json").write_text(json.dumps(
        {"keys": ["sample.stress", "stage.*.n_break"], "names": {"stage.*.n_break": "n_break"}}))
    return str(tmp_path)


def test_the_capacities_are_tabulated_by_variant_and_ageing_time(tmp_path):
    table = pile_sweep_figure.rows(_sweep_dir(tmp_path), "compression")
    assert [(r["variant"], r["ageing_time_s"]) for r in table] == [
        ("nb1", 3600.0), ("nb1", 86400.0), ("nb2", 3600.0), ("nb2", 86400.0)]  # nb4 failed
    assert table[3]["capacity_N"] == pytest.approx(17.0 * 0.92)
    assert table[2]["A"] == -0.08 and table[2]["shaft_A"] == -0.04
    assert table[0]["stage.*.n_break"] == 1 and table[0]["Q0_N"] == 17.0
    assert pile_sweep_figure.short_names(str(tmp_path)) == {"stage.*.n_break": "n_break"}
    assert table[0]["t0_s"] == 3600.0 and math.isnan(table[0]["shaft_t0_s"])  # not tabulated
    with pytest.raises(ValueError, match="no capacities of load test 'tension'"):
        pile_sweep_figure.rows(str(tmp_path), "tension")
    # No variant finished yet: said, not a crash of the table.
    df = pd.read_csv(tmp_path / "results.csv")
    df["status"] = "failed"
    df.to_csv(tmp_path / "results.csv", index=False)
    with pytest.raises(ValueError, match="no finished variant"):
        pile_sweep_figure.rows(str(tmp_path), "compression")
    assert pile_sweep_figure.main([str(tmp_path)]) == 2


def test_the_command_writes_its_table_and_figure(tmp_path, capsys):
    d = _sweep_dir(tmp_path)
    assert pile_sweep_figure.main([d]) == 0
    df = pd.read_csv(os.path.join(d, "pile_sweep.csv"))
    assert len(df) == 4 and set(df["stage.*.n_break"]) == {1, 2}
    assert os.path.getsize(os.path.join(d, "pile_sweep.png")) > 1000
    printed = capsys.readouterr().out
    assert "stage.*.n_break" in printed and "sample.stress" not in printed  # the same for all
    assert pile_sweep_figure.main([str(tmp_path / "missing")]) == 2
