"""The laboratory functions of crushdem_sand.lab come from the engine's stage kinds: their keyword
arguments that are stage keys take type, default and meaning from the C++ tables, their
keyword arguments are those callers have always used, and they build the stages they always
built; `lab.Result` reads each table of a run directory as a DataFrame of the right column
types. Nothing here runs a simulation (``lab.run`` is replaced by a recorder, the run
directories are written by hand)."""

import importlib.util
import inspect
import os
import sys

import pytest

import crushdem_sand
from crushdem_sand import _core, lab

TABLES = {section: {row["key"]: row for row in rows}
          for section, rows in _core.parameter_tables().items()}


def _default(kind, key):
    return TABLES["stage." + kind][key]["default"]


def test_every_stage_kind_has_its_table_and_docs():
    kinds = [k["name"] for k in _core.stage_kinds()]
    assert {"isotropic", "oedometric", "triaxial", "hold", "age"} <= set(kinds)
    assert len(set(kinds)) == len(kinds)
    assert sorted(s for s in TABLES if s.startswith("stage.")) == sorted(f"stage.{k}"
                                                                         for k in kinds)
    docs = crushdem_sand.parameter_reference()["stage"]
    for k in _core.stage_kinds():
        assert f'### type = "{k["name"]}": {k["description"]}' in docs
        for key in TABLES["stage." + k["name"]]:
            assert f"| `{key}` |" in docs
    assert "age" in [k["name"] for k in _core.stage_kinds() if k["needs_crack_growth"]]
    row = TABLES["stage.age"]["n_break"]
    assert row["type"] == "int" and isinstance(row["default"], int) and not row["required"]
    assert TABLES["stage.age"]["duration"]["required"]
    assert TABLES["stage.hold"]["axial"]["choices"] == '"fixed" or "servo"'


# The keyword arguments callers use (reproduce.py, sensitivity.py, the docs, the examples).
SIGNATURES = {
    "prepare_sample": "out side count void_ratio grading seed stress progress overwrite backend "
                      "material contact output parameters sample_keys",
    "isotropic_test": "out sample stress progress overwrite backend stage sections",
    "oedometric_test": "out sample stress strain_rate hold_steps unload_to progress overwrite "
                       "backend stage sections",
    "triaxial_test": "out sample sigma_3 strain_rate axial_strain stop_q hold_steps consolidate "
                     "progress overwrite backend stage sections",
    "oedometric_relaxation": "out sample stress duration strain_rate min_cycles n_break progress "
                             "overwrite backend stage age_stage branch_from sections",
    "creep_test": "out sample stress duration strain_rate min_cycles n_break progress overwrite "
                  "backend stage age_stage sections",
    "triaxial_relaxation": "out sample sigma_3 stop_q duration strain_rate axial_strain "
                           "min_cycles n_break progress overwrite backend stage age_stage "
                           "branch_from sections",
}


@pytest.mark.parametrize("name", sorted(SIGNATURES))
def test_laboratory_functions_keep_their_keyword_arguments(name):
    f = getattr(lab, name)
    assert getattr(crushdem_sand, name) is f
    assert f.__name__ == name and f.__module__ == "crushdem_sand.lab"
    assert list(inspect.signature(f).parameters) == SIGNATURES[name].split()


def _stage_keys(f):
    """{argument: (kind, key)} of the stage keys a function's docstring lists."""
    out = {}
    for line in f.__doc__.splitlines():
        line = line.strip()
        if line.startswith("* ``") and " stage, " in line:
            key = line[4:line.index("``", 4)]
            kind = line[line.index("(") + 1:line.index(" stage, ")]
            out[key] = (kind, key)
    return out


