"""The ParaView files of a run directory (src/crushdem/io/vtk.cpp), read back with VTK's own
XML reader: the particles, the contact network and the walls of every snapshot, and the .pvd
collections that list them with their times."""

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402

DATA = os.path.join(os.path.dirname(__file__), "..", "data")


def _read(path):
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    assert reader.GetErrorCode() == 0, path
    return reader.GetOutput()


def _array(data, name):
    arr = data.GetArray(name)
    assert arr is not None, name
    return vtk_to_numpy(arr)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    pytest.importorskip("crushdem_sand._core")
    tmp = tmp_path_factory.mktemp("paraview")
    particles = os.path.abspath(os.path.join(DATA, "lattice_64.txt"))
    config = tmp / "iso.toml"
    config.write_text(f"""[contact]
law = "hertz"
[particles]
file = "{particles}"
[[stage]]
type = "isotropic"
name = "isotropic"
stress = 1e6
[output]
interval = 2000
vtk_interval = 20000
progress_seconds = 0
""")
    out = tmp / "run"
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "run", str(config), "--out",
                          str(out)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    return out


def _collection(path):
    entries = ET.parse(path).getroot().find("Collection").findall("DataSet")
    return [(float(e.get("timestep")), e.get("file")) for e in entries]


def test_pvd_lists_every_snapshot_by_step_with_increasing_times(run_dir):
    with open(run_dir / "summary.json") as f:
        summary = json.load(f)
    for kind in ("particles", "contacts", "box"):
        entries = _collection(run_dir / "vtk" / f"{kind}.pvd")
        assert len(entries) == summary["snapshots"] >= 3
        times = [t for t, _ in entries]
        assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:]))
        assert times[-1] == pytest.approx(summary["time_s"], rel=1e-12)
        for _, name in entries:
            assert name.startswith(kind + "_") and (run_dir / "vtk" / name).is_file()
        steps = [int(name[len(kind) + 1:-4]) for _, name in entries]
        assert steps[0] == 0 and steps[-1] == summary["steps"]
        assert all(s % 20000 == 0 for s in steps[:-1])


def test_particles_hold_the_grains_with_their_fields(run_dir):
    sample = np.loadtxt(os.path.join(DATA, "lattice_64.txt"), comments="#")
    first = _read(run_dir / "vtk" / "particles_0000000000.vtp")
    assert first.GetNumberOfPoints() == len(sample) == first.GetNumberOfVerts()
    pd = first.GetPointData()
    ids = _array(pd, "id")
    order = np.argsort(ids)
    # The sample file's rows: id x y z d.
    assert np.array_equal(ids[order], sample[:, 0].astype(np.int64))
    points = vtk_to_numpy(first.GetPoints().GetData())
    np.testing.assert_array_equal(points[order], sample[:, 1:4])
    np.testing.assert_array_equal(2.0 * _array(pd, "radius")[order], sample[:, 4])
    assert np.all(_array(pd, "parent_id") == -1)
    for name in ("velocity", "angular_velocity", "force"):
        assert _array(pd, name).shape == (len(sample), 3)


def test_contacts_join_touching_grains_with_their_forces(run_dir):
    entries = _collection(run_dir / "vtk" / "contacts.pvd")
    net = _read(run_dir / "vtk" / entries[-1][1])
    grains = _read(run_dir / "vtk" / entries[-1][1].replace("contacts", "particles"))
    n = net.GetNumberOfLines()
    assert n > 0 and net.GetNumberOfPoints() == 2 * n
    cd = net.GetCellData()
    fn, wall, overlap = _array(cd, "normal_force"), _array(cd, "is_wall"), _array(cd, "overlap")
    assert np.all(fn > 0) and np.all(overlap > 0) and wall.sum() > 0 and (wall == 0).sum() > 0
    ft = _array(cd, "tangential_force")
    np.testing.assert_allclose(_array(cd, "tangential_force_magnitude"),
                               np.linalg.norm(ft, axis=1), rtol=1e-12, atol=0)
    # Each grain-grain line runs between the centres of the two grains it names, and the
    # centres are overlap apart less than the sum of the radii.
    ids = _array(grains.GetPointData(), "id")
    radius = _array(grains.GetPointData(), "radius")
    centre = vtk_to_numpy(grains.GetPoints().GetData())
    where = {int(g): k for k, g in enumerate(ids)}
    ends = vtk_to_numpy(net.GetPoints().GetData()).reshape(n, 2, 3)
    id_i, id_j = _array(cd, "id_i"), _array(cd, "id_j")
    for c in np.flatnonzero(wall == 0):
        i, j = where[int(id_i[c])], where[int(id_j[c])]
        np.testing.assert_array_equal(ends[c, 0], centre[i])
        np.testing.assert_array_equal(ends[c, 1], centre[j])
        gap = np.linalg.norm(centre[j] - centre[i])
        assert gap == pytest.approx(radius[i] + radius[j] - overlap[c], rel=1e-9)


