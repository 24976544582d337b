"""A prepared sample (``sample.txt``) and its void ratio by region (NumPy and pandas only).

A sample is as homogeneous as the way it was compacted lets it be: a loose cloud swept together
by its walls can jam with a looser core (docs/chamber.md, "Compaction"). :func:`void_ratio_map`
measures the void ratio in bins of a chamber sample (radius and height, as fractions of the
chamber's radius and the platens' distance) or of a cube (shells about its centre, and height),
so that a sample can be checked before a long test starts on it.

The solid fraction of a bin is the share of points, drawn uniformly in it, that lie inside a
grain: a Monte Carlo estimate of the volume of the grains' union in the bin, exact in the limit
(the grains cut by the bin's faces count by the part inside; the small overlaps of touching
grains count once, so a whole sample measures a little looser than its header's void ratio).
Its error is that of a binomial share, sqrt(phi (1 - phi) / points): for the default 20,000
points about 0.0035 in phi, 1.5 % of a void ratio near 0.65 (one standard error). The packing's
own scatter in a bin of few grains is larger.
"""

from __future__ import annotations

import os
from typing import Dict, Optional, Sequence, Tuple, Union

import numpy as np
import pandas as pd

PathLike = Union[str, "os.PathLike[str]"]

#: The bins of a chamber sample when none are given: fractions of the chamber's radius (the axis,
#: the body, the layer along the wall) and of the height (the platens' layers and the middle).
CHAMBER_R_EDGES = (0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0)
HEIGHT_EDGES = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0)
#: A cube's shells: fractions of the half-side (the largest of |x - x_c|, |y - y_c| over it).
CUBE_SHELL_EDGES = (0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 1.0)


def read_sample(path: PathLike) -> Tuple[Dict[str, str], pd.DataFrame]:
    """``sample.txt``: its ``# key=value`` header and its grains (``id``, ``x``, ``y``, ``z``,
    ``diameter``, in m). Raises ValueError naming the file for a malformed line or no grains."""
    path = os.fspath(path)
    header: Dict[str, str] = {}
    rows = []
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line:
                continue
            if line.startswith("#"):
                key, eq, value = line[1:].strip().partition("=")
                if eq:
                    header[key.strip()] = value.strip()
                continue
            fields = line.split()
            try:
                if len(fields) < 5:
                    raise ValueError(line)
                rows.append([float(v) for v in fields[:5]])
            except ValueError:
                raise ValueError(f"{path}:{n}: expected 'id x y z diameter', "
                                 f"got '{line[:80]}'") from None
    if not rows:
        raise ValueError(f"{path}: no grains")
    a = np.asarray(rows, dtype=float)
    grains = pd.DataFrame({"id": a[:, 0].astype(np.int64), "x": a[:, 1], "y": a[:, 2],
                           "z": a[:, 3], "diameter": a[:, 4]})
    return header, grains


class _CellList:
    """Spheres sorted into cubic cells of side the largest diameter, so that a point's spheres
    are in its cell and the 26 around it."""

    def __init__(self, centres: np.ndarray, radii: np.ndarray) -> None:
        self.cell = 2.0 * float(radii.max())
        self.lo = centres.min(axis=0) - self.cell
        self.dims = np.floor((centres.max(axis=0) + self.cell - self.lo) / self.cell).astype(
            np.int64) + 1
        key = self._flat(np.floor((centres - self.lo) / self.cell).astype(np.int64))
        order = np.argsort(key, kind="stable")
        cells = np.arange(int(self.dims.prod()))
        self.start = np.searchsorted(key[order], cells, side="left")
        self.end = np.searchsorted(key[order], cells, side="right")
        self.most = int((self.end - self.start).max())
        self.centres = centres[order]
        self.r2 = radii[order] ** 2

    def _flat(self, ijk: np.ndarray) -> np.ndarray:
        return ijk[:, 0] + self.dims[0] * (ijk[:, 1] + self.dims[1] * ijk[:, 2])

    def inside(self, points: np.ndarray) -> np.ndarray:
        """For each point, whether it lies in at least one sphere."""
        inside = np.zeros(len(points), dtype=bool)
        pij = np.floor((points - self.lo) / self.cell).astype(np.int64)
        for off in np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1]), -1).reshape(-1, 3):
            q = pij + off
            ok = np.all((q >= 0) & (q < self.dims), axis=1) & ~inside
            if not ok.any():
                continue
            k = self._flat(q[ok])
            s, e = self.start[k], self.end[k]
            pts = points[ok]
            hit = np.zeros(len(pts), dtype=bool)
            for m in range(self.most):
                j = s + m
                valid = j < e
                if not valid.any():
                    break
                jj = np.where(valid, j, 0)
                d2 = np.sum((pts - self.centres[jj]) ** 2, axis=1)
                hit |= valid & (d2 <= self.r2[jj])
            inside[np.flatnonzero(ok)[hit]] = True
        return inside


