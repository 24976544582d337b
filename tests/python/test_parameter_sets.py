"""The named parameter sets (docs/configuration.md, "parameters"): the engine's default is
crushdem's set, `parameters = "table1"` is Table 1 as printed, and crushdem_sand.study's sets for
`crushdem-sand reproduce --parameters` hold the same values."""

import tomllib

import pytest

import crushdem_sand
from crushdem_sand import _core, study


def _engine_sets():
    return {name: tomllib.loads(text) for name, _, text in _core.parameter_sets()}


def test_the_study_module_and_the_engine_hold_the_same_sets():
    engine = _engine_sets()
    assert list(engine)[0] == "crushdem"
    for name in ("crushdem", "table1"):
        contact, crushing, _ = study.PARAMETER_SETS[name]
        for key, value in engine[name]["contact"].items():
            assert contact[key] == value, (name, key)
        for key, value in engine[name]["crushing"].items():
            assert crushing[key] == value, (name, key)


def test_a_simulation_gets_crushdems_set_unless_it_names_another():
    box = {"box": {"min": [0, 0, 0], "max": [1e-3, 1e-3, 1e-3]}}
    resolved = tomllib.loads(_core.resolved_config(box))
    assert resolved["contact"]["rotation"] == "blocked"
    resolved = tomllib.loads(_core.resolved_config({**box, "parameters": "table1"}))
    assert resolved["contact"]["rotation"] == "free"
    # The file's own key wins over its set.
    resolved = tomllib.loads(_core.resolved_config(
        {**box, "parameters": "table1", "contact": {"rotation": "blocked"}}))
    assert resolved["contact"]["rotation"] == "blocked"
    crushdem_sand.Simulation(parameters="table1", **box)
    with pytest.raises(crushdem_sand.ConfigError, match=r"parameters.*\"table2\".*\"table1\""):
        crushdem_sand.Simulation(parameters="table2", **box)


def test_check_names_the_set_and_where_each_key_came_from(tmp_path, capfd):
    cfg = tmp_path / "t.toml"
    cfg.write_text('parameters = "table1"\n'
                   '[box]\nmin = [0.0, 0.0, 0.0]\nmax = [1e-3, 1e-3, 1e-3]\n'
                   '[particles.generate]\ncount = 10\ndiameter_min = 1e-4\ndiameter_max = 2e-4\n'
                   '[run]\nsteps = 10\n[crushing]\nd0 = 2e-3\n')
    assert crushdem_sand.cli_main(["check", str(cfg)]) == 0
    out = capfd.readouterr().out
    assert 'parameters = "table1" (named by the file)' in out
    assert 'contact.rotation = "free" (from the set)' in out
    assert "crushing.d0 = 0.002 (set by the file)" in out



def test_a_laboratory_configuration_takes_the_set_by_name():
    # What a crushdem_sand.lab function hands the engine (lab._base): a section stays a table, the
    # set's name a top-level string.
    from crushdem_sand import lab

    sample = {"count": 500, "void_ratio": 0.95}
    for kw, rotation in (({}, "blocked"), ({"parameters": "table1"}, "free")):
        cfg = lab._base(sample, {"material": None, **kw})
        resolved = tomllib.loads(_core.resolved_run_config(cfg))
        assert resolved["contact"]["rotation"] == rotation
        assert resolved["parameters"] == kw.get("parameters", "crushdem")


def test_settings_of_an_earlier_table1_reproduction_still_match():
    # settings.json of a `reproduce --parameters table1` made when free rotation and d0 = d50
    # were the engine's defaults names neither key; read with those, it matches today's.
    today = study.settings(quick=True, parameters="table1")
    earlier = {**today, "contact": {k: v for k, v in today["contact"].items() if k != "rotation"},
               "crushing": {k: v for k, v in today["crushing"].items() if k != "d0"}}
    assert study.settings_changes(earlier, today)
    assert not study.settings_changes(study.with_earlier_defaults(earlier), today)
    # crushdem's set names both keys: nothing is filled in.
    chosen = study.settings(quick=True)
    assert study.with_earlier_defaults(chosen) == chosen
