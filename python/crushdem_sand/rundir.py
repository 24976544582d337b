"""Reading a crushdem run directory (NumPy only: no figures, no engine).

A run directory holds ``config.toml`` (written when the run starts), ``timeseries.csv``,
``summary.json`` (written when it ends), and, depending on the run, ``events.csv`` and
``phases.csv`` (age stages), ``penetration.csv``, ``shaft_profile.csv`` and
``penetration_field.csv`` (penetrate stages), ``grading.csv`` and ``breakage.csv`` (grain
crushing) and ``timing.json``; docs/configuration.md lists their columns. Every reader here
returns an empty or ``None`` result for a file that is missing, so a run still going can be read
too.

:func:`read_run` reads everything the figures need into one :class:`RunData`.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from .analysis import mask_unmeasured_contacts

PathLike = Union[str, "os.PathLike[str]"]
Columns = Dict[str, np.ndarray]


MANIFEST = "manifest.json"


def record_entries(run_dir: PathLike, names: List[str]) -> None:
    """Adds top-level ``names`` (files crushdem wrote into ``run_dir``, such as figures) to the
    run's ``manifest.json``, so that ``--overwrite`` removes them with the run and nothing else.
    A folder without a manifest (not a run directory) is left alone."""
    path = os.path.join(os.fspath(run_dir), MANIFEST)
    if not os.path.isfile(path):
        return
    with open(path, encoding="utf-8") as f:
        manifest = json.load(f)
    entries = manifest.setdefault("entries", [])
    added = [n for n in names if n not in entries and os.path.basename(n) == n]
    if not added:
        return
    entries.extend(added)
    tmp = f"{path}.{os.getpid()}.tmp"  # not the engine's temporary name
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(manifest, f, indent=2)
        f.write("\n")
    os.replace(tmp, path)


def read_csv(path: PathLike) -> Columns:
    """A CSV with one header row as {column: float64 array}; blanks and text become NaN and
    lines starting with ``#`` are skipped. Raises ValueError for an empty file or a row with the
    wrong number of fields."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path}: empty file")
    header = [h.strip() for h in rows[0]]
    data: Dict[str, List[float]] = {h: [] for h in header}
    for line_no, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(f"{path}:{line_no}: {len(row)} fields, the header has {len(header)}")
        for h, v in zip(header, row):
            v = v.strip()
            try:
                data[h].append(float(v) if v else math.nan)
            except ValueError:
                data[h].append(math.nan)
    return {h: np.asarray(v, dtype=np.float64) for h, v in data.items()}


def read_timeseries(path: PathLike) -> Columns:
    """DIR/timeseries.csv when ``path`` is a run directory, else the CSV file ``path``, as
    {column: float64 array} (see :func:`read_csv`)."""
    if os.path.isdir(path):
        path = os.path.join(path, "timeseries.csv")
    return read_csv(path)


def read_summary(run_dir: PathLike) -> Dict[str, Any]:
    """DIR/summary.json as a dict; {} when it is missing or not valid JSON."""
    return _read_json(os.path.join(run_dir, "summary.json"))


def read_timing(run_dir: PathLike) -> Dict[str, Any]:
    """DIR/timing.json (the run's wall-clock seconds, threads, time by part); {} when it is
    missing or unreadable."""
    return _read_json(os.path.join(run_dir, "timing.json"))


def _read_json(path: str) -> Dict[str, Any]:
    try:
        with open(path) as f:
            s = json.load(f)
    except (OSError, ValueError):
        return {}
    return s if isinstance(s, dict) else {}


def is_finished(run_dir: PathLike) -> bool:
    """Whether the run has ended (summary.json, written last, exists)."""
    return os.path.isfile(os.path.join(run_dir, "summary.json"))


def has_stage_state(run_dir: PathLike, stage: int) -> bool:
    """Whether the run kept its state at the start of stage ``stage`` (DIR/stages/stage_K.bin),
    which a branch (``crushdem-sand run --from DIR:STAGE``) starts from."""
    return os.path.isfile(os.path.join(run_dir, "stages", f"stage_{int(stage)}.bin"))


