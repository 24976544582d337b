"""``crushdem-sand calibrate CALIBRATION.toml --out DIR``: the values of one or two parameters that
make a run match targets, found by a library optimiser whose evaluations are sweep tasks.

A calibration file::

    base = "triaxial_small.toml"        # relative to the calibration file
    tolerance = 0.02                    # relative error allowed on every target
    max_evaluations = 12
    [parameters]                        # dotted keys (as in a sweep) and their bounds
    "contact.rolling_friction" = [0.1, 0.6]
    [targets]                           # summary figures (the columns of a sweep's table)
    "shear.q_max_MPa" = 22.6

One parameter and one target: Brent's method (scipy.optimize.brentq) between the bounds, whose
figures must bracket the target (both bounds run first, at once). Otherwise: Nelder-Mead
(scipy.optimize.minimize, within the bounds) on the sum of the squared relative errors. The
search stops as soon as every target is within the tolerance. Each evaluation is a run in
``DIR/runs`` named by its values (a repeated call reuses the finished ones: the optimiser takes
the same path); ``DIR/evaluations.csv`` lists them, ``DIR/calibrated.toml`` is the base
configuration with the calibrated values (every key resolved), ``DIR/convergence.png`` draws the
error against the evaluation and ``DIR/calibration.json`` the result.
"""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import sys
from typing import Any, Callable, Dict, List, Optional, Sequence

from ._optional import available, message, require
from .sweep import (cluster_parser, read_file_and_base, refuse_overlaps, run_variant, set_dotted,
                    stop_local_runs, summary_figures, variant_name)


class _Converged(Exception):
    pass


def read_calibration(path: str) -> Dict[str, Any]:
    """The calibration file, checked: base (dict and its directory), parameters (key: bounds),
    targets (figure: value), tolerance, max_evaluations."""
    doc, base, base_path = read_file_and_base(
        path, "calibration", ("base", "tolerance", "max_evaluations", "parameters", "targets"))
    params = doc.get("parameters") or {}
    targets = doc.get("targets") or {}
    if not 1 <= len(params) <= 2:
        raise ValueError(f"{path}: [parameters] needs one or two keys (got {len(params)})")
    if not targets:
        raise ValueError(f"{path}: [targets] needs at least one summary figure")
    for key, bounds in params.items():
        if (not isinstance(bounds, list) or len(bounds) != 2
                or not all(isinstance(b, (int, float)) for b in bounds) or bounds[0] >= bounds[1]):
            raise ValueError(f"{path}: [parameters] \"{key}\" = {bounds!r}: expected [low, high] "
                             "with low < high")
        set_dotted(copy.deepcopy(base), key, None, check_only=True)
    refuse_overlaps(path, base, list(params))
    for key, value in targets.items():
        if not isinstance(value, (int, float)) or not math.isfinite(value) or value == 0:
            raise ValueError(f"{path}: [targets] \"{key}\" = {value!r}: expected a non-zero "
                             "number")
    tol = doc.get("tolerance", 0.02)
    if not (isinstance(tol, (int, float)) and tol > 0):
        raise ValueError(f"{path}: tolerance = {tol!r}: expected a positive relative error")
    n = doc.get("max_evaluations", 12)
    if not (isinstance(n, int) and n >= 2):
        raise ValueError(f"{path}: max_evaluations = {n!r}: expected an integer >= 2")
    return {"base": base, "base_dir": os.path.dirname(base_path), "base_path": base_path,
            "parameters": {k: (float(b[0]), float(b[1])) for k, b in params.items()},
            "targets": {k: float(v) for k, v in targets.items()}, "tolerance": float(tol),
            "max_evaluations": n}


