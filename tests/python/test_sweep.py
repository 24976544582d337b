"""``crushdem-sand sweep`` (python/crushdem_sand/sweep.py) on a local Dask cluster of 2 workers,
with the 64-grain lattice of tests/data (a run takes a second or two): the table equals the runs
made one by one; a stopped sweep (SIGTERM, or SIGKILL of one worker) run again completes with the
same results; a bad value fails alone with its error in the table; --scheduler reaches a scheduler
and a worker started here."""

import csv
import glob
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("distributed")
pytest.importorskip("pandas")

from crushdem_sand import lab, sweep  # noqa: E402

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data")
BASE = os.path.join(DATA, "isotropic_lattice.toml")
EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))), "examples")
# Figures compared between runs (wall-clock is not).
COMPARED = ("isotropic.K0_end", "final.void_ratio", "final.coordination_number",
            "final.mean_stress_Pa", "steps")


def _write_sweep(tmp_path, vary, base=BASE, extra=""):
    text = f'base = "{base}"\n{extra}\n[vary]\n'
    for k, v in vary.items():
        text += f'"{k}" = {json.dumps(v)}\n'
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    return str(path)


def _long_base(tmp_path, hold_steps):
    """The lattice base with a hold stage after the compression, to make each run last."""
    text = open(BASE).read().replace('file = "lattice_64.txt"',
                                     f'file = "{os.path.join(DATA, "lattice_64.txt")}"')
    text += f'\n[[stage]]\ntype = "hold"\nname = "hold"\nsteps = {hold_steps}\n'
    path = tmp_path / "long.toml"
    path.write_text(text)
    return str(path)


def _figures(df):
    return {row["variant"]: tuple(row[c] for c in COMPARED) for _, row in df.iterrows()}


def test_read_sweep_names_what_is_wrong(tmp_path):
    with pytest.raises(ValueError, match="base"):
        sweep.read_sweep(_write_sweep(tmp_path, {"material.friction": [0.2]}, base="nope.toml"))
    with pytest.raises(ValueError, match="must be a list"):
        p = tmp_path / "s.toml"
        p.write_text(f'base = "{BASE}"\n[vary]\n"material.friction" = 0.2\n')
        sweep.read_sweep(str(p))
    with pytest.raises(ValueError, match="no stage 'shear'"):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.shear.stress": [1e6]}))
    with pytest.raises(ValueError, match="one length"):
        p = tmp_path / "z.toml"
        p.write_text(f'base = "{BASE}"\n[zip]\n"a.b" = [1, 2]\n"c.d" = [1]\n')
        sweep.read_sweep(str(p))
    with pytest.raises(ValueError, match="unknown key"):
        p = tmp_path / "u.toml"
        p.write_text(f'base = "{BASE}"\nvaries = 1\n[vary]\n"a.b" = [1]\n')
        sweep.read_sweep(str(p))
    s = sweep.read_sweep(_write_sweep(tmp_path, {"stage.isotropic.stress": [5e5, 1e6],
                                                 "material.friction": [0.2, 0.4]}))
    names = [v["name"] for v in sweep.variants(s)]
    assert len(names) == 4 and len(set(names)) == 4
    assert names[0] == "stage.isotropic.stress=500000.0__material.friction=0.2"