@pytest.mark.parametrize("name", sorted(SIGNATURES))
def test_stage_keys_take_type_default_and_meaning_from_the_tables(name):
    f = getattr(lab, name)
    sig = inspect.signature(f)
    own = {"strain_rate", "axial_strain", "duration"}  # the functions' own defaults
    for arg, (kind, key) in _stage_keys(f).items():
        row = TABLES["stage." + kind][key]
        p = sig.parameters[arg]
        assert p.annotation == row["type"], (name, arg)
        assert row["doc"] in f.__doc__, (name, arg)
        if arg in own or (name == "triaxial_relaxation" and arg == "stop_q"):
            continue
        if row["required"]:
            assert p.default is inspect.Parameter.empty, (name, arg)
        else:
            assert p.default == row["default"], (name, arg)
    if "n_break" in sig.parameters:
        assert sig.parameters["n_break"].default == _default("age", "n_break")
        assert sig.parameters["min_cycles"].default == _default("age", "min_cycles")
        assert set(_stage_keys(f)) >= {"n_break", "min_cycles", "duration"}


def test_sample_defaults_are_the_sample_table():
    sig = inspect.signature(lab.prepare_sample)
    for key in ("void_ratio", "seed", "stress"):
        assert sig.parameters[key].default == TABLES["sample"][key]["default"], key
        assert TABLES["sample"][key]["doc"] in lab.prepare_sample.__doc__


def test_a_changed_table_default_changes_the_functions(monkeypatch):
    """The defaults are read from the engine when the module loads, not written in Python: a
    table with another n_break gives functions with that default."""
    tables = _core.parameter_tables()
    for row in tables["stage.age"]:
        if row["key"] == "n_break":
            row["default"] = 7
    monkeypatch.setattr(_core, "parameter_tables", lambda: tables)
    spec = importlib.util.spec_from_file_location("crushdem_sand._lab_probe", lab.__file__)
    probe = importlib.util.module_from_spec(spec)
    probe.__package__ = "crushdem_sand"
    monkeypatch.setitem(sys.modules, "crushdem_sand._lab_probe", probe)
    spec.loader.exec_module(probe)
    for name in ("oedometric_relaxation", "creep_test", "triaxial_relaxation"):
        assert inspect.signature(getattr(probe, name)).parameters["n_break"].default == 7
        assert "default 7" in getattr(probe, name).__doc__


@pytest.fixture
def recorded(monkeypatch):
    """lab.run replaced: each call's (config, out, options) is recorded instead of run."""
    calls = []

    def record(config, out, **options):
        calls.append((config, os.fspath(out), options))
        return lab.Result(os.fspath(out))

    monkeypatch.setattr(lab, "run", record)
    return calls


