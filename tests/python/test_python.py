"""Tests of the Python front end (run with `python -m pytest tests/python` after
`pip install .`)."""

import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import crushdem_sand
from _data import data_text
from crushdem_sand import _core

G = 32e9
NU = 0.19
E_STAR = G / (1.0 - NU)  # two grains of one material (docs/model.md 1.1)
BOX = {"min": [0.0, 0.0, 0.0], "max": [1e-3, 1e-3, 1e-3]}


def hertz_sim(**extra):
    cfg = dict(
        material={"shear_modulus": G, "poisson_ratio": NU, "friction": 0.0},
        contact={"law": "hertz"},
        damping={"local_alpha": 0.0},
        box=BOX,
    )
    cfg.update(extra)
    return crushdem_sand.Simulation(**cfg)


def test_head_on_collision_conserves_energy():
    sim = hertz_sim()
    r = 1e-4
    v0 = 0.5
    sim.add_particles(
        np.array([[3.5e-4, 5e-4, 5e-4], [6.5e-4, 5e-4, 5e-4]]),
        np.array([r, r]),
        np.array([[v0, 0.0, 0.0], [-v0, 0.0, 0.0]]),
    )
    ke0 = sim.kinetic_energy()
    m = sim.masses()
    assert ke0 == pytest.approx(0.5 * m.sum() * v0**2, rel=1e-12)

    touched = False
    for _ in range(2000):
        sim.step(10)
        c = sim.contacts()
        if len(c["overlap"]) > 0:
            touched = True
            assert not c["is_wall"].any()
            assert sim.kinetic_energy() < ke0  # part of it is stored in the contact
        if touched and len(c["overlap"]) == 0:
            break
    assert touched, "the spheres never met"
    assert len(sim.contacts()["overlap"]) == 0, "the spheres did not separate"

    v = sim.velocities()
    # They bounced: velocities reversed along x, nothing else.
    assert v[0, 0] < 0.0 < v[1, 0]
    np.testing.assert_allclose(v[:, 1:], 0.0, atol=1e-12)
    assert sim.kinetic_energy() == pytest.approx(ke0, rel=1e-4)
    np.testing.assert_allclose(np.abs(v[:, 0]), v0, rtol=1e-4)
    # Momentum is conserved exactly by the symmetric pair force.
    assert abs(m @ v[:, 0]) < 1e-12 * m.sum() * v0
    assert sim.step_count > 0 and sim.time == pytest.approx(sim.step_count * sim.dt, rel=1e-9)


def test_array_shapes_and_dtypes():
    sim = hertz_sim()
    n = 5
    rng = np.random.default_rng(3)
    pos = 2e-4 + rng.random((n, 3)) * 6e-4
    pos[:, 0] = np.linspace(1.5e-4, 8.5e-4, n)  # separated along x
    ids = sim.add_particles(pos, np.full(n, 5e-5))
    assert ids.dtype == np.uint64 and ids.shape == (n,)
    assert list(ids) == list(range(n))
    assert sim.num_particles == n

    for name in ("positions", "velocities", "angular_velocities", "forces", "torques"):
        a = getattr(sim, name)()
        assert a.shape == (n, 3), name
        assert a.dtype == np.float64, name
    for name in ("radii", "masses"):
        a = getattr(sim, name)()
        assert a.shape == (n,) and a.dtype == np.float64, name
    for name in ("ids", "parent_ids"):
        a = getattr(sim, name)()
        assert a.shape == (n,) and a.dtype == np.uint64, name
    assert (sim.parent_ids() == crushdem_sand.NO_PARENT).all()

    np.testing.assert_allclose(np.sort(sim.positions()[:, 0]), pos[:, 0])
    np.testing.assert_allclose(sim.masses(), 2650.0 * 4.0 / 3.0 * math.pi * 5e-5**3, rtol=1e-12)

    # Copies: editing them does not touch the simulation.
    p = sim.positions()
    p[:] = 0.0
    assert sim.positions().max() > 0.0

    assert sim.wall_positions().shape == (6,)
    np.testing.assert_allclose(sim.wall_positions(), [0, 1e-3, 0, 1e-3, 0, 1e-3])
    assert sim.wall_stresses().shape == (6,)
    assert sim.wall_forces().shape == (6, 3)
    lw = sim.love_weber_stress()
    assert lw.shape == (3, 3) and lw.dtype == np.float64

    c = sim.contacts()
    assert list(c) == CONTACT_COLUMNS
    assert c["id_i"].dtype == np.uint64 and c["is_wall"].dtype == np.bool_
    assert all(v.shape == (0,) for v in c.values())

    with pytest.raises(ValueError, match="positions"):
        sim.add_particles(np.zeros((2, 2)), np.ones(2) * 1e-5)
    with pytest.raises(ValueError, match="radi"):
        sim.add_particles(np.full((1, 3), 5e-4), [-1.0])
    assert sim.num_particles == n


# Simulation.contacts(): one column per scalar, three (x, y, z) per vector.
CONTACT_COLUMNS = ["id_i", "id_j", "is_wall", "overlap", "normal_force",
                   "normal_x", "normal_y", "normal_z",
                   "tangential_force_x", "tangential_force_y", "tangential_force_z",
                   "rolling_moment_x", "rolling_moment_y", "rolling_moment_z"]


