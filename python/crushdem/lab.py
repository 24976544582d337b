"""Laboratory tests from Python: the same configurations as the TOML files, run by the same
C++ driver (``crushdem run``), with the results read back as NumPy arrays.

Each function writes a run directory (``timeseries.csv``, ``summary.json``, ``config.toml``,
``vtk/``) and returns a :class:`Result`. ``sample`` is either the path of a prepared sample file
(``sample.txt`` from :func:`prepare_sample`) or a dict of ``[sample]`` keys, in which case the
sample is prepared first in the same run. ``material``, ``contact``, ``damping``, ``timestep``,
``neighbor`` and ``output`` are the sections of docs/configuration.md; ``stage`` keyword
arguments (``tolerance``, ``unbalanced``, ``max_strain_rate``, ``check_interval``,
``max_steps``) are passed to every stage. SI units throughout. ``backend`` chooses what
advances the run: ``"cpu"`` (default), ``"cuda"`` (a GPU, in a build with CUDA) or
``"emulated"`` (the GPU's step run on the host: its results without a GPU); every laboratory
function, sample preparation and resuming take it.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Mapping, Optional, Union

import numpy as np

from . import _core

SampleSpec = Union[str, os.PathLike, Mapping[str, Any]]


class Result:
    """A finished run directory."""

    def __init__(self, directory: str) -> None:
        self.directory = directory

    @property
    def summary(self) -> Dict[str, Any]:
        with open(os.path.join(self.directory, "summary.json")) as f:
            return json.load(f)

    @property
    def timeseries(self) -> Dict[str, np.ndarray]:
        """``timeseries.csv`` as {column: float64 array}."""
        from .rundir import read_timeseries

        return read_timeseries(os.path.join(self.directory, "timeseries.csv"))

    @property
    def timing(self) -> Dict[str, Any]:
        """``timing.json``: wall-clock seconds, threads, particle-steps per second, and
        ``seconds_by_part`` (integration, neighbor_search, contact_forces, crushing,
        ageing_jump, output, other) with the ``dominant_part``."""
        with open(os.path.join(self.directory, "timing.json")) as f:
            return json.load(f)

    @property
    def stages(self) -> List[Dict[str, Any]]:
        return list(self.summary.get("stages", []))

    @property
    def sample_file(self) -> Optional[str]:
        p = os.path.join(self.directory, "sample.txt")
        return p if os.path.exists(p) else None

    def __repr__(self) -> str:
        return f"crushdem.lab.Result({self.directory!r})"


def run(config: Mapping[str, Any], out: Union[str, os.PathLike], *, base_dir: str = ".",
        progress: bool = False, overwrite: bool = False, backend: str = "cpu",
        branch_from: Union[str, os.PathLike, None] = None,
        branch_stage: Union[int, str, None] = None) -> Result:
    """Runs a whole configuration dict (the sections of a run file; ``stage`` a list of dicts).
    ``out`` must be new or empty; ``overwrite=True`` replaces a crushdem run already there (every
    laboratory function below takes it too). ``branch_from``: a run directory whose state at the
    start of stage ``branch_stage`` (index or name; default: the first stage ``config``
    changes) this run starts from, as ``crushdem run --from DIR:STAGE`` (the stages before it
    and the grains must be the original's)."""
    _core.run(dict(config), os.fspath(out), base_dir, progress, overwrite,
              os.fspath(branch_from) if branch_from is not None else "",
              "" if branch_stage is None else str(branch_stage), backend)
    return Result(os.fspath(out))


def resume(out: Union[str, os.PathLike], *, progress: bool = False,
           backend: str = "cpu") -> Result:
    """Continues an interrupted run from ``out/checkpoint.bin`` (written at every ageing event,
    between stages and every ``output.checkpoint_seconds``); the files come out as those of an
    uninterrupted run on the same backend. Raises ValueError if ``out`` has no checkpoint (e.g.
    it has finished)."""
    _core.resume(os.fspath(out), progress, backend)
    return Result(os.fspath(out))


def _base(sample: SampleSpec, sections: Mapping[str, Any]) -> Dict[str, Any]:
    cfg: Dict[str, Any] = {k: dict(v) for k, v in sections.items() if v is not None}
    if isinstance(sample, Mapping):
        cfg["sample"] = dict(sample)
    else:
        cfg["particles"] = {"file": os.path.abspath(os.fspath(sample))}
    return cfg


def _stage(kind: str, name: str, common: Mapping[str, Any], **keys: Any) -> Dict[str, Any]:
    st = {"type": kind, "name": name}
    st.update({k: v for k, v in keys.items() if v is not None})
    st.update(common)
    return st


def prepare_sample(out: Union[str, os.PathLike], *, side: Optional[float] = None,
                   count: Optional[int] = None, void_ratio: float = 0.65,
                   grading: Optional[Mapping[str, Any]] = None, seed: int = 1,
                   stress: float = 100e3, progress: bool = False, overwrite: bool = False,
                   backend: str = "cpu",
                   material: Optional[Mapping[str, Any]] = None,
                   contact: Optional[Mapping[str, Any]] = None,
                   output: Optional[Mapping[str, Any]] = None, **sample_keys: Any) -> Result:
    """Prepares a sample from a grading curve (``[sample]``); ``Result.sample_file`` is the
    reusable ``sample.txt``. ``grading`` = {"diameter": [...m], "passing": [...0-1]}; default
    NE34-like. Other ``[sample]`` keys (``tolerance``, ``friction_start``, ...) pass through."""
    s: Dict[str, Any] = {"void_ratio": void_ratio, "seed": seed, "stress": stress}
    if side is not None:
        s["side"] = side
    if count is not None:
        s["count"] = count
    if grading is not None:
        s["grading"] = dict(grading)
    s.update(sample_keys)
    cfg = _base(s, {"material": material, "contact": contact, "output": output})
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend)


