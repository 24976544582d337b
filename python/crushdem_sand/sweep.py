"""``crushdem-sand sweep SWEEP.toml --out DIR``: many runs of one base configuration on Dask.

A sweep file names a base configuration and the values to vary::

    base = "relaxation_small.toml"      # relative to the sweep file
    experiment = "run"                  # optional: "run" (the default: each variant one
                                        # crushdem-sand run) or "pile" (each variant a
                                        # crushdem-sand pile: its load tests at every ageing
                                        # time and the set-up fit)
    from = "runs/loaded:relaxation"     # optional: every variant branches from this run's
                                        # state at the start of that stage
                                        # (crushdem-sand run --from)
    stages = ["install", "unload"]      # optional: only these of the base's stages (by name
                                        # or index, run in the base's order; with from, the
                                        # first ones); stage.INDEX below counts the kept ones
    [vary]                              # combined as a product
    "contact.rolling_friction" = [0.1, 0.3]
    "crushing.seed" = [1, 2, 3]
    [zip]                               # optional: varied together (equal lengths), one factor
    "crushing.r_prime" = ["R_star", "2R_star"]
    "crushing.d0" = [0.0, 2e-3]
    [[variant]]                         # optional: named variants, one factor; each sets its
    name = "rolling_0.3"                # own keys (none: the base as it is)
    "contact.rotation" = "rolling"
    "contact.rolling_friction" = 0.3
    [names]                             # optional: a short name for a varied key in the
    "crushing.r_prime" = "r_prime"      # directory names (r_prime=R_star, not the dotted key)

Named variants give their directory names (joined with ``__`` to the other factors' values);
the other factors give KEY=VALUE, KEY being the key's entry in [names] or the dotted key.
A dotted key is a section and a key of the base configuration (``crushing.seed``), or a stage
and a key: ``stage.1.strain_rate`` (by index), ``stage.shear.strain_rate`` (by name) or
``stage.*.n_break`` (every stage of the base that sets ``n_break``: the age stages of a pile), or
a body and a key, the same way: ``body.pile.friction``, ``body.0.radius``, ``body.*.friction``. Each
variant is one task: ``crushdem-sand run`` in a subprocess with ``--threads-per-run`` threads, on a
local Dask cluster of ``--workers`` processes (default: the cores divided by the threads per
run), or on the cluster at ``--scheduler ADDRESS``. Its configuration is written to
``DIR/configs/NAME.toml`` and its run to ``DIR/runs/NAME``. A finished variant is not run again
and an interrupted one resumes from its checkpoint, so the command can be repeated until every
variant is done; a variant that fails (a bad value, a blow-up) fails alone, its error in the
table. ``DIR/results.csv`` and ``DIR/results.parquet`` hold one row per variant: its values (a
column per dotted key), status, error, run directory, wall-clock and the summary figures of each
stage (of a pile experiment: those of its DIR/main, each load test's capacity at every ageing
time and the set-up factors A with their standard errors); ``DIR/results.png`` draws each figure
against each varied key.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import os
import re
import signal
import subprocess
import sys
import time
import tomllib
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from ._cli import CommandParser
from ._optional import available, message, require
# summary_figures is also this module's (calibrate and the tests read runs with it).
from .sweep_results import EXPERIMENTS, figure, finished, results_table, summary_figures

if TYPE_CHECKING:
    import pandas as pd

# How long a task waits for the lock of its run directory: a run killed with its worker takes a
# moment to write its checkpoint and let go.
LOCK_WAIT_S = 120.0
# How long a stopped sweep (or pile) waits for its runs to save their checkpoints and stop.
STOP_WAIT_S = 300.0


# --- the sweep file ----------------------------------------------------------------------------


def read_file_and_base(path: str, what: str, keys: Sequence[str]) -> Tuple[Dict, Dict, str]:
    """A sweep or calibration file (its top-level ``keys`` only) and the base configuration it
    names (relative to it): (file, base, base path); every problem named by file and key."""
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except OSError as e:
        raise ValueError(f"{path}: cannot read the {what} file ({e.strerror})") from None
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path}: not valid TOML ({e})") from None
    unknown = set(doc) - set(keys)
    if unknown:
        raise ValueError(f"{path}: unknown key(s) {', '.join(sorted(unknown))} (expected "
                         f"{', '.join(keys)})")
    if not isinstance(doc.get("base"), str):
        raise ValueError(f"{path}: base = \"CONFIG.toml\" (the base configuration, relative to "
                         f"the {what} file) is missing")
    base_path = os.path.join(os.path.dirname(os.path.abspath(path)), doc["base"])
    try:
        with open(base_path, "rb") as f:
            base = tomllib.load(f)
    except OSError as e:
        raise ValueError(f"{path}: base '{doc['base']}': cannot read {base_path} "
                         f"({e.strerror})") from None
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{base_path}: not valid TOML ({e})") from None
    return doc, base, base_path


def read_sweep(path: str) -> Dict[str, Any]:
    """The sweep file as {"base": dict, "base_path", "base_dir", "factors": [[{key: value}]],
    "keys", "from", "experiment", "names": {key: short name}}; every problem named by file and
    key. A named variant's element of its factor carries its name under NAME_KEY."""
    doc, base, base_path = read_file_and_base(
        path, "sweep", ("base", "experiment", "from", "stages", "vary", "zip", "variant", "names"))
    experiment = doc.get("experiment", "run")
    if experiment not in EXPERIMENTS:
        raise ValueError(f"{path}: experiment = {experiment!r}: expected \"run\" (each variant "
                         "one crushdem-sand run, the default) or \"pile\" (each variant a "
                         "crushdem-sand pile: its load tests at every ageing time and the set-up "
                         "fit)")
    if "stages" in doc:
        kept = _kept_stages(path, base, doc["stages"])
        # A branch's stages before its start must be the original run's, position by position:
        # with `from`, only stages after the kept ones may be left out.
        if "from" in doc and kept != base["stage"][:len(kept)]:
            raise ValueError(f"{path}: with from = \"DIR:STAGE\", stages must keep the base's "
                             f"first stages in order and leave out only later ones (got "
                             f"{doc['stages']!r})")
        base["stage"] = kept
    branch = doc.get("from")
    if branch is not None:
        if not isinstance(branch, str):
            raise ValueError(f"{path}: from = \"DIR[:STAGE]\" (a finished run to branch from)")
        branch = os.path.join(os.path.dirname(os.path.abspath(path)), branch)
    factors: List[List[Dict[str, Any]]] = []
    keys: List[str] = []
    for key, values in (doc.get("vary") or {}).items():
        _check_values(path, "vary", key, values)
        factors.append([{key: v} for v in values])
        keys.append(key)
    zipped = doc.get("zip") or {}
    if zipped:
        lengths = set()
        for key, values in zipped.items():
            _check_values(path, "zip", key, values)
            lengths.add(len(values))
        if len(lengths) != 1:
            raise ValueError(f"{path}: [zip] lists must have one length (got "
                             f"{', '.join(str(n) for n in sorted(lengths))})")
        n = lengths.pop()
        factors.append([{k: v[i] for k, v in zipped.items()} for i in range(n)])
        keys.extend(zipped)
    named = doc.get("variant")
    named_keys: List[str] = []
    if named is not None:
        factor, named_keys = _named_variants(path, named)
        factors.append(factor)
        keys.extend(named_keys)
    if not factors:
        raise ValueError(f"{path}: nothing to vary ([vary], [zip] or [[variant]] with at least "
                         "one entry)")
    if len(set(keys)) != len(keys):
        raise ValueError(f"{path}: a key is varied twice")
    # Keys one variant may set together: every [vary] and [zip] key with any other, a named
    # variant's only with those of its own table.
    tables = [set(v) - {NAME_KEY} for v in (named if named is not None else [])]

    def together(a: str, b: str) -> bool:
        return (a not in named_keys or b not in named_keys
                or any(a in t and b in t for t in tables))

    for k in keys:
        set_dotted(copy.deepcopy(base), k, None, check_only=True)
    refuse_overlaps(path, base, keys, together)
    if experiment == "pile":
        from .pile import plan

        plan(base, f"{path}: base '{doc['base']}'" + (" (its kept stages)" if "stages" in doc
                                                      else ""))
    names = _short_names(path, doc.get("names"), [k for k in keys if k not in named_keys])
    return {"base": base, "base_path": base_path, "base_dir": os.path.dirname(base_path),
            "factors": factors, "keys": keys, "from": branch, "experiment": experiment,
            "names": names}


