"""``crushdem-sand pile CONFIG --out DIR``: a pile installed, aged and load-tested at every ageing
time (docs/pile.md).

CONFIG is a run configuration whose stages are, in order: the installation (one or more "penetrate"
stages of the pile, and any "hold" after them, the head load taken off, say), the ageing ("age"
stages, each ending at an ageing time: ``until = 3600.0``, ``86400.0``, ...) and one or more
"load_test" stages after the last age stage. ``crushdem-sand run CONFIG --out DIR`` runs those tests
one after the other on the same pile; ``crushdem-sand pile`` instead tests a fresh copy of the aged
pile at every ageing time, without running the installation or the ageing again:

* ``DIR/main``: the installation, every age stage and the first load test;
* ``DIR/t{i}_{test}``: the load test ``test`` branched (``crushdem-sand run --from``) from the state
  of DIR/main at the end of age stage i, for every age stage and every load test DIR/main did not
  run; ``DIR/configs/`` holds each run's configuration.

Then ``DIR/pile_capacity.csv`` (a row per load test: its run, its age stage, the ageing time, the
test, the capacity and the shaft and base loads at it, the head displacement there),
``DIR/pile_setup.json`` (per test, the set-up factor A of Q(t)/Q(t0) = 1 + A log10(t/t0), Skov and
Denver 1988, fitted by least squares over the ageing times t >= t0 = the first positive one, with
its standard error), ``DIR/pile_setup.png`` and the figures of DIR/main (``crushdem-sand plot``).
Called again, finished runs are kept, interrupted ones resumed, and the tables redrawn.

``--from RUN[:STAGE]`` branches DIR/main from another run's state (``crushdem-sand run --from``):
a variant of the unloading, the ageing or the tests starts from an installed pile instead of
installing it again (CONFIG's stages before STAGE must be the run's).
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import tomllib
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

import numpy as np

from ._cli import CommandParser
from .rundir import MANIFEST, read_summary, stages_from_config


def fit_setup(t: Sequence[float], Q: Sequence[float], t0: Optional[float] = None
              ) -> Dict[str, float]:
    """The set-up factor of Skov and Denver (1988), Q(t) / Q(t0) = 1 + A log10(t / t0), fitted
    by least squares to capacities Q at ageing times t (the points with t >= t0; t0 = the
    smallest positive t when None): Q = Q0 + Q0 A x with x = log10(t / t0), so A = b1 / b0 of the
    straight line b0 + b1 x. A's standard error comes from the line's covariance (residual
    variance over n - 2 degrees of freedom) by the delta method; NaN with fewer than three
    points. Returns {A, A_std, Q0_N (b0), Q0_std_N, t0_s, points}."""
    t_arr, q_arr = np.asarray(t, dtype=float), np.asarray(Q, dtype=float)
    ok = np.isfinite(t_arr) & np.isfinite(q_arr) & (t_arr > 0)
    if t0 is None:
        t0 = float(t_arr[ok].min()) if np.any(ok) else math.nan
    ok &= t_arr >= t0 * (1.0 - 1e-12)
    n = int(ok.sum())
    out = {"A": math.nan, "A_std": math.nan, "Q0_N": math.nan, "Q0_std_N": math.nan,
           "t0_s": float(t0), "points": n}
    if n < 2:
        return out
    x = np.log10(t_arr[ok] / t0)
    y = q_arr[ok]
    X = np.column_stack([np.ones(n), x])
    if np.linalg.matrix_rank(X) < 2:
        return out
    (b0, b1), *_ = np.linalg.lstsq(X, y, rcond=None)
    out["A"] = float(b1 / b0)
    out["Q0_N"] = float(b0)
    if n > 2:
        resid = y - X @ np.array([b0, b1])
        s2 = float(resid @ resid) / (n - 2)
        cov = s2 * np.linalg.inv(X.T @ X)
        # A = b1 / b0: grad = (-b1 / b0^2, 1 / b0).
        g = np.array([-b1 / b0 ** 2, 1.0 / b0])
        out["A_std"] = float(math.sqrt(max(0.0, g @ cov @ g)))
        out["Q0_std_N"] = float(math.sqrt(max(0.0, cov[0, 0])))
    return out


def plan(config: Mapping[str, Any], path: str = "CONFIG") -> Dict[str, Any]:
    """What ``crushdem-sand pile`` runs for ``config`` (a configuration as a dict): ``ages`` (the
    indices of the age stages), ``tests`` (those of the load tests after the last one),
    ``main`` (the stages of DIR/main) and ``branches`` ([(name, stages, from_stage, age index,
    test)]). ValueError naming the stage when the order is not installation, ageing, load tests."""
    stages = list(config.get("stage", []))
    kinds = [s.get("type") for s in stages]
    ages = [i for i, k in enumerate(kinds) if k == "age"]
    if not ages:
        raise ValueError(f"{path}: no \"age\" stage: a pile run ages the sand between its "
                         "installation and its load tests")
    last = ages[-1]
    tests = [i for i, k in enumerate(kinds) if k == "load_test" and i > last]
    # A test out of order is named first: it is the likelier mistake than a missing one.
    for i, k in enumerate(kinds):
        if k == "load_test" and i < last:
            raise ValueError(f"{path}: stage[{i}] is a load test before the last age stage: "
                             "the load tests come after the ageing (each is branched from every "
                             "ageing time)")
    if not tests:
        raise ValueError(f"{path}: no \"load_test\" stage after the last age stage "
                         f"(stage[{last}])")
    for i, k in enumerate(kinds):
        if i > last and k != "load_test":
            raise ValueError(f"{path}: stage[{i}] ({k}) follows the last age stage: only load "
                             "tests may")
    if not any(k == "penetrate" for k in kinds[:ages[0]]):
        raise ValueError(f"{path}: no \"penetrate\" stage before the first age stage: the pile "
                         "is installed first")
    names = [str(stages[i].get("name") or stages[i]["type"]) for i in range(len(stages))]
    # The tests' names name their branches' folders and their rows: one name, one test.
    for j, t in enumerate(tests):
        for t0 in tests[:j]:
            if names[t0] == names[t]:
                raise ValueError(f"{path}: stage[{t}].name = \"{names[t]}\": expected a name "
                                 f"of its own (stage[{t0}] is a load test named so too; an "
                                 "unnamed load test is named \"load_test\"), since each test's "
                                 "branches and rows go by its name")
    main = stages[:last + 1] + [stages[tests[0]]]
    branches = []
    for a_pos, a in enumerate(ages):
        for j, t in enumerate(tests):
            if a == last and j == 0:
                continue  # DIR/main runs it
            branches.append((f"t{a_pos}_{names[t]}", stages[:a + 1] + [stages[t]], a + 1, a_pos,
                             names[t]))
    return {"ages": ages, "tests": tests, "main": main, "branches": branches,
            "age_names": [names[a] for a in ages], "test_names": [names[t] for t in tests]}


def _write_config(base: Mapping[str, Any], stages: List[Any], path: str, base_dir: str) -> None:
    from . import _core

    cfg = dict(base)
    cfg["stage"] = stages
    text = _core.resolved_run_config(cfg, base_dir)
    if os.path.isfile(path):
        with open(path) as f:
            if f.read() != text:
                raise ValueError(f"{path} holds another configuration (CONFIG changed since the "
                                 "first call): use another --out")
        return
    with open(path, "w") as f:
        f.write(text)


def capacity_rows(out: str, p: Mapping[str, Any]) -> List[Dict[str, Any]]:
    """A row per finished load test of DIR: its run, age stage, ageing time (the run's ageing
    clock: the age stages' ageing summed), test, capacity and the loads at it."""
    runs = [("main", len(p["ages"]) - 1, p["test_names"][0])]
    runs += [(name, a_pos, test) for name, _, _, a_pos, test in p["branches"]]
    rows = []
    for name, a_pos, test in runs:
        summary = read_summary(os.path.join(out, name))
        stages = summary.get("stages") if summary else None
        if not stages:
            continue
        clock = sum(float(s.get("ageing_time_s") or 0.0) for s in stages[:-1])
        last = stages[-1]
        if last.get("type") != "load_test":
            continue
        rows.append({"run": name, "age_stage": p["age_names"][a_pos], "ageing_time_s": clock,
                     "test": test, "capacity_N": float(last["capacity_N"]),
                     "shaft_at_capacity_N": float(last["shaft_at_capacity_N"]),
                     "base_at_capacity_N": float(last["base_at_capacity_N"]),
                     "displacement_at_capacity_m": float(last["displacement_at_capacity_m"])})
    rows.sort(key=lambda r: (r["test"], r["ageing_time_s"]))
    return rows


def _split_branch(branch: str) -> tuple:
    """RUN[:STAGE] as (RUN, STAGE), STAGE the index of the stage named ("" when none is): a
    directory whose own name holds a colon stays whole. ValueError, naming what is wrong, when RUN
    is not a crushdem-sand run directory or has no such stage, so that the pile command refuses
    it before it writes anything (the nested ``run --from`` checks the configurations)."""
    run, _, stage = branch.rpartition(":") if ":" in branch else (branch, "", "")
    if not os.path.isdir(run) and os.path.isdir(branch):
        run, stage = branch, ""
    if not os.path.isdir(run):
        raise ValueError(f"--from {branch}: {run} is not a directory (expected RUN[:STAGE], "
                         "RUN a crushdem-sand run directory)")
    if not os.path.isfile(os.path.join(run, MANIFEST)):
        raise ValueError(f"--from {branch}: {run} is not a crushdem-sand run directory (it has "
                         f"no {MANIFEST})")
    if not stage:
        return run, stage
    names = [s.get("name") or s.get("type") for s in stages_from_config(run)]
    index = int(stage) if stage.isdigit() else names.index(stage) if stage in names else -1
    if not 0 <= index < len(names):
        raise ValueError(f"--from {branch}: {stage!r} is not a stage of {run} (expected a stage "
                         f"index below {len(names)} or one of its names: {', '.join(names)})")
    return run, str(index)


def _check_main_origin(main_dir: str, branch: Optional[str]) -> None:
    """A DIR/main begun before must have begun as this call says (from ``branch``, or from its
    own sample); ValueError otherwise, so that one experiment never mixes two origins."""
    if not os.path.isdir(main_dir) or not os.listdir(main_dir):
        return
    path = os.path.join(main_dir, "branch.json")
    was, b = None, {}
    if os.path.isfile(path):
        with open(path) as f:
            b = json.load(f)
        was = f"{b.get('run')}:{b.get('stage')}"
    if branch is None and was is None:
        return
    if branch is not None and was is not None:
        run, stage = _split_branch(branch)
        same_run = os.path.realpath(run) == os.path.realpath(str(b.get("run")))
        if same_run and (not stage or stage == str(b.get("stage"))):
            return
    raise ValueError(f"{main_dir} was begun " + (f"from {was}" if was else "from its own sample")
                     + ", not " + (f"from {branch}" if branch else "from its own sample")
                     + " (--from): use another --out")


def pile(config_path: str, out: str, threads: int = 1, backend: str = "cpu",
         log: Callable[[str], None] = print, branch: Optional[str] = None,
         keep_columns: bool = False) -> Dict[str, Any]:
    """Runs (or resumes) every run of the pile experiment of ``config_path`` into ``out`` and
    writes its tables and figures; returns {"capacity": rows, "fits": {test: fit}}. With
    ``branch`` (RUN[:STAGE]) DIR/main starts from that run's state (``crushdem-sand run
    --from``) instead of its own sample. ``keep_columns``: interrupted runs started by a
    crushdem that wrote fewer columns are resumed keeping each file's own."""
    from .sweep import run_variant

    with open(config_path, "rb") as f:
        try:
            config = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise ValueError(f"{config_path}: {e}") from None
    p = plan(config, config_path)
    if branch is not None:
        _split_branch(branch)  # refused before anything is written
    base_dir = os.path.dirname(os.path.abspath(config_path))
    os.makedirs(os.path.join(out, "configs"), exist_ok=True)
    main_cfg = os.path.join(out, "configs", "main.toml")
    try:
        _write_config(config, p["main"], main_cfg, base_dir)
    except (ValueError, RuntimeError) as e:
        # The main run's stages are the file's first ones, at the file's indices: name the file.
        raise ValueError(str(e).replace("<python>", config_path, 1)) from None
    main_dir = os.path.join(out, "main")
    _check_main_origin(main_dir, branch)
    log(f"main: installation, {len(p['ages'])} age stages and load test "
        f"'{p['test_names'][0]}' in {main_dir}" + (f", branched from {branch}" if branch else ""))
    r = run_variant(main_cfg, main_dir, threads, branch=branch, backend=backend,
                    keep_columns=keep_columns)
    log("main: " + ("finished before" if r.get("skipped") else f"done in {r['wall_s']:.1f} s"))
    for name, stages, from_stage, _, test in p["branches"]:
        cfg_path = os.path.join(out, "configs", name + ".toml")
        _write_config(config, stages, cfg_path, base_dir)
        run_dir = os.path.join(out, name)
        log(f"{name}: load test '{test}' from {main_dir}:{from_stage}")
        r = run_variant(cfg_path, run_dir, threads, branch=f"{main_dir}:{from_stage}",
                        backend=backend, keep_columns=keep_columns)
        log(f"{name}: " + ("finished before" if r.get("skipped") else
                           f"done in {r['wall_s']:.1f} s"))
    return write_results(out, p, log)


def write_results(out: str, p: Mapping[str, Any],
                  log: Callable[[str], None] = print) -> Dict[str, Any]:
    """pile_capacity.csv, pile_setup.png, the figures of DIR/main and, last, pile_setup.json."""
    import pandas as pd

    rows = capacity_rows(out, p)
    df = pd.DataFrame(rows)
    df.to_csv(os.path.join(out, "pile_capacity.csv"), index=False)
    fits: Dict[str, Dict[str, float]] = {}
    for test in p["test_names"]:
        sel = df[df["test"] == test] if len(df) else df
        fits[test] = fit_setup(sel["ageing_time_s"], sel["capacity_N"]) if len(sel) else \
            fit_setup([], [])
        # The shaft's share on its own: set-up is a shaft effect (Axelsson 2000).
        fits[f"{test} (shaft)"] = (fit_setup(sel["ageing_time_s"], sel["shaft_at_capacity_N"])
                                   if len(sel) else fit_setup([], []))
    from .figures import use_file_backend_without_display
    from .figures.pile import figure_pile_setup

    use_file_backend_without_display()
    if len(df):
        fig = figure_pile_setup(df.to_dict("list"), fits, os.path.basename(os.path.normpath(out)))
        if fig is not None:
            fig.savefig(os.path.join(out, "pile_setup.png"), dpi=120)
    main_dir = os.path.join(out, "main")
    if os.path.isfile(os.path.join(main_dir, "timeseries.csv")):
        from .plot import make_plots

        make_plots(main_dir, None)
    # Last, whole or not at all: a sweep takes it to mean the variant is done, figures included.
    setup = os.path.join(out, "pile_setup.json")
    with open(setup + ".part", "w") as f:
        json.dump({"model": "Q(t)/Q(t0) = 1 + A log10(t/t0) (Skov and Denver 1988)",
                   "fits": fits}, f, indent=1, allow_nan=True)
        f.write("\n")
    os.replace(setup + ".part", setup)
    if len(df):
        with pd.option_context("display.width", 120, "display.max_columns", 20):
            log("capacities:\n" + df[["ageing_time_s", "test", "capacity_N",
                                      "shaft_at_capacity_N", "base_at_capacity_N"]]
                .to_string(index=False))
    for test, fit in fits.items():
        log(f"set-up '{test}': A = {fit['A']:.4g} +- {fit['A_std']:.2g} (Q0 = {fit['Q0_N']:.4g} "
            f"N, t0 = {fit['t0_s']:.4g} s, {fit['points']} points)")
    return {"capacity": rows, "fits": fits}


class _Stop(Exception):
    pass


def _raise_stop(signum, _frame):
    raise _Stop(signum)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand pile CONFIG --out DIR [--from RUN[:STAGE]] [--threads N] [--backend B]
    [--keep-columns]``."""
    parser = CommandParser("pile", __doc__)
    parser.add_argument("config", metavar="CONFIG",
                        help="the pile's run configuration: installation, age stages, a load test")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="directory for DIR/main, the branches and the set-up fit")
    parser.add_argument("--threads", type=int, default=1, metavar="N",
                        help="threads of each run (they run one after the other)")
    parser.add_argument("--from", dest="branch", metavar="RUN[:STAGE]",
                        help="start DIR/main from the state of run RUN at the start of its stage "
                             "STAGE (index or name; without it, the first stage CONFIG changes): "
                             "a variant of an installed pile without installing it again")
    parser.add_backend("what advances the runs: cpu (default), cuda or emulated")
    parser.add_argument("--keep-columns", action="store_true",
                        help="resume interrupted runs started by a crushdem that wrote fewer "
                             "columns, each file keeping its own (crushdem-sand resume "
                             "--keep-columns)")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))

    def log(msg: str) -> None:
        print(f"crushdem-sand pile: {msg}", flush=True)

    signal.signal(signal.SIGTERM, _raise_stop)
    try:
        pile(args.config, args.out, args.threads, args.backend, log, branch=args.branch,
             keep_columns=args.keep_columns)
    except _Stop as e:
        return 128 + int(e.args[0])
    except KeyboardInterrupt:
        return 128 + signal.SIGINT
    except (OSError, ValueError, RuntimeError) as e:
        print(f"crushdem-sand pile: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