def isotropic_test(out: Union[str, os.PathLike], sample: SampleSpec, *, stress: float,
                   progress: bool = False, overwrite: bool = False, backend: str = "cpu",
                   stage: Optional[Mapping[str, Any]] = None,
                   **sections: Any) -> Result:
    """All six walls servo-controlled to ``stress`` until equilibrium."""
    cfg = _base(sample, sections)
    cfg["stage"] = [_stage("isotropic", "isotropic", stage or {}, stress=stress)]
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend)


def oedometric_test(out: Union[str, os.PathLike], sample: SampleSpec, *, stress: float,
                    strain_rate: float = 10.0, hold_steps: int = 0,
                    unload_to: Optional[float] = None, progress: bool = False,
                    overwrite: bool = False, backend: str = "cpu",
                    stage: Optional[Mapping[str, Any]] = None, **sections: Any) -> Result:
    """Lateral walls fixed; the top loads at ``strain_rate`` to the vertical ``stress``, holds
    for ``hold_steps`` (walls fixed) and unloads to ``unload_to`` when given."""
    common = stage or {}
    cfg = _base(sample, sections)
    stages = [_stage("oedometric", "loading", common, stress=stress, strain_rate=strain_rate)]
    if hold_steps > 0:
        stages.append(_stage("hold", "hold", common, steps=hold_steps))
    if unload_to is not None:
        stages.append(_stage("oedometric", "unloading", common, stress=unload_to,
                             strain_rate=-abs(strain_rate)))
    cfg["stage"] = stages
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend)


def triaxial_test(out: Union[str, os.PathLike], sample: SampleSpec, *, sigma_3: float,
                  strain_rate: float = 50.0, axial_strain: float = 0.30,
                  stop_q: Optional[float] = None, hold_steps: int = 0,
                  consolidate: bool = True, progress: bool = False, overwrite: bool = False,
                  backend: str = "cpu",
                  stage: Optional[Mapping[str, Any]] = None, **sections: Any) -> Result:
    """Drained triaxial shear: isotropic compression to ``sigma_3`` (unless ``consolidate`` is
    False), then axial compression at ``strain_rate`` with the lateral walls servo-controlled at
    ``sigma_3``, to ``axial_strain`` or until q reaches ``stop_q``; then, if ``hold_steps``, the
    axial strain is held (axial walls fixed, lateral servo kept)."""
    common = stage or {}
    cfg = _base(sample, sections)
    stages = []
    if consolidate:
        stages.append(_stage("isotropic", "isotropic", common, stress=sigma_3))
    stages.append(_stage("triaxial", "shear", common, sigma_3=sigma_3, strain_rate=strain_rate,
                         axial_strain=axial_strain, stop_q=stop_q))
    if hold_steps > 0:
        stages.append(_stage("hold", "hold", common, steps=hold_steps, axial="fixed",
                             lateral="servo", lateral_stress=sigma_3))
    cfg["stage"] = stages
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend)


def _crushing_with_cracks(sections: Dict[str, Any]) -> None:
    crushing = dict(sections.get("crushing") or {})
    crushing.setdefault("crack_growth", True)
    sections["crushing"] = crushing