def is_being_written(run_dir: PathLike) -> bool:
    """Whether a crushdem run is writing the directory now: it holds an exclusive ``flock`` on
    DIR/.lock while it runs (released by the kernel when its process ends, however it ends)."""
    import fcntl

    path = os.path.join(run_dir, ".lock")
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # closing drops a lock taken here
    return False


def read_config(run_dir: PathLike) -> Dict[str, Any]:
    """DIR/config.toml (the resolved configuration a run writes when it starts) as a dict; {}
    when it is missing or unreadable."""
    import tomllib

    try:
        with open(os.path.join(run_dir, "config.toml"), "rb") as f:
            return tomllib.load(f)
    except (OSError, ValueError):
        return {}


def stages_from_config(run_dir: PathLike) -> List[Dict[str, Any]]:
    """The stages (type and name) of DIR/config.toml, which a run writes when it starts: the
    stage types for a run still going or stopped before summary.json exists. [] when the file
    is missing, unreadable or has no [[stage]]."""
    listed = read_config(run_dir).get("stage")
    if not isinstance(listed, list):
        return []
    return [{"type": st.get("type"), "name": st.get("name")} for st in listed
            if isinstance(st, dict)]


def read_events(run_dir: PathLike) -> Optional[Columns]:
    """DIR/events.csv (one row per dynamic phase of the "age" stages) as {column: array}.

    None when the file is missing, or unreadable (as it can be for a moment while a run is still
    writing it: a message goes to stderr).
    """
    path = os.path.join(run_dir, "events.csv")
    if not os.path.isfile(path):
        return None
    try:
        return read_csv(path)
    except (OSError, ValueError) as e:
        print(f"crushdem: {path} skipped: {e}", file=sys.stderr)
        return None


def read_penetration(run_dir: PathLike) -> Optional[Columns]:
    """DIR/penetration.csv (a row every ``record_interval`` steps of each "penetrate" stage:
    ``travel_m``, the tip's position, ``q_c_Pa``, ``f_s_Pa``, the tip, shaft and sleeve loads
    and the run's measurements), or None when missing."""
    path = os.path.join(run_dir, "penetration.csv")
    return read_csv(path) if os.path.isfile(path) else None


def read_shaft_profile(run_dir: PathLike) -> Optional[Columns]:
    """DIR/shaft_profile.csv (at every row of penetration.csv, one row per bin along the shaft:
    ``travel_m``, ``bin``, ``height_m`` above the shaft's start, ``sigma_r_Pa``, ``tau_Pa``,
    ``contacts``), or None when missing."""
    path = os.path.join(run_dir, "shaft_profile.csv")
    return read_csv(path) if os.path.isfile(path) else None


def read_penetration_field(run_dir: PathLike) -> Optional[Columns]:
    """DIR/penetration_field.csv (a penetrate stage's ``field_interval``: at each of its records,
    one row per ring and slice about the body: ``stage``, ``time_s``, ``travel_m``, ``tip_z_m``,
    ``ring``, ``bin``, ``r_in_m``, ``r_out_m``, ``z_m`` (the slice's middle), ``sigma_rr_Pa``,
    ``sigma_tt_Pa``, ``sigma_zz_Pa``, ``tau_rz_Pa``, ``grains``, ``body_volume_m3``), or None
    when missing."""
    path = os.path.join(run_dir, "penetration_field.csv")
    return read_csv(path) if os.path.isfile(path) else None


def read_phases(run_dir: PathLike) -> Optional[Columns]:
    """DIR/phases.csv (rows within the dynamic phases of age stages), or None when missing."""
    path = os.path.join(run_dir, "phases.csv")
    if not os.path.isfile(path):
        return None
    return read_csv(path)


def read_grading(run_dir: PathLike) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """DIR/grading.csv as (sieve sizes [m] increasing, mass fraction passing [rows, sieves]).

    The sieve size is read from the column name ``passing_<d>_m``. None when the file is missing,
    unreadable or has no passing column or no row.
    """
    path = os.path.join(run_dir, "grading.csv")
    if not os.path.isfile(path):
        return None
    try:
        g = read_csv(path)
    except (OSError, ValueError):
        return None
    cols = []
    for name in g:
        if name.startswith("passing_") and name.endswith("_m"):
            try:
                size = float(name[len("passing_"):-len("_m")])
            except ValueError:
                continue
            if size > 0 and math.isfinite(size):
                cols.append((size, name))
    if not cols:
        return None
    cols.sort()
    passing = np.column_stack([g[name] for _, name in cols])
    if passing.shape[0] == 0:
        return None
    return np.asarray([size for size, _ in cols]), passing


