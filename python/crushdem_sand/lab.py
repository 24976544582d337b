"""Laboratory tests from Python: the same configurations as the TOML files, run by the same
C++ driver (``crushdem-sand run``), with the results read back: each table of the run as a pandas
DataFrame (:class:`Result`).

Each function writes a run directory (``timeseries.csv``, ``summary.json``, ``config.toml``,
``vtk/``) and returns a :class:`Result`. ``sample`` is either the path of a prepared sample file
(``sample.txt`` from :func:`prepare_sample`) or a dict of ``[sample]`` keys, in which case the
sample is prepared first in the same run. ``material``, ``contact``, ``damping``, ``timestep``,
``neighbor`` and ``output`` are the sections of docs/configuration.md; ``stage`` is a dict of
keys passed to every stage (the keys every kind has, listed below); ``parameters="table1"``
selects Table 1 as printed instead of crushdem's parameter set, the default (rotation blocked,
d0 = 1.07 mm; docs/configuration.md). SI units throughout.
``backend`` chooses what advances the run: ``"cpu"`` (default), ``"cuda"`` (a GPU, in a build
with CUDA) or ``"emulated"`` (the GPU's step run on the host: its results without a GPU); every
laboratory function, sample preparation and resuming take it.

The keyword arguments that are keys of a stage (``stress``, ``n_break``, ...) take their type,
default and meaning from the engine's parameter tables (``crushdem_sand.parameter_reference()``),
as the configuration reader does; each function lists them in its docstring.
"""

from __future__ import annotations

import inspect
import json
import numbers
import os
import textwrap
import types
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Sequence, Union

from . import _core
from ._core import ConfigError

if TYPE_CHECKING:
    import pandas as pd

SampleSpec = Union[str, os.PathLike, Mapping[str, Any]]