def test_box_is_the_walls_at_the_end(run_dir):
    entries = _collection(run_dir / "vtk" / "box.pvd")
    box = _read(run_dir / "vtk" / entries[-1][1])
    assert box.GetNumberOfPoints() == 8 and box.GetNumberOfPolys() == 6
    corners = vtk_to_numpy(box.GetPoints().GetData())
    with open(run_dir / "timeseries.csv") as f:
        header = f.readline().strip().split(",")
        last = f.readlines()[-1].strip().split(",")
    row = dict(zip(header, (float(v) for v in last)))
    assert corners[:, 0].min() == pytest.approx(row["wall_xmin_position_m"], rel=1e-12)
    assert corners[:, 2].max() == pytest.approx(row["wall_zmax_position_m"], rel=1e-12)


@pytest.fixture(scope="module")
def chamber_dir(tmp_path_factory):
    """tests/data/chamber_400.toml: a chamber sample and a cone pushed into it."""
    pytest.importorskip("crushdem_sand._core")
    out = tmp_path_factory.mktemp("paraview_chamber") / "run"
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "run",
                          os.path.join(DATA, "chamber_400.toml"), "--out", str(out)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    return out


def test_bodies_are_surfaces_where_their_degrees_of_freedom_put_them(chamber_dir):
    entries = _collection(chamber_dir / "vtk" / "bodies.pvd")
    assert [f for _, f in entries] == [f.replace("box", "bodies")
                                       for _, f in _collection(chamber_dir / "vtk" / "box.pvd")]
    last = _read(chamber_dir / "vtk" / entries[-1][1])
    body = vtk_to_numpy(last.GetCellData().GetArray("body"))
    part = vtk_to_numpy(last.GetCellData().GetArray("part"))
    # The cone (body 6, the configuration's [[body]]): a tip of 48 triangles and a shaft of 48
    # quadrilaterals; the chamber the sample added (body 7): 48 quadrilaterals.
    assert last.GetNumberOfPolys() == 144
    assert ((body == 6) & (part == 0)).sum() == 48 and ((body == 6) & (part == 1)).sum() == 48
    assert (body == 7).sum() == 48
    points = vtk_to_numpy(last.GetPoints().GetData())
    cells = vtk_to_numpy(last.GetPolys().GetConnectivityArray())
    offsets = vtk_to_numpy(last.GetPolys().GetOffsetsArray())  # 0, then each polygon's end
    chamber = np.unique(cells[offsets[96]:offsets[144]])
    radius = np.hypot(points[chamber, 0], points[chamber, 1])
    np.testing.assert_allclose(radius, radius[0], rtol=1e-12)  # a cylinder about the z axis
    with open(chamber_dir / "penetration.csv") as f:
        header = f.readline().strip().split(",")
        row = dict(zip(header, (float(v) for v in f.readlines()[-1].strip().split(","))))
    apex = cells[offsets[0]]  # the cone's first triangle starts at its apex
    np.testing.assert_allclose(points[apex], [row["tip_x_m"], row["tip_y_m"], row["tip_z_m"]],
                               rtol=0, atol=1e-15)


def test_frames_mark_the_prepared_sample_each_stage_start_and_each_dynamic_phase(tmp_path):
    # The small creep test of tests/data: a hold, then an age stage of a day. The frames are the
    # first state, the age stage's start, the end of every dynamic phase (at its ageing time:
    # the .pvd's time is the DEM time plus the ageing clock), the periodic ones and the end.
    import csv

    from _data import data_text

    config = tmp_path / "creep.toml"
    config.write_text(data_text("grains_300.toml", "creep_300.toml"))
    out = tmp_path / "run"
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "run", str(config), "--out",
                          str(out), "--quiet"], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    entries = _collection(out / "vtk" / "particles.pvd")
    frames = {int(name[len("particles_"):-4]): t for t, name in entries}
    times = [t for t, _ in entries]
    assert all(b > a for a, b in zip(times, times[1:]))
    with open(out / "summary.json") as f:
        summary = json.load(f)
    assert 25000 in frames  # the age stage's start (after the 25,000-step hold)
    with open(out / "events.csv") as f:
        events = list(csv.DictReader(f))
    assert len(events) >= 3
    for row in events:
        step = int(row["step"])
        assert step in frames, step
        assert frames[step] == pytest.approx(float(row["time_s"]) + float(row["ageing_time_s"]),
                                             rel=1e-12)
    assert times[-1] == pytest.approx(summary["time_s"] + 86400.0, rel=1e-9)


def test_the_first_frame_of_a_prepared_sample_is_the_sample_not_the_loose_cloud(tmp_path):
    config = tmp_path / "sample.toml"
    config.write_text('[sample]\ncount = 500\nvoid_ratio = 0.8\nseed = 3\n'
                      '[output]\nprogress_seconds = 0\n')
    out = tmp_path / "run"
    res = subprocess.run([sys.executable, "-m", "crushdem_sand", "run", str(config), "--out",
                          str(out), "--quiet"], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    entries = _collection(out / "vtk" / "particles.pvd")
    with open(out / "summary.json") as f:
        summary = json.load(f)
    first = int(entries[0][1][len("particles_"):-4])
    assert first == summary["steps"] > 0  # the prepared state: the preparation's last step
    grains = _read(out / "vtk" / entries[0][1])
    assert grains.GetNumberOfPoints() == summary["particles"]