def oedometric_relaxation(out: Union[str, os.PathLike], sample: SampleSpec, *, stress: float,
                          duration: float = 86400.0, strain_rate: float = 10.0,
                          min_cycles: int = 150000, n_break: int = 30,
                          progress: bool = False, overwrite: bool = False, backend: str = "cpu",
                          stage: Optional[Mapping[str, Any]] = None,
                          age_stage: Optional[Mapping[str, Any]] = None,
                          branch_from: Union[str, os.PathLike, None] = None,
                          **sections: Any) -> Result:
    """Oedometric stress relaxation (study section 3.1): load to the vertical ``stress`` with
    crushing on, fix the walls, age for ``duration`` seconds of ageing time with the on-off
    scheme. ``crushing`` keys pass through (crack growth is turned on). ``age_stage``: keys for
    the age stage only (e.g. ``max_strain_rate``), on top of the common ``stage`` keys.
    ``branch_from``: an oedometric relaxation with the same loading whose state at the start of
    its ageing this run starts from (another ``n_break`` or ``min_cycles`` without loading
    again)."""
    common = stage or {}
    _crushing_with_cracks(sections)
    cfg = _base(sample, sections)
    cfg["stage"] = [
        _stage("oedometric", "loading", common, stress=stress, strain_rate=strain_rate),
        _stage("age", "relaxation", {**common, **(age_stage or {})}, duration=duration,
               min_cycles=min_cycles, n_break=n_break),
    ]
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend,
               branch_from=branch_from,
               branch_stage=None if branch_from is None else "relaxation")


def creep_test(out: Union[str, os.PathLike], sample: SampleSpec, *, stress: float,
               duration: float = 86400.0, strain_rate: float = 10.0, min_cycles: int = 150000,
               n_break: int = 30, progress: bool = False, overwrite: bool = False,
               backend: str = "cpu",
               stage: Optional[Mapping[str, Any]] = None,
               age_stage: Optional[Mapping[str, Any]] = None, **sections: Any) -> Result:
    """Oedometric creep: load to the vertical ``stress``, then hold it by servo control of the
    top wall during every dynamic phase while the sample ages; the axial strain against ageing
    time is the creep curve (``events.csv``). ``age_stage``: keys for the age stage only."""
    common = stage or {}
    _crushing_with_cracks(sections)
    cfg = _base(sample, sections)
    cfg["stage"] = [
        _stage("oedometric", "loading", common, stress=stress, strain_rate=strain_rate),
        _stage("age", "creep", {**common, **(age_stage or {})}, duration=duration,
               min_cycles=min_cycles, n_break=n_break, axial="servo", axial_stress=stress),
    ]
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend)


def triaxial_relaxation(out: Union[str, os.PathLike], sample: SampleSpec, *, sigma_3: float,
                        stop_q: float, duration: float = 86400.0, strain_rate: float = 50.0,
                        axial_strain: float = 0.30, min_cycles: int = 150000,
                        n_break: int = 30, progress: bool = False, overwrite: bool = False,
                        backend: str = "cpu",
                        stage: Optional[Mapping[str, Any]] = None,
                        age_stage: Optional[Mapping[str, Any]] = None,
                        branch_from: Union[str, os.PathLike, None] = None,
                        **sections: Any) -> Result:
    """Triaxial stress relaxation (study section 3.2): isotropic compression to ``sigma_3``,
    shear until q reaches ``stop_q`` (e.g. 0.7 q_max), then hold the axial strain with the
    lateral walls servo-controlled at ``sigma_3`` during dynamic phases, and age.
    ``age_stage``: keys for the age stage only (e.g. a faster lateral servo,
    ``max_strain_rate``, which the other stages must not get). ``branch_from``: a
    ``triaxial_test`` (or relaxation) with the same grains, settings and isotropic compression
    whose state at the start of its shear this run starts from, instead of compressing again;
    the results are those of the unbranched run."""
    common = stage or {}
    _crushing_with_cracks(sections)
    cfg = _base(sample, sections)
    cfg["stage"] = [
        _stage("isotropic", "isotropic", common, stress=sigma_3),
        _stage("triaxial", "shear", common, sigma_3=sigma_3, strain_rate=strain_rate,
               axial_strain=axial_strain, stop_q=stop_q),
        _stage("age", "relaxation", {**common, **(age_stage or {})}, duration=duration,
               min_cycles=min_cycles, n_break=n_break, axial="fixed", lateral="servo",
               lateral_stress=sigma_3),
    ]
    return run(cfg, out, progress=progress, overwrite=overwrite, backend=backend,
               branch_from=branch_from, branch_stage=None if branch_from is None else "shear")