def _check_out_matches(out: str, listed: Sequence[Mapping[str, Any]], experiment: str) -> None:
    """ValueError when the sweep already in ``out`` ran another experiment (its run directories
    hold the other command's files), or a variant of these values under another directory name
    ([names] changed: its runs would be started again beside the old ones)."""
    try:
        with open(os.path.join(out, "sweep.json")) as f:
            doc = json.load(f)
        was = doc.get("experiment", "run")
        before = {json.dumps(v["values"], sort_keys=True): v["name"] for v in doc["variants"]}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return
    if was != experiment:
        raise ValueError(f"{out}: its variants ran as experiment = \"{was}\", not "
                         f"\"{experiment}\": use another --out")
    for v in listed:
        old = before.get(json.dumps(v["values"], sort_keys=True))
        if old is not None and old != v["name"] and os.path.isdir(os.path.join(out, "runs", old)):
            raise ValueError(f"{out}: the variant {v['name']} ran there as {old} (the directory "
                             "names changed: [names]); keep the names it ran with or use "
                             "another --out")


def _short_names(path: str, table: Any, keys: Sequence[str]) -> Dict[str, str]:
    """[names]: {dotted key: short name} for the directory names, each key one of [vary] or
    [zip] (a named variant's keys never appear there) and each name a distinct directory word."""
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ValueError(f"{path}: [names] must be a table of \"DOTTED.KEY\" = \"short_name\"")
    for key, name in table.items():
        if isinstance(name, dict):
            raise ValueError(f"{path}: [names] {key}: quote the dotted key (\"{key}.KEY\" = "
                             "\"short_name\"), or TOML reads it as a table")
        if key not in keys:
            raise ValueError(f"{path}: [names] \"{key}\": not a key of [vary] or [zip] (they "
                             f"are: {', '.join(keys) or 'none'})")
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9.+-]+(_[A-Za-z0-9.+-]+)*",
                                                           name):
            raise ValueError(f"{path}: [names] \"{key}\" = {name!r}: expected a short name of "
                             "letters, digits and ._+- (no '=' and no '__', which separate the "
                             "parts of a directory name)")
    shown = [_DIR_UNSAFE.sub("-", table.get(k, k)) for k in keys]
    twice = sorted({n for n in shown if shown.count(n) > 1})
    if twice:
        raise ValueError(f"{path}: [names]: '{twice[0]}' would name two keys in the directory "
                         "names")
    return dict(table)


