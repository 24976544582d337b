"""One function per figure of a run directory, each returning its matplotlib Figure.

Every ``figure_*(run)`` takes a run directory (a path) or the :class:`~crushdem_sand.rundir.RunData`
that :func:`~crushdem_sand.rundir.read_run` returns (read once when drawing several), and returns a
:class:`matplotlib.figure.Figure`, laid out and ready to save or show, or ``None`` when the run
lacks the data the figure needs. The figures are made with pyplot under whatever backend is in
use (inline in a notebook); nothing here selects one. :data:`FIGURES` maps each file name that
``crushdem-sand plot`` writes to its function; the module docstring of :mod:`crushdem_sand.plot`
describes them. The reference study's four figures (``crushdem-sand reproduce``) follow the same
rule, with the arguments their figure needs besides the run (:mod:`crushdem_sand.figures.study`).

Time: the figures against time use the DEM clock, except for "age" stages, whose off-DEM jumps
make a day of ageing a few milliseconds of DEM time: the figures with an ageing panel draw the
age stages against the ageing time (events.csv, one point per dynamic phase, log axis) and the
other stages against DEM time.

The figures live in modules by subject: :mod:`~crushdem_sand.figures.time_series`,
:mod:`~crushdem_sand.figures.laboratory`, :mod:`~crushdem_sand.figures.crushing`,
:mod:`~crushdem_sand.figures.ageing`, :mod:`~crushdem_sand.figures.penetration`,
:mod:`~crushdem_sand.figures.pile` and
:mod:`~crushdem_sand.figures.study`, on the helpers of
:mod:`~crushdem_sand.figures.common`; every one is importable from here.
"""

from __future__ import annotations

import os
from typing import Any, Callable, Dict, List, Tuple

from .ageing import figure_relaxation, figure_relaxation_breakage, figure_relaxation_forces
from .common import (AGEING_TIME_LABEL, MARKERS, MPA, WALL_COLORS, WALL_STYLES,  # noqa: F401
                     Run, as_run, label_axes, mark_times, plain_log_ticks, pyplot, stacked_axes,
                     stage_color, time_axis, unique_legend)
from .crushing import figure_breakage, figure_breakage_sizes, figure_grading
from .laboratory import (figure_inertial_number, figure_oedometer, figure_preparation,
                         figure_q_p_path, figure_strain_stress, figure_stress_profile,
                         figure_triaxial, figure_void_ratio, oedometer_label, oedometric_stages)
from .study import (figure_dynamic_phase, figure_force_statistics, figure_oedometric_relaxation,
                    figure_triaxial_relaxation)
from .penetration import (figure_breakage_field, figure_penetration, figure_shaft_stress,
                          figure_stress_field)
from .pile import (figure_pile_breakage, figure_pile_forces, figure_pile_rings,
                   figure_pile_setup, figure_pile_shaft)
from .time_series import figure_coordination, figure_kinetic_energy, figure_stress_time

# The functions of the modules below (FIGURES and the constants of figures.common are
# importable from here too).
__all__ = [
    "as_run", "pyplot", "stacked_axes", "unique_legend", "label_axes", "plain_log_ticks",
    "mark_times", "stage_color", "time_axis",
    "figure_stress_time", "figure_coordination", "figure_kinetic_energy",
    "figure_strain_stress", "figure_void_ratio", "figure_triaxial", "figure_q_p_path",
    "oedometer_label", "oedometric_stages", "figure_oedometer", "figure_inertial_number",
    "figure_preparation", "figure_stress_profile",
    "figure_grading", "figure_breakage", "figure_breakage_sizes",
    "figure_relaxation", "figure_relaxation_forces", "figure_relaxation_breakage",
    "figure_oedometric_relaxation", "figure_dynamic_phase", "figure_triaxial_relaxation",
    "figure_force_statistics", "figure_penetration", "figure_shaft_stress", "figure_stress_field",
    "figure_breakage_field", "figure_pile_shaft", "figure_pile_rings", "figure_pile_forces",
    "figure_pile_breakage", "figure_pile_setup",
    "draw_all", "display_available", "use_file_backend_without_display",
]


# The figures of `crushdem-sand plot`, in the order they are written: file name -> function.
FIGURES: Dict[str, Callable[[Run], Any]] = {
    "stress_time.png": figure_stress_time,
    "strain_stress.png": figure_strain_stress,
    "void_ratio.png": figure_void_ratio,
    "triaxial.png": figure_triaxial,
    "q_p_path.png": figure_q_p_path,
    "oedometer.png": figure_oedometer,
    "inertial_number.png": figure_inertial_number,
    "preparation.png": figure_preparation,
    "stress_profile.png": figure_stress_profile,
    "coordination.png": figure_coordination,
    "kinetic_energy.png": figure_kinetic_energy,
    "grading.png": figure_grading,
    "breakage.png": figure_breakage,
    "breakage_sizes.png": figure_breakage_sizes,
    "relaxation.png": figure_relaxation,
    "relaxation_forces.png": figure_relaxation_forces,
    "relaxation_breakage.png": figure_relaxation_breakage,
    "penetration.png": figure_penetration,
    "shaft_stress.png": figure_shaft_stress,
    "stress_field.png": figure_stress_field,
    "breakage_field.png": figure_breakage_field,
    "pile_shaft.png": figure_pile_shaft,
    "pile_rings.png": figure_pile_rings,
    "pile_forces.png": figure_pile_forces,
    "pile_breakage.png": figure_pile_breakage,
}


def draw_all(run: Run) -> List[Tuple[str, Any]]:
    """[(file name, Figure)] of every figure ``run`` has the data for, in FIGURES order."""
    run = as_run(run)
    out = []
    for name, make in FIGURES.items():
        fig = make(run)
        if fig is not None:
            out.append((name, fig))
    return out


def display_available() -> bool:
    """Whether a GUI display can be opened (on Linux and the BSDs: $DISPLAY or
    $WAYLAND_DISPLAY set)."""
    import sys

    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def use_file_backend_without_display() -> None:
    """For the commands that only write files: selects the Agg backend when no display can be
    opened (never called on import: a notebook or an application keeps its backend)."""
    if not display_available():
        from .._optional import require

        require("matplotlib", "crushdem's figures").use("Agg")
