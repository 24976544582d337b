"""Run-or-resume: the step of a pipeline (``crushdem-sand reproduce``,
``crushdem-sand sensitivity``) that runs one test into its own run directory, unless it has
finished, and continues it from its checkpoint when an earlier call was interrupted."""

from __future__ import annotations

import os
import shutil
import time
from typing import Any, Callable, Dict, Optional

from .analysis import as_float
from .rundir import is_being_written, is_finished, read_timing


def set_threads(n: int) -> int:
    """Sets the OpenMP thread count of every later run (``crushdem_sand._core.set_threads``);
    returns the count in force (1 in a build without OpenMP)."""
    from . import _core

    return int(_core.set_threads(int(n)))


def timing_record(run_dir: str) -> Dict[str, Any]:
    """The run's own wall-clock seconds, threads and dominant part (timing.json); NaN and None
    where it has none."""
    timing = read_timing(run_dir)
    return {"wall_s": as_float(timing.get("wall_seconds")), "threads": timing.get("threads"),
            "dominant_part": timing.get("dominant_part")}


def run_step(name: str, run_dir: str, start: Callable[[], Any], log: Callable[[str], None],
             record: Dict[str, Any],
             resume: Optional[Callable[[str, bool], Any]],
             progress: bool = False) -> None:
    """Runs ``start()`` unless ``run_dir`` already has a finished run; records the timing in
    ``record[name]``: wall_s is the run's own wall-clock over every call that advanced it
    (timing.json), wall_s_this_call this call's.

    An interrupted run that left ``checkpoint.bin`` is continued with ``resume`` instead of
    being started over; if that fails (e.g. the checkpoint belongs to another build), or
    ``resume`` is None (explicitly: nothing can resume this run), the run starts over. A run that
    another process is writing (DIR/.lock held) raises RuntimeError: it is neither resumed nor
    removed. progress: passed to ``resume`` (the engine's progress lines); ``start`` chooses its
    own.
    """
    if is_finished(run_dir):
        log(f"{name}: {run_dir} has finished (summary.json): not run again")
        record[name] = {"skipped": True, **timing_record(run_dir)}
        return
    if is_being_written(run_dir):  # never resumed or removed under a running process
        raise RuntimeError(f"{name}: {run_dir} is being written by another crushdem process "
                           "(its .lock is held); wait for it to finish, then call again")
    t0 = time.perf_counter()
    resumed = False
    if resume is not None and os.path.isfile(os.path.join(run_dir, "checkpoint.bin")):
        log(f"{name}: resuming the interrupted run in {run_dir} from checkpoint.bin")
        try:
            resume(run_dir, progress)
            resumed = True
        except (ValueError, RuntimeError) as e:
            log(f"{name}: cannot resume ({e}): starting over")
    if not resumed:
        if os.path.isdir(run_dir):  # unfinished and not resumable: this tool's own directory
            log(f"{name}: removing the unfinished run in {run_dir} to start it again")
            shutil.rmtree(run_dir)
        log(f"{name}: running into {run_dir}")
        start()
    wall = time.perf_counter() - t0
    record[name] = {**timing_record(run_dir), "skipped": False, "resumed": resumed,
                    "wall_s_this_call": wall}
    if not (resumed and record[name]["wall_s"] > 0):  # a resumed run's timing.json sums its calls
        record[name]["wall_s"] = wall
    log(f"{name}: done in {wall:.1f} s" +
        (f" (this call; {record[name]['wall_s']:.1f} s over all its calls)" if resumed else ""))
