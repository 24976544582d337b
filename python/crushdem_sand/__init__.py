"""crushdem: discrete element simulation of crushable granular materials.

The engine is C++ (``crushdem_sand._core``); this package is a thin Python front end.
All quantities are SI: lengths in m, times in s, forces in N, stresses and moduli in Pa,
masses in kg, energies in J.

A simulation is configured with the same sections and keys as a TOML configuration file
(``crushdem-sand check FILE`` validates one), given as keyword arguments::

    import numpy as np
    import crushdem_sand

    sim = crushdem_sand.Simulation(
        material={"shear_modulus": 32e9, "poisson_ratio": 0.19},
        contact={"law": "hertz"},
        box={"min": [0, 0, 0], "max": [1e-3] * 3},
        walls={"zmax": {"mode": "servo", "target_stress": 1e6}},
    )
    g = (np.arange(3) + 0.5) / 3 * 1e-3  # 27 grains on a grid, the top wall servo-controlled
    sim.add_particles(np.stack(np.meshgrid(g, g, g), axis=-1).reshape(-1, 3), 1.65e-4)
    sim.step(10_000)
    print(sim.time, sim.num_contacts, sim.wall_stresses())

Invalid or unknown keys raise :class:`ConfigError` (a subclass of :class:`ValueError`) with a
message naming the key, e.g. ``material.shear_modulus``.

Run directories (``crushdem-sand run``, the laboratory functions of :mod:`crushdem_sand.lab`) are
read with :class:`crushdem_sand.lab.Result`, each table as a pandas DataFrame.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import math
import numbers
import operator
import re
import threading
import warnings
from typing import (Any, Callable, Dict, Iterator, Mapping, Optional, Sequence, Tuple, TypeVar,
                    cast)

import numpy as np

from . import _core
from ._core import (ConfigError, Interrupted, RuntimeFailure, __commit__, __version__,
                    cli_main, set_threads, threads)
from . import lab
from .lab import (creep_test, isotropic_test, oedometric_relaxation, oedometric_test,
                  prepare_sample, triaxial_relaxation, triaxial_test)

__all__ = [
    "Simulation",
    "ConfigError",
    "Interrupted",
    "RuntimeFailure",
    "WALL_NAMES",
    "NO_PARENT",
    "backends",
    "cli_main",
    "parameter_reference",
    "set_threads",
    "threads",
    "resolved_config",
    "lab",
    "prepare_sample",
    "isotropic_test",
    "oedometric_test",
    "triaxial_test",
    "oedometric_relaxation",
    "creep_test",
    "triaxial_relaxation",
]


def _interactive() -> bool:
    """Whether progress bars help: stderr is a terminal, or this runs in a notebook kernel."""
    import sys

    if getattr(sys.stderr, "isatty", lambda: False)():
        return True
    return "ipykernel" in sys.modules


#: Wall order used by every per-wall array (axis k//2, low side when k is even).
WALL_NAMES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")

#: ``parent_ids`` value of a grain that has no parent (it was not produced by a fracture).
NO_PARENT = np.uint64(2**64 - 1)


def backends() -> Tuple[str, ...]:
    """The backends this build can run, as names for ``backend=`` and ``--backend``:
    ``("cpu", "emulated")``, with ``"cuda"`` after them in a build with CUDA (whether a GPU is
    there is found when a run starts)."""
    return tuple(name for name in re.split(r",\s*|\s+or\s+", _core.backends().strip()) if name)


class _ContactCount(int):
    """``Simulation.num_contacts``, a property that was a method: an int that may still be
    called, until the next release, with a DeprecationWarning. A call counts again, as the
    method did: a stored ``sim.num_contacts`` called after ``step()`` gives the new count."""

    _count: Any

    def __new__(cls, count: Callable[[], int]) -> "_ContactCount":
        obj = super().__new__(cls, count())
        obj._count = count
        return obj

    def __call__(self) -> int:
        warnings.warn("Simulation.num_contacts is a property: write sim.num_contacts without the "
                      "parentheses (calling it stops working in the next release)",
                      DeprecationWarning, stacklevel=2)
        return int(self._count())


def _step_count(what: str, n: Any) -> int:
    """A number of steps: an integer (Python or NumPy) >= 0; 1.5, "10" or True are refused
    rather than rounded or parsed."""
    if isinstance(n, bool):
        raise TypeError(f"{what}: {n!r} steps: expected an integer count")
    if isinstance(n, float) and n.is_integer():  # 1e4 is a count; 1.5 is not
        n = int(n)
    try:
        count = operator.index(n)
    except TypeError:
        raise TypeError(f"{what}: {n!r} steps: expected an integer count") from None
    if count < 0:
        raise ValueError(f"{what}: {count} steps: expected a count >= 0")
    return count


def _config_dict(sections: Mapping[str, Any]) -> Dict[str, Any]:
    """Drops sections given as None so that ``Simulation(walls=None)`` means "defaults"."""
    return {k: v for k, v in sections.items() if v is not None}


def resolved_config(**sections: Any) -> str:
    """Validates a configuration and returns it as TOML with every default filled in.

    Takes the same keyword arguments as :class:`Simulation`.
    """
    return _core.resolved_config(_config_dict(sections))


_Method = TypeVar("_Method", bound=Callable[..., Any])


def _read(method: _Method) -> _Method:
    """A read of the simulation's state, refused (RuntimeError) while another thread steps it
    (the arrays would mix grains before and after a step)."""

    @functools.wraps(method)
    def guarded(self: "Simulation", *args: Any, **kwargs: Any) -> Any:
        with self._exclusive(method.__name__):
            return method(self, *args, **kwargs)

    return cast(_Method, guarded)


class Simulation:
    """A DEM simulation of spheres in a box of six walls, with rigid bodies of any common shape
    and gravity where configured.

    Properties and methods: the scalars the simulation keeps, its counts and clock, are
    properties (``num_particles``, ``num_contacts``, ``time``, ``step_count``, ``dt``; and
    ``core``, the engine object); whatever copies arrays, computes a measure or takes arguments
    is a method (``positions()``, ``contacts()``, ``wall_stresses()``, ``kinetic_energy()``,
    ``step(n)``, ...). Arrays are NumPy copies; editing them does not change the simulation.
    ``contacts()`` and ``bodies()`` return columns (1-D arrays of one length) that
    ``pandas.DataFrame`` takes as they are.

    Keyword arguments are the sections of a configuration file, each a dict (SI units). The
    keys of ``material``, ``contact``, ``damping``, ``timestep`` and ``neighbor`` are listed at
    the end, from the engine's parameter tables (``crushdem_sand.parameter_reference()``); besides:

    ``box``
        ``min``, ``max``: corners [m] as 3-lists.
    ``walls``
        a dict keyed by wall name (``xmin`` ... ``zmax``), each with ``mode``
        ("fixed", "velocity", "servo"), ``velocity`` [m/s], ``target_stress`` [Pa],
        ``servo_alpha`` [-], ``max_speed`` [m/s].
    ``body``
        a list of dicts, one per rigid body (a plane, disk, cylinder, cone or pile: the
        ``[[body]]`` keys of docs/configuration.md); read with ``bodies()`` and
        ``probe_body()``, driven with ``set_wall()`` by its name.
    ``gravity``
        ``g``: the gravitational acceleration [m/s^2] as a 3-list.

    Alternatively pass one nested dict as ``config`` (sections given as keywords override it).
    Raises :class:`ConfigError` (a :class:`ValueError`) for a bad or unknown key.

    Threads: ``step()`` and ``run()`` release the GIL, and while one runs every call from another
    thread raises RuntimeError (a read would mix grains before and after a step, a change would
    tear it); ``core``, the engine object itself, is not guarded. Other calls from several
    threads take turns. A ``progress`` callback runs in the stepping thread between two chunks of
    steps and may read and drive the simulation, but not step it.
    """

    def __init__(self, config: Optional[Mapping[str, Any]] = None, **sections: Any) -> None:
        merged: Dict[str, Any] = dict(config or {})
        merged.update(sections)
        self._sim = _core.Simulation(_config_dict(merged))
        # step() releases the GIL: another Python thread must neither change the grains meanwhile
        # nor read them half-way through a step. Reentrant: step's progress callback, in the
        # stepping thread between two chunks of steps, may read and drive the simulation.
        self._busy = threading.RLock()
        self._stepping: Optional[int] = None  # the thread whose step() or run() holds _busy

    @contextlib.contextmanager
    def _exclusive(self, what: str, steps: bool = False) -> Iterator[None]:
        """Holds the simulation for one call. Other calls hold it briefly and are waited for; a
        step in another thread is refused (RuntimeError), as is a step within a step."""
        me = threading.get_ident()
        while not self._busy.acquire(timeout=0.05):
            if self._stepping not in (None, me):
                raise RuntimeError(f"Simulation.{what}: the simulation is stepping in another "
                                   "thread; wait for step() to return")
        try:
            if steps and self._stepping is not None:
                raise RuntimeError(f"Simulation.{what}: called from step()'s progress callback, "
                                   "the step in progress would go beyond its count: step after "
                                   "it returns")
            if steps:
                self._stepping = me
            try:
                yield
            finally:
                if steps:
                    self._stepping = None
        finally:
            self._busy.release()

    # --- particles --------------------------------------------------------------------------

    def add_particles(
        self,
        positions: Any,
        radii: Any,
        velocities: Any = None,
    ) -> np.ndarray:
        """Adds spheres and returns their ids (uint64 array).

        positions: (N, 3) centres [m]; radii: (N,) [m] (a scalar is broadcast);
        velocities: (N, 3) [m/s] or None for rest. Mass follows from ``material.density``.
        Every grain must be finite, with a positive radius, and inside the walls (overlapping
        none by more than a tenth of its radius); otherwise ConfigError names the first that
        is not, and none is added.
        """
        for name, a in (("positions", positions), ("radii", radii), ("velocities", velocities)):
            if a is not None and np.iscomplexobj(a):
                raise ConfigError(f"add_particles: {name} are complex: expected real numbers")
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        if pos.ndim == 1 and pos.size == 3:
            pos = pos.reshape(1, 3)
        rad = np.asarray(radii, dtype=np.float64)
        if rad.ndim == 0:
            rad = np.full(pos.shape[0] if pos.ndim == 2 else 1, float(rad))
        rad = np.ascontiguousarray(rad)
        vel = None
        if velocities is not None:
            vel = np.ascontiguousarray(velocities, dtype=np.float64)
            if vel.ndim == 1 and vel.size == 3 and pos.shape[0] == 1:
                vel = vel.reshape(1, 3)
        with self._exclusive("add_particles"):
            return self._sim.add_particles(pos, rad, vel)

    def add_particle(self, position: Sequence[float], radius: float,
                     velocity: Optional[Sequence[float]] = None) -> int:
        """Adds one sphere (centre [m], radius [m], velocity [m/s]); returns its id."""
        ids = self.add_particles([position], [radius], None if velocity is None else [velocity])
        return int(ids[0])

    @property
    @_read
    def num_particles(self) -> int:
        """Number of grains."""
        return self._sim.num_particles

    @_read
    def positions(self) -> np.ndarray:
        """Centres, (N, 3) float64 copy [m]."""
        return self._sim.positions()

    @_read
    def velocities(self) -> np.ndarray:
        """Velocities, (N, 3) float64 copy [m/s]."""
        return self._sim.velocities()

    @_read
    def angular_velocities(self) -> np.ndarray:
        """Angular velocities, (N, 3) float64 copy [rad/s]."""
        return self._sim.angular_velocities()

    @_read
    def forces(self) -> np.ndarray:
        """Forces of the last evaluation (after local damping), (N, 3) float64 copy [N]."""
        return self._sim.forces()

    @_read
    def torques(self) -> np.ndarray:
        """Torques of the last evaluation, (N, 3) float64 copy [N m]."""
        return self._sim.torques()

    @_read
    def radii(self) -> np.ndarray:
        """Radii, (N,) float64 copy [m]."""
        return self._sim.radii()

    @_read
    def masses(self) -> np.ndarray:
        """Masses, (N,) float64 copy [kg]."""
        return self._sim.masses()

    @_read
    def ids(self) -> np.ndarray:
        """Stable particle ids, (N,) uint64 (array order changes when particles are sorted)."""
        return self._sim.ids()

    @_read
    def parent_ids(self) -> np.ndarray:
        """Id of the grain each particle came from, (N,) uint64; NO_PARENT if none."""
        return self._sim.parent_ids()

    # --- time stepping ----------------------------------------------------------------------

    def step(self, n: int = 1, progress: Any = None) -> None:
        """Advances ``n`` time steps (the GIL is released meanwhile).

        Ctrl-C stops it within about a second with KeyboardInterrupt, between two steps (the
        state stays consistent; ``step_count`` says how far it got). ``progress``: a callable
        ``progress(done, n)`` called about twice a second; True for a progress bar (tqdm, also
        in a notebook), False for none; None (default) shows the bar for 10,000 steps or more
        when the output is a terminal or a notebook.
        """
        n = _step_count("step", n)
        if progress is None:
            progress = n >= 10_000 and _interactive()
        with self._exclusive("step", steps=True):
            if progress is True:
                from tqdm.auto import tqdm

                with tqdm(total=n, unit="step", unit_scale=True, desc="crushdem step",
                          leave=False) as bar:
                    self._sim.step(n, lambda done, total: bar.update(done - bar.n))
            elif progress is False:
                self._sim.step(n)
            else:
                self._sim.step(n, progress)

    def run(self, duration: Optional[float] = None, *, steps: Optional[int] = None) -> None:
        """Advances by at least ``duration`` seconds of simulated time, in whole steps, or by
        ``steps`` time steps (as ``step``; give one of the two)."""
        if (duration is None) == (steps is None):
            raise TypeError("Simulation.run: give either duration (s) or steps=")
        if steps is not None:
            self.step(steps)
            return
        if isinstance(duration, (bool, str)) or not isinstance(duration, numbers.Real):
            raise TypeError(f"Simulation.run: duration {duration!r}: expected a time in s")
        duration = float(duration)
        if not (math.isfinite(duration) and duration >= 0.0):
            raise ValueError(f"Simulation.run: duration = {duration}: expected a finite time "
                             ">= 0 s")
        with self._exclusive("run", steps=True):
            end = self.time + duration
            while self.time < end:
                dt = self.dt
                if not dt > 0.0:
                    raise RuntimeFailure(f"run: time step is {dt} s (no particles?)")
                n = max(1, int(np.ceil((end - self.time) / dt - 1e-9)))
                self._sim.step(min(n, 1_000_000))

    def compute_forces(self) -> None:
        """Evaluates forces and torques at the current state without moving anything."""
        with self._exclusive("compute_forces"):
            self._sim.compute_forces()

    @property
    @_read
    def time(self) -> float:
        """Simulated time [s]."""
        return self._sim.time

    @property
    @_read
    def step_count(self) -> int:
        """Number of steps taken."""
        return self._sim.step_count

    @property
    @_read
    def dt(self) -> float:
        """Time step [s] the next step uses (computed when automatic). Assigning fixes it."""
        return self._sim.dt

    @dt.setter
    def dt(self, value: float) -> None:
        self.set_dt(value)

    def set_dt(self, dt: float) -> None:
        """Fixes the time step [s], overriding the automatic choice; warns (RuntimeWarning) when
        it is above the automatic step of the grains present (the run may be unstable)."""
        dt = float(dt)
        with self._exclusive("set_dt"):
            self._sim.set_dt(dt)
            automatic = self._sim.automatic_dt() if self._sim.num_particles else math.inf
        if dt > automatic:
            warnings.warn(f"set_dt: {dt:g} s is {dt / automatic:.3g} times the automatic "
                          f"step {automatic:g} s: the run may be unstable", RuntimeWarning,
                          stacklevel=2)

    @_read
    def rayleigh_dt(self) -> float:
        """Rayleigh time-step estimate of the smallest grain [s]."""
        return self._sim.rayleigh_dt()

    @_read
    def stiffness_dt(self) -> float:
        """Stiffness (sqrt(m/k)) time-step estimate [s]."""
        return self._sim.stiffness_dt()

    # --- contacts, walls, measures ----------------------------------------------------------

    @_read
    def contacts(self) -> Dict[str, np.ndarray]:
        """Touching contacts at the current state, grain-grain then grain-wall, as columns: a
        dict of 1-D arrays of one length, one entry per contact, so that
        ``pandas.DataFrame(sim.contacts())`` is the table of contacts.

        ``id_i``, ``id_j`` (uint64; for a wall contact ``id_j`` is the wall index: 0..5 for the
        box's walls, see WALL_NAMES, then the bodies' ``index`` of :meth:`bodies`),
        ``is_wall`` (bool), ``overlap`` [m], ``normal_force`` [N] (elastic);
        ``normal_x``, ``normal_y``, ``normal_z``: the unit normal from i towards j (or into the
        wall); ``tangential_force_x``, ``_y``, ``_z`` [N] on grain i; ``rolling_moment_x``,
        ``_y``, ``_z`` [N m] on grain i (zero without rolling resistance and at walls). A
        vector as an (n, 3) array: ``np.column_stack([c["normal_x"], c["normal_y"],
        c["normal_z"]])``.
        """
        return _columns(self._sim.contacts())

    @property
    @_read
    def num_contacts(self) -> int:
        """Grain-grain contacts with positive overlap. A property (it was a method:
        ``sim.num_contacts()`` still works until the next release, with a DeprecationWarning)."""
        return _ContactCount(self._num_contacts)

    def _num_contacts(self) -> int:
        with self._exclusive("num_contacts"):
            return int(self._sim.num_contacts())

    @_read
    def wall_positions(self) -> np.ndarray:
        """Wall plane coordinates (6,) [m], in WALL_NAMES order."""
        return self._sim.wall_positions()

    @_read
    def wall_velocities(self) -> np.ndarray:
        """Wall velocities along their axes (6,) [m/s]."""
        return self._sim.wall_velocities()

    @_read
    def wall_stresses(self) -> np.ndarray:
        """Compressive normal stress on each wall (6,) [Pa]."""
        return self._sim.wall_stresses()

    @_read
    def wall_forces(self) -> np.ndarray:
        """Total force of the grains on each wall (6, 3) [N]."""
        return self._sim.wall_forces()

    @_read
    def bodies(self) -> Dict[str, np.ndarray]:
        """The rigid bodies beyond the box (the ``body`` section's tables, and a chamber
        sample's chamber and symmetry planes) as columns, one entry per body, so that
        ``pandas.DataFrame(sim.bodies())`` is their table; as the last force evaluation left
        them (``compute_forces()`` brings them up to date without a step).

        ``name``, ``index`` (a wall contact's ``id_j`` in :meth:`contacts`), ``mode`` ("fixed",
        "velocity", "servo"); ``position`` [m] and ``velocity`` [m/s]: the body's degree of
        freedom q and dq/dt (a translation along its direction, or a cylinder's change of
        radius); ``force_x``, ``_y``, ``_z`` [N]: the grains' force on it; ``moment_x``, ``_y``,
        ``_z`` [N m]: their moment about its reference point (its ``origin`` where q has put
        it; NaN when grains were added or moved since the last force evaluation, as the wall
        contacts then no longer match them); ``stress`` [Pa]: its load over its area (NaN for a
        plane given no ``area``). The same values as the time series' ``body_NAME_...``
        columns of a run.
        """
        columns = _columns(self._sim.bodies())
        for name in ("name", "mode"):  # text, also when there is no body
            columns[name] = np.asarray(columns[name], dtype=object)
        return columns

    @_read
    def probe_body(self, name: str, sleeve_length: float = 0.0, bins: int = 1) -> Dict[str, Any]:
        """What the grains do to the pile, cone or shaft ``name``, by part and along its axis:
        the measurements of a penetration test (docs/chamber.md), from the last force
        evaluation.

        ``q_c`` [Pa]: the tip's load over its base area; ``f_s`` [Pa]: the load on the friction
        sleeve (``sleeve_length`` [m] of shaft above the tip, 0: the standard 3.75 diameters)
        over its surface; ``tip_load``, ``shaft_load``, ``sleeve_load`` [N]: the forces
        resisting the advance; ``tip_contacts``, ``shaft_contacts``; ``sigma_r`` and ``tau``
        [Pa]: the radial and shear stress on the shaft in ``bins`` bins of ``bin_height`` [m]
        from the shaft's start up, with ``bin_contacts``; ``tip`` [m], ``radius`` [m] and
        ``sector`` (the fraction of the circumference the grains reach; areas are taken over
        it). Raises :class:`ConfigError` for a body that is not a translating pile, cone, disk
        or outer cylinder, and :class:`RuntimeFailure` when grains were added or moved since
        the last force evaluation (``compute_forces()`` first).
        """
        return dict(self._sim.probe_body(name, sleeve_length=sleeve_length, bins=bins))

    def set_wall(self, name: str, mode: Optional[str] = None, velocity: Optional[float] = None,
                 target_stress: Optional[float] = None, servo_alpha: Optional[float] = None,
                 max_speed: Optional[float] = None) -> None:
        """Changes how wall ``name`` (xmin ... zmax) or body ``name`` (a ``body`` table's
        ``name``) is driven; unspecified settings are kept.

        mode: "fixed", "velocity" or "servo"; velocity [m/s] along the coordinate axis (a
        body's: dq/dt, along its direction or its radius); target_stress [Pa] (compressive);
        servo_alpha [-]; max_speed [m/s]. A servo needs an area: a plane body without ``area``
        cannot be one.
        """
        with self._exclusive("set_wall"):
            self._sim.set_wall(name, mode=mode, velocity=velocity, target_stress=target_stress,
                               servo_alpha=servo_alpha, max_speed=max_speed)

    @_read
    def wall_config(self, name: str) -> Dict[str, Any]:
        """Current settings of wall or body ``name`` as a dict."""
        return self._sim.wall_config(name)

    @_read
    def love_weber_stress(self) -> np.ndarray:
        """Love-Weber stress tensor over the box volume (3, 3) [Pa], compression positive."""
        return self._sim.love_weber_stress()

    @_read
    def kinetic_energy(self) -> float:
        """Translational plus rotational kinetic energy [J]."""
        return self._sim.kinetic_energy()

    @_read
    def config_toml(self) -> str:
        """The configuration this simulation was built with (all keys resolved), as TOML."""
        return self._sim.config_toml()

    @property
    def core(self) -> "_core.Simulation":
        """The underlying C++ object (crushdem_sand._core.Simulation)."""
        return self._sim

    def __repr__(self) -> str:
        try:
            return (f"<crushdem_sand.Simulation: {self.num_particles} particles, "
                    f"t = {self.time:.6g} s, {self.step_count} steps>")
        except RuntimeError:
            return "<crushdem_sand.Simulation: stepping in another thread>"


def _columns(table: Mapping[str, Any]) -> Dict[str, Any]:
    """A table of columns from the engine with each (n, 3) vector split into its ``_x``,
    ``_y`` and ``_z`` columns, for ``pandas.DataFrame``."""
    columns: Dict[str, Any] = {}
    for name, values in table.items():
        values = np.asarray(values)
        if values.ndim == 2:  # a vector per row: one column per axis
            for k, axis in enumerate("xyz"):
                columns[f"{name}_{axis}"] = np.ascontiguousarray(values[:, k])
        else:
            columns[name] = values
    return columns


def parameter_reference() -> Dict[str, str]:
    """The configuration keys that have a parameter table in the engine: {section: Markdown
    table of key, default, unit and meaning}, as in docs/configuration.md ("stage": each stage
    kind's heading and table)."""
    return dict(_core.parameter_reference())


def _parameter_doc() -> str:
    """The keys of the simulation sections as docstring text, from the parameter tables."""
    lines = []
    for section, table in _core.parameter_reference():
        if section not in ("material", "contact", "damping", "timestep", "neighbor"):
            continue
        lines.append(f"``{section}``")
        for row in table.splitlines()[2:]:
            cells = [c.strip() for c in row.strip().strip("|").split(" | ")]
            if len(cells) >= 4:
                key, default, unit, meaning = cells[0], cells[1], cells[2], " | ".join(cells[3:])
                unit = f" [{unit}]" if unit and unit != "-" else ""
                meaning = meaning.replace("\\|", "|")
                lines.append(f"    {key}{unit}, default {default}: {meaning}")
    return "\n".join(lines)


# Cleaned first: CPython 3.13 strips a docstring's indentation when it compiles it, 3.11 does not,
# and the tables appended must read the same under both.
Simulation.__doc__ = (inspect.cleandoc(Simulation.__doc__ or "") + "\n\nParameter tables:\n\n"
                      + _parameter_doc() + "\n")