class Result:
    """A run directory: what ``crushdem-sand run`` or a laboratory function wrote there
    (docs/configuration.md, "Result directory", lists the files and their columns).
    ``Result(path)`` opens any run directory, one of the command line's too.

    What is an attribute and what is a call: what is small and cheap to read is a property
    (``directory``, ``summary``, ``stages``, ``timing``, ``sample_file``); a table of the run (a
    CSV file) is a method that reads the file anew on every call and returns a pandas DataFrame,
    one column per CSV column, so that a run still going gives the rows written so far:
    ``timeseries()``, ``events()``, ``phases()``, ``breakages()``, and ``table(name)`` for any
    other CSV file of the run (``"grading"``, ``"preparation"``, ``"penetration"``, ...).

    Column types: counts and indices (``step``, ``stage``, ``dynamic_phase``, ``cycle``, ``id``,
    ``fragments``, ``n_particles``, ``n_contacts``, ``breakages_*``, ...) are int64 (float64
    where a value is missing), the text columns of breakage.csv (``cause``, ``fragment_ids``)
    strings, every other column float64.

    A table that a run writes only when it applies and that this run did not write is empty:
    ``breakages()`` of a run without ``[crushing]``, ``events()`` and ``phases()`` of a run
    without an age stage are DataFrames of no rows with the columns the engine writes there
    (for ``events()``, whose columns follow the time series, the three it starts with).
    ``timeseries()`` (every run writes it) and ``table(name)`` raise FileNotFoundError when the
    file is missing.
    """

    def __init__(self, directory: Union[str, os.PathLike]) -> None:
        self.directory = os.fspath(directory)

    def _path(self, name: str) -> str:
        return os.path.join(self.directory, name)

    @property
    def summary(self) -> Dict[str, Any]:
        """``summary.json``: the final state and each stage's results (written when the run
        ends; FileNotFoundError before)."""
        with open(self._path("summary.json")) as f:
            return json.load(f)

    @property
    def timing(self) -> Dict[str, Any]:
        """``timing.json``: wall-clock seconds, threads, particle-steps per second, and
        ``seconds_by_part`` (integration, neighbor_search, contact_forces, wall_forces, crushing,
        ageing_jump, output, other) with the ``dominant_part``."""
        with open(self._path("timing.json")) as f:
            return json.load(f)

    @property
    def stages(self) -> List[Dict[str, Any]]:
        """The stages' results of ``summary.json``, one dict per stage in order."""
        return list(self.summary.get("stages", []))

    @property
    def sample_file(self) -> Optional[str]:
        """The path of ``sample.txt`` (a run with ``[sample]``: the prepared grains, which a
        later test starts from), or None."""
        p = self._path("sample.txt")
        return p if os.path.exists(p) else None

    def timeseries(self) -> pd.DataFrame:
        """``timeseries.csv``: one row every ``output.interval`` steps (time_s, step, the wall
        positions and stresses, strains, void ratio, contact statistics, ...; the stage and
        crushing columns when they apply). The values as written: the contact columns of a
        test's first row are 0 before its contacts are computed
        (:func:`crushdem_sand.analysis.mask_unmeasured_contacts` marks them)."""
        return read_table(self._path("timeseries.csv"))

    def events(self) -> pd.DataFrame:
        """``events.csv``: one row per dynamic phase of the age stages, at its end
        (ageing_time_s, stage, dynamic_phase, then the time-series measurements); empty
        without an age stage."""
        return read_table(self._path("events.csv"), _EVENTS_COLUMNS)

    def phases(self) -> pd.DataFrame:
        """``phases.csv``: rows every ``record_interval`` cycles within each dynamic phase of
        the age stages (cycle, the stresses, the phase's strains, the breakages); empty
        without an age stage."""
        return read_table(self._path("phases.csv"), _PHASES_COLUMNS)

    def breakages(self) -> pd.DataFrame:
        """``breakage.csv``: one row per broken grain (time_s, step, id, diameter_m, cause,
        sigma_Pa, sigma_lim_Pa, fragments, removed_fragments, fragment_ids, x_m, y_m, z_m);
        empty without ``[crushing]`` or before the first breakage."""
        return read_table(self._path("breakage.csv"), _BREAKAGE_COLUMNS)

    def table(self, name: str) -> pd.DataFrame:
        """The CSV file ``name`` of the run (``"grading"`` or ``"grading.csv"``) as a
        DataFrame, typed as the methods above; FileNotFoundError when the run has none."""
        return read_table(self._path(name if name.endswith(".csv") else name + ".csv"))

    def __repr__(self) -> str:
        return f"crushdem_sand.lab.Result({self.directory!r})"


# The columns of the tables a run writes only when they apply (an empty table has them).
_EVENTS_COLUMNS = ("ageing_time_s", "stage", "dynamic_phase")
_PHASES_COLUMNS = ("stage", "dynamic_phase", "cycle", "ageing_time_s", "time_s",
                   "axial_stress_Pa", "lateral_stress_Pa", "deviator_stress_Pa",
                   "confining_fluctuation", "volumetric_strain_phase", "axial_strain_phase",
                   "unbalanced_force_ratio", "breakages_instant", "breakages_crack",
                   "n_particles")
_BREAKAGE_COLUMNS = ("time_s", "step", "id", "diameter_m", "cause", "sigma_Pa", "sigma_lim_Pa",
                     "fragments", "removed_fragments", "fragment_ids", "x_m", "y_m", "z_m")
# Columns of counts and indices (besides n_*, breakages_* and *_contacts) and of text.
_INTEGER_COLUMNS = frozenset({"step", "stage", "dynamic_phase", "cycle", "id", "fragments",
                              "removed_fragments", "phase", "bin", "ring", "grains",
                              "contacts", "strokes", "moving", "direction"})
_TEXT_COLUMNS = ("cause", "fragment_ids")


def _is_integer_column(name: str) -> bool:
    """Whether the column ``name`` of a run's CSV files holds counts or indices (the engine
    writes every value as a number; these are whole)."""
    return (name in _INTEGER_COLUMNS or name.startswith(("n_", "breakages_"))
            or name.endswith("_contacts"))


