"""crushdem_sand.packing: a sample.txt read back, and its void ratio by region measured on packings
whose answer is known: a simple cubic lattice of touching spheres (solid fraction pi / 6 in
every bin away from the faces) in a cube and in a quarter chamber, and the same chamber with a
hole bored along its axis, which the map must show where it is and nowhere else."""

import math

import numpy as np
import pytest

from crushdem_sand.packing import read_sample, void_ratio_map, void_ratio_profile

E_LATTICE = (1.0 - math.pi / 6.0) / (math.pi / 6.0)  # 0.9099


def _write(path, header, centres, d):
    with open(path, "w") as f:
        for k, v in header.items():
            f.write(f"# {k}={v}\n")
        f.write(f"# particles={len(centres)}\n")
        for i, c in enumerate(centres):
            f.write(f"{i} {float(c[0])!r} {float(c[1])!r} {float(c[2])!r} {d!r}\n")


def _lattice(n, d, lo=(0.0, 0.0, 0.0)):
    g = (np.arange(n) + 0.5) * d
    x, y, z = np.meshgrid(g + lo[0], g + lo[1], g + lo[2], indexing="ij")
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()])


def _box(lo, hi):
    return {f"box_{a}{m}": (lo if m == "min" else hi)[i]
            for i, a in enumerate("xyz") for m in ("min", "max")}


def test_a_sample_file_is_read_with_its_header(tmp_path):
    p = tmp_path / "sample.txt"
    _write(p, {"void_ratio": 0.65, **_box((0, 0, 0), (1, 1, 1))}, [(0.1, 0.2, 0.3)], 0.05)
    header, g = read_sample(p)
    assert header["void_ratio"] == "0.65"
    assert list(g.columns) == ["id", "x", "y", "z", "diameter"]
    assert g.loc[0, "z"] == 0.3 and g.loc[0, "diameter"] == 0.05
    with open(p, "a") as f:
        f.write("1 0.5 0.5\n")
    with pytest.raises(ValueError, match=r"sample.txt:\d+: expected 'id x y z diameter'"):
        read_sample(p)


def test_a_cube_lattice_has_its_void_ratio_in_every_shell(tmp_path):
    d, n = 1e-3, 20  # every bin edge on a lattice plane (shells of 2, 2, 2, 2, 1, 1 cells)
    p = tmp_path / "sample.txt"
    _write(p, _box((0, 0, 0), (n * d,) * 3), _lattice(n, d), d)
    m = void_ratio_map(p, z_edges=[0.1, 0.5, 0.9], points=20000)
    assert len(m) == 2 * 6
    assert m["d50"].iloc[0] == d
    # Each bin is whole lattice cells: pi / 6 to the sampling error (1.4 % of e here, one
    # standard error).
    np.testing.assert_allclose(m["void_ratio"], E_LATTICE, rtol=0.05)
    assert m["grains"].sum() > 0.7 * n ** 3
    # The same call, the same numbers.
    assert void_ratio_map(p, z_edges=[0.1, 0.5, 0.9], points=20000).equals(m)