def test_a_sweep_gives_the_table_of_the_runs_made_one_by_one(tmp_path):
    vary = {"stage.isotropic.stress": [5e5, 1e6], "material.friction": [0.2, 0.4]}
    df = sweep.sweep(_write_sweep(tmp_path, vary), str(tmp_path / "out"), workers=2,
                     progress=False, log=lambda m: None)
    assert list(df["status"]) == ["done"] * 4
    assert set(df.columns) >= {"stage.isotropic.stress", "material.friction", "run_dir",
                               "wall_s", *COMPARED}
    assert os.path.isfile(tmp_path / "out" / "results.csv")
    assert os.path.isfile(tmp_path / "out" / "results.parquet")
    assert os.path.isfile(tmp_path / "out" / "results.png")
    import tomllib

    with open(BASE, "rb") as f:
        base = tomllib.load(f)
    for _, row in df.iterrows():
        cfg = json.loads(json.dumps(base))
        cfg["stage"][0]["stress"] = row["stage.isotropic.stress"]
        cfg.setdefault("material", {})["friction"] = row["material.friction"]
        alone = tmp_path / "alone" / row["variant"]
        lab.run(cfg, alone, base_dir=DATA)
        mine = sweep.summary_figures(str(alone))
        assert tuple(mine[c] for c in COMPARED) == tuple(row[c] for c in COMPARED)
    # Run again: everything is finished, nothing runs, the same table.
    again = sweep.sweep(_write_sweep(tmp_path, vary), str(tmp_path / "out"), workers=2,
                        progress=False, log=lambda m: None)
    assert _figures(again) == _figures(df)


def test_a_sweep_runs_on_another_backend(tmp_path):
    """Every variant on the emulated device (the GPU's step on the host): done, and the runs say
    which backend advanced them."""
    df = sweep.sweep(_write_sweep(tmp_path, {"material.friction": [0.2, 0.4]}),
                     str(tmp_path / "out"), workers=2, progress=False, log=lambda m: None,
                     backend="emulated")
    assert list(df["status"]) == ["done"] * 2
    for run_dir in df["run_dir"]:
        with open(os.path.join(run_dir, "timing.json")) as f:
            assert json.load(f)["backend"] == "emulated"


def test_a_bad_value_fails_alone_with_its_error(tmp_path):
    df = sweep.sweep(_write_sweep(tmp_path, {"material.friction": [0.3, -1.0]}),
                     str(tmp_path / "out"), workers=2, progress=False, log=lambda m: None)
    by = {row["material.friction"]: row for _, row in df.iterrows()}
    assert by[0.3]["status"] == "done"
    assert by[-1.0]["status"] == "failed"
    assert "material.friction" in by[-1.0]["error"]