def _kept_stages(path: str, base: Dict[str, Any], kept: Any) -> List[Dict[str, Any]]:
    """The base's stages that ``stages = [...]`` keeps (names or indices), in the base's order."""
    stages = base.get("stage")
    if not isinstance(stages, list) or not stages:
        raise ValueError(f"{path}: stages = [...] needs a base configuration with [[stage]] tables")
    if not isinstance(kept, list) or not kept or not all(
            isinstance(k, (str, int)) and not isinstance(k, bool) for k in kept):
        raise ValueError(f"{path}: stages must be a list of stage names or indices, got {kept!r}")
    names = [str(st.get("name", i)) if isinstance(st, dict) else str(i)
             for i, st in enumerate(stages)]
    keep = set()
    for k in kept:
        if isinstance(k, int):
            if not 0 <= k < len(stages):
                raise ValueError(f"{path}: stages: no stage {k} (the base has {len(stages)})")
            keep.add(k)
        elif k in names:
            keep.add(names.index(k))
        else:
            raise ValueError(f"{path}: stages: no stage '{k}' (stages: {', '.join(names)})")
    if len(keep) != len(kept):
        raise ValueError(f"{path}: stages names a stage twice ({kept!r})")
    return [st for i, st in enumerate(stages) if i in keep]


# The name of a [[variant]] inside its factor's element (not a configuration key: no dot).
NAME_KEY = "name"