def test_a_hole_along_a_quarter_chambers_axis_is_found_where_it_is(tmp_path):
    # A quarter chamber of radius R filled with the lattice (the spheres whose centres are inside
    # the quarter cylinder), and the same with the spheres within 0.2 R of the axis in the middle
    # fifth of the height removed.
    d, n = 1e-3, 30
    R, H = n * d, n * d
    c = _lattice(n, d)
    keep = np.hypot(c[:, 0], c[:, 1]) < R
    c = c[keep]
    header = {**_box((-R, -R, 0.0), (R, R, H)), "chamber_radius": R, "sector": 90}
    full, bored = tmp_path / "full.txt", tmp_path / "bored.txt"
    _write(full, header, c, d)
    hole = (np.hypot(c[:, 0], c[:, 1]) < 0.2 * R) & (c[:, 2] > 0.4 * H) & (c[:, 2] < 0.6 * H)
    _write(bored, header, c[~hole], d)
    kw = dict(r_edges=[0.0, 0.2, 0.5, 0.8], z_edges=[0.1, 0.4, 0.6, 0.9], points=20000)
    a, b = void_ratio_map(full, **kw), void_ratio_map(bored, **kw)
    # Away from the curved wall the full quarter is the lattice, the axis included: the points
    # are drawn in the quarter's own angle (drawn in the whole circle, three quarters would be
    # empty and e would be about 6.6).
    np.testing.assert_allclose(a["void_ratio"], E_LATTICE, rtol=0.06)
    in_hole = (b["r_hi"] == 0.2) & (b["z_lo"] == 0.4)
    assert b.loc[in_hole, "void_ratio"].item() > 5.0  # the caps of the spheres around it
    assert b.loc[in_hole, "grains"].item() == 0
    # Elsewhere the map is the full quarter's: the same points (drawn from the seed), which
    # only the removed spheres' caps in the bins beside the hole miss.
    np.testing.assert_allclose(b.loc[~in_hole, "void_ratio"], a.loc[~in_hole, "void_ratio"],
                               rtol=0.1)
    assert (b["void_ratio"] == a["void_ratio"]).sum() >= 4


def test_a_half_chamber_is_measured_in_its_own_half(tmp_path):
    # The half (sector 180) holds the grains at x > 0: its points are drawn there, so its
    # lattice measures as the lattice (drawn at y > 0 instead, half of them would miss).
    d, n = 1e-3, 20
    R, H = n * d, n * d
    c = _lattice(2 * n, d, lo=(0.0, -R, 0.0))
    c = c[(np.hypot(c[:, 0], c[:, 1]) < R) & (c[:, 2] < H)]
    p = tmp_path / "half.txt"
    _write(p, {**_box((-R, -R, 0.0), (R, R, H)), "chamber_radius": R, "sector": 180}, c, d)
    m = void_ratio_map(p, r_edges=[0.0, 0.5, 0.8], z_edges=[0.1, 0.5, 0.9])
    np.testing.assert_allclose(m["void_ratio"], E_LATTICE, rtol=0.06)


def test_bad_input_is_named(tmp_path):
    p = tmp_path / "sample.txt"
    _write(p, {"void_ratio": 0.65}, [(0.1, 0.2, 0.3)], 0.05)
    with pytest.raises(ValueError, match="no box_xmin in the header"):
        void_ratio_map(p)
    _write(p, _box((0, 0, 0), (1, 1, 1)), [(0.1, 0.2, 0.3)], 0.05)
    with pytest.raises(ValueError, match=r"r_edges = \[0.5, 0.2\]: expected increasing"):
        void_ratio_map(p, r_edges=[0.5, 0.2])
    with pytest.raises(ValueError, match="points = 10"):
        void_ratio_map(p, points=10)


def _quarter_lattice(tmp_path, name, drop=None, n=30, d=1e-3, sector=90):
    """A quarter (or half) chamber of radius n d filled with the simple cubic lattice; `drop`
    removes the grains whose centres it selects."""
    R, H = n * d, n * d
    c = _lattice(n, d)
    if sector == 180:  # the mirror image in y too
        c = np.vstack([c, c * np.array([1.0, -1.0, 1.0])])
    c = c[np.hypot(c[:, 0], c[:, 1]) < R]
    if drop is not None:
        c = c[~drop(c)]
    p = tmp_path / name
    _write(p, {**_box((-R, -R, 0.0), (R, R, H)), "chamber_radius": R, "sector": sector}, c, d)
    return p


