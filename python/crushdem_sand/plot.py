"""``crushdem-sand plot DIR``: figures of a run's DIR/timeseries.csv (and DIR/summary.json).

The CSV has one header row whose column names carry their SI unit (``time_s``,
``wall_zmax_stress_Pa``, ``kinetic_energy_J``, ...); strains are fractions, compression positive,
counted from the start of the test. Every figure is drawn only when the columns (and, for the
laboratory figures, the stages listed in summary.json) it needs exist, so the command works for
any experiment. A run still going, or stopped with a checkpoint, has no summary.json yet: its
stage types then come from DIR/config.toml and the figures show the rows written so far.
Stresses are drawn in MPa and strains in %. Figures written (PNG, into DIR unless ``--out`` is
given):

* ``stress_time.png``      wall normal stresses [MPa] against time [s], a row of panels per axis
                           (x, y, z walls, one stress scale) with the mean stress p dotted: the
                           low wall (xmin, ...) a wide pale solid line with filled circles, the
                           high one dashed with open squares, so that both show where they carry
                           the same stress; the "age" stages against ageing time on panels to
                           the right (see below)
* ``strain_stress.png``    deviator stress q (or axial wall stress) [MPa] against axial strain [%],
                           with volumetric strain [%] on a second panel when present; for an
                           oedometric test (every stage oedometric, hold or age, whose
                           volumetric strain is its axial strain) sigma_v and sigma_h [MPa]
                           against axial strain [%] and the stress path sigma_h against sigma_v
                           with each oedometric stage's K0 line
* ``void_ratio.png``       void ratio e against mean stress p [MPa] on a log axis (the e - log p
                           compression curve), one colour per test stage when there is a
                           ``stage`` column
* ``coordination.png``     coordination number against time
* ``kinetic_energy.png``   kinetic energy [J] against time (log axis)

The first row of a test that starts from a prepared sample has its contact columns (number of
contacts, Z, the contact force statistics, the Love-Weber stress) written as 0 before the contact
list is computed; those values are left out (NaN), not drawn as a drop to zero.

Laboratory tests (a ``stage`` column, stages described in summary.json ``"stages"``):

* ``triaxial.png``         for each triaxial stage, deviator stress q [MPa] (peak marked with
                           q_max and the peak friction angle from summary.json) and the change of
                           volumetric strain during the stage [%] against the stage's axial
                           strain [%]
* ``q_p_path.png``         stress path q [MPa] against p [MPa], one colour per stage (drawn for
                           any run with both columns)
* ``oedometer.png``        for oedometric stages: void ratio e against vertical stress
                           sigma_v = mean of the zmin/zmax wall stresses [MPa] (log axis), each
                           stage labelled loading or unloading, with its K0 = sigma_h/sigma_v
* ``inertial_number.png``  inertial number I against time (log axis) with the quasi-static
                           limit I = 1e-3 dashed

Sample preparation (a ``friction`` column):

* ``preparation.png``      void ratio (with the target) and the preparation friction coefficient
                           against time

Grain crushing (DIR/grading.csv, DIR/breakage.csv and the crushing columns of the time series):

* ``grading.png``          grading curves, mass passing [%] against particle size d [mm] (log
                           axis): the initial curve, the end of every stage (when grading.csv has
                           one row per time-series row) and the final curve, each labelled with
                           the relative breakage B_r; removed fragments count as finer than every
                           sieve. The size d_c below which grains crack is dashed when
                           summary.json ``"crushing"`` gives it
* ``breakage.png``         cumulative breakages by cause (instant, crack) with the number of
                           particles on a second axis, and the relative breakage B_r with the
                           void ratio e and the void ratio counting the removed fines as solid,
                           against axial strain [%] (time [s] when there is no axial strain)
* ``breakage_sizes.png``   histogram of the diameters [mm] of the broken grains by cause (when
                           breakage.csv has rows)

Ageing (off-DEM stress relaxation or creep, ``"age"`` stages; drawn only when DIR/events.csv
exists). events.csv has one row per dynamic DEM phase: ``ageing_time_s`` (the ageing clock since
the boundary was frozen, 0 for the first phase), ``stage``, ``dynamic_phase`` and the time-series
columns of the end of that phase. The x axis is the ageing time [s] on a log scale, so only the
phases with ageing time > 0 are drawn (each phase a marker); the first phase (t = 0) gives the
reference values shown in the legends. Each age stage is its own curve, with its own t = 0. Dotted
vertical lines mark 1 h and 1 day when they lie within the ageing time reached:

* ``relaxation.png``          vertical stress sigma_v(t)/sigma_v(0) (sigma_v = mean of the
                              zmin/zmax wall stresses; sigma_v(0) in MPa in the legend; for a
                              relaxation with every wall fixed, sigma_v(t)/sigma_v(4 s) as in the
                              study, with its value at 1 day and the plausible band 0.70-0.97
                              there), one point per dynamic phase (t = 0 drawn open at the left
                              edge), and on a
                              second panel the deviator stress q [MPa] with the axial strain [%]
                              on a twin axis (which grows in creep, when the axial wall is
                              servo-controlled)
* ``relaxation_forces.png``   standard deviations of the contact normal and tangential forces
                              (solid), with their means (dashed), each over its value at t = 0
                              (in N in the legend), the axis spanning what they reach, so that a
                              change of a percent shows
* ``relaxation_breakage.png`` cumulative breakages by cause (instant, crack) with the number of
                              particles on a second axis

A chamber at rest (a "hold" stage with ``profile_bins``; drawn only when DIR/stress_profile.csv
exists):

* ``stress_profile.png``      vertical, radial and hoop stress [kPa] of the core's grains against
                              the depth below the top platen [mm], with K = sigma_rr / sigma_zz

Penetration ("penetrate" stages; drawn only when DIR/penetration.csv exists):

* ``penetration.png``         cone resistance q_c [MPa] and sleeve friction f_s [kPa] against
                              the body's travel [mm], downwards
* ``shaft_stress.png``        radial stress on the shaft [kPa] against the height above its
                              start [mm], at four travels of the last penetrate stage
* ``stress_field.png``        radial, hoop and vertical stress [kPa] of the grains about the
                              body in rings by slices (r [mm] against z [mm]) at the last record
                              of penetration_field.csv (with ``field_interval``)
* ``breakage_field.png``      where grains broke around the body (with [crushing]): distance
                              from its axis [mm] against z [mm], coloured by the travel

A pile's ageing ("age" stages that name a pile; drawn only when DIR/pile_ageing.csv exists):

* ``pile_shaft.png``          radial stress on the shaft [kPa] by depth against ageing time
* ``pile_rings.png``          radial and hoop stress [kPa] in rings of grains about the shaft
                              against r / R, at four ageing times
* ``pile_forces.png``         std of the normal and tangential contact forces near the shaft
                              against ageing time, over their first values
* ``pile_breakage.png``       where grains failed while the sand aged, coloured by ageing time

A day of ageing is a few milliseconds of DEM time, so the figures against time (stress_time,
coordination, kinetic_energy) draw the stages before the age stages against DEM time and the age
stages, from events.csv, against ageing time on a second panel.

From Python, :mod:`crushdem_sand.figures` has one function per figure returning its matplotlib
Figure (``figure_stress_time(run_dir)``, ...), drawn under the backend in use; only the command
``crushdem-sand plot`` selects the file backend Agg, and only when there is no display.
"""