def _sweep_process(path, out, workers):
    return subprocess.Popen([sys.executable, "-m", "crushdem_sand", "sweep", path, "--out", out,
                             "--workers", str(workers)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def _children(pid):
    kids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        kids.append(int(entry))
            except (OSError, IndexError, ValueError):
                pass
    return kids


def _runs_under(pid):
    """(worker pid, run pid) of the crushdem runs started below process pid."""
    found, stack = [], [pid]
    while stack:
        p = stack.pop()
        for c in _children(p):
            try:
                cmd = open(f"/proc/{c}/cmdline").read().split("\0")
            except OSError:
                continue
            if "crushdem_sand" in cmd and ("run" in cmd or "resume" in cmd) and "sweep" not in cmd:
                found.append((p, c))
            stack.append(c)
    return found


def _wait_for_runs(proc, n=1, timeout=60.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        runs = _runs_under(proc.pid)
        if len(runs) >= n:
            return runs
        time.sleep(0.2)
    raise AssertionError("no crushdem run started")


@pytest.mark.parametrize("stop", ["sigterm", "sigkill_worker"])
def test_a_stopped_sweep_run_again_completes_with_the_same_results(tmp_path, stop):
    base = _long_base(tmp_path, hold_steps=150000)
    vary = {"stage.isotropic.stress": [5e5, 1e6, 2e6, 4e6]}
    path = _write_sweep(tmp_path, vary, base=base)
    reference = sweep.sweep(path, str(tmp_path / "whole"), workers=2, progress=False,
                            log=lambda m: None)
    out = str(tmp_path / "stopped")
    proc = _sweep_process(path, out, 2)
    runs = _wait_for_runs(proc, 2)
    time.sleep(1.0)  # well inside the runs (each takes a few seconds)
    if stop == "sigterm":
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=120)
        assert proc.returncode == 128 + signal.SIGTERM, proc.stdout.read()
        done = [d for d in os.listdir(os.path.join(out, "runs"))
                if os.path.isfile(os.path.join(out, "runs", d, "summary.json"))]
        assert len(done) < 4  # it really stopped mid-way
    else:
        worker, _run = runs[0]
        os.kill(worker, signal.SIGKILL)  # the run gets SIGTERM, saves its checkpoint, stops
        proc.wait(timeout=300)
    df = sweep.sweep(path, out, workers=2, progress=False, log=lambda m: None)
    assert list(df["status"]) == ["done"] * 4
    assert _figures(df) == {k: v for k, v in _figures(reference).items()}
    for name in df["variant"]:  # byte-identical results, as an uninterrupted run's
        for f in ("timeseries.csv", "summary.json"):
            a = open(os.path.join(tmp_path, "whole", "runs", name, f)).read()
            b = open(os.path.join(out, "runs", name, f)).read()
            assert a == b, (name, f)


def test_scheduler_option_reaches_an_existing_cluster(tmp_path):
    dask = shutil.which("dask", path=os.path.dirname(sys.executable))
    if dask is None:
        pytest.skip("the dask command is not installed beside this Python")
    file = str(tmp_path / "scheduler.json")
    sched = subprocess.Popen([dask, "scheduler", "--scheduler-file", file, "--port", "0",
                              "--dashboard-address", ":0"], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    worker = None
    try:
        t0 = time.time()
        while not os.path.isfile(file) and time.time() - t0 < 60:
            time.sleep(0.2)
        worker = subprocess.Popen([dask, "worker", "--scheduler-file", file, "--nthreads", "1",
                                   "--no-dashboard"], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        with open(file) as f:
            address = json.load(f)["address"]
        df = sweep.sweep(_write_sweep(tmp_path, {"material.friction": [0.2, 0.4]}),
                         str(tmp_path / "out"), scheduler=address, progress=False,
                         log=lambda m: None)
        assert list(df["status"]) == ["done", "done"]
    finally:
        for p in (worker, sched):
            if p is not None:
                p.terminate()
                p.wait(timeout=30)


def test_a_sweep_branches_from_a_loaded_state(tmp_path):
    """Every variant starts from the original's state at the start of its hold stage: the
    compression is not repeated, and the unchanged part of the results is the original's."""
    base = _long_base(tmp_path, hold_steps=20000)
    original = tmp_path / "original"
    import tomllib

    with open(base, "rb") as f:
        lab.run(tomllib.load(f), original)
    path = _write_sweep(tmp_path, {"stage.hold.steps": [10000, 30000]}, base=base,
                        extra=f'from = "{original}:hold"')
    df = sweep.sweep(path, str(tmp_path / "out"), workers=2, progress=False, log=lambda m: None)
    assert list(df["status"]) == ["done", "done"]
    orig = sweep.summary_figures(str(original))
    for _, row in df.iterrows():
        assert row["steps"] == orig["steps"] - 20000 + row["stage.hold.steps"]
        assert row["isotropic.K0_end"] == orig["isotropic.K0_end"]
        summary = json.load(open(os.path.join(row["run_dir"], "summary.json")))
        assert summary["branched_from"]["stage"] == 1


def test_named_variants_set_their_own_keys(tmp_path):
    """[[variant]] tables: one factor whose entries set their own keys and name their runs;
    combined with [vary] as a product; bad names and nested values are refused by name."""
    path = _write_sweep(tmp_path, {"output.interval": [1000, 2000]}, extra=(
        '[[variant]]\nname = "plain"\n'
        '[[variant]]\nname = "soft"\n"stage.isotropic.stress" = 5e5\n"contact.law" = "rough"\n'))
    listed = sweep.variants(sweep.read_sweep(path))
    assert [v["name"] for v in listed] == [
        "plain__output.interval=1000", "soft__output.interval=1000",
        "plain__output.interval=2000", "soft__output.interval=2000"]
    soft = listed[1]["config"]
    assert soft["stage"][0]["stress"] == 5e5 and soft["contact"]["law"] == "rough"
    assert listed[0]["config"]["stage"][0]["stress"] == 1e6  # the base's value
    for bad, message in (('[[variant]]\nname = "a b"\n', "directory name"),
                         ('[[variant]]\nname = "a"\n[[variant]]\nname = "a"\n', "two variants"),
                         ('[[variant]]\nname = "a"\n"contact.law" = ["x"]\n', "one value"),
                         ('[[variant]]\nname = "a"\nlaw = "rough"\n', "not a dotted key")):
        with pytest.raises(ValueError, match=message):
            sweep.read_sweep(_write_sweep(tmp_path, {"output.interval": [1000]}, extra=bad))


def test_stages_keeps_some_of_the_base_stages(tmp_path):
    """stages = [...]: the variants run only the named (or numbered) stages of the base, in the
    base's order; a stage that is not there, a repeat or a non-list is refused by name."""
    base = _long_base(tmp_path, 100)
    listed = sweep.variants(sweep.read_sweep(_write_sweep(
        tmp_path, {"material.friction": [0.2]}, base=base, extra='stages = ["hold"]')))
    assert [st["name"] for st in listed[0]["config"]["stage"]] == ["hold"]
    kept = sweep.read_sweep(_write_sweep(tmp_path, {"stage.hold.steps": [5]}, base=base,
                                         extra='stages = [1, "isotropic"]'))
    assert [st["name"] for st in sweep.variants(kept)[0]["config"]["stage"]] == [
        "isotropic", "hold"]
    for bad, message in (('stages = ["shear"]', "no stage 'shear'"),
                         ('stages = [2]', "no stage 2"),
                         ('stages = ["hold", 1]', "twice"),
                         ('stages = "hold"', "a list of stage names")):
        with pytest.raises(ValueError, match=message):
            sweep.read_sweep(_write_sweep(tmp_path, {"material.friction": [0.2]}, base=base,
                                          extra=bad))
    # With from, the branch's first stages must be the base's: only later ones may be left out.
    assert sweep.read_sweep(_write_sweep(tmp_path, {"material.friction": [0.2]}, base=base,
                                         extra='from = "x:isotropic"\nstages = ["isotropic"]'))
    with pytest.raises(ValueError, match="first stages in order"):
        sweep.read_sweep(_write_sweep(tmp_path, {"material.friction": [0.2]}, base=base,
                                      extra='from = "x:hold"\nstages = ["hold"]'))
    # A varied key of a stage that is left out is refused.
    with pytest.raises(ValueError, match="no stage 'isotropic'"):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.isotropic.stress": [1e6]}, base=base,
                                      extra='stages = ["hold"]'))


def test_a_star_stage_key_sets_every_stage_that_has_it(tmp_path):
    """stage.*.KEY: the key in every stage of the base that sets it, and in no other; refused
    when no stage sets it, or when a named stage's same key is varied beside it."""
    base = _long_base(tmp_path, 100)
    text = open(base).read() + '\n[[stage]]\ntype = "hold"\nname = "hold2"\nsteps = 300\n'
    with open(base, "w") as f:
        f.write(text)
    listed = sweep.variants(sweep.read_sweep(_write_sweep(
        tmp_path, {"stage.*.steps": [7, 9]}, base=base)))
    assert [v["name"] for v in listed] == ["stage.-.steps=7", "stage.-.steps=9"]
    stages = listed[1]["config"]["stage"]
    assert [st.get("steps") for st in stages] == [None, 9, 9]  # the isotropic stage has none
    with pytest.raises(ValueError, match="no stage of the base sets duration"):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.*.duration": [1.0]}, base=base))
    with pytest.raises(ValueError, match="both set steps"):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.*.steps": [7],
                                                 "stage.hold.steps": [8]}, base=base))
    # Two named variants, one setting each, never set both in one run; one variant with both does.
    two = ('[[variant]]\nname = "all"\n"stage.*.steps" = 7\n'
           '[[variant]]\nname = "one"\n"stage.hold.steps" = 8\n')
    listed = sweep.variants(sweep.read_sweep(_write_sweep(
        tmp_path, {"material.friction": [0.2]}, base=base, extra=two)))
    assert [[st.get("steps") for st in v["config"]["stage"]] for v in listed] == [
        [None, 7, 7], [None, 8, 300]]
    with pytest.raises(ValueError, match="both set steps"):
        sweep.read_sweep(_write_sweep(tmp_path, {"material.friction": [0.2]}, base=base, extra=(
            '[[variant]]\nname = "both"\n"stage.*.steps" = 7\n"stage.hold.steps" = 8\n')))