def read_breakage_positions(run_dir: PathLike) -> Optional[Columns]:
    """``time_s``, ``diameter_m`` and the centre ``x_m``, ``y_m``, ``z_m`` of every breakage in
    DIR/breakage.csv, as arrays; None when the file is missing or has no positions (runs begun
    by a version that did not write them)."""
    path = os.path.join(run_dir, "breakage.csv")
    keys = ("time_s", "diameter_m", "x_m", "y_m", "z_m")
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            if not reader.fieldnames or "x_m" not in reader.fieldnames:
                return None
            rows = [[float(row[k]) for k in keys] for row in reader]
    except (OSError, ValueError, KeyError, TypeError, csv.Error):
        return None
    table = np.asarray(rows, dtype=float).reshape(-1, len(keys))
    return {k: table[:, j] for j, k in enumerate(keys)}


def read_breakage(run_dir: PathLike) -> List[Tuple[float, str]]:
    """(diameter [m], cause) of every breakage in DIR/breakage.csv; [] when there is none."""
    path = os.path.join(run_dir, "breakage.csv")
    out: List[Tuple[float, str]] = []
    try:
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                try:
                    dia = float(row.get("diameter_m") or "nan")
                except ValueError:
                    continue
                if math.isfinite(dia) and dia > 0:
                    out.append((dia, (row.get("cause") or "").strip() or "unknown"))
    except (OSError, ValueError, csv.Error):
        return []
    return out


def read_run_table(run_dir: PathLike, name: str) -> Optional[Columns]:
    """DIR/NAME (a result file a run writes only when a stage asks for it: pile_ageing.csv,
    stress_profile.csv, ...) as columns; None when the run has none, it cannot be read, or it
    has no rows."""
    path = os.path.join(run_dir, name)
    if not os.path.isfile(path):
        return None
    try:
        d = read_csv(path)
    except ValueError:
        return None
    return d if d and next(iter(d.values())).size else None


@dataclass
class RunData:
    """What the figures of one run directory read, loaded once.

    ``timeseries`` has its contact columns NaN on rows written before the contact measurements
    were computed (:func:`crushdem_sand.analysis.mask_unmeasured_contacts`). ``summary`` is
    summary.json, or for a run not ``finished`` only the stages of config.toml.
    """

    directory: str
    timeseries: Columns
    summary: Dict[str, Any]
    finished: bool
    events: Optional[Columns] = None
    grading: Optional[Tuple[np.ndarray, np.ndarray]] = None
    breakage: List[Tuple[float, str]] = field(default_factory=list)
    penetration: Optional[Columns] = None
    shaft_profile: Optional[Columns] = None
    penetration_field: Optional[Columns] = None
    breakage_positions: Optional[Columns] = None

    @property
    def title(self) -> str:
        return os.path.basename(os.path.normpath(self.directory))


def read_run(run_dir: PathLike) -> RunData:
    """Reads ``run_dir`` (timeseries.csv is required; OSError or ValueError without it)."""
    run_dir = os.fspath(run_dir)
    d = mask_unmeasured_contacts(read_timeseries(os.path.join(run_dir, "timeseries.csv")))
    summary = read_summary(run_dir)
    finished = bool(summary)
    if not finished:
        # Still running, or stopped (a checkpoint waits for `crushdem-sand resume`): the stage types
        # come from the configuration, the figures from the rows written so far.
        summary = {"stages": stages_from_config(run_dir)}
    return RunData(directory=run_dir, timeseries=d, summary=summary, finished=finished,
                   events=read_events(run_dir), grading=read_grading(run_dir),
                   breakage=read_breakage(run_dir), penetration=read_penetration(run_dir),
                   shaft_profile=read_shaft_profile(run_dir),
                   penetration_field=read_penetration_field(run_dir),
                   breakage_positions=read_breakage_positions(run_dir))