def calibrate(path: str, out: str, workers: Optional[int] = None, threads_per_run: int = 1,
              scheduler: Optional[str] = None,
              log: Callable[[str], None] = print) -> Dict[str, Any]:
    """Runs the calibration of ``path`` into ``out``; returns calibration.json's content."""
    import numpy as np

    from . import _core

    distributed = require("distributed", "crushdem-sand calibrate", "calibrate")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    optimize = require("scipy.optimize", "crushdem-sand calibrate")

    cal = read_calibration(path)
    keys, targets, tol = list(cal["parameters"]), cal["targets"], cal["tolerance"]
    os.makedirs(os.path.join(out, "configs"), exist_ok=True)
    os.makedirs(os.path.join(out, "runs"), exist_ok=True)
    evaluations: List[Dict[str, Any]] = []

    def config_of(x: Sequence[float]) -> Dict[str, Any]:
        cfg = copy.deepcopy(cal["base"])
        for k, v in zip(keys, x):
            set_dotted(cfg, k, float(v))
        return cfg

    def submit(client, x):
        values = {k: float(v) for k, v in zip(keys, x)}
        name = variant_name(values)
        text = _core.resolved_run_config(config_of(x), cal["base_dir"])
        cfg_path = os.path.join(out, "configs", name + ".toml")
        with open(cfg_path, "w") as f:
            f.write(text)
        run_dir = os.path.join(out, "runs", name)
        return name, values, run_dir, client.submit(run_variant, cfg_path, run_dir,
                                                    threads_per_run, key=name, pure=False)

    def record(name, values, run_dir, fut) -> List[float]:
        fut.result()  # a failed run stops the calibration: its error says why
        figures = summary_figures(run_dir)
        missing = [k for k in targets if k not in figures]
        if missing:
            raise ValueError(f"{run_dir}: no summary figure {', '.join(missing)} (available: "
                             f"{', '.join(sorted(figures))})")
        errors = [(figures[k] - v) / abs(v) for k, v in targets.items()]
        evaluations.append({"evaluation": len(evaluations) + 1, "run": name, **values,
                            **{k: figures[k] for k in targets},
                            "max_relative_error": max(abs(e) for e in errors)})
        log(f"evaluation {len(evaluations)}: "
            + ", ".join(f"{k} = {v:.6g}" for k, v in values.items()) + " -> "
            + ", ".join(f"{k} = {figures[k]:.6g}" for k in targets)
            + f" (error {evaluations[-1]['max_relative_error']:.2%})")
        return errors

    cluster = None
    client = Client(scheduler) if scheduler else None
    if client is None:
        cluster = LocalCluster(n_workers=workers or 2, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    best: Dict[str, Any] = {}
    converged = False
    seen: Dict[tuple, List[float]] = {}  # an optimiser may ask for a point twice (brentq: bounds)
    try:
        def evaluate(x) -> List[float]:
            point = tuple(float(v) for v in np.atleast_1d(x))
            if point in seen:
                return seen[point]
            if len(evaluations) >= cal["max_evaluations"]:
                raise StopIteration
            errors = seen[point] = record(*submit(client, x))
            if max(abs(e) for e in errors) <= tol:
                raise _Converged
            return errors

        try:
            if len(keys) == 1 and len(targets) == 1:
                lo, hi = cal["parameters"][keys[0]]
                first = [submit(client, [lo]), submit(client, [hi])]  # both bounds at once
                e_lo, e_hi = (record(*s)[0] for s in first)
                seen[(float(lo),)], seen[(float(hi),)] = [e_lo], [e_hi]
                if min(abs(e_lo), abs(e_hi)) <= tol:
                    raise _Converged
                if e_lo * e_hi > 0:
                    raise ValueError(
                        f"{keys[0]} in [{lo:g}, {hi:g}] does not bracket the target "
                        f"{next(iter(targets))} = {next(iter(targets.values())):g} (relative "
                        f"errors {e_lo:+.3f} and {e_hi:+.3f}): widen the bounds")
                optimize.brentq(lambda v: evaluate([v])[0], lo, hi, xtol=1e-12,
                                maxiter=cal["max_evaluations"])
            else:
                lows = [cal["parameters"][k][0] for k in keys]
                highs = [cal["parameters"][k][1] for k in keys]
                optimize.minimize(lambda x: float(np.sum(np.square(evaluate(x)))),
                                  x0=[0.5 * (a + b) for a, b in zip(lows, highs)],
                                  method="Nelder-Mead", bounds=list(zip(lows, highs)),
                                  options={"maxfev": cal["max_evaluations"]})
        except _Converged:
            converged = True
        except StopIteration:
            pass
    except KeyboardInterrupt:
        if cluster is not None:
            stop_local_runs(log)  # each run saves its checkpoint before the workers close
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()

    if evaluations:
        best = min(evaluations, key=lambda e: e["max_relative_error"])
        with open(os.path.join(out, "evaluations.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(evaluations[0]))
            w.writeheader()
            w.writerows(evaluations)
        text = _core.resolved_run_config(config_of([best[k] for k in keys]), cal["base_dir"])
        with open(os.path.join(out, "calibrated.toml"), "w") as f:
            f.write(f"# crushdem-sand calibrate {os.path.abspath(path)}: "
                    + ", ".join(f"{k} = {best[k]!r}" for k in keys) + "\n" + text)
        if available("matplotlib"):
            _figure(evaluations, os.path.join(out, "convergence.png"), tol)
        else:
            log(message("matplotlib", "convergence.png", "plot") + " (not drawn)")
    result = {"converged": converged, "tolerance": tol, "evaluations": len(evaluations),
              "calibrated": {k: best.get(k) for k in keys},
              "figures": {k: best.get(k) for k in targets}, "targets": targets,
              "max_relative_error": best.get("max_relative_error")}
    with open(os.path.join(out, "calibration.json"), "w") as f:
        json.dump(result, f, indent=1)
    return result


def _figure(evaluations: List[Dict[str, Any]], path: str, tol: float) -> None:
    Figure = require("matplotlib.figure", "crushdem-sand calibrate's figure", "plot").Figure
    fig = Figure(figsize=(6, 3.8))
    ax = fig.subplots()
    n = [e["evaluation"] for e in evaluations]
    ax.semilogy(n, [max(e["max_relative_error"], 1e-16) for e in evaluations], "o-")
    ax.axhline(tol, color="0.4", ls="--", label=f"tolerance {tol:g}")
    ax.set_xlabel("evaluation")
    ax.set_ylabel("largest relative error of the targets")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand calibrate CALIBRATION.toml --out DIR [--workers N] [--threads-per-run T]
    [--scheduler ADDRESS]``."""
    parser = cluster_parser("calibrate", __doc__, "calibration", "CALIBRATION.toml")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))

    def log(msg: str) -> None:
        print(f"crushdem-sand calibrate: {msg}", flush=True)

    try:
        result = calibrate(args.calibration, args.out, args.workers, args.threads_per_run,
                           args.scheduler, log)
    except (OSError, ValueError, RuntimeError) as e:
        print(f"crushdem-sand calibrate: error: {e}", file=sys.stderr)
        return 2
    log(("converged: " if result["converged"] else "NOT converged: ")
        + json.dumps(result["calibrated"]) + f" after {result['evaluations']} evaluations")
    return 0 if result["converged"] else 1


if __name__ == "__main__":
    sys.exit(main())