def test_a_body_key_is_varied_by_name_index_or_star(tmp_path):
    """body.NAME|INDEX|*.KEY: a [[body]]'s key, as a stage's (examples/pile_small.toml's pile);
    the varied configuration is accepted by crushdem with the value in its body; an unknown
    body, a base without bodies, a body's name and a key set twice are refused by name."""
    import tomllib

    from crushdem_sand import _core

    base = tmp_path / "pile.toml"
    text = open(os.path.join(EXAMPLES, "pile_small.toml")).read()
    base.write_text(text + '\n[[body]]\nname = "lid"\nshape = "disk"\norigin = [0.0, 0.0, 0.04]'
                    '\naxis = [0.0, 0.0, -1.0]\nradius = 1e-3\nfriction = 0.1\n')
    listed = sweep.variants(sweep.read_sweep(_write_sweep(
        tmp_path, {"body.pile.friction": [0.1, 0.5], "body.0.half_angle": [45.0]},
        base=str(base))))
    assert [v["name"] for v in listed] == ["body.pile.friction=0.1__body.0.half_angle=45.0",
                                           "body.pile.friction=0.5__body.0.half_angle=45.0"]
    bodies = listed[1]["config"]["body"]
    assert (bodies[0]["friction"], bodies[0]["half_angle"], bodies[1]["friction"]) == (
        0.5, 45.0, 0.1)
    resolved = tomllib.loads(_core.resolved_run_config(listed[1]["config"], str(tmp_path)))
    assert [(b["name"], b["friction"]) for b in resolved["body"]] == [("pile", 0.5), ("lid", 0.1)]
    assert resolved["body"][0]["half_angle"] == 45.0
    every = sweep.variants(sweep.read_sweep(_write_sweep(
        tmp_path, {"body.*.friction": [0.4]}, base=str(base))))
    assert [b["friction"] for b in every[0]["config"]["body"]] == [0.4, 0.4]
    for vary, message in (({"body.tube.friction": [0.1]}, r"no body 'tube' \(bodies: pile, lid\)"),
                          ({"body.*.height": [0.1]}, "no body of the base sets height"),
                          ({"body.pile.name": ["p"]}, "name is how stages"),
                          ({"body.friction": [0.1]}, "body.INDEX.KEY"),
                          ({"body.*.friction": [0.1], "body.lid.friction": [0.2]},
                           "both set friction")):
        with pytest.raises(ValueError, match=message):
            sweep.read_sweep(_write_sweep(tmp_path, vary, base=str(base)))
    with pytest.raises(ValueError, match=r"needs \[\[body\]\] tables"):
        sweep.read_sweep(_write_sweep(tmp_path, {"body.0.friction": [0.1]}))
    # One body's key by its index and by its name is one key varied twice.
    with pytest.raises(ValueError, match="both set friction of body 0"):
        sweep.read_sweep(_write_sweep(tmp_path, {"body.0.friction": [0.1],
                                                 "body.pile.friction": [0.5]}, base=str(base)))
    with pytest.raises(ValueError, match="both set steps of stage 1"):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.1.steps": [7], "stage.unload.steps": [8]},
                                      base=str(base)))
    for key, message in (("body.lid.friction.x", "body.INDEX.KEY"), ("body.lid.", "body.INDEX.KEY"),
                         ("body.\u00b2.friction", "no body"), ("stage.*.name", "name is how")):
        with pytest.raises(ValueError, match=message):
            sweep.read_sweep(_write_sweep(tmp_path, {key: [0.1]}, base=str(base)))
    # A body named with another's index is ambiguous, not silently the indexed one.
    base.write_text(base.read_text().replace('name = "lid"', 'name = "0"'))
    with pytest.raises(ValueError, match="both body 0's index and body 1's name"):
        sweep.read_sweep(_write_sweep(tmp_path, {"body.0.friction": [0.1]}, base=str(base)))
    assert sweep.variants(sweep.read_sweep(_write_sweep(
        tmp_path, {"body.1.friction": [0.3]}, base=str(base))))[0]["config"]["body"][1][
            "friction"] == 0.3