def _named_variants(path: str, named: Any) -> Tuple[List[Dict[str, Any]], List[str]]:
    """The [[variant]] tables as one factor, and the keys they set (each once, in order)."""
    if not isinstance(named, list) or not named or not all(isinstance(v, dict) for v in named):
        raise ValueError(f"{path}: [[variant]] must be tables, each with a name")
    factor, keys, names = [], [], set()
    for i, v in enumerate(named):
        name = v.get(NAME_KEY)
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9._+-]+", name):
            raise ValueError(f"{path}: variant[{i}].name must be a directory name (letters, "
                             f"digits and ._+-), got {name!r}")
        if name in names:
            raise ValueError(f"{path}: two variants are named '{name}'")
        names.add(name)
        for key, value in v.items():
            if key == NAME_KEY:
                continue
            if "." not in key:
                raise ValueError(f"{path}: variant '{name}': '{key}' is not a dotted key "
                                 "(SECTION.KEY, stage.INDEX|NAME|*.KEY or body.INDEX|NAME|*.KEY)")
            if isinstance(value, (list, dict)):
                raise ValueError(f"{path}: variant '{name}': \"{key}\" must be one value")
            if key not in keys:
                keys.append(key)
        factor.append(dict(v))
    return factor, keys


def _check_values(path: str, table: str, key: str, values: Any) -> None:
    if not isinstance(values, list) or not values:
        raise ValueError(f"{path}: [{table}] \"{key}\" must be a list of values")


# The arrays of tables a dotted key can address by element: ``stage.INDEX|NAME|*.KEY``.
ARRAYS = {"stage": ("[[stage]]", "stages"), "body": ("[[body]]", "bodies")}


def element_targets(cfg: Mapping[str, Any], key: str) -> Optional[Tuple[str, List[int], str]]:
    """(array, the indices of the elements it sets, KEY) for a key of a [[stage]] or [[body]]
    element (``stage.INDEX.KEY``, ``stage.NAME.KEY``, ``stage.*.KEY``: every element of the base
    that sets KEY; the same with ``body``), None for a ``SECTION.KEY``; ValueError naming the key
    when it reaches no element or could mean two."""
    parts = key.split(".")
    if parts[0] not in ARRAYS:
        return None
    array = parts[0]
    tables, plural = ARRAYS[array]
    form = (f"a key of {tables} is {array}.INDEX.KEY, {array}.NAME.KEY or {array}.*.KEY")
    if len(parts) != 3 or not parts[1] or not parts[2]:
        raise ValueError(f"'{key}': {form}")
    elements = cfg.get(array)
    if not isinstance(elements, list) or not all(isinstance(el, dict) for el in elements):
        raise ValueError(f"'{key}': {form}, and the base configuration needs {tables} tables")
    which, name = parts[1], parts[2]
    if name == "name":
        raise ValueError(f"'{key}': a {array}'s name is how stages and results find it; vary "
                         "its other keys")
    shown = ", ".join(str(el["name"]) if "name" in el else f"#{i} (unnamed)"
                      for i, el in enumerate(elements))
    if which == "*":
        targets = [i for i, el in enumerate(elements) if name in el]
        if not targets:
            raise ValueError(f"'{key}': no {array} of the base sets {name} ({plural}: {shown}); "
                             f"{array}.*.KEY changes the {plural} that set it")
        return array, targets, name
    named = [i for i, el in enumerate(elements) if el.get("name") == which]
    index = int(which) if which.isascii() and which.isdigit() else None
    if index is not None and named and named != [index]:
        raise ValueError(f"'{key}': '{which}' is both {array} {index}'s index and {array} "
                         f"{named[0]}'s name: rename that {array}")
    if named:
        return array, named[:1], name
    if index is not None and index < len(elements):
        return array, [index], name
    raise ValueError(f"'{key}': no {array} '{which}' ({plural}: {shown})")