def read_table(path: Union[str, os.PathLike],
               columns: Optional[Sequence[str]] = None) -> pd.DataFrame:
    """The CSV file ``path`` of a run as a DataFrame: counts and indices int64 (float64 where a
    value is missing), ``cause`` and ``fragment_ids`` strings, the rest float64. With
    ``columns``, a missing or empty file is a DataFrame of no rows with those columns; without,
    a missing file raises FileNotFoundError."""
    import pandas as pd

    path = os.fspath(path)
    if columns is None and not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such file in the run directory")
    try:
        raw = pd.read_csv(path, dtype={c: str for c in _TEXT_COLUMNS})
    except (FileNotFoundError, pd.errors.EmptyDataError):  # not written (yet)
        raw = pd.DataFrame({c: pd.Series(dtype=object) for c in columns or ()})
    typed = {}
    for name in raw.columns:
        col = raw[name]
        if name in _TEXT_COLUMNS:
            typed[name] = col.astype(str) if col.empty else col
            continue
        if _is_integer_column(name) and pd.api.types.is_integer_dtype(col.dtype):
            typed[name] = col.astype("int64")  # as read: ids beyond 2**53 stay exact
            continue
        values = pd.to_numeric(col, errors="coerce").astype("float64")
        whole = values.notna().all() and (values == values.round()).all()
        typed[name] = values.astype("int64") if _is_integer_column(name) and whole else values
    return pd.DataFrame(typed, index=raw.index, columns=raw.columns)