def test_names_shorten_the_directory_names(tmp_path):
    """[names]: a varied key's short name in the directory names (the values and the table keep
    the dotted key); a key that is not varied, a name with '=' or '__', two keys under one name
    and an unquoted dotted key are refused by name; a sweep whose directories would change name
    in an --out that ran it is refused."""
    base = _long_base(tmp_path, 100)
    extra = '[names]\n"stage.*.steps" = "steps"\n"material.friction" = "mu"\n'
    path = _write_sweep(tmp_path, {"stage.*.steps": [7], "material.friction": [0.2, 0.3]},
                        base=base, extra=extra)
    listed = sweep.variants(sweep.read_sweep(path))
    assert [v["name"] for v in listed] == ["steps=7__mu=0.2", "steps=7__mu=0.3"]
    assert listed[1]["values"] == {"stage.*.steps": 7, "material.friction": 0.3}
    for bad, message in (('[names]\n"contact.law" = "law"\n', "not a key of"),
                         ('[names]\n"material.friction" = "a=b"\n', "short name"),
                         ('[names]\n"material.friction" = "a__b"\n', "short name"),
                         ('[names]\n"material.friction" = "stage.-.steps"\n', "two keys"),
                         ('[names]\nmaterial.friction = "mu"\n', "quote the dotted key")):
        with pytest.raises(ValueError, match=message):
            sweep.read_sweep(_write_sweep(tmp_path, {"stage.*.steps": [7],
                                                     "material.friction": [0.2]},
                                          base=base, extra=bad))
    # The --out of a sweep that ran under the dotted names: its runs would start again.
    path = _write_sweep(tmp_path, {"stage.*.steps": [7], "material.friction": [0.2]},
                        base=base, extra=extra)
    out = tmp_path / "out"
    (out / "runs" / "stage.-.steps=7__material.friction=0.2").mkdir(parents=True)
    (out / "sweep.json").write_text(json.dumps({"variants": [
        {"name": "stage.-.steps=7__material.friction=0.2",
         "values": {"stage.*.steps": 7, "material.friction": 0.2}}]}))
    with pytest.raises(ValueError, match="ran there as stage.-.steps=7__material.friction=0.2"):
        sweep.sweep(path, str(out))


