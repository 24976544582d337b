"""`crushdem-sand bench` on small packings: the peer format (a cube [0, L]^3 from '# L_m=') and a
prepared sample (six wall positions from '# box_xmin=' ...) both load, and the figure is the
last line of the output."""

import os
import subprocess
import sys


def _lattice(path, header, L, n=4):
    d = L / n
    with open(path, "w") as f:
        f.write(header)
        k = 0
        for i in range(n):
            for j in range(n):
                for m in range(n):
                    f.write(f"{k} {(i + 0.5) * d} {(j + 0.5) * d} {(m + 0.5) * d} {1.001 * d}\n")
                    k += 1


def _line(lines, key):
    """The output line that starts with `key=` (the lines before the last may grow)."""
    found = [line for line in lines if line.startswith(key + "=")]
    assert len(found) == 1, (key, lines)
    return found[0]


def _bench(packing, *extra):
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", "--packing", str(packing),
                          "--steps", "20", "--warm", "5", "--threads", "1", *extra],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.strip().splitlines()
    assert lines[-1].startswith("particle_steps_per_s=")
    assert float(lines[-1].split("=")[1]) > 0
    return lines


def test_bench_loads_the_peer_format(tmp_path):
    L = 1e-3
    _lattice(tmp_path / "p.txt", f"# L_m={L}\n", L)
    lines = _bench(tmp_path / "p.txt")
    assert lines[0].startswith("N=64 ")
    # Every grain overlaps its lattice neighbours and the walls: the walls are loaded.
    p_wall = float(_line(lines, "p_wall_Pa").split()[0].split("=")[1])
    assert p_wall > 0


def test_bench_loads_a_prepared_sample_box(tmp_path):
    L = 1e-3
    box = "".join(f"# box_{a}{m}={0.0 if m == 'min' else L}\n" for a in "xyz"
                  for m in ("min", "max"))
    _lattice(tmp_path / "s.txt", box, L)
    _lattice(tmp_path / "p.txt", f"# L_m={L}\n", L)
    for law in ("hertz", "rough"):
        # Same box either way, so the same state after the same steps.
        assert _bench(tmp_path / "s.txt", "--law", law)[2] == _bench(tmp_path / "p.txt", "--law",
                                                                     law)[2]
    wide = box.replace(f"# box_xmax={L}", f"# box_xmax={2 * L}")
    _lattice(tmp_path / "w.txt", wide, L)
    # A wider box leaves the xmax wall unloaded.
    assert _bench(tmp_path / "w.txt")[2] != _bench(tmp_path / "s.txt")[2]


def test_bench_without_a_box_names_the_header(tmp_path):
    _lattice(tmp_path / "n.txt", "", 1e-3)
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", "--packing",
                          str(tmp_path / "n.txt"), "--steps", "5"], capture_output=True, text=True)
    assert res.returncode != 0
    assert "L_m" in res.stderr


def test_bench_settles_under_its_own_law_first(tmp_path):
    L = 1e-3
    _lattice(tmp_path / "p.txt", f"# L_m={L}\n# p_target_Pa=1e5\n", L)
    lines = _bench(tmp_path / "p.txt", "--law", "rough", "--settle", "200")
    settled = dict(kv.split("=") for kv in lines[0].split()[1:])
    assert lines[0].startswith("settled ") and settled["steps"] == "200"
    assert float(settled["target_Pa"]) == 1e5
    # The servo has moved the walls, so the timed state differs from the unsettled one.
    assert _line(lines, "p_wall_Pa") != _line(_bench(tmp_path / "p.txt", "--law", "rough"),
                                              "p_wall_Pa")
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", "--packing",
                          str(tmp_path / "p.txt"), "--settle", "-3"], capture_output=True,
                         text=True)
    assert res.returncode != 0 and "--settle" in res.stderr and "-3" in res.stderr