def _mass_d50(diameter: np.ndarray) -> float:
    """The median diameter by mass (volume) of a sample's grains."""
    vol = (0.5 * diameter) ** 3
    by_size = np.argsort(diameter)
    return float(diameter[by_size][np.searchsorted(np.cumsum(vol[by_size]), 0.5 * vol.sum())])


def _sector_points(rad: np.ndarray, z: np.ndarray, sector: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Points at radii `rad` and heights `z`, at angles uniform in the sector's own (x, y > 0 for
    a quarter; x > 0 for a half)."""
    start = -0.5 * np.pi if sector == 180.0 else 0.0
    th = start + np.deg2rad(sector) * rng.uniform(0.0, 1.0, len(rad))
    return np.column_stack([rad * np.cos(th), rad * np.sin(th), z])


def void_ratio_map(path: PathLike, r_edges: Optional[Sequence[float]] = None,
                   z_edges: Optional[Sequence[float]] = None, points: int = 20000,
                   seed: int = 1) -> pd.DataFrame:
    """The void ratio of a prepared sample by region, one row per bin: ``r_lo``, ``r_hi`` (a
    chamber sample: fractions of the chamber's radius about the z axis; a cube: of its half-side,
    as shells about its centre), ``z_lo``, ``z_hi`` (fractions of the height from the bottom
    platen), ``void_ratio``, ``grains`` (centres in the bin) and ``d50`` (the grains' median
    diameter by mass, m, the same in every row). A sector (``sector`` in the header) is measured
    in its own angle. ``points`` are drawn per bin from ``seed``: the same call gives the same
    numbers."""
    header, g = read_sample(path)
    if points < 100:
        raise ValueError(f"points = {points}: expected at least 100 per bin")
    box = {}
    for k in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        if f"box_{k}" not in header:
            raise ValueError(f"{os.fspath(path)}: no box_{k} in the header (not a crushdem sample)")
        box[k] = float(header[f"box_{k}"])
    chamber = "chamber_radius" in header
    R = float(header["chamber_radius"]) if chamber else 0.0
    sector = float(header.get("sector", "360")) if chamber else 360.0
    z0, H = box["zmin"], box["zmax"] - box["zmin"]
    r_edges = np.asarray(r_edges if r_edges is not None else
                         (CHAMBER_R_EDGES if chamber else CUBE_SHELL_EDGES), dtype=float)
    z_edges = np.asarray(z_edges if z_edges is not None else HEIGHT_EDGES, dtype=float)
    for name, e in (("r_edges", r_edges), ("z_edges", z_edges)):
        if len(e) < 2 or np.any(np.diff(e) <= 0) or e[0] < 0 or e[-1] > 1:
            raise ValueError(f"{name} = {e.tolist()}: expected increasing fractions in [0, 1]")
    c = g[["x", "y", "z"]].to_numpy()
    r = 0.5 * g["diameter"].to_numpy()
    d50 = _mass_d50(g["diameter"].to_numpy())
    mid = np.array([0.5 * (box["xmin"] + box["xmax"]), 0.5 * (box["ymin"] + box["ymax"])])
    half = 0.5 * np.array([box["xmax"] - box["xmin"], box["ymax"] - box["ymin"]])
    if chamber:
        radial = np.hypot(c[:, 0], c[:, 1]) / R
    else:
        radial = np.max(np.abs(c[:, :2] - mid) / half, axis=1)
    height = (c[:, 2] - z0) / H
    cells = _CellList(c, r)
    rng = np.random.default_rng(seed)
    rows = []
    for z_lo, z_hi in zip(z_edges[:-1], z_edges[1:]):
        for r_lo, r_hi in zip(r_edges[:-1], r_edges[1:]):
            zs = z0 + H * rng.uniform(z_lo, z_hi, points)
            if chamber:
                # Uniform in the annulus's area, in the sector's angle (x, y > 0 for a quarter;
                # x > 0 for a half).
                rad = R * np.sqrt(rng.uniform(r_lo ** 2, r_hi ** 2, points))
                pts = _sector_points(rad, zs, sector, rng)
            else:
                # Uniform in the square shell: draw in the square, keep those in the shell.
                xy = np.empty((0, 2))
                while len(xy) < points:
                    u = rng.uniform(-r_hi, r_hi, (2 * points, 2))
                    m = np.max(np.abs(u), axis=1)
                    xy = np.vstack([xy, u[(m >= r_lo) & (m < r_hi)]])
                pts = np.column_stack([mid + xy[:points] * half, zs])
            phi = float(cells.inside(pts).mean())
            in_bin = (radial >= r_lo) & (radial < r_hi) & (height >= z_lo) & (height < z_hi)
            rows.append({"r_lo": r_lo, "r_hi": r_hi, "z_lo": z_lo, "z_hi": z_hi,
                         "void_ratio": (1.0 - phi) / phi if phi > 0 else float("inf"),
                         "grains": int(in_bin.sum()), "d50": d50})
    return pd.DataFrame(rows)


#: The bins of :func:`void_ratio_profile`, in median grain diameters from the boundary.
PROFILE_EDGES = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)

#: What :func:`void_ratio_profile` measures the distance from.
PROFILE_BOUNDARIES = ("axis", "planes", "chamber", "platens")


def void_ratio_profile(path: PathLike, boundary: str,
                       edges: Sequence[float] = PROFILE_EDGES, points: int = 20000,
                       seed: int = 1, r_range: Tuple[float, float] = (0.25, 0.9),
                       z_range: Tuple[float, float] = (0.1, 0.9)) -> pd.DataFrame:
    """The void ratio of a chamber sample against the distance from one of its boundaries, in
    median grain diameters (``edges``), one row per bin: ``distance_lo``, ``distance_hi`` (in
    d50), ``void_ratio``, ``grains`` (centres in the bin) and ``d50`` (m). A wall orders the
    grains beside it and loosens the packing within a few diameters; this measures by how much
    and how far, for each kind of boundary of a chamber sample:

    - ``"axis"``: the distance from the chamber's axis (where a sector's symmetry planes meet,
      and where a penetrometer goes), at heights ``z_range``;
    - ``"planes"``: the distance from the nearer symmetry plane of a sector (90 or 180 degrees),
      at radii ``r_range`` and heights ``z_range``;
    - ``"chamber"``: the distance from the chamber's cylinder, at heights ``z_range``;
    - ``"platens"``: the distance from the nearer platen, at radii ``r_range``.

    ``r_range`` and ``z_range`` are fractions of the chamber's radius and of the platens'
    distance; their defaults keep each profile clear of the other boundaries. Each bin's solid
    fraction is the share of ``points`` drawn uniformly in it that lie in a grain (as
    :func:`void_ratio_map`; the same call gives the same numbers)."""
    header, g = read_sample(path)
    name = os.fspath(path)
    if boundary not in PROFILE_BOUNDARIES:
        raise ValueError(f"boundary = {boundary!r}: expected one of "
                         f"{', '.join(PROFILE_BOUNDARIES)}")
    if "chamber_radius" not in header:
        raise ValueError(f"{name}: not a chamber sample (no chamber_radius in its header)")
    if points < 100:
        raise ValueError(f"points = {points}: expected at least 100 per bin")
    edges = np.asarray(edges, dtype=float)
    if len(edges) < 2 or np.any(np.diff(edges) <= 0) or edges[0] < 0:
        raise ValueError(f"edges = {edges.tolist()}: expected increasing distances >= 0 (d50)")
    for key, (lo, hi) in (("r_range", r_range), ("z_range", z_range)):
        if not 0.0 <= lo < hi <= 1.0:
            raise ValueError(f"{key} = {(lo, hi)}: expected fractions 0 <= lo < hi <= 1")
    sector = float(header.get("sector", "360"))
    if boundary == "planes" and sector not in (90.0, 180.0):
        raise ValueError(f"{name}: boundary 'planes' needs a sector of 90 or 180 degrees "
                         f"(this sample's sector is {sector:g})")
    R = float(header["chamber_radius"])
    z0 = float(header["box_zmin"])
    H = float(header["box_zmax"]) - z0
    c = g[["x", "y", "z"]].to_numpy()
    radius = 0.5 * g["diameter"].to_numpy()
    d50 = _mass_d50(g["diameter"].to_numpy())
    # A sector's planes' inward normals (a quarter: x, y > 0; a half: x > 0).
    normals = [np.array([1.0, 0.0])] if sector == 180.0 else [np.array([0.0, 1.0]),
                                                              np.array([1.0, 0.0])]

    def plane_distance(xy: np.ndarray) -> np.ndarray:
        return np.min(np.stack([xy @ n for n in normals]), axis=0)

    def distance(p: np.ndarray) -> np.ndarray:
        if boundary == "axis":
            return np.hypot(p[:, 0], p[:, 1])
        if boundary == "chamber":
            return R - np.hypot(p[:, 0], p[:, 1])
        if boundary == "platens":
            return np.minimum(p[:, 2] - z0, z0 + H - p[:, 2])
        return plane_distance(p[:, :2])

    def in_range(p: np.ndarray) -> np.ndarray:
        rad, hgt = np.hypot(p[:, 0], p[:, 1]) / R, (p[:, 2] - z0) / H
        ok_z = (hgt >= z_range[0]) & (hgt < z_range[1])
        ok_r = (rad >= r_range[0]) & (rad < r_range[1])
        if boundary in ("axis", "chamber"):
            return ok_z & (rad < 1.0)
        if boundary == "platens":
            return ok_r & (hgt >= 0.0) & (hgt < 1.0)
        return ok_r & ok_z

    def draw(lo: float, hi: float, n: int, rng: np.random.Generator) -> np.ndarray:
        """n points uniform in the bin [lo, hi) (m) of the region: drawn where the bin is, then
        kept where the distance and the ranges say (uniform in a superset, then rejected, stays
        uniform)."""
        def zs(k: int) -> np.ndarray:
            return z0 + H * rng.uniform(z_range[0], z_range[1], k)

        if boundary == "axis":
            return _sector_points(np.sqrt(rng.uniform(lo ** 2, hi ** 2, n)), zs(n), sector, rng)
        if boundary == "chamber":
            a, b = max(R - hi, 0.0), R - lo
            return _sector_points(np.sqrt(rng.uniform(a ** 2, b ** 2, n)), zs(n), sector, rng)
        if boundary == "platens":
            rad = R * np.sqrt(rng.uniform(r_range[0] ** 2, r_range[1] ** 2, n))
            s = rng.uniform(lo, hi, n)
            z = np.where(rng.uniform(0.0, 1.0, n) < 0.5, z0 + s, z0 + H - s)
            return _sector_points(rad, z, sector, rng)
        # A strip along a plane chosen at random: along it from r_range[0] R to r_range[1] R,
        # at s from it; the strips of the two planes of a quarter are mirror images.
        k = rng.integers(0, len(normals), n)
        nrm = np.stack(normals)[k]
        along = np.column_stack([nrm[:, 1], nrm[:, 0]])  # the plane's radial direction
        t = R * rng.uniform(r_range[0], r_range[1], n)
        if sector == 180.0:  # the half's plane runs from y = -R to R
            t *= np.where(rng.uniform(0.0, 1.0, n) < 0.5, -1.0, 1.0)
        s = rng.uniform(lo, hi, n)
        xy = along * t[:, None] + nrm * s[:, None]
        return np.column_stack([xy, zs(n)])

    cells = _CellList(c, radius)
    rng = np.random.default_rng(seed)
    d_grain, ok_grain = distance(c), in_range(c)
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        a, b = lo * d50, hi * d50
        kept = np.empty((0, 3))
        for _ in range(200):
            p = draw(a, b, 2 * points, rng)
            dist = distance(p)
            p = p[(dist >= a) & (dist < b) & in_range(p)]
            kept = np.vstack([kept, p])
            if len(kept) >= points:
                break
        if len(kept) < points:
            raise ValueError(f"{name}: the bin {lo:g}-{hi:g} d50 from the {boundary} lies "
                             "outside the sample's region (r_range, z_range)")
        phi = float(cells.inside(kept[:points]).mean())
        rows.append({"distance_lo": lo, "distance_hi": hi,
                     "void_ratio": (1.0 - phi) / phi if phi > 0 else float("inf"),
                     "grains": int(((d_grain >= a) & (d_grain < b) & ok_grain).sum()),
                     "d50": d50})
    return pd.DataFrame(rows)