def test_a_pile_sweep_runs_each_variant_as_a_pile_experiment(tmp_path):
    """experiment = "pile": each variant is a crushdem-sand pile (its main run and the load test
    branched at the other ageing time), its row the capacities and set-up fits of that command's
    files; run again, a finished variant is not run again; an unknown experiment is refused."""
    text = open(os.path.join(DATA, "pile_400.toml")).read().replace("@DATA@", DATA)
    base = tmp_path / "pile.toml"
    base.write_text(text)
    path = _write_sweep(tmp_path, {"stage.*.n_break": [2]}, base=str(base),
                        extra='experiment = "pile"')
    df = sweep.sweep(path, str(tmp_path / "out"), workers=1, progress=False,
                     log=lambda s: None)
    row = df.iloc[0]
    assert row["status"] == "done", row["error"]
    run = row["run_dir"]
    assert sorted(d for d in os.listdir(run) if os.path.isdir(os.path.join(run, d))) == [
        "configs", "main", "t0_compression"]
    fits = json.load(open(os.path.join(run, "pile_setup.json")))["fits"]
    assert row["setup.compression.A"] == pytest.approx(fits["compression"]["A"], rel=1e-12)
    assert row["setup.compression.Q0_N"] == pytest.approx(fits["compression"]["Q0_N"])
    capacity = {r["ageing_time_s"]: r["capacity_N"] for r in csv.DictReader(
        open(os.path.join(run, "pile_capacity.csv")))}
    assert row["compression.capacity_N@3600s"] == pytest.approx(float(capacity["3600.0"]))
    assert row["compression.capacity_N@86400s"] == pytest.approx(float(capacity["86400.0"]))
    assert row["install.q_c_max_MPa"] > 0 and row["wall_s"] > 0
    said = []
    again = sweep.sweep(path, str(tmp_path / "out"), workers=1, progress=False, log=said.append)
    assert "1 finished before, 0 to run" in said[0]
    assert again.iloc[0]["setup.compression.A"] == row["setup.compression.A"]
    with pytest.raises(ValueError, match="expected \"run\""):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.*.n_break": [2]}, base=str(base),
                                      extra='experiment = "piles"'))
    # The same --out as runs of the other command: refused before anything runs.
    as_runs = _write_sweep(tmp_path, {"stage.*.n_break": [2]}, base=str(base))
    with pytest.raises(ValueError, match="ran as experiment = \"pile\", not \"run\""):
        sweep.sweep(as_runs, str(tmp_path / "out"), workers=1, progress=False, log=lambda s: None)
    # A base that is not a pile run (no age stage left) is refused once, by the sweep file.
    with pytest.raises(ValueError,
                       match="sweep.toml: base '.*pile.toml' .its kept stages.: no .age. stage"):
        sweep.read_sweep(_write_sweep(tmp_path, {"stage.install.velocity": [1.0]},
                                      base=str(base), extra='experiment = "pile"\n'
                                      'stages = ["install", "unload"]'))