def test_laboratory_functions_build_their_stages(recorded, tmp_path):
    sample = str(tmp_path / "sample.txt")
    particles = {"file": os.path.abspath(sample)}
    common = {"max_steps": 99}
    d_age = {"min_cycles": _default("age", "min_cycles"), "n_break": _default("age", "n_break")}

    lab.isotropic_test(tmp_path / "i", sample, stress=1e6, material={"friction": 0.3})
    cfg, out, options = recorded[-1]
    assert cfg == {"material": {"friction": 0.3}, "particles": particles,
                   "stage": [{"type": "isotropic", "name": "isotropic", "stress": 1e6}]}
    assert out == str(tmp_path / "i")
    assert options == {"progress": False, "overwrite": False, "backend": "cpu",
                       "branch_from": None, "branch_stage": None}

    lab.oedometric_test(tmp_path / "o", sample, stress=2e6, hold_steps=10, unload_to=1e5,
                        stage=common, backend="emulated", overwrite=True)
    cfg, _, options = recorded[-1]
    assert cfg["stage"] == [
        {"type": "oedometric", "name": "loading", "stress": 2e6, "strain_rate": 10.0, **common},
        {"type": "hold", "name": "hold", "steps": 10, **common},
        {"type": "oedometric", "name": "unloading", "stress": 1e5, "strain_rate": -10.0,
         **common}]
    assert options["backend"] == "emulated" and options["overwrite"] is True

    lab.triaxial_test(tmp_path / "t", {"count": 500}, sigma_3=1e6, hold_steps=5,
                      crushing={"d0": 1e-3})
    cfg, _, _ = recorded[-1]
    assert cfg["sample"] == {"count": 500} and "particles" not in cfg
    assert cfg["crushing"] == {"d0": 1e-3}  # no crack growth: no stage needs it
    assert cfg["stage"] == [
        {"type": "isotropic", "name": "isotropic", "stress": 1e6},
        {"type": "triaxial", "name": "shear", "sigma_3": 1e6, "strain_rate": 50.0,
         "axial_strain": 0.3, "stop_q": _default("triaxial", "stop_q")},
        {"type": "hold", "name": "hold", "steps": 5, "axial": "fixed", "lateral": "servo",
         "lateral_stress": 1e6}]
    lab.triaxial_test(tmp_path / "t2", sample, sigma_3=1e6, consolidate=False, stop_q=None)
    assert [st["type"] for st in recorded[-1][0]["stage"]] == ["triaxial"]
    assert "stop_q" not in recorded[-1][0]["stage"][0]  # None: not given

    lab.oedometric_relaxation(tmp_path / "r", sample, stress=1e6, n_break=4, stage=common,
                              age_stage={"max_strain_rate": 100.0}, crushing={"d0": 1e-3},
                              branch_from=tmp_path / "original")
    cfg, _, options = recorded[-1]
    assert cfg["crushing"] == {"d0": 1e-3, "crack_growth": True}
    assert cfg["stage"] == [
        {"type": "oedometric", "name": "loading", "stress": 1e6, "strain_rate": 10.0, **common},
        {"type": "age", "name": "relaxation", "duration": 86400.0, **d_age, "n_break": 4,
         **common, "max_strain_rate": 100.0}]
    assert options["branch_from"] == tmp_path / "original"
    assert options["branch_stage"] == "relaxation"

    lab.creep_test(tmp_path / "c", sample, stress=1e6, duration=60.0)
    cfg, _, options = recorded[-1]
    assert cfg["crushing"] == {"crack_growth": True}
    assert cfg["stage"][1] == {"type": "age", "name": "creep", "duration": 60.0, **d_age,
                               "axial": "servo", "axial_stress": 1e6}
    assert options["branch_stage"] is None

    lab.triaxial_relaxation(tmp_path / "x", sample, sigma_3=1e6, stop_q=2e6,
                            crushing={"crack_growth": False}, branch_from="shear_run")
    cfg, _, options = recorded[-1]
    assert cfg["crushing"] == {"crack_growth": False}  # given: kept
    assert cfg["stage"] == [
        {"type": "isotropic", "name": "isotropic", "stress": 1e6},
        {"type": "triaxial", "name": "shear", "sigma_3": 1e6, "strain_rate": 50.0,
         "axial_strain": 0.3, "stop_q": 2e6},
        {"type": "age", "name": "relaxation", "duration": 86400.0, **d_age, "axial": "fixed",
         "lateral": "servo", "lateral_stress": 1e6}]
    assert options["branch_stage"] == "shear"

    lab.prepare_sample(tmp_path / "s", count=500, contact={"law": "hertz"})
    cfg, _, _ = recorded[-1]
    assert cfg == {"contact": {"law": "hertz"},
                   "sample": {key: TABLES["sample"][key]["default"]
                              for key in ("void_ratio", "seed", "stress")} | {"count": 500}}


def test_arguments_are_checked_as_a_signature_checks_them(recorded, tmp_path):
    with pytest.raises(TypeError, match="stress"):
        lab.isotropic_test(tmp_path / "i", "s.txt")
    with pytest.raises(TypeError, match="stop_q"):
        lab.triaxial_relaxation(tmp_path / "x", "s.txt", sigma_3=1e6)
    with pytest.raises(TypeError):
        lab.creep_test(tmp_path / "c", "s.txt", 1e6)  # keys are keyword-only
    assert not recorded


