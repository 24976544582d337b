"""A run killed with SIGKILL in the middle of a dynamic phase, then resumed with
``crushdem-sand resume``, writes the same files as an uninterrupted run.

The run is the small creep test of tests/data (grains_300.toml, creep_300.toml), which
tests/test_checkpoint.cpp runs too: 300 weak grains squeezed to 2 MPa, then off-DEM ageing for a
day with the walls servo-controlled during every dynamic phase (several phases, grains breaking).
"""

import csv
import os
import signal
import subprocess
import sys
import time
import tomllib

import pytest
from _data import data_text

CONFIG = data_text("grains_300.toml", "creep_300.toml")
MIN_CYCLES = tomllib.loads(CONFIG)["stage"][1]["min_cycles"]  # of each dynamic phase


def crushdem(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "crushdem_sand", *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, **kw)


def mid_phase(run_dir):
    """True once phases.csv shows the run inside a dynamic phase after at least one event."""
    path = os.path.join(run_dir, "phases.csv")
    if not os.path.exists(path):
        return False
    with open(path) as f:
        rows = list(csv.DictReader(f))
    # The last complete row (the file may be mid-write).
    for row in reversed(rows):
        try:
            phase, cycle = float(row["dynamic_phase"]), float(row["cycle"])
        except (KeyError, TypeError, ValueError):
            continue
        return phase >= 1 and 0 < cycle < MIN_CYCLES
    return False


def files(run_dir):
    out = {}
    for root, _dirs, names in os.walk(run_dir):
        for n in names:
            if n in ("timing.json", "run.log"):  # wall-clock times
                continue
            p = os.path.join(root, n)
            with open(p, "rb") as f:
                out[os.path.relpath(p, run_dir)] = f.read()
    return out


def test_sigkill_mid_phase_then_resume_gives_identical_files(tmp_path):
    cfg = tmp_path / "creep.toml"
    cfg.write_text(CONFIG)
    whole = tmp_path / "whole"
    p = crushdem("run", str(cfg), "--out", str(whole), "--threads", "1")
    assert p.wait(timeout=600) == 0, p.stderr.read()

    killed = tmp_path / "killed"
    p = crushdem("run", str(cfg), "--out", str(killed), "--threads", "1")
    deadline = time.time() + 300
    while p.poll() is None and not mid_phase(killed) and time.time() < deadline:
        time.sleep(0.02)
    if p.poll() is not None:
        pytest.fail("the run ended before it could be killed in a dynamic phase")
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert p.returncode == -signal.SIGKILL
    assert (killed / "checkpoint.bin").exists()
    assert not (killed / "summary.json").exists()

    r = crushdem("resume", str(killed), "--threads", "2")
    assert r.wait(timeout=600) == 0, r.stderr.read()
    assert not (killed / "checkpoint.bin").exists()

    a, b = files(whole), files(killed)
    assert sorted(a) == sorted(b)
    different = [k for k in a if a[k] != b[k]]
    assert not different, f"files differ after resume: {different}"
    # The run aged: several dynamic phases, and grains broke.
    with open(whole / "events.csv") as f:
        assert len(list(csv.DictReader(f))) >= 4
    with open(whole / "breakage.csv") as f:
        assert len(list(csv.DictReader(f))) >= 5


def test_sigint_saves_and_stops_with_a_resume_hint_then_python_resumes(tmp_path):
    cfg = tmp_path / "creep.toml"
    cfg.write_text(CONFIG)
    out = tmp_path / "run"
    p = crushdem("run", str(cfg), "--out", str(out), "--threads", "1")
    deadline = time.time() + 300
    while p.poll() is None and not (out / "timeseries.csv").exists() and time.time() < deadline:
        time.sleep(0.02)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 128 + signal.SIGINT, err
    assert "crushdem-sand resume" in err
    assert (out / "checkpoint.bin").exists()

    # Resumed from Python this time.
    from crushdem_sand import lab

    res = lab.resume(out)
    assert res.summary["stages"][-1]["end"] == "target ageing time"
    assert not (out / "checkpoint.bin").exists()
    with pytest.raises(ValueError, match="finished"):
        lab.resume(out)