@pytest.mark.parametrize("path", sorted(glob.glob(os.path.join(
    os.path.dirname(os.path.dirname(DATA)), "examples", "sweeps", "*.toml"))))
def test_the_example_sweeps_read(path):
    """Each sweep of examples/sweeps names its base, stages and keys correctly."""
    listed = sweep.variants(sweep.read_sweep(path))
    assert listed and len({v["name"] for v in listed}) == len(listed)


_SLOTS_LOCK = threading.Lock()
_SLOTS = {"now": 0, "most": 0}


def _slot_task(i):
    """A run of 0.2 s that counts how many run at once (threads of one process share _SLOTS)."""
    with _SLOTS_LOCK:
        _SLOTS["now"] += 1
        _SLOTS["most"] = max(_SLOTS["most"], _SLOTS["now"])
    time.sleep(0.2)
    with _SLOTS_LOCK:
        _SLOTS["now"] -= 1
    if i == 3:
        raise RuntimeError("run 3 blew up")
    return i


def test_runs_are_handed_out_as_slots_free_up():
    """_follow keeps as many runs in flight as the cluster has worker threads and submits the
    next as one ends, so no run waits behind another on a busy worker while one is idle; a
    failing run is recorded and the rest go on."""
    from distributed import Client

    class TwoSlots:
        def nthreads(self):
            return {"a": 1, "b": 1}

    errors, lines = {}, []
    with Client(processes=False, n_workers=1, threads_per_worker=4,
                dashboard_address=None) as client:
        sweep._follow(TwoSlots(), list(range(6)),
                      lambda i: (client.submit(_slot_task, i, key=f"t{i}", pure=False), f"t{i}"),
                      errors, False, lines.append)
    assert _SLOTS["most"] == 2
    assert len(lines) == 6 and list(errors) == ["t3"] and "blew up" in errors["t3"]