def test_bench_keeps_the_settled_state_in_a_file(tmp_path):
    L = 1e-3
    _lattice(tmp_path / "p.txt", f"# L_m={L}\n# p_target_Pa=1e5\n", L)
    state = tmp_path / "settled.bin"
    args = ("--law", "rough", "--settle", "200", "--settled-state", str(state),
            "--state-out")
    first = _bench(tmp_path / "p.txt", *args, str(tmp_path / "a.txt"))
    assert state.exists()
    # Read back instead of settling: the same timed run, to the last bit.
    again = _bench(tmp_path / "p.txt", *args, str(tmp_path / "b.txt"))
    plain = _bench(tmp_path / "p.txt", "--law", "rough", "--settle", "200", "--state-out",
                   str(tmp_path / "c.txt"))
    assert first[0] == again[0] == plain[0]  # the settled line
    assert first[3] == again[3] == plain[3]  # the timed run's final stresses
    assert (tmp_path / "a.txt").read_bytes() == (tmp_path / "b.txt").read_bytes() == \
        (tmp_path / "c.txt").read_bytes()
    # A file settled for another run is refused, with what it expected.
    for other in (("--law", "hertz", "--settle", "200"), ("--law", "rough", "--settle", "300")):
        res = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", "--packing",
                              str(tmp_path / "p.txt"), "--steps", "5", *other,
                              "--settled-state", str(state)], capture_output=True, text=True)
        assert res.returncode != 0
        assert "--settled-state" in res.stderr and "written for another run" in res.stderr
    # Without --settle there is nothing to keep.
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", "--packing",
                          str(tmp_path / "p.txt"), "--steps", "5", "--settled-state", str(state)],
                         capture_output=True, text=True)
    assert res.returncode != 0 and "needs --settle" in res.stderr


CHAMBER = """[contact]
rotation = "blocked"
[sample]
shape = "cylinder"
sector = 90
count = 200
void_ratio = 0.8
stress = 100e3
seed = 4
[output]
progress_seconds = 0
"""


def _values(line):
    return dict(kv.split("=") for kv in line.split()[1:] if "=" in kv)


def test_bench_times_a_runs_chamber_sample_with_its_chamber(tmp_path):
    (tmp_path / "chamber.toml").write_text(CHAMBER)
    run = tmp_path / "run"
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "run",
                          str(tmp_path / "chamber.toml"), "--out", str(run), "--threads", "1"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr

    def bench(*args):
        r = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", *args, "--steps", "200",
                            "--warm", "0", "--threads", "1"],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        return r.stdout.strip().splitlines()

    lines = bench("--run", str(run))
    # The chamber and the quarter's two planes hold the grains; the run's own law and step: the
    # prepared sample stays at its 100 kPa (the Love-Weber mean stress) with the walls fixed.
    assert _line(lines, "bodies").startswith("bodies=3 ")
    assert _line(lines, "bodies").endswith("sector_deg=90")
    assert "law=rough" in lines[0]
    p_love = float(_line(lines, "p_wall_Pa").split()[1].split("=")[1])
    assert abs(p_love / 1e5 - 1.0) < 0.1
    # The boundary's mean stress is the chamber's and the platens' (the x and y box walls,
    # untouched in a chamber, would pull a six-wall mean to a third of it).
    p_wall = float(_line(lines, "p_wall_Pa").split()[0].split("=")[1])
    assert abs(p_wall / 1e5 - 1.0) < 0.1
    timed = {k: float(v) for k, v in _values(next(ln for ln in lines
                                                  if ln.startswith("timed_seconds "))).items()}
    assert timed["wall_forces"] > 0 and timed["contact_forces"] > 0
    # The emulated device steps the same chamber: the same stress to the order of the sums.
    device = bench("--run", str(run), "--backend", "emulated")
    p_device = float(_line(device, "p_wall_Pa").split()[1].split("=")[1])
    assert abs(p_device / p_love - 1.0) < 1e-6
    # The sample file alone, with the peers' constants, is confined by the same bodies.
    assert _line(bench("--packing", str(run / "sample.txt")), "bodies").startswith("bodies=3 ")


def test_bench_refuses_a_run_it_cannot_time(tmp_path):
    def refused(*args):
        r = subprocess.run([sys.executable, "-m", "crushdem_sand", "bench", *args, "--steps", "5"],
                           capture_output=True, text=True, timeout=60,
                           env={k: v for k, v in os.environ.items() if k != "PACKING"})
        assert r.returncode != 0
        return r.stderr

    assert "--run" in refused("--run", str(tmp_path)) and "sample.txt" in refused(
        "--run", str(tmp_path))
    (tmp_path / "config.toml").write_text(CHAMBER)
    (tmp_path / "sample.txt").write_text("")
    assert "--law" in refused("--run", str(tmp_path), "--law", "hertz")
    assert "--settle" in refused("--run", str(tmp_path), "--settle", "10")
    assert "--packing" in refused()
    assert "excludes" in refused("--run", str(tmp_path), "--packing", "x.txt")