def test_contacts_are_columns_a_dataframe_takes():
    import pandas as pd

    sim = hertz_sim(material={"shear_modulus": G, "poisson_ratio": NU, "friction": 0.3})
    r = 1e-4
    # Two grains stacked on the bottom wall, each overlap 2e-7 m: a contact between them, then
    # one with the wall.
    sim.add_particles(np.array([[5e-4, 5e-4, r - 2e-7], [5e-4, 5e-4, 3 * r - 4e-7]]),
                      np.array([r, r]))
    sim.compute_forces()
    c = sim.contacts()
    assert list(c) == CONTACT_COLUMNS and len({len(v) for v in c.values()}) == 1
    assert all(v.ndim == 1 for v in c.values())
    df = pd.DataFrame(c)
    assert list(df.columns) == CONTACT_COLUMNS and len(df) == 2
    assert df["id_i"].dtype == np.uint64 and df["is_wall"].dtype == np.bool_
    assert df["is_wall"].tolist() == [False, True] and sim.num_contacts == 1
    pair = df[~df["is_wall"]].iloc[0]
    normal = pair[["normal_x", "normal_y", "normal_z"]].to_numpy(float)
    np.testing.assert_allclose(np.abs(normal), [0.0, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(df["overlap"], [2e-7, 2e-7], rtol=1e-6)
    assert (df["normal_force"] > 0).all()


def test_properties_are_the_counts_and_the_clock():
    # The rule of the class docstring: what the simulation keeps as a scalar is a property,
    # whatever copies, computes or takes arguments a method.
    properties = {name for name, value in vars(crushdem_sand.Simulation).items()
                  if isinstance(value, property)}
    assert properties == {"num_particles", "num_contacts", "time", "step_count", "dt", "core"}
    for name in ("positions", "contacts", "wall_stresses", "kinetic_energy", "rayleigh_dt"):
        assert callable(vars(crushdem_sand.Simulation)[name]), name


def test_num_contacts_is_a_property_still_callable_with_a_warning():
    sim = hertz_sim()
    sim.add_particles(np.array([[3e-4, 5e-4, 5e-4], [3e-4 + 2e-4 - 1e-7, 5e-4, 5e-4]]),
                      np.array([1e-4, 1e-4]))
    sim.compute_forces()
    assert sim.num_contacts == 1 and isinstance(sim.num_contacts, int)
    assert sim.num_contacts + 1 == 2 and f"{sim.num_contacts}" == "1"
    with pytest.warns(DeprecationWarning, match="num_contacts is a property"):
        assert sim.num_contacts() == 1
    # The method a caller kept counts again when called, as it did.
    stored = sim.num_contacts
    sim.add_particles(np.array([[3e-4 + 4e-4 - 2e-7, 5e-4, 5e-4]]), np.array([1e-4]))
    sim.compute_forces()
    with pytest.warns(DeprecationWarning):
        assert stored() == 2


def test_wall_contact_is_hertz():
    sim = hertz_sim()
    r = 1e-4
    delta = 1e-7
    sim.add_particles(np.array([[5e-4, 5e-4, r - delta]]), np.array([r]))
    sim.compute_forces()
    c = sim.contacts()
    assert len(c["overlap"]) == 1
    assert c["is_wall"][0]
    assert crushdem_sand.WALL_NAMES[int(c["id_j"][0])] == "zmin"
    assert c["id_i"][0] == 0
    assert c["overlap"][0] == pytest.approx(delta, rel=1e-9)
    expected = 4.0 / 3.0 * E_STAR * math.sqrt(r) * delta**1.5
    assert abs(c["normal_force"][0] - expected) <= 1e-9 * expected
    np.testing.assert_allclose([c["normal_x"][0], c["normal_y"][0], c["normal_z"][0]],
                               [0.0, 0.0, -1.0], atol=1e-15)
    # The wall pushes the grain up with that force; the wall feels the reaction.
    assert sim.forces()[0, 2] == pytest.approx(expected, rel=1e-9)
    assert sim.wall_forces()[4, 2] == pytest.approx(-expected, rel=1e-9)
    assert sim.wall_stresses()[4] == pytest.approx(expected / 1e-6, rel=1e-9)


def test_rolling_moment_is_readable_and_capped():
    # An oblique impact of unequal spheres with friction spins them at different rates, which
    # loads the rolling spring; the moment stays within mu_r R* F_n.
    mu_r = 0.2
    sim = hertz_sim(material={"shear_modulus": G, "poisson_ratio": NU, "friction": 0.3},
                    contact={"law": "hertz", "rolling_friction": mu_r},
                    timestep={"dt": 5e-10})
    r1, r2, v, dy = 1e-4, 0.5e-4, 0.2, 2.5e-5
    dx = math.sqrt((r1 + r2 + 1e-7) ** 2 - dy**2)  # 1e-7 m apart, offset by dy
    sim.add_particles(np.array([[3e-4, 5e-4, 5e-4], [3e-4 + dx, 5e-4 + dy, 5e-4]]),
                      np.array([r1, r2]), np.array([[v, 0.0, 0.0], [-v, 0.0, 0.0]]))
    largest, ratio = 0.0, 0.0
    for _ in range(400):
        sim.step(5)
        c = sim.contacts()
        for k in np.flatnonzero(~c["is_wall"]):
            m = float(np.linalg.norm([c[f"rolling_moment_{a}"][k] for a in "xyz"]))
            largest = max(largest, m)
            cap = mu_r * (r1 * r2 / (r1 + r2)) * c["normal_force"][k]
            ratio = max(ratio, m / cap if cap > 0 else 0.0)
    assert largest > 0.0
    assert ratio <= 1.0 + 1e-9


def test_bad_value_names_the_key():
    with pytest.raises(ValueError, match=r"material\.shear_modulus"):
        crushdem_sand.Simulation(material={"shear_modulus": -1}, box=BOX)
    with pytest.raises(crushdem_sand.ConfigError):
        crushdem_sand.Simulation(material={"shear_modulus": -1}, box=BOX)
    with pytest.raises(ValueError, match=r"box"):
        crushdem_sand.Simulation(material={"shear_modulus": 32e9})  # [box] is required


def test_unknown_key_is_named():
    with pytest.raises(ValueError, match="shear_modulsu"):
        crushdem_sand.Simulation(material={"shear_modulsu": 32e9}, box=BOX)
    with pytest.raises(ValueError, match="nonsense"):
        crushdem_sand.Simulation(material={"shear_modulus": 32e9}, box=BOX, nonsense={"a": 1})


def test_value_conversion():
    # numpy scalars and arrays, tuples, ints for floats, bools
    sim = crushdem_sand.Simulation(
        material={"shear_modulus": np.float64(30e9), "density": 2600},
        neighbor={"sort_particles": np.bool_(False), "prune": False},
        box={"min": np.zeros(3), "max": (1e-3, 1e-3, np.float32(2e-3))},
        walls={"zmax": {"mode": "servo", "target_stress": 1e6}},
    )
    np.testing.assert_allclose(sim.wall_positions(), [0, 1e-3, 0, 1e-3, 0, 2e-3], rtol=1e-7)
    toml = sim.config_toml()
    assert "sort_particles = false" in toml
    assert "prune = false" in toml
    assert "shear_modulus = 3e+10" in toml or "shear_modulus = 30000000000.0" in toml
    assert sim.wall_config("zmax")["mode"] == "servo"
    with pytest.raises(ValueError, match="None"):
        crushdem_sand.Simulation(material={"density": None}, box=BOX)
    with pytest.raises(ValueError, match="material.density"):
        crushdem_sand.Simulation(material={"density": object()}, box=BOX)
    with pytest.raises(ValueError):
        # an integer is not a boolean
        crushdem_sand.Simulation(neighbor={"sort_particles": 1}, box=BOX)
    with pytest.raises(ValueError, match="neighbor.prune"):
        crushdem_sand.Simulation(neighbor={"prune": "yes"}, box=BOX)


def test_set_wall_moves_it():
    sim = hertz_sim()
    sim.add_particles(np.array([[5e-4, 5e-4, 5e-4]]), np.array([1e-4]))
    sim.set_dt(1e-8)
    assert sim.dt == 1e-8
    sim.set_wall("zmax", mode="velocity", velocity=-0.1)
    sim.step(100)
    assert sim.wall_positions()[5] == pytest.approx(1e-3 - 0.1 * 100 * 1e-8, rel=1e-9)
    assert sim.wall_velocities()[5] == -0.1
    with pytest.raises(ValueError, match="wall"):
        sim.set_wall("top", mode="fixed")
    with pytest.raises(ValueError, match="walls.zmax.mode"):
        sim.set_wall("zmax", mode="spinning")
    sim.set_wall("zmax", mode="fixed")
    z = sim.wall_positions()[5]
    sim.step(10)
    assert sim.wall_positions()[5] == z


PILE = {"name": "pile", "shape": "pile", "origin": [0.0, 0.0, -5e-3], "axis": [0.0, 0.0, 1.0],
        "radius": 1e-3, "length": 8e-3, "tip": "flat"}
PLANE = {"name": "floor", "shape": "plane", "origin": [0.0, 0.0, -9e-3], "axis": [0.0, 0.0, -1.0]}


def body_sim():
    return hertz_sim(box={"min": [-0.02] * 3, "max": [0.02] * 3}, body=[PILE, PLANE])


def test_bodies_read_as_a_table_with_their_force_and_moment():
    pd = pytest.importorskip("pandas")
    sim = body_sim()
    R, r, delta, h = 1e-3, 1e-4, 2e-7, 3e-3
    # One grain pressed on the shaft's +x side, h above the pile's origin (its flat tip).
    sim.add_particles(np.array([[R + r - delta, 0.0, -5e-3 + h]]), np.array([r]))
    sim.compute_forces()
    table = pd.DataFrame(sim.bodies())
    assert list(table["name"]) == ["pile", "floor"]
    assert list(table["index"]) == [6, 7]
    assert list(table["mode"]) == ["fixed", "fixed"]
    assert {"position", "velocity", "force_x", "moment_z", "stress"} <= set(table.columns)
    pile = table.iloc[0]
    # The grain pushes the shaft towards -x at (R, 0, h) from the origin: M = (R, 0, h) x F.
    F = pile["force_x"]
    assert F < 0.0
    assert pile["force_y"] == pytest.approx(0.0, abs=1e-12 * abs(F))
    assert pile["moment_y"] == pytest.approx(h * F, rel=1e-9)
    assert pile["moment_x"] == pytest.approx(0.0, abs=1e-12 * abs(F))
    assert pile["moment_z"] == pytest.approx(0.0, abs=1e-12 * abs(F))
    # Its contact is a wall contact whose id_j is the body's index.
    c = sim.contacts()
    assert list(c["id_j"][c["is_wall"]]) == [6]
    assert -F == pytest.approx(c["normal_force"][c["is_wall"]][0], rel=1e-12)
    # A plane given no area has no stress; nothing touches it.
    assert math.isnan(table.iloc[1]["stress"])
    assert table.iloc[1]["force_z"] == 0.0


def test_a_pile_is_probed_and_driven_by_its_name():
    sim = body_sim()
    R, r, delta = 1e-3, 1e-4, 2e-7
    # A grain under the tip, one on the shaft 1.3 mm up (of 8 mm in 4 bins: bin 0).
    sim.add_particles(np.array([[0.0, 0.0, -5e-3 - r + delta], [R + r - delta, 0.0, -3.7e-3]]),
                      np.array([r, r]))
    sim.compute_forces()
    p = sim.probe_body("pile", bins=4)
    c = sim.contacts()
    on_wall = dict(zip(c["id_i"][c["is_wall"]], c["normal_force"][c["is_wall"]]))
    assert p["tip_contacts"] == 1 and p["shaft_contacts"] == 1
    assert p["q_c"] == pytest.approx(on_wall[0] / (math.pi * R * R), rel=1e-12)
    assert p["bin_height"] == pytest.approx(2e-3, rel=1e-12)
    assert p["sigma_r"][0] == pytest.approx(on_wall[1] / (2 * math.pi * R * 2e-3), rel=1e-12)
    assert list(p["sigma_r"][1:]) == [0.0, 0.0, 0.0]
    assert list(p["bin_contacts"]) == [1, 0, 0, 0]
    assert p["sleeve_length"] == pytest.approx(0.1337 / 0.0357 * 2 * R, rel=1e-12)
    np.testing.assert_allclose(p["tip"], [0.0, 0.0, -5e-3], atol=1e-15)
    # Driven down at 1 mm/s: its degree of freedom and its tip follow.
    sim.set_dt(1e-8)
    sim.set_wall("pile", mode="velocity", velocity=1e-3)
    assert sim.wall_config("pile")["mode"] == "velocity"
    sim.step(100)
    assert sim.bodies()["position"][0] == pytest.approx(1e-3 * 100 * 1e-8, rel=1e-9)
    assert sim.probe_body("pile")["tip"][2] == pytest.approx(-5e-3 - 1e-9, rel=1e-9)


def test_bad_body_requests_are_refused_naming_what_is_wrong():
    sim = body_sim()
    with pytest.raises(crushdem_sand.ConfigError, match="or a body, pile, floor"):
        sim.set_wall("pipe", mode="fixed")
    with pytest.raises(crushdem_sand.ConfigError, match=r"body\[1\]\.mode.*no area"):
        sim.set_wall("floor", mode="servo", target_stress=1e5)
    assert sim.wall_config("floor")["mode"] == "fixed"  # unchanged
    with pytest.raises(crushdem_sand.ConfigError, match=r"body\[0\]\.mode"):
        sim.set_wall("pile", mode="spinning")
    with pytest.raises(crushdem_sand.ConfigError, match="tip or a shaft.*one of pile$"):
        sim.probe_body("floor")
    with pytest.raises(crushdem_sand.ConfigError, match="translates with a tip or a shaft"):
        sim.probe_body("zmax")
    with pytest.raises(crushdem_sand.ConfigError, match="bins"):
        sim.probe_body("pile", bins=2**40)
    with pytest.raises(crushdem_sand.ConfigError, match="bins"):
        sim.probe_body("pile", bins=0)
    with pytest.raises(crushdem_sand.ConfigError, match="sleeve_length"):
        sim.probe_body("pile", sleeve_length=-1.0)
    with pytest.raises(crushdem_sand.ConfigError, match="no \\[\\[body\\]\\] is configured"):
        hertz_sim().set_wall("pile", mode="fixed")
    empty = hertz_sim().bodies()
    assert len(empty["name"]) == 0 and empty["name"].dtype == object
    # Grains added after the last force evaluation: the wall entries no longer match them.
    sim.add_particles(np.array([[1e-3 + 1e-4 - 2e-7, 0.0, -2e-3]]), np.array([1e-4]))
    sim.compute_forces()
    assert not math.isnan(sim.bodies()["moment_y"][0])
    sim.add_particles(np.array([[0.01, 0.01, 0.01]]), np.array([1e-4]))
    assert math.isnan(sim.bodies()["moment_y"][0])
    with pytest.raises(crushdem_sand.RuntimeFailure, match="compute_forces"):
        sim.probe_body("pile")


def test_a_servo_on_a_load_is_a_body_key():
    sim = hertz_sim(box={"min": [-0.02] * 3, "max": [0.02] * 3},
                    body=[{"name": "plate", "shape": "disk", "origin": [0.0, 0.0, 1e-3],
                           "radius": 1e-3, "mode": "servo", "target_force": 2e-3}])
    assert sim.wall_config("plate")["target_stress"] == pytest.approx(2e-3 / (math.pi * 1e-6))
    with pytest.raises(crushdem_sand.ConfigError, match="beside target_force"):
        hertz_sim(body=[{"name": "plate", "shape": "disk", "radius": 1e-3, "mode": "servo",
                         "target_force": 2e-3, "target_stress": 1e5}])


def test_step_releases_gil():
    """While one thread steps, another runs Python code at about its own speed: the GIL is
    released for the stepping (held, the other thread would only run between chunks)."""
    import threading
    import time

    def spin(seconds):
        n, end = 0, time.perf_counter() + seconds
        while time.perf_counter() < end:
            n += 1
        return n

    sim = _rattling_pair()
    before = crushdem_sand.threads()
    crushdem_sand.set_threads(1)
    try:
        t0 = time.perf_counter()
        sim.step(20_000, progress=False)
        n = max(20_000, int(20_000 * 1.5 / max(time.perf_counter() - t0, 1e-6)))  # ~1.5 s
        alone = spin(0.3)
        t = threading.Thread(target=sim.step, args=(n,), kwargs={"progress": False})
        t.start()
        time.sleep(0.1)
        during = spin(0.3)
        overlapped = t.is_alive()
        t.join()
    finally:
        crushdem_sand.set_threads(before)
    assert overlapped, "the step ended before the measurement: too few steps"
    assert sim.step_count == 20_000 + n
    # Held, the main thread would get the GIL at chunk ends only (a few per 0.3 s).
    assert during > 0.1 * alone, (during, alone)


def test_resolved_config():
    text = crushdem_sand.resolved_config(contact={"law": "hertz"}, box=BOX)
    assert 'law = "hertz"' in text
    assert "[walls.zmax]" in text


SMALL_CONFIG = data_text("one_servo_wall.toml")


def test_cli_check(tmp_path, capfd):
    path = tmp_path / "small.toml"
    path.write_text(SMALL_CONFIG)
    assert crushdem_sand.cli_main(["check", str(path)]) == 0
    assert "valid" in capfd.readouterr().out

    bad = tmp_path / "bad.toml"
    bad.write_text(SMALL_CONFIG.replace("shear_modulus = 32e9", "shear_modulus = -1.0"))
    assert crushdem_sand.cli_main(["check", str(bad)]) == 2
    assert "material.shear_modulus" in capfd.readouterr().err


def test_console_script_help():
    out = subprocess.run([sys.executable, "-m", "crushdem_sand", "--help"], capture_output=True,
                         text=True, check=True).stdout
    assert "Usage: crushdem" in out and "\n  check " in out and "\n  plot " in out
    # One usage, the Python commands in its list of subcommands.
    assert out.index("Usage") < out.index("Subcommands:") < out.index("\n  plot ")


def test_plot_writes_png(tmp_path):
    n = 20
    t = np.linspace(0.0, 1e-3, n)
    p = np.geomspace(1e5, 1e7, n)
    cols = {
        "time_s": t,
        "step": np.arange(n) * 100,
        "wall_xmin_stress_Pa": p,
        "wall_xmax_stress_Pa": p,
        "wall_zmax_stress_Pa": 1.5 * p,
        "mean_stress_Pa": p * 4.0 / 3.0,
        "deviator_stress_Pa": 0.5 * p,
        "axial_strain": np.linspace(0.0, 0.1, n),
        "volumetric_strain": np.linspace(0.0, 0.05, n),
        "void_ratio": np.linspace(0.8, 0.6, n),
        "kinetic_energy_J": np.geomspace(1e-6, 1e-12, n),
    }
    header = ",".join(cols)
    rows = "\n".join(",".join(repr(float(cols[c][i])) for c in cols) for i in range(n))
    (tmp_path / "timeseries.csv").write_text(header + "\n" + rows + "\n")

    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "plot", str(tmp_path)],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    for name in ("stress_time.png", "strain_stress.png", "void_ratio.png"):
        f = tmp_path / name
        assert f.exists(), name
        assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert str(f) in res.stdout

    missing = subprocess.run(
        [sys.executable, "-m", "crushdem_sand", "plot", str(tmp_path / "nope")],
        capture_output=True, text=True)
    assert missing.returncode == 2 and "timeseries.csv" in missing.stderr


def test_runtime_failure_is_runtime_error():
    sim = hertz_sim()
    # So fast that it crosses the zmax wall within one step (no contact can stop it).
    sim.add_particles(np.array([[5e-4, 5e-4, 5e-4]]), np.array([4e-5]),
                      np.array([[0.0, 0.0, 1e7]]))
    with pytest.raises(RuntimeError,
                       match="left the box through wall zmax.*of its radius in the last step"):
        sim.step(10)
    assert issubclass(crushdem_sand.RuntimeFailure, RuntimeError)


def test_installed_console_script():
    script = os.path.join(os.path.dirname(sys.executable), "crushdem-sand")
    if not os.path.exists(script):
        pytest.skip("console script not next to the interpreter")
    res = subprocess.run([script, "--help"], capture_output=True, text=True)
    assert res.returncode == 0 and "Usage: crushdem-sand" in res.stdout and not res.stderr
    res = subprocess.run([script, "frobnicate"], capture_output=True, text=True)
    assert res.returncode == 2 and "frobnicate" in res.stderr and "--help" in res.stderr


def test_the_old_command_name_is_an_alias_that_says_so():
    """`crushdem` (the name before the rename; PyPI's crushdem is another project's) runs the same
    program until 0.2, after a note on stderr."""
    script = os.path.join(os.path.dirname(sys.executable), "crushdem")
    if not os.path.exists(script):
        pytest.skip("console script not next to the interpreter")
    res = subprocess.run([script, "--version"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert res.stdout == f"crushdem-sand {crushdem_sand.__version__}\n"
    assert res.stderr.startswith("note: `crushdem` is now `crushdem-sand`"), res.stderr


@pytest.fixture(scope="module")
def small_sample(tmp_path_factory):
    """One 500-grain sample (about 20 s to prepare) shared by the laboratory tests."""
    out = tmp_path_factory.mktemp("lab") / "sample"
    return crushdem_sand.prepare_sample(out, count=500, void_ratio=0.75, seed=3)


def test_lab_functions_prepare_and_shear(tmp_path, small_sample):
    sample = small_sample
    assert sample.sample_file is not None
    info = sample.summary["sample"]
    assert abs(info["void_ratio"] - 0.75) <= 0.005
    assert info["grains"] > 400
    for got, want in zip(info["passing"], info["passing_target"]):
        assert abs(got - want) <= 0.02
    tri = crushdem_sand.triaxial_test(tmp_path / "tri", sample.sample_file, sigma_3=1e6,
                                 strain_rate=40.0, axial_strain=0.01, hold_steps=1000,
                                 crushing={"seed": 2})
    assert [s["type"] for s in tri.stages] == ["isotropic", "triaxial", "hold"]
    assert tri.stages[1]["max_lateral_stress_error"] < 0.01
    assert tri.stages[1]["q_max_Pa"] > 0
    ts = tri.timeseries()  # a DataFrame: counts and indices are integers
    assert ts["stage"].max() == 2 and ts["stage"].dtype == np.int64
    assert ts["step"].dtype == np.int64 and ts["void_ratio"].dtype == np.float64
    assert np.all(np.isfinite(ts["inertial_number"][ts["stage"] == 1]))
    # Crushing is on (Table 1 strengths: few or no grains break at 1 MPa); its outputs exist.
    assert "relative_breakage_Br" in ts and "void_ratio_with_fines" in ts
    assert os.path.exists(os.path.join(tri.directory, "grading.csv"))
    assert tri.summary["crushing"]["pattern_fragments"] == 14
    # Where the time went: every second in one part, the force loop the largest.
    timing = tri.timing
    parts = timing["seconds_by_part"]
    assert set(parts) == {"other", "integration", "neighbor_search", "contact_forces",
                          "wall_forces", "crushing", "ageing_jump", "output"}
    assert sum(parts.values()) == pytest.approx(timing["wall_seconds"], rel=0.1, abs=0.2)
    assert timing["finished"] is True and timing["dominant_part"] in parts
    with pytest.raises(crushdem_sand.ConfigError, match="sample.void_ratio"):
        crushdem_sand.prepare_sample(tmp_path / "bad", count=500, void_ratio=0.5)
    with pytest.raises(crushdem_sand.ConfigError, match=r"stage\[0\]\.stress"):
        crushdem_sand.isotropic_test(tmp_path / "bad2", sample.sample_file, stress=-1.0)


def test_creep_and_relaxation_functions(tmp_path, small_sample):
    sample = small_sample
    # Weaker grains (sigma_lim0 = 1 GPa) so that cracks grow within the test; short phases.
    weak = {"sigma_lim0": 1e9, "density_scaling": True, "d_min": 0.05e-3}
    creep = crushdem_sand.creep_test(tmp_path / "creep", sample.sample_file, stress=1e6,
                                strain_rate=20.0, duration=3600.0, min_cycles=500, n_break=3,
                                crushing=weak)
    ages = [s for s in creep.stages if s["type"] == "age"]
    assert len(ages) == 1 and ages[0]["dynamic_phases"] >= 2
    with open(os.path.join(creep.directory, "events.csv")) as f:
        rows = f.read().strip().splitlines()
    assert len(rows) == 1 + ages[0]["dynamic_phases"]
    t_age = [float(r.split(",")[0]) for r in rows[1:]]
    assert t_age[0] == 0.0 and all(b > a for a, b in zip(t_age, t_age[1:]))
    assert t_age[-1] == pytest.approx(3600.0)
    # The same tables as DataFrames.
    events = creep.events()
    assert list(events["ageing_time_s"]) == t_age
    assert list(events["dynamic_phase"]) == list(range(len(t_age)))
    phases = creep.phases()
    assert set(phases["dynamic_phase"]) == set(range(len(t_age)))
    assert phases["cycle"].dtype == np.int64 and phases["cycle"].min() == 0
    # The solid mass balance (density scaling on: the stored masses of the small fragments are
    # not their solid masses, the balance is of volumes times the material density).
    co = creep.summary["crushing"]
    assert co["breakages_instant"] + co["breakages_crack"] > 0 and co["removed_volume_m3"] > 0
    rho = co["solid_density_kg_m3"]
    assert rho == 2650.0
    assert co["removed_solid_mass_kg"] == pytest.approx(rho * co["removed_volume_m3"], rel=1e-15)
    assert co["initial_solid_mass_kg"] == pytest.approx(
        co["retained_solid_mass_kg"] + co["removed_solid_mass_kg"], rel=1e-12)
    assert abs(co["mass_balance_relative_error"]) < 1e-12
    assert co["retained_solid_mass_kg"] < co["initial_solid_mass_kg"]
    broken = creep.breakages()
    assert len(broken) == co["breakages_instant"] + co["breakages_crack"]
    assert set(broken["cause"]) <= {"instant", "crack"} and broken["id"].dtype == np.int64


def _needed_libraries(path):
    """The DT_NEEDED entries (the shared libraries it links, as ``ldd`` lists them) of a 64-bit
    little-endian ELF file."""
    import struct

    with open(path, "rb") as f:
        data = f.read()
    if data[:6] != b"\x7fELF\x02\x01":
        pytest.skip(f"{path}: not a 64-bit little-endian ELF file")
    (shoff,) = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    # (sh_name, sh_type, sh_flags, sh_addr, sh_offset, sh_size, sh_link, ...) per section
    sections = [struct.unpack_from("<IIQQQQII", data, shoff + k * shentsize)
                for k in range(shnum)]
    needed = []
    for _, kind, _, _, offset, size, link, _ in sections:
        if kind != 6:  # SHT_DYNAMIC: (tag, value) pairs; DT_NEEDED = 1 names a library
            continue
        strings = sections[link][4]
        for k in range(offset, offset + size, 16):
            tag, value = struct.unpack_from("<qQ", data, k)
            if tag == 1:
                end = data.index(b"\0", strings + value)
                needed.append(data[strings + value:end].decode())
    return needed


def test_set_threads_sets_the_engine_thread_count():
    # Built with OpenMP the engine links its runtime (GCC's libgomp, LLVM's libomp, Intel's
    # libiomp5) and a count takes effect exactly; built without, every count is 1.
    needed = _needed_libraries(_core.__file__)
    # The list was read: every module needs the C library (glibc's libc.so.6, musl's
    # libc.musl-*), not always libstdc++, which the portable wheel's module has inside it.
    assert any(lib.startswith(("libc.so", "libc.musl")) for lib in needed), needed
    openmp = any(lib.startswith(("libgomp", "libomp", "libiomp")) for lib in needed)
    before = crushdem_sand.threads()
    try:
        assert crushdem_sand.set_threads(1) == 1 and crushdem_sand.threads() == 1
        for n in (2, 3):
            expected = n if openmp else 1
            assert crushdem_sand.set_threads(n) == expected and crushdem_sand.threads() == expected
        for bad in (0, -2, 10**6):
            with pytest.raises(crushdem_sand.ConfigError, match="threads"):
                crushdem_sand.set_threads(bad)
        assert crushdem_sand.threads() == (3 if openmp else 1)  # a refused count changes nothing
    finally:
        crushdem_sand.set_threads(before)


def _rattling_pair():
    sim = hertz_sim()
    sim.add_particles(np.array([[3.5e-4, 5e-4, 5e-4], [6.5e-4, 5e-4, 5e-4]]),
                      np.array([1e-4, 1e-4]), np.array([[0.5, 0.1, 0.0], [-0.5, 0.0, 0.2]]))
    return sim


def test_step_reports_progress_and_gives_the_bits_of_single_steps():
    calls = []
    a, b = _rattling_pair(), _rattling_pair()
    a.step(20_000, progress=lambda done, total: calls.append((done, total)))
    for _ in range(20_000):
        b.step(1)
    assert calls and calls[-1] == (20_000, 20_000)
    assert all(t == 20_000 for _, t in calls)
    assert [d for d, _ in calls] == sorted({d for d, _ in calls})
    assert a.step_count == b.step_count == 20_000
    np.testing.assert_array_equal(a.positions(), b.positions())
    np.testing.assert_array_equal(a.velocities(), b.velocities())
    a.step(100, progress=False)
    a.step(100, progress=True)  # a tqdm bar (not a terminal here: it still works)
    assert a.step_count == 20_200


def test_ctrl_c_interrupts_a_long_step_within_a_second():
    import signal
    import threading
    import time

    sim = _rattling_pair()
    n = 10**12  # years of stepping
    main = threading.get_ident()
    timer = threading.Timer(0.5, lambda: signal.pthread_kill(main, signal.SIGINT))
    # Python's own Ctrl-C handler: a process started in the background of a non-interactive
    # shell inherits SIGINT ignored, and the step would then never be interrupted.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        t0 = time.perf_counter()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            sim.step(n, progress=False)
        stopped_after = time.perf_counter() - t0
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert stopped_after < 2.0, stopped_after  # 0.5 s until the signal, then within a second
    done = sim.step_count
    assert 0 < done < n
    sim.step(10)  # the state is consistent: stepping goes on
    assert sim.step_count == done + 10


def _docstring_tables(doc):
    """{section: {key: (unit or None, default as written)}} of the "Parameter tables:" part of
    a docstring; a key listed twice fails."""
    tables, section = {}, None
    for line in doc.split("Parameter tables:", 1)[1].splitlines():
        header = re.fullmatch(r"``(\w+)``", line)
        if header:
            section = tables.setdefault(header.group(1), {})
            continue
        row = re.match(r" {4}`(\w+)`(?: \[([^\]]+)\])?, default (`[^`]*`|[^:`]+):", line)
        if row:
            assert row.group(1) not in section, line
            section[row.group(1)] = (row.group(2), row.group(3).strip("`"))
    return tables


def _reference_units(table):
    """{key: unit or None} of one of parameter_reference()'s Markdown tables (whose unit is "-"
    for a number without one and empty for a string or a switch)."""
    units = {}
    for row in table.splitlines()[2:]:
        cells = [c.strip() for c in row.strip("|").split("|")]
        units[cells[0].strip("`")] = None if cells[2] in ("-", "") else cells[2]
    return units


def test_the_docstring_lists_every_key_with_the_default_in_force_and_its_unit():
    # The defaults the engine uses are read another way than the docstring's text: the
    # configuration it resolves for a Simulation without any of these keys.
    import tomllib

    resolved = tomllib.loads(crushdem_sand.resolved_config(box=BOX))
    listed = _docstring_tables(crushdem_sand.Simulation.__doc__)
    reference = crushdem_sand.parameter_reference()
    sections = ("material", "contact", "damping", "timestep", "neighbor")
    assert set(listed) == set(sections)
    for section in sections:
        in_force = resolved[section]
        assert set(listed[section]) == set(in_force), section
        units = _reference_units(reference[section])
        for key, (unit, default) in listed[section].items():
            assert tomllib.loads(f"v = {default}")["v"] == in_force[key], (section, key)
            assert unit == units[key], (section, key)
    # Spot checks that the parsing reads what it must.
    assert listed["material"]["density"] == ("kg/m^3", "2650")
    assert listed["contact"]["law"] == (None, '"rough"')
    assert listed["neighbor"]["prune"] == (None, "true")


def test_add_particles_refuses_what_would_blow_up():
    sim = hertz_sim()
    with pytest.raises(crushdem_sand.ConfigError, match="not inside the box"):
        sim.add_particles(np.array([[5e-4, 5e-4, 5e-4]]), np.array([5e-3]))  # 10 mm in 1 mm
    with pytest.raises(crushdem_sand.ConfigError, match="grain 1 .* not inside the box"):
        sim.add_particles(np.array([[5e-4, 5e-4, 5e-4], [5e-4, 5e-4, 2e-3]]), 1e-4)
    with pytest.raises(crushdem_sand.ConfigError, match="complex"):
        sim.add_particles(np.array([[5e-4 + 1e-5j, 5e-4, 5e-4]]), np.array([1e-4]))
    with pytest.raises(crushdem_sand.ConfigError, match="finite"):
        sim.add_particles(np.array([[np.nan, 5e-4, 5e-4]]), np.array([1e-4]))
    assert sim.num_particles == 0
    sim.add_particles(np.array([[5e-4, 5e-4, 5e-4]]), np.array([1e-4]))
    assert sim.num_particles == 1


def test_add_particles_while_stepping_in_another_thread_is_refused():
    import threading

    sim = _rattling_pair()
    errors = []
    started = threading.Event()

    def stepper():
        started.set()
        sim.step(3_000_000, progress=False)

    t = threading.Thread(target=stepper)
    t.start()
    started.wait()
    import time

    time.sleep(0.2)
    try:
        sim.add_particles(np.array([[5e-4, 2e-4, 2e-4]]), np.array([5e-5]))
    except RuntimeError as e:
        errors.append(str(e))
    t.join()
    assert errors and "stepping in another thread" in errors[0]
    assert sim.num_particles == 2 and sim.step_count == 3_000_000


def test_results_record_the_version_and_commit(tmp_path):
    import re

    assert re.fullmatch(r"[0-9a-f]{12}(-dirty)?|unknown", crushdem_sand.__commit__)
    sample = os.path.join(os.path.dirname(__file__), "..", "data", "lattice_64.txt")
    run = crushdem_sand.lab.run({"contact": {"law": "hertz"},
                            "particles": {"file": os.path.abspath(sample)},
                            "run": {"steps": 10}, "output": {"progress_seconds": 0}},
                           tmp_path / "r")
    assert run.summary["crushdem_version"] == crushdem_sand.__version__
    assert run.summary["crushdem_commit"] == crushdem_sand.__commit__


def test_a_fixed_step_above_the_automatic_one_warns():
    import warnings

    sim = _rattling_pair()
    sim.compute_forces()
    auto = sim.core.automatic_dt()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.dt = 0.5 * auto  # below: no warning
    with pytest.warns(RuntimeWarning, match="times the automatic step"):
        sim.set_dt(6.7 * auto)
    assert sim.dt == 6.7 * auto


def test_step_and_run_refuse_what_they_cannot_mean():
    """A step count is a whole number >= 0 and a duration a finite time >= 0: 1.5 steps, "10",
    True, -1 s or NaN are refused (before anything moves), not rounded, parsed or ignored."""
    sim = _rattling_pair()
    for bad, error in ((1.5, TypeError), ("10", TypeError), (True, TypeError), (-1, ValueError)):
        with pytest.raises(error, match="step"):
            sim.step(bad)
    for bad, error in ((-1.0, ValueError), (float("nan"), ValueError), (float("inf"), ValueError),
                       ("1e-6", TypeError)):
        with pytest.raises(error, match="duration"):
            sim.run(bad)
    with pytest.raises(TypeError, match="either"):
        sim.run()
    assert sim.step_count == 0
    sim.step(np.int64(3))
    sim.run(steps=4)
    assert sim.step_count == 7
    sim.run(3 * sim.dt)
    assert sim.step_count == 10


def test_state_changes_wait_for_a_step_in_another_thread():
    """While step() runs in one thread (the GIL released), set_dt, set_wall, run and
    compute_forces from another are refused, not interleaved with the step."""
    import threading
    import time

    sim = _rattling_pair()
    t0 = time.perf_counter()
    sim.step(20_000, progress=False)
    n = max(20_000, int(20_000 * 1.5 / max(time.perf_counter() - t0, 1e-6)))  # ~1.5 s
    t = threading.Thread(target=sim.step, args=(n,), kwargs={"progress": False})
    t.start()
    time.sleep(0.2)
    try:
        assert t.is_alive(), "the step ended before the check: make it longer"
        for call in (lambda: sim.set_dt(1e-9), lambda: sim.set_wall("xmin", velocity=0.1),
                     lambda: sim.run(1e-9), sim.compute_forces):
            with pytest.raises(RuntimeError, match="another thread"):
                call()
    finally:
        t.join()


def test_reads_are_refused_while_another_thread_steps_and_the_progress_callback_may_read():
    """While step() runs in one thread, the arrays, the tables (contacts, bodies, the probe)
    and the clock are refused to another (they would mix grains before and after a step);
    the progress callback, in the stepping thread between two chunks, reads and drives it but
    may not step it; threads that only read take turns."""
    import threading
    import time

    sim = _rattling_pair()
    t0 = time.perf_counter()
    sim.step(20_000, progress=False)
    n = max(50_000, int(20_000 * 2.0 / max(time.perf_counter() - t0, 1e-6)))  # ~2 s
    start = sim.step_count
    stored_count = sim.num_contacts  # the deprecated call form counts again when called
    reached, release = threading.Event(), threading.Event()
    seen = {}

    def progress(done, total):
        if not reached.is_set():
            seen["positions"] = sim.positions().shape  # the stepping thread may read
            seen["done"] = sim.step_count - start
            sim.set_wall("xmin", velocity=0.0)  # and drive
            try:
                sim.step(10)
            except RuntimeError as e:
                seen["nested"] = str(e)
            reached.set()
            release.wait(30)

    t = threading.Thread(target=sim.step, args=(n,), kwargs={"progress": progress})
    t.start()
    try:
        assert reached.wait(30), "the progress callback was not called"
        reads = {"positions": sim.positions, "forces": sim.forces, "contacts": sim.contacts,
                 "bodies": sim.bodies, "probe_body": lambda: sim.probe_body("pile"),
                 "wall_stresses": sim.wall_stresses, "kinetic_energy": sim.kinetic_energy,
                 "config_toml": sim.config_toml, "time": lambda: sim.time,
                 "step_count": lambda: sim.step_count, "num_contacts": lambda: sim.num_contacts}
        for name, read in reads.items():
            with pytest.raises(RuntimeError, match=f"Simulation.{name}: .*another thread"):
                read()
        with pytest.warns(DeprecationWarning), pytest.raises(RuntimeError, match="another"):
            stored_count()
        assert "stepping in another thread" in repr(sim)
    finally:
        release.set()
        t.join()
    assert seen["positions"] == (2, 3) and 0 < seen["done"] < n  # between two chunks
    assert "progress callback" in seen["nested"]
    assert sim.step_count == start + n and sim.positions().shape == (2, 3)
    # Threads that only read are not refused: they wait for each other.
    errors = []

    def reader():
        try:
            for _ in range(2000):
                sim.contacts()
                sim.time
        except RuntimeError as e:
            errors.append(str(e))

    readers = [threading.Thread(target=reader) for _ in range(3)]
    for r in readers:
        r.start()
    for r in readers:
        r.join()
    assert not errors


def test_a_deeply_nested_configuration_is_an_error_not_a_crash():
    deep: dict = {}
    inner = deep
    for _ in range(100_000):
        inner["k"] = {}
        inner = inner["k"]
    with pytest.raises(crushdem_sand.ConfigError, match="nested more than"):
        crushdem_sand.Simulation(deep)
    loop: list = []
    loop.append(loop)
    with pytest.raises(crushdem_sand.ConfigError, match="nested more than"):
        crushdem_sand.Simulation(material={"friction": loop})


def test_add_particles_refuses_what_the_sample_reader_refuses():
    """Two grains at one centre, or one deep inside another (new against present, and new
    against new), are refused before any is added; contact-like overlaps are not."""
    sim = hertz_sim()
    sim.add_particles(np.array([[5e-4, 5e-4, 5e-4]]), np.array([1e-4]))
    with pytest.raises(crushdem_sand.ConfigError, match="grain id 0 and new grain 0"):
        sim.add_particle([5e-4, 5e-4, 5e-4], 1e-4)
    with pytest.raises(crushdem_sand.ConfigError,
                       match="new grain 0 and new grain 1 overlap by 175 %"):
        sim.add_particles(np.array([[2e-4, 2e-4, 2e-4], [2.25e-4, 2e-4, 2e-4]]),
                          np.array([1e-4, 1e-4]))
    assert sim.num_particles == 1
    sim.add_particle([6.99e-4, 5e-4, 5e-4], 1e-4)  # 1 % of a radius: as in a dense sample
    assert sim.num_particles == 2