def refuse_overlaps(path: str, base: Mapping[str, Any], keys: Sequence[str],
                    together: Callable[[str, str], bool] = lambda a, b: True) -> None:
    """ValueError when two keys that one run may set together reach one key of one element
    (``body.*.friction`` and ``body.pile.friction``; ``stage.0.steps`` and ``stage.hold.steps``
    of that stage): the run would keep one of the values, its name would show both."""
    reached: Dict[Tuple[str, int, str], str] = {}
    for k in keys:
        t = element_targets(base, k)
        for i in t[1] if t else []:
            slot = (t[0], i, t[2])
            other = reached.get(slot)
            if other is not None and together(other, k):
                raise ValueError(f"{path}: \"{other}\" and \"{k}\" both set {t[2]} of "
                                 f"{t[0]} {i}: vary it by one key")
            reached.setdefault(slot, k)


def set_dotted(cfg: Dict[str, Any], key: str, value: Any, check_only: bool = False) -> None:
    """Sets ``section.key``, or a key of a [[stage]] or [[body]] element: ``stage.INDEX.key``,
    ``stage.NAME.key`` or ``stage.*.key`` (every stage of the base that sets that key), the same
    with ``body`` (element_targets)."""
    target = element_targets(cfg, key)
    parts = key.split(".")
    if target is not None:
        if not check_only:
            for i in target[1]:
                cfg[target[0]][i][target[2]] = value
        return
    if len(parts) < 2:
        raise ValueError(f"'{key}': expected SECTION.KEY (e.g. crushing.seed)")
    table = cfg
    for p in parts[:-1]:
        nxt = table.setdefault(p, {}) if not check_only else table.get(p, {})
        if not isinstance(nxt, dict):
            raise ValueError(f"'{key}': '{p}' is not a table in the base configuration")
        table = nxt
    if not check_only:
        table[parts[-1]] = value


def variants(sweep: Mapping[str, Any]) -> List[Dict[str, Any]]:
    """Every combination: [{"name", "values": {key: value}, "config": dict}] in product order."""
    out = []
    for combo in itertools.product(*sweep["factors"]):
        values: Dict[str, Any] = {}
        names: List[str] = []
        for part in combo:
            part = dict(part)
            name = part.pop(NAME_KEY, None)
            if name is not None:
                names.append(name)
            values.update(part)
        cfg = copy.deepcopy(sweep["base"])
        for k, v in values.items():
            set_dotted(cfg, k, v)
        unnamed = {k: v for k, v in values.items()
                   if not any(k in p and NAME_KEY in p for p in combo)}
        label = "__".join(names + ([variant_name(unnamed, sweep.get("names"))] if unnamed
                                   else []))
        out.append({"name": label or "base", "values": values, "config": cfg})
    return out


# What a directory name does not hold (each such character becomes '-').
_DIR_UNSAFE = re.compile(r"[^A-Za-z0-9._=+-]")


def variant_name(values: Mapping[str, Any], names: Optional[Mapping[str, str]] = None) -> str:
    """A directory name from the values, each key shown by its entry in ``names`` or dotted (the
    same values give the same name on every call)."""
    names = names or {}
    text = "__".join(f"{names.get(k, k)}={_show(v)}" for k, v in values.items())
    text = _DIR_UNSAFE.sub("-", text)
    if len(text) > 120:
        text = text[:100] + "-" + hashlib.sha1(text.encode()).hexdigest()[:12]
    return text


def _show(v: Any) -> str:
    return json.dumps(v) if not isinstance(v, str) else v


# --- one task ----------------------------------------------------------------------------------