def test_common_stage_keys_are_listed_in_the_module_docstring():
    for key in ("tolerance", "unbalanced", "max_strain_rate", "check_interval", "max_steps"):
        assert f"``{key}``" in lab.__doc__.split("Keys every stage kind has")[1]


def test_a_negative_hold_is_refused(tmp_path):
    with pytest.raises(crushdem_sand.ConfigError, match="hold_steps"):
        lab.oedometric_test(tmp_path / "o", str(tmp_path / "none.txt"), stress=1e6, hold_steps=-1)
    with pytest.raises(crushdem_sand.ConfigError, match="hold_steps"):
        lab.triaxial_test(tmp_path / "t", str(tmp_path / "none.txt"), sigma_3=1e6, hold_steps=2.5)


# --- crushdem_sand.lab.Result: a run directory's tables as DataFrames -----------------------------

def _write(path, text):
    path.write_text(text)
    return path


def _result_dir(tmp_path):
    """A run directory as the engine writes it (every value a number in %.17g, so a float column
    whose values happen to be whole, such as a wall at 0, reads like integers)."""
    run = tmp_path / "run"
    run.mkdir()
    _write(run / "timeseries.csv",
           "time_s,step,wall_zmin_position_m,wall_zmax_stress_Pa,n_contacts,stage,void_ratio\n"
           "0,0,0,0,0,0,0.75\n"
           "1.0000000000000001e-05,1000,0,250000.5,812,0,0.74\n"
           "2.0000000000000002e-05,2000,0,500001,830,1,0.73\n")
    _write(run / "events.csv", "ageing_time_s,stage,dynamic_phase,time_s,step,n_particles\n"
                               "0,1,0,2e-05,2000,500\n4.5,1,1,3e-05,3000,511\n")
    _write(run / "phases.csv", ",".join(lab._PHASES_COLUMNS) + "\n"
           + "1,0,0,0,2e-05,1e6,5e5,5e5,0,0,0,0.5,0,0,500\n"
           + "1,0,500,0,2.5e-05,9e5,5e5,4e5,-0.01,1e-4,0,0.1,1,0,511\n")
    _write(run / "breakage.csv", ",".join(lab._BREAKAGE_COLUMNS) + "\n"
           + "1e-05,1000,17,0.0002,instant,4e8,3.9e8,1,13,500,0.1,0.2,0.3\n"
           + "2e-05,2000,3,0.0001,crack,3e8,2.9e8,2,12,501 502,0.4,0.5,0.6\n")
    _write(run / "grading.csv", "time_s,step,passing_1e-05_m,passing_0.001_m\n0,0,0,1\n")
    _write(run / "summary.json", '{"stages": [{"name": "loading"}, {"name": "relaxation"}]}')
    _write(run / "timing.json", '{"wall_seconds": 1.5}')
    _write(run / "sample.txt", "0 0 0 0 1e-4\n")
    return run


def test_result_properties_are_small_and_tables_are_methods():
    # The rule of the class docstring: metadata as properties, each table a method.
    members = {name: value for name, value in vars(lab.Result).items()
               if not name.startswith("_")}
    properties = {name for name, value in members.items() if isinstance(value, property)}
    assert properties == {"summary", "timing", "stages", "sample_file"}
    tables = set(members) - properties
    assert tables == {"timeseries", "events", "phases", "breakages", "table"}
    for name in tables:
        assert inspect.signature(members[name]).return_annotation == "pd.DataFrame", name