from __future__ import annotations

import os
import sys
from typing import List, Optional, Sequence

from ._cli import CommandParser
from .analysis import WALLS  # noqa: F401  (re-exported)
from .figures import (FIGURES, MPA, as_run, figure_breakage,  # noqa: F401  (re-exported)
                      figure_breakage_sizes, figure_coordination, figure_grading,
                      figure_inertial_number, figure_kinetic_energy, figure_oedometer,
                      figure_preparation, figure_q_p_path, figure_relaxation,
                      figure_relaxation_breakage, figure_relaxation_forces, figure_strain_stress,
                      figure_stress_time, figure_triaxial, figure_void_ratio,
                      use_file_backend_without_display)
from .rundir import (read_breakage, read_events, read_grading,  # noqa: F401  (re-exported)
                     read_run, read_summary, read_timeseries, record_entries,
                     stages_from_config)


def make_plots(run_dir: str, out_dir: Optional[str] = None) -> List[str]:
    """Draws the figures of ``run_dir`` that its files have the data for into ``out_dir``
    (default: ``run_dir``) as PNG files; returns the paths written."""
    from ._optional import require

    plt = require("matplotlib.pyplot", "crushdem-sand plot")
    run = read_run(run_dir)
    out_dir = out_dir or run_dir
    os.makedirs(out_dir, exist_ok=True)
    written: List[str] = []
    for name, make in FIGURES.items():
        fig = make(run)
        if fig is None:
            continue
        try:
            path = os.path.join(out_dir, name)
            fig.savefig(path, dpi=150)
            written.append(path)
        finally:
            plt.close(fig)
    if os.path.abspath(out_dir) == os.path.abspath(run_dir):
        record_entries(run_dir, [os.path.basename(p) for p in written])
    return written


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``crushdem-sand plot DIR [--out OUT]``; returns the exit status."""
    parser = CommandParser("plot")
    parser.add_argument("dir", metavar="DIR", help="run directory containing timeseries.csv")
    parser.add_argument("--out", default=None, help="directory for the PNGs (default: DIR)")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    use_file_backend_without_display()
    try:
        written = make_plots(args.dir, args.out)
    except (OSError, ValueError) as e:
        print(f"crushdem-sand plot: error: {e}", file=sys.stderr)
        return 2
    if not written:
        series = os.path.join(args.dir, "timeseries.csv")
        print(f"crushdem-sand plot: {series} has no column to plot", file=sys.stderr)
        return 1
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