PYTHON_RUN = """
import sys, tomllib, crushdem_sand
cfg = tomllib.loads(open(sys.argv[1]).read())
try:
    crushdem_sand.lab.run(cfg, sys.argv[2])
except crushdem_sand.Interrupted as e:
    print(e.signal, e.out_dir, isinstance(e, KeyboardInterrupt))
    sys.exit(3)
"""


def test_sigterm_stops_a_python_run_with_a_checkpoint_and_resume_completes_it(tmp_path):
    # From Python the same signals must save the state: a script (or `crushdem-sand sensitivity`)
    # killed by the batch system loses nothing past its last step.
    import tomllib

    from crushdem_sand import lab

    cfg = tmp_path / "creep.toml"
    cfg.write_text(CONFIG)
    whole = tmp_path / "whole"
    lab.run(tomllib.loads(CONFIG), whole)

    out = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-c", PYTHON_RUN, str(cfg), str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while p.poll() is None and not mid_phase(out) and time.time() < deadline:
        time.sleep(0.02)
    if p.poll() is not None:
        pytest.fail("the run ended before it could be stopped: " + p.stderr.read())
    p.send_signal(signal.SIGTERM)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 3, stderr
    assert stdout.split() == [str(int(signal.SIGTERM)), str(out), "True"]
    assert (out / "checkpoint.bin").exists()
    assert not (out / "summary.json").exists()

    lab.resume(out)
    a, b = files(whole), files(out)
    assert sorted(a) == sorted(b)
    different = [k for k in a if a[k] != b[k]]
    assert not different, f"files differ after resume: {different}"


def test_a_format_4_checkpoint_of_release_0_1_0_still_resumes(tmp_path):
    """tests/data/run_format4: stopped by release 0.1.0 during its hold stage. The current code
    resumes it to the end; its legacy .vtk snapshot stays, and the new snapshots are .vtp files
    listed in the .pvd collections."""
    import json
    import shutil

    src = os.path.join(os.path.dirname(__file__), "..", "data", "run_format4")
    run = tmp_path / "run"
    shutil.copytree(src, run)
    with open(run / "checkpoint.bin", "rb") as f:
        assert b"crushdem-checkpoint-4" in f.read(64)
    # The run names its particle file by the absolute path it had where it was made (a resolved
    # configuration always does, and the checkpoint holds that text, so it cannot be edited):
    # put tests/data/lattice_64.txt there when that path does not exist on this machine.
    with open(run / "config.toml", "rb") as f:
        particles = tomllib.load(f)["particles"]["file"]
    if not os.path.isfile(particles):
        os.makedirs(os.path.dirname(particles), exist_ok=True)
        shutil.copyfile(os.path.join(os.path.dirname(src), "lattice_64.txt"), particles)
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "resume", str(run)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    assert not (run / "checkpoint.bin").exists()
    with open(run / "summary.json") as f:
        summary = json.load(f)
    assert summary["steps"] == 1_093_600  # isotropic (93,600) + the hold's 1,000,000
    assert [st["name"] for st in summary["stages"]] == ["isotropic", "hold"]
    # Another build resumed it, and says so: the checkpoint names no build before format 8.
    build = f"{summary['crushdem_version']} ({summary['crushdem_commit']})"
    assert summary["crushdem_builds"] == ["a crushdem before checkpoint format 8", build]
    assert ("warning: this run is resumed by crushdem " + build
            + "; it was run so far by a crushdem before checkpoint format 8"
            in (run / "run.log").read_text())
    assert (run / "vtk" / "particles_000000.vtk").is_file()
    assert summary["snapshots"] == 2  # the legacy first one and the final .vtp
    pvd = (run / "vtk" / "particles.pvd").read_text()
    assert pvd.count("<DataSet ") == 1 and "particles_0001093600.vtp" in pvd
    # The time series goes on from the checkpoint's row to the end, every 10,000 steps, with no
    # row repeated but the stage boundary's (the end of one stage, the start of the next).
    with open(run / "timeseries.csv") as f:
        steps = [int(row["step"]) for row in csv.DictReader(f)]
    assert steps == sorted(steps) and steps[-1] == 1_093_600
    assert len(steps) == len(set(steps)) + 1 and steps.count(93_600) == 2
    assert set(range(0, 1_093_600, 10_000)) <= set(steps)