def test_result_reads_each_table_as_a_dataframe(tmp_path):
    import numpy as np
    import pandas as pd

    run = _result_dir(tmp_path)
    r = lab.Result(run)  # a path-like works
    assert r.directory == str(run)
    assert r.stages == [{"name": "loading"}, {"name": "relaxation"}]
    assert r.timing["wall_seconds"] == 1.5 and r.sample_file == str(run / "sample.txt")
    ts = r.timeseries()
    assert isinstance(ts, pd.DataFrame) and len(ts) == 3
    assert list(ts.columns) == ["time_s", "step", "wall_zmin_position_m", "wall_zmax_stress_Pa",
                                "n_contacts", "stage", "void_ratio"]
    # Counts and indices are integers; a measure stays float even where its values are whole.
    assert {c: str(t) for c, t in ts.dtypes.items()} == {
        "time_s": "float64", "step": "int64", "wall_zmin_position_m": "float64",
        "wall_zmax_stress_Pa": "float64", "n_contacts": "int64", "stage": "int64",
        "void_ratio": "float64"}
    assert ts["step"].tolist() == [0, 1000, 2000]
    assert ts["time_s"].iloc[1] == 1.0000000000000001e-05  # the bits as written
    ev = r.events()
    assert ev["dynamic_phase"].tolist() == [0, 1] and ev["n_particles"].dtype == np.int64
    assert ev["ageing_time_s"].tolist() == [0.0, 4.5]
    ph = r.phases()
    assert list(ph.columns) == list(lab._PHASES_COLUMNS)
    assert ph["cycle"].tolist() == [0, 500] and ph["breakages_instant"].dtype == np.int64
    br = r.breakages()
    assert br["id"].tolist() == [17, 3] and br["fragments"].dtype == np.int64
    assert br["cause"].tolist() == ["instant", "crack"]
    assert br["fragment_ids"].tolist() == ["500", "501 502"]  # text, one id or several
    assert br["x_m"].tolist() == [0.1, 0.4]
    grading = r.table("grading")
    assert grading.equals(r.table("grading.csv")) and grading["passing_1e-05_m"].dtype == float
    # Read anew on every call: a run still going gives the rows written so far.
    with open(run / "events.csv", "a") as f:
        f.write("9,1,2,4e-05,4000,520\n")
    assert len(r.events()) == 3


def test_result_tables_a_run_did_not_write_are_empty_with_their_columns(tmp_path):
    import numpy as np

    run = tmp_path / "plain"
    run.mkdir()
    r = lab.Result(str(run))
    with pytest.raises(FileNotFoundError, match="timeseries.csv"):
        r.timeseries()
    with pytest.raises(FileNotFoundError, match="grading.csv"):
        r.table("grading")
    assert r.sample_file is None
    br = r.breakages()  # no [crushing]
    assert len(br) == 0 and list(br.columns) == list(lab._BREAKAGE_COLUMNS)
    assert br["id"].dtype == np.int64 and br["diameter_m"].dtype == np.float64
    assert len(r.phases()) == 0 and list(r.phases().columns) == list(lab._PHASES_COLUMNS)
    ev = r.events()  # no age stage: the columns every events.csv starts with
    assert len(ev) == 0 and list(ev.columns) == ["ageing_time_s", "stage", "dynamic_phase"]
    # Written but empty (created, header not yet there) or header only: no rows either.
    _write(run / "events.csv", "")
    assert list(r.events().columns) == ["ageing_time_s", "stage", "dynamic_phase"]
    _write(run / "breakage.csv", ",".join(lab._BREAKAGE_COLUMNS) + "\n")
    br = r.breakages()
    assert len(br) == 0 and br["step"].dtype == np.int64 and br["x_m"].dtype == np.float64


def test_a_count_with_a_missing_value_is_float(tmp_path):
    import numpy as np

    path = _write(tmp_path / "t.csv", "step,n_contacts,mean_Fn_N\n0,,nan\n10,5,0.5\n")
    t = lab.read_table(path)
    assert t["step"].dtype == np.int64
    assert t["n_contacts"].dtype == np.float64 and np.isnan(t["n_contacts"].iloc[0])
    assert np.isnan(t["mean_Fn_N"].iloc[0]) and t["mean_Fn_N"].iloc[1] == 0.5