def test_a_lattice_is_as_dense_beside_its_planes_and_platens_as_inside(tmp_path):
    # Every bin one or more whole lattice layers from the boundary: pi / 6 (to the sampling error
    # and the part cells the bins' other faces cut).
    p = _quarter_lattice(tmp_path, "quarter.txt")
    for boundary in ("planes", "platens"):
        m = void_ratio_profile(p, boundary, edges=[0, 1, 2, 3], points=20000)
        assert list(m.columns) == ["distance_lo", "distance_hi", "void_ratio", "grains", "d50"]
        np.testing.assert_allclose(m["void_ratio"], E_LATTICE, rtol=0.06, err_msg=boundary)
        assert (m["grains"] > 0).all()
    # A half chamber's one plane, both sides of its axis.
    half = _quarter_lattice(tmp_path, "half.txt", sector=180)
    m = void_ratio_profile(half, "planes", edges=[0, 1, 2], points=20000)
    np.testing.assert_allclose(m["void_ratio"], E_LATTICE, rtol=0.06)
    assert void_ratio_profile(p, "planes", edges=[0, 1, 2, 3], points=20000).equals(
        void_ratio_profile(p, "planes", edges=[0, 1, 2, 3], points=20000))


def test_a_layer_missing_along_one_plane_loosens_its_bin_only(tmp_path):
    d = 1e-3
    # The layer of grains touching the plane y = 0 removed: the first bin's points on that plane's
    # strip (half of them) find no grain, those on the other plane's strip the lattice.
    p = _quarter_lattice(tmp_path, "no_layer.txt", drop=lambda c: c[:, 1] < d)
    m = void_ratio_profile(p, "planes", edges=[0, 1, 2, 3], points=20000)
    phi = math.pi / 12.0
    assert m["void_ratio"].iloc[0] == pytest.approx((1 - phi) / phi, rel=0.08)
    np.testing.assert_allclose(m["void_ratio"].iloc[1:], E_LATTICE, rtol=0.06)


def test_an_empty_core_shows_in_the_axis_profile_and_ends_where_the_grains_begin(tmp_path):
    d = 1e-3
    p = _quarter_lattice(tmp_path, "core.txt", drop=lambda c: np.hypot(c[:, 0], c[:, 1]) < 3 * d)
    m = void_ratio_profile(p, "axis", edges=[0, 1, 2, 6, 10], points=20000)
    # No grain reaches within 2.5 d of the axis.
    assert np.isinf(m["void_ratio"].iloc[0]) and np.isinf(m["void_ratio"].iloc[1])
    assert m["grains"].iloc[0] == 0 and m["grains"].iloc[1] == 0
    assert m["void_ratio"].iloc[3] == pytest.approx(E_LATTICE, rel=0.08)
    c = void_ratio_profile(p, "chamber", edges=[0, 2, 4], points=5000)
    assert np.isfinite(c["void_ratio"]).all()


def test_a_profile_refuses_what_it_cannot_measure(tmp_path):
    d, n = 1e-3, 10
    cube = tmp_path / "cube.txt"
    _write(cube, _box((0, 0, 0), (n * d,) * 3), _lattice(n, d), d)
    with pytest.raises(ValueError, match="not a chamber sample"):
        void_ratio_profile(cube, "axis")
    p = _quarter_lattice(tmp_path, "quarter.txt", n=10)
    with pytest.raises(ValueError, match="boundary = 'wall'"):
        void_ratio_profile(p, "wall")
    with pytest.raises(ValueError, match=r"edges = \[1.0, 0.5\]"):
        void_ratio_profile(p, "axis", edges=[1, 0.5])
    with pytest.raises(ValueError, match="r_range"):
        void_ratio_profile(p, "planes", r_range=(0.5, 0.2))
    full = tmp_path / "full.txt"
    _write(full, {**_box((-1, -1, 0), (1, 1, 1)), "chamber_radius": 0.01, "sector": 360},
           _lattice(4, d), d)
    with pytest.raises(ValueError, match="sector of 90 or 180"):
        void_ratio_profile(full, "planes")
    with pytest.raises(ValueError, match="outside the sample's region"):
        void_ratio_profile(p, "axis", edges=[20, 30], points=200)