def _die_with_parent() -> None:  # pragma: no cover (runs in the child)
    """The run gets SIGTERM (checkpoint and stop) when the worker that started it dies."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


def _run_command(cmd: Sequence[str]) -> Tuple[int, str, str]:
    """(exit status, output, error output) of ``cmd``. When this process is stopped meanwhile
    (SIGTERM made an exception, Ctrl-C), the command gets SIGTERM and is waited for, so that a
    run saves its checkpoint: subprocess.run would SIGKILL it."""
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          preexec_fn=_die_with_parent) as p:
        try:
            stdout, stderr = p.communicate()
        except BaseException:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
            try:
                p.communicate(timeout=STOP_WAIT_S)  # its pipes drained while it saves
            except subprocess.TimeoutExpired:
                p.kill()
            raise
    return p.returncode, stdout, stderr


def run_variant(config_path: str, run_dir: str, threads: int,
                branch: Optional[str] = None, backend: str = "cpu",
                experiment: str = "run", keep_columns: bool = False) -> Dict[str, Any]:
    """Runs (or resumes) one variant with the crushdem command on ``backend``, branching from
    ``branch`` (DIR[:STAGE]) when given: ``crushdem-sand run`` (``experiment`` "run"), or
    ``crushdem-sand pile`` ("pile", which keeps its finished runs and resumes the others when
    called again); returns {"resumed", "wall_s"}. ``keep_columns``: a resumed run started by a
    crushdem that wrote fewer columns keeps each file's own (``resume --keep-columns``). Raises
    RuntimeError with the end of the command's error output when it fails."""
    if finished(run_dir, experiment):
        return {"resumed": False, "skipped": True}
    crushdem = [sys.executable, "-m", "crushdem_sand"]
    resumed = os.path.isdir(run_dir) and bool(os.listdir(run_dir))
    if experiment == "pile":
        cmd = crushdem + ["pile", config_path, "--out", run_dir, "--threads", str(threads)] + (
            ["--from", branch] if branch else []) + (["--keep-columns"] if keep_columns else [])
    elif resumed:
        cmd = crushdem + ["resume", run_dir, "--threads", str(threads), "--quiet"] + (
            ["--keep-columns"] if keep_columns else [])
    else:
        cmd = crushdem + ["run", config_path, "--out", run_dir, "--threads", str(threads),
                          "--quiet"] + (["--from", branch] if branch else [])
    cmd += ["--backend", backend]
    t0 = time.perf_counter()
    deadline = t0 + LOCK_WAIT_S
    while True:
        code, stdout, stderr = _run_command(cmd)
        locked = code == 2 and "another crushdem-sand run" in stderr
        if locked and time.perf_counter() < deadline:
            time.sleep(1.0)
            continue
        break
    if code != 0:
        tail = "\n".join((stderr or stdout).strip().splitlines()[-5:])
        raise RuntimeError(f"exit status {code}: {tail}")
    return {"resumed": resumed, "skipped": False, "wall_s": time.perf_counter() - t0}


# --- the driver --------------------------------------------------------------------------------


class _Stop(Exception):
    pass


def _raise_stop(signum, _frame):
    raise _Stop(signum)


def sweep(path: str, out: str, workers: Optional[int] = None, threads_per_run: int = 1,
          scheduler: Optional[str] = None, progress: Optional[bool] = None,
          log: Callable[[str], None] = print, backend: str = "cpu",
          keep_columns: bool = False) -> pd.DataFrame:
    """Runs (or completes) the sweep of ``path`` into ``out``, every run on ``backend``
    ("cpu", "cuda" or "emulated"); returns the results DataFrame. ``keep_columns``: interrupted
    runs started by a crushdem that wrote fewer columns are resumed keeping each file's own."""
    from . import _core

    if threads_per_run < 1:
        raise ValueError(f"--threads-per-run {threads_per_run}: expected a count >= 1")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers {workers}: expected a count >= 1")
    sw = read_sweep(path)
    listed = variants(sw)
    _check_out_matches(out, listed, sw["experiment"])
    os.makedirs(os.path.join(out, "configs"), exist_ok=True)
    os.makedirs(os.path.join(out, "runs"), exist_ok=True)
    errors: Dict[str, str] = {}
    todo = []
    for v in listed:
        cfg_path = os.path.join(out, "configs", v["name"] + ".toml")
        try:
            text = _core.resolved_run_config(v["config"], sw["base_dir"])
        except (ValueError, RuntimeError) as e:  # ConfigError: a bad value fails this variant
            errors[v["name"]] = str(e)
            continue
        if os.path.isfile(cfg_path):
            with open(cfg_path) as f:
                if f.read() != text:
                    errors[v["name"]] = (f"{cfg_path} holds another configuration for this "
                                         "variant (the base configuration changed): use "
                                         "another --out")
                    continue
        else:
            with open(cfg_path, "w") as f:
                f.write(text)
        run_dir = os.path.join(out, "runs", v["name"])
        if not finished(run_dir, sw["experiment"]):
            todo.append((v["name"], cfg_path, run_dir))
    with open(os.path.join(out, "sweep.json"), "w") as f:
        json.dump({"sweep": os.path.abspath(path), "base": sw["base_path"], "keys": sw["keys"],
                   "names": sw["names"], "experiment": sw["experiment"],
                   "variants": [{"name": v["name"], "values": v["values"]} for v in listed]},
                  f, indent=1)
    log(f"{len(listed)} variants: {len(listed) - len(todo) - len(errors)} finished before, "
        f"{len(todo)} to run, {len(errors)} refused")
    if todo:
        _run_tasks(todo, errors, workers, threads_per_run, scheduler, progress, log, sw["from"],
                   backend, sw["experiment"], keep_columns)
    if not available("pyarrow"):
        log(message("pyarrow", "results.parquet") + " (results.csv is written)")
    df = results_table(out, listed, sw["keys"], errors, sw["experiment"])
    if available("matplotlib"):
        figure(df, sw["keys"], os.path.join(out, "results.png"))
    else:
        log(message("matplotlib", "results.png", "plot") + " (not drawn)")
    return df