def _check_steps(key: str, value: Any) -> None:
    """A count of steps given to a laboratory function: an integer >= 0 (ConfigError naming the
    keyword otherwise, as the engine does for a configuration key)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ConfigError(f"{key} = {value!r}: expected a whole number of steps >= 0")


def run(config: Mapping[str, Any], out: Union[str, os.PathLike], *, base_dir: str = ".",
        progress: bool = False, overwrite: bool = False, backend: str = "cpu",
        branch_from: Union[str, os.PathLike, None] = None,
        branch_stage: Union[int, str, None] = None, keep_columns: bool = False) -> Result:
    """Runs a whole configuration dict (the sections of a run file; ``stage`` a list of dicts).
    ``out`` must be new or empty; ``overwrite=True`` replaces a crushdem run already there (every
    laboratory function below takes it too). ``branch_from``: a run directory whose state at the
    start of stage ``branch_stage`` (index or name; default: the first stage ``config``
    changes) this run starts from, as ``crushdem-sand run --from DIR:STAGE`` (the stages before it
    and the grains must be the original's). ``keep_columns`` (with ``branch_from``): the
    original's result files, written by a build of other columns, keep theirs, as
    ``--keep-columns``."""
    _core.run(dict(config), os.fspath(out), base_dir, progress, overwrite,
              os.fspath(branch_from) if branch_from is not None else "",
              "" if branch_stage is None else str(branch_stage), backend, keep_columns)
    return Result(os.fspath(out))


def resume(out: Union[str, os.PathLike], *, progress: bool = False,
           backend: str = "cpu", keep_columns: bool = False) -> Result:
    """Continues an interrupted run from ``out/checkpoint.bin`` (written at every ageing event,
    between stages and every ``output.checkpoint_seconds``); the files come out as those of an
    uninterrupted run on the same backend. Raises ValueError if ``out`` has no checkpoint (e.g.
    it has finished). ``keep_columns``: a run started by a crushdem that wrote other columns (a
    build before this one) goes on with its result files' own columns, this build's new ones
    left out (run.log names them), as ``crushdem-sand resume --keep-columns``."""
    _core.resume(os.fspath(out), progress, backend, keep_columns)
    return Result(os.fspath(out))


# ----------------------------------------------------------------------------------------------
# The keys of the engine's tables: type, default and meaning of every keyword argument that is a
# configuration key.

_TABLES: Dict[str, Dict[str, Dict[str, Any]]] = {
    section: {row["key"]: row for row in rows}
    for section, rows in _core.parameter_tables().items()}
_KINDS: Dict[str, Dict[str, Any]] = {k["name"]: k for k in _core.stage_kinds()}
# The keys every stage kind has: what the ``stage`` dict of every function may hold.
_COMMON_KEYS = [key for key in _TABLES["stage." + next(iter(_KINDS))]
                if all(key in _TABLES["stage." + kind] for kind in _KINDS)]

# The functions' own choices where a stage's table has no default (the key is required in a
# [[stage]]) or another one (strain_rate = 0 servo-controls an oedometric stage): the study's
# loading at 10 /s, shear at 50 /s to 30 % axial strain, one day of ageing.
_LOADING_RATE = 10.0
_SHEAR_RATE = 50.0
_SHEAR_STRAIN = 0.30
_AGEING_TIME = 86400.0

_TABLE = object()  # a _Key's default: the table's
_KW = inspect.Parameter.KEYWORD_ONLY


def _unit(row: Mapping[str, Any]) -> str:
    return f" [{row['unit']}]" if row["unit"] not in ("", "-") else ""


class _Key:
    """A keyword argument that is the key ``key`` of the table ``section`` ("sample",
    "stage.KIND"): its type, default and meaning come from the table; ``default`` is the
    function's own where it has one, ``required`` makes it required where the table has a
    default."""

    def __init__(self, section: str, key: str, default: Any = _TABLE,
                 required: bool = False) -> None:
        self.section, self.key, self.row = section, key, _TABLES[section][key]
        self.own_default, self.required = default, required

    @property
    def default(self) -> Any:
        if self.required or (self.own_default is _TABLE and self.row["required"]):
            return inspect.Parameter.empty
        return self.row["default"] if self.own_default is _TABLE else self.own_default

    def parameter(self) -> inspect.Parameter:
        return inspect.Parameter(self.key, _KW, default=self.default,
                                 annotation=self.row["type"])

    def doc(self) -> str:
        row, where = self.row, self.section.replace("stage.", "") + (
            " stage" if self.section.startswith("stage.") else "")
        if self.default is inspect.Parameter.empty:
            default = "required"
        elif self.own_default is _TABLE or row["required"]:
            default = f"default {self.default!r}"
        else:
            default = f"default {self.default!r}; the table's {row['default']!r}"
        choices = f"; one of {row['choices']}" if row["choices"] else ""
        return f"* ``{self.key}``{_unit(row)} ({where}, {default}): {row['doc']}{choices}"


def _keys_doc(keys: List[_Key]) -> str:
    return ("Keys from the engine's tables (docs/configuration.md), SI units:\n\n" +
            "\n".join(k.doc() for k in keys))


def _base(sample: SampleSpec, sections: Mapping[str, Any]) -> Dict[str, Any]:
    # A section is a mapping; a top-level key (``parameters="table1"``) passes as it is.
    cfg: Dict[str, Any] = {k: dict(v) if isinstance(v, Mapping) else v
                           for k, v in sections.items() if v is not None}
    if isinstance(sample, Mapping):
        cfg["sample"] = dict(sample)
    else:
        cfg["particles"] = {"file": os.path.abspath(os.fspath(sample))}
    return cfg


def _stage(a: types.SimpleNamespace, kind: str, name: str,
           extra: Optional[Mapping[str, Any]] = None, **keys: Any) -> Dict[str, Any]:
    """A [[stage]] of ``kind``: ``keys`` (None: not given), then the function's ``stage`` keys
    for every stage and ``extra`` for this one."""
    st = {"type": kind, "name": name}
    st.update({k: v for k, v in keys.items() if v is not None})
    st.update(a.stage or {})
    st.update(extra or {})
    return st


_OUT = inspect.Parameter("out", inspect.Parameter.POSITIONAL_OR_KEYWORD,
                         annotation="Union[str, os.PathLike]")
_SAMPLE = inspect.Parameter("sample", inspect.Parameter.POSITIONAL_OR_KEYWORD,
                            annotation="SampleSpec")
_RUN_OPTIONS = [inspect.Parameter("progress", _KW, default=False, annotation="bool"),
                inspect.Parameter("overwrite", _KW, default=False, annotation="bool"),
                inspect.Parameter("backend", _KW, default="cpu", annotation="str")]
_STAGE = inspect.Parameter("stage", _KW, default=None,
                           annotation="Optional[Mapping[str, Any]]")
_AGE_STAGE = inspect.Parameter("age_stage", _KW, default=None,
                               annotation="Optional[Mapping[str, Any]]")
_BRANCH_FROM = inspect.Parameter("branch_from", _KW, default=None,
                                 annotation="Union[str, os.PathLike, None]")
_SECTIONS = inspect.Parameter("sections", inspect.Parameter.VAR_KEYWORD, annotation="Any")


def _laboratory_test(*params: Union[_Key, inspect.Parameter], age_stage: bool = False,
                     branch_stage: Optional[str] = None
                     ) -> Callable[[Callable[[types.SimpleNamespace], List[Dict[str, Any]]]],
                                   Callable[..., "Result"]]:
    """A laboratory function from ``build(a)``, which returns its stages for the arguments
    ``a``: ``out`` and ``sample``, then ``params`` (keys of the stage tables, or the function's
    own), the run options, ``stage`` (keys for every stage), ``age_stage`` (keys for the age
    stage), ``branch_from`` (a run whose state at the start of the stage named
    ``branch_stage`` this one starts from) and the configuration sections. Crack growth is
    turned on when a stage needs it. The function's docstring is build's, then the keys."""
    def make(build: Callable[[types.SimpleNamespace], List[Dict[str, Any]]]
             ) -> Callable[..., Result]:
        keys = [p for p in params if isinstance(p, _Key)]
        parameters = [_OUT, _SAMPLE,
                      *[p.parameter() if isinstance(p, _Key) else p for p in params],
                      *_RUN_OPTIONS, _STAGE]
        parameters += [_AGE_STAGE] if age_stage else []
        parameters += [_BRANCH_FROM] if branch_stage else []
        signature = inspect.Signature(parameters + [_SECTIONS], return_annotation="Result")

        def laboratory_test(*args: Any, **kwargs: Any) -> Result:
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            a = types.SimpleNamespace(**bound.arguments)
            stages = build(a)
            sections = dict(a.sections)
            if any(_KINDS[st["type"]]["needs_crack_growth"] for st in stages):
                crushing = dict(sections.get("crushing") or {})
                crushing.setdefault("crack_growth", True)
                sections["crushing"] = crushing
            cfg = _base(a.sample, sections)
            cfg["stage"] = stages
            branch_from = getattr(a, "branch_from", None)
            return run(cfg, a.out, progress=a.progress, overwrite=a.overwrite,
                       backend=a.backend, branch_from=branch_from,
                       branch_stage=None if branch_from is None else branch_stage)

        laboratory_test.__name__ = laboratory_test.__qualname__ = build.__name__
        laboratory_test.__module__ = build.__module__
        laboratory_test.__signature__ = signature  # type: ignore[attr-defined]
        laboratory_test.__doc__ = inspect.cleandoc(build.__doc__ or "") + "\n\n" + \
            _keys_doc(keys)
        return laboratory_test
    return make


# ----------------------------------------------------------------------------------------------
# The laboratory functions.

_SAMPLE_KEYS = [_Key("sample", "void_ratio"), _Key("sample", "seed"), _Key("sample", "stress")]


def prepare_sample(out: Union[str, os.PathLike], *, side: Optional[float] = None,
                   count: Optional[int] = None,
                   void_ratio: float = _SAMPLE_KEYS[0].default,
                   grading: Optional[Mapping[str, Any]] = None,
                   seed: int = _SAMPLE_KEYS[1].default,
                   stress: float = _SAMPLE_KEYS[2].default, progress: bool = False,
                   overwrite: bool = False, backend: str = "cpu",
                   material: Optional[Mapping[str, Any]] = None,
                   contact: Optional[Mapping[str, Any]] = None,
                   output: Optional[Mapping[str, Any]] = None,
                   parameters: Optional[str] = None, **sample_keys: Any) -> Result:
    """Prepares a sample from a grading curve (``[sample]``); ``Result.sample_file`` is the
    reusable ``sample.txt``. ``grading`` = {"diameter": [...m], "passing": [...0-1]}; default
    NE34-like. Other ``[sample]`` keys pass through: ``shape="cylinder"`` (with
    ``height_ratio``) prepares a cylinder in a servo-controlled chamber (docs/chamber.md),
    ``tolerance``, ``friction_start``, ... ``parameters`` names the parameter set (default
    crushdem's, docs/configuration.md)."""
    s: Dict[str, Any] = {"void_ratio": void_ratio, "seed": seed, "stress": stress}
    if side is not None:
        s["side"] = side
    if count is not None:
        s["count"] = count
    if grading is not None:
        s["grading"] = dict(grading)
    s.update(sample_keys)
    cfg = _base(s, {"parameters": parameters, "material": material, "contact": contact,
                    "output": output})
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend)


prepare_sample.__doc__ = inspect.cleandoc(prepare_sample.__doc__ or "") + "\n\n" + \
    _keys_doc(_SAMPLE_KEYS)


@_laboratory_test(_Key("stage.isotropic", "stress"))
def isotropic_test(a: types.SimpleNamespace) -> List[Dict[str, Any]]:
    """All six walls servo-controlled to ``stress`` until equilibrium."""
    return [_stage(a, "isotropic", "isotropic", stress=a.stress)]


@_laboratory_test(_Key("stage.oedometric", "stress"),
                  _Key("stage.oedometric", "strain_rate", _LOADING_RATE),
                  inspect.Parameter("hold_steps", _KW, default=0, annotation="int"),
                  inspect.Parameter("unload_to", _KW, default=None, annotation="Optional[float]"))
def oedometric_test(a: types.SimpleNamespace) -> List[Dict[str, Any]]:
    """Lateral walls fixed; the top loads at ``strain_rate`` to the vertical ``stress``, holds
    for ``hold_steps`` (walls fixed) and unloads to ``unload_to`` when given."""
    stages = [_stage(a, "oedometric", "loading", stress=a.stress, strain_rate=a.strain_rate)]
    _check_steps("hold_steps", a.hold_steps)
    if a.hold_steps > 0:
        stages.append(_stage(a, "hold", "hold", steps=a.hold_steps))
    if a.unload_to is not None:
        stages.append(_stage(a, "oedometric", "unloading", stress=a.unload_to,
                             strain_rate=-abs(a.strain_rate)))
    return stages


@_laboratory_test(_Key("stage.triaxial", "sigma_3"),
                  _Key("stage.triaxial", "strain_rate", _SHEAR_RATE),
                  _Key("stage.triaxial", "axial_strain", _SHEAR_STRAIN),
                  _Key("stage.triaxial", "stop_q"),
                  inspect.Parameter("hold_steps", _KW, default=0, annotation="int"),
                  inspect.Parameter("consolidate", _KW, default=True, annotation="bool"))
def triaxial_test(a: types.SimpleNamespace) -> List[Dict[str, Any]]:
    """Drained triaxial shear: isotropic compression to ``sigma_3`` (unless ``consolidate`` is
    False), then axial compression at ``strain_rate`` with the lateral walls servo-controlled at
    ``sigma_3``, to ``axial_strain`` or until q reaches ``stop_q``; then, if ``hold_steps``, the
    axial strain is held (axial walls fixed, lateral servo kept)."""
    stages = []
    if a.consolidate:
        stages.append(_stage(a, "isotropic", "isotropic", stress=a.sigma_3))
    stages.append(_stage(a, "triaxial", "shear", sigma_3=a.sigma_3, strain_rate=a.strain_rate,
                         axial_strain=a.axial_strain, stop_q=a.stop_q))
    _check_steps("hold_steps", a.hold_steps)
    if a.hold_steps > 0:
        stages.append(_stage(a, "hold", "hold", steps=a.hold_steps, axial="fixed",
                             lateral="servo", lateral_stress=a.sigma_3))
    return stages


# The keys of the age stage in the ageing functions.
_AGEING_KEYS = [_Key("stage.age", "min_cycles"), _Key("stage.age", "n_break")]


def _age(a: types.SimpleNamespace, name: str, **keys: Any) -> Dict[str, Any]:
    """The age stage of an ageing function: its keys, then ``stage`` and ``age_stage``."""
    return _stage(a, "age", name, a.age_stage, duration=a.duration, min_cycles=a.min_cycles,
                  n_break=a.n_break, **keys)


@_laboratory_test(_Key("stage.oedometric", "stress"),
                  _Key("stage.age", "duration", _AGEING_TIME),
                  _Key("stage.oedometric", "strain_rate", _LOADING_RATE), *_AGEING_KEYS,
                  age_stage=True, branch_stage="relaxation")
def oedometric_relaxation(a: types.SimpleNamespace) -> List[Dict[str, Any]]:
    """Oedometric stress relaxation (study section 3.1): load to the vertical ``stress`` with
    crushing on, fix the walls, age for ``duration`` seconds of ageing time with the on-off
    scheme. ``crushing`` keys pass through (crack growth is turned on). ``age_stage``: keys for
    the age stage only (e.g. ``max_strain_rate``), on top of the common ``stage`` keys.
    ``branch_from``: an oedometric relaxation with the same loading whose state at the start of
    its ageing this run starts from (another ``n_break`` or ``min_cycles`` without loading
    again)."""
    return [_stage(a, "oedometric", "loading", stress=a.stress, strain_rate=a.strain_rate),
            _age(a, "relaxation")]


@_laboratory_test(_Key("stage.oedometric", "stress"),
                  _Key("stage.age", "duration", _AGEING_TIME),
                  _Key("stage.oedometric", "strain_rate", _LOADING_RATE), *_AGEING_KEYS,
                  age_stage=True)
def creep_test(a: types.SimpleNamespace) -> List[Dict[str, Any]]:
    """Oedometric creep: load to the vertical ``stress``, then hold it by servo control of the
    top wall during every dynamic phase while the sample ages; the axial strain against ageing
    time is the creep curve (``events.csv``). ``age_stage``: keys for the age stage only."""
    return [_stage(a, "oedometric", "loading", stress=a.stress, strain_rate=a.strain_rate),
            _age(a, "creep", axial="servo", axial_stress=a.stress)]


@_laboratory_test(_Key("stage.triaxial", "sigma_3"),
                  _Key("stage.triaxial", "stop_q", required=True),
                  _Key("stage.age", "duration", _AGEING_TIME),
                  _Key("stage.triaxial", "strain_rate", _SHEAR_RATE),
                  _Key("stage.triaxial", "axial_strain", _SHEAR_STRAIN), *_AGEING_KEYS,
                  age_stage=True, branch_stage="shear")
def triaxial_relaxation(a: types.SimpleNamespace) -> List[Dict[str, Any]]:
    """Triaxial stress relaxation (study section 3.2): isotropic compression to ``sigma_3``,
    shear until q reaches ``stop_q`` (e.g. 0.7 q_max), then hold the axial strain with the
    lateral walls servo-controlled at ``sigma_3`` during dynamic phases, and age.
    ``age_stage``: keys for the age stage only (e.g. a faster lateral servo,
    ``max_strain_rate``, which the other stages must not get). ``branch_from``: a
    ``triaxial_test`` (or relaxation) with the same grains, settings and isotropic compression
    whose state at the start of its shear this run starts from, instead of compressing again;
    the results are those of the unbranched run."""
    return [_stage(a, "isotropic", "isotropic", stress=a.sigma_3),
            _stage(a, "triaxial", "shear", sigma_3=a.sigma_3, strain_rate=a.strain_rate,
                   axial_strain=a.axial_strain, stop_q=a.stop_q),
            _age(a, "relaxation", axial="fixed", lateral="servo", lateral_stress=a.sigma_3)]


__doc__ = (__doc__ or "") + "\n" + textwrap.fill(
    "Keys every stage kind has (the ``stage`` dict): " +
    ", ".join(f"``{k}``" for k in _COMMON_KEYS) + ".", width=96) + "\n"