def test_a_stopped_sweep_lets_its_runs_save_their_checkpoints(tmp_path):
    """SIGTERM to a sweep started apart from its terminal (its output in a file, as with nohup):
    each run it started gets one SIGTERM, saves its checkpoint and stops before the workers
    close. Closing a busy worker can signal its run twice, and a second signal ends a run at
    once, without its checkpoint."""
    pile = os.path.join(os.path.dirname(os.path.dirname(DATA)), "examples", "pile_small.toml")
    path = tmp_path / "s.toml"
    path.write_text(f'base = "{pile}"\nstages = ["install"]\n[vary]\n"sample.seed" = [7]\n')
    out = str(tmp_path / "out")
    with open(tmp_path / "sweep.log", "w") as logfile:
        proc = subprocess.Popen([sys.executable, "-m", "crushdem_sand", "sweep", str(path),
                                 "--out", out, "--workers", "1"], stdout=logfile,
                                stderr=subprocess.STDOUT, start_new_session=True)
    try:
        _wait_for_runs(proc, 1)
        time.sleep(5.0)  # preparing its sample (about 30 s)
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    run = os.path.join(out, "runs", "sample.seed=7")
    log = open(os.path.join(run, "run.log")).read()
    assert "stopped by signal 15" in log, log[-800:]
    assert os.path.isfile(os.path.join(run, "checkpoint.bin"))


def test_a_stopped_sweep_signals_a_pile_experiment_and_not_its_run(monkeypatch):
    """stop_local_runs: SIGTERM to each run and pile experiment the workers started, once, but
    not to a run that a pile experiment started (the pile stops it; a second SIGTERM more than
    a second after the first would end that run without its checkpoint)."""
    import psutil

    class Proc:
        def __init__(self, pid, ppid, what):
            self.pid, self._ppid, self.signals = pid, ppid, []
            self._cmd = [sys.executable, "-m", "crushdem_sand", what, "x.toml"]

        def cmdline(self):
            return self._cmd

        def ppid(self):
            return self._ppid

        def send_signal(self, sig):
            self.signals.append(sig)

    worker = Proc(10, 1, "worker")
    worker._cmd = [sys.executable, "-c", "worker"]
    pile = Proc(11, 10, "pile")
    piles_run = Proc(12, 11, "run")
    alone = Proc(13, 10, "resume")
    children = [worker, pile, piles_run, alone]
    waited = []
    monkeypatch.setattr(psutil.Process, "children", lambda self, recursive=False: children)
    monkeypatch.setattr(psutil, "wait_procs", lambda procs, timeout: waited.extend(procs))
    said = []
    sweep.stop_local_runs(said.append, wait_s=1.0)
    assert pile.signals == [signal.SIGTERM] and alone.signals == [signal.SIGTERM]
    assert piles_run.signals == [] and worker.signals == []
    assert waited == [pile, alone] and said == ["stopping: 2 run(s) saving their checkpoints"]


@pytest.mark.parametrize("experiment, keep", [("run", True), ("run", False), ("pile", True),
                                              ("pile", False)])
def test_a_resumed_variant_passes_keep_columns_on(tmp_path, monkeypatch, experiment, keep):
    """run_variant: an interrupted run resumed with keep_columns goes on with `resume
    --keep-columns` (a pile experiment with `pile ... --keep-columns`, which passes it to its
    own resumes); without it neither command carries the option."""
    run_dir = tmp_path / "v"
    run_dir.mkdir()
    (run_dir / "checkpoint.bin").write_bytes(b"")
    seen = []
    monkeypatch.setattr(sweep, "_run_command", lambda cmd: (seen.append(cmd), (0, "", ""))[1])
    r = sweep.run_variant("cfg.toml", str(run_dir), 1, experiment=experiment, keep_columns=keep)
    assert r["resumed"] and len(seen) == 1
    cmd = seen[0]
    assert cmd[3] == ("resume" if experiment == "run" else "pile"), cmd
    assert ("--keep-columns" in cmd) == keep, cmd