def _run_tasks(todo, errors, workers, threads_per_run, scheduler, progress, log,
               branch=None, backend="cpu", experiment="run", keep_columns=False) -> None:
    distributed = require("distributed", "crushdem-sand sweep")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    previous = signal.signal(signal.SIGTERM, _raise_stop)
    cluster = None
    try:
        if scheduler:
            client = Client(scheduler)
            # Runs go out as the cluster's threads free up (_follow): wait for a first worker,
            # or a cluster still starting would be handed one run at a time.
            if not client.nthreads():
                log(f"waiting for a worker at {scheduler}")
            client.wait_for_workers(1)
        else:
            n = workers or max(1, (os.cpu_count() or 1) // threads_per_run)
            cluster = LocalCluster(n_workers=min(n, len(todo)), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            client = Client(cluster)
        try:
            def submit(task):
                name, cfg, run_dir = task
                return client.submit(run_variant, cfg, run_dir, threads_per_run, branch, backend,
                                     experiment, keep_columns, key=name, pure=False), name

            _follow(client, list(todo), submit, errors, progress, log)
        finally:
            client.close()
    except (_Stop, KeyboardInterrupt):
        if cluster is not None:
            stop_local_runs(log)
        log("stopped: the runs in progress save their checkpoints; run the same command again "
            "to go on")
        raise
    finally:
        if cluster is not None:
            cluster.close()
        signal.signal(signal.SIGTERM, previous)




def stop_local_runs(log: Callable[[str], None], wait_s: float = STOP_WAIT_S) -> None:
    """SIGTERM to the runs and pile experiments that this process's local workers started (each
    run saves its checkpoint and stops; a pile experiment stops its run so), and waits for them,
    before the cluster is closed: closing it kills a busy worker after a few seconds, and its run
    with it, before the run's checkpoint. A run that a pile experiment started is left to it: a
    second SIGTERM more than a second after the first would end the run at once."""
    import psutil  # a dependency of distributed

    ours = []  # (process, its command after "-m crushdem_sand", its parent's pid)
    for child in psutil.Process().children(recursive=True):
        try:
            cmd, parent = child.cmdline(), child.ppid()
        except psutil.Error:
            continue
        if cmd[1:3] == ["-m", "crushdem_sand"]:
            ours.append((child, cmd[3:4], parent))
    piles = {c.pid for c, what, _ in ours if what == ["pile"]}
    runs = [c for c, what, parent in ours
            if what == ["pile"] or (what in (["run"], ["resume"]) and parent not in piles)]
    if runs:
        log(f"stopping: {len(runs)} run(s) saving their checkpoints")
    for run in runs:
        try:
            run.send_signal(signal.SIGTERM)
        except psutil.Error:
            pass
    psutil.wait_procs(runs, timeout=wait_s)


def _slots(client) -> int:
    """How many runs the cluster takes at once: its workers' threads (at least one)."""
    return max(1, sum(client.nthreads().values()))


def _follow(client, tasks, submit, errors, progress, log) -> None:
    """Runs ``tasks`` (each made a future by ``submit(task) -> (future, name)``) with as many in
    flight as the cluster has worker threads, the next submitted as one ends, and waits for every
    one, with a progress display (done, running, failed, ETA). Submitting all at once would let
    the scheduler queue several long runs on one worker while another stands idle (tasks of
    unknown length are not stolen back reliably); workers that join later take runs as others
    end."""
    from distributed import as_completed

    total = len(tasks)
    queue = list(tasks)
    names = {}
    seq = as_completed()

    def top_up():
        while queue and len(names) < _slots(client):
            fut, name = submit(queue.pop(0))
            names[fut] = name
            seq.add(fut)

    show_bar = sys.stderr.isatty() if progress is None else progress
    bar = None
    if show_bar:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, unit="variant", desc="sweep")
    done = failed = 0
    t0 = time.perf_counter()
    top_up()
    for fut in seq:
        name = names.pop(fut)
        try:
            fut.result()
            done += 1
            what = "done"
        except Exception as e:  # noqa: BLE001 - one failed variant does not stop the others
            errors[name] = str(e)
            failed += 1
            what = f"FAILED ({str(e).splitlines()[-1] if str(e) else type(e).__name__})"
        top_up()
        left = total - done - failed
        running = len(names)
        elapsed = time.perf_counter() - t0
        eta = elapsed / (done + failed) * left
        if bar is not None:
            bar.set_postfix(running=running, failed=failed)
            bar.update(1)
        else:
            log(f"{name}: {what}  [{done} done, {running} running, {failed} failed, {left} left, "
                f"ETA {eta:.0f} s]")
    if bar is not None:
        bar.close()


def cluster_parser(command: str, details: Optional[str], file: str,
                   metavar: str) -> CommandParser:
    """The command line of a command whose runs are sweep tasks (``crushdem-sand sweep``,
    ``crushdem-sand calibrate``): its file (argument ``file``, shown as ``metavar``), --out,
    --workers, --threads-per-run, --scheduler."""
    parser = CommandParser(command, details)
    parser.add_argument(file, metavar=metavar, help=f"the {file} file")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="directory for the runs (DIR/runs) and the result tables")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="local worker processes (default: cores / threads per run)")
    parser.add_argument("--threads-per-run", type=int, default=1, metavar="T",
                        help="OpenMP threads of each run (default 1)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="an existing Dask scheduler (tcp://host:port) instead of a local "
                             "cluster")
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand sweep SWEEP.toml --out DIR [--workers N] [--threads-per-run T]
    [--scheduler ADDRESS] [--keep-columns]``."""
    parser = cluster_parser("sweep", __doc__, "sweep", "SWEEP.toml")
    parser.add_backend("what advances every run: cpu (default), cuda (a GPU, in a build with "
                       "CUDA; one worker per GPU) or emulated")
    parser.add_argument("--keep-columns", action="store_true",
                        help="resume interrupted runs started by a crushdem that wrote fewer "
                             "columns, each file keeping its own (crushdem-sand resume "
                             "--keep-columns)")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))

    def log(msg: str) -> None:
        print(f"crushdem-sand sweep: {msg}", flush=True)

    try:
        df = sweep(args.sweep, args.out, args.workers, args.threads_per_run, args.scheduler,
                   log=log, backend=args.backend, keep_columns=args.keep_columns)
    except _Stop as e:
        return 128 + int(e.args[0])
    except KeyboardInterrupt:
        return 128 + signal.SIGINT
    except (OSError, ValueError) as e:
        print(f"crushdem-sand sweep: error: {e}", file=sys.stderr)
        return 2
    failed = int((df["status"] != "done").sum())
    log(f"results: {os.path.join(args.out, 'results.csv')} ({len(df) - failed} done, "
        f"{failed} not done)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
