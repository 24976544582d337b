"""The reference study's recipes, written once ("Discrete modelling of stress relaxation in
crushable sands based on fracture theory"; docs/model.md): Table 1 (material, rough contact law,
grain strength and crack growth), the NE34 grading, crushdem's chosen parameter set, the study's
own results that a reproduction is compared with, and the settings of every run of
``crushdem-sand reproduce`` (:func:`settings`, changed by ``--set``: :func:`apply_overrides`).
``crushdem-sand reproduce``, ``crushdem-sand sensitivity`` and the tests read them from here.

A settings dict is plain JSON (``DIR/settings.json`` of a reproduction); nothing here runs,
reads or draws."""

from __future__ import annotations

import json
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

# Table 1 of the study (docs/model.md 1-3) with the first reconstruction choices: free rotation
# and d0 = d50 (0), the engine's parameter set "table1" (`parameters = "table1"`; a test checks
# that the two agree).
MATERIAL = {"density": 2650.0, "shear_modulus": 32e9, "poisson_ratio": 0.19, "friction": 0.275}
ROUGH_LAW = {"law": "rough", "roughness_Sq": 0.6e-6, "k1": 0.05, "k2": 5.0}
TABLE1_CONTACT = {**ROUGH_LAW, "rotation": "free"}
NE34 = {"diameter": [0.12e-3, 0.15e-3, 0.18e-3, 0.21e-3, 0.23e-3, 0.25e-3, 0.27e-3],
        "passing": [0.0, 0.10, 0.30, 0.50, 0.70, 0.90, 1.0]}
# density_scaling as in examples/relaxation_small.toml and the runs of docs/crushing.md: the
# fragments keep the initial time step (14-fragment splitting would lower it about five times,
# which a one-day relaxation of 150,000-cycle phases cannot afford); only inertia changes, and the
# inertial number is reported per stage.
TABLE1_CRUSHING = {"sigma_lim0": 3.75e9, "weibull_m": 12.0, "var": 0.38, "distribution": "normal",
                   "r_prime": "R_star", "dc_ratio": 0.55, "d_min": 0.01e-3, "crack_growth": True,
                   "v0": 0.1, "n": 60.0, "density_scaling": True, "d0": 0.0}
# crushdem's parameter set for the study (the engine's default set, "crushdem"), chosen by the
# decision study of docs/crushing.md
# ("Which rotation model and which grain strength"): Table 1 with rotation blocked (Table 1 lists
# no rotation model; free spheres cannot reach the study's strength) and d0 = 1.07 mm (a d50
# grain breaks between platens at F / d^2 = 0.50 GPa, the top of the 0.05-0.5 GPa accepted for
# quartz grains: the study's q_max needs the strongest grains the band allows).
CONTACT = {**TABLE1_CONTACT, "rotation": "blocked"}
CRUSHING = {**TABLE1_CRUSHING, "d0": 1.07e-3}
# Named parameter sets of `crushdem-sand reproduce --parameters`: (contact, crushing, what it is).
PARAMETER_SETS: Dict[str, Tuple[Dict[str, Any], Dict[str, Any], str]] = {
    "crushdem": (CONTACT, CRUSHING,
                 "Table 1 with rotation blocked and d0 = 1.07 mm (the decision study's choice)"),
    "blocked_d0_1mm": (CONTACT, {**CRUSHING, "d0": 1e-3},
                       "Table 1 with rotation blocked and d0 = 1 mm (crushdem's set before "
                       "d0 = 1.07 mm: q_max 5.5 % low on four samples)"),
    "table1": (TABLE1_CONTACT, TABLE1_CRUSHING,
               "Table 1 with free rotation and d0 = d50 (the earlier defaults: q_max 8.5 MPa)"),
}

# The tests of the study's section 3.
OEDOMETRIC_STRESS_PA = 7.5e6   # the oedometric relaxation starts at sigma_v = 7.5 MPa
SIGMA_3_PA = 10e6              # the triaxial shear and relaxation at sigma_3 = 10 MPa
STUDY_Q_MAX_PA = 22.6e6        # the study's q_max at sigma_3 = 10 MPa (section 3.2)

# The run directories of a reproduction, in the order they run.
RUNS = ("sample", "oedometric_relaxation", "triaxial_shear", "triaxial_relaxation")
TESTS = ("oedometric", "triaxial")  # --only: the runs of each besides the sample
TEST_RUNS = {"oedometric": ("oedometric_relaxation",),
             "triaxial": ("triaxial_shear", "triaxial_relaxation")}


def settings(quick: bool, parameters: str = "crushdem", backend: str = "cpu") -> Dict[str, Any]:
    """The parameters of every run, study scale or ``--quick``, with the named parameter set
    ``parameters`` (PARAMETER_SETS), as one JSON-able dict; ``backend`` (what advances the runs:
    "cpu", "cuda" or "emulated") is recorded when it is not the CPU, since the backends agree
    only statistically."""
    if parameters not in PARAMETER_SETS:
        raise ValueError(f"--parameters {parameters!r}: expected one of "
                         f"{', '.join(PARAMETER_SETS)}")
    contact, crushing, _ = PARAMETER_SETS[parameters]
    s: Dict[str, Any] = {
        "mode": "quick" if quick else "study",
        "material": dict(MATERIAL),
        "contact": dict(contact),
        "crushing": dict(crushing),
        "sample": {"side": 4e-3, "void_ratio": 0.65, "seed": 1, "stress": 100e3,
                   "grading": NE34},
        "oedometric": {"stress": OEDOMETRIC_STRESS_PA, "strain_rate": 10.0},
        "triaxial": {"sigma_3": SIGMA_3_PA, "strain_rate": 50.0, "axial_strain": 0.30},
        "relaxation": {"q_fraction": 0.7},
        # The study: dynamic phases of at least 150,000 cycles, N_break = 30, one day.
        "age": {"duration": 86400.0, "min_cycles": 150000, "n_break": 30},
        "age_stage": {},
        "record_interval": None,  # phases.csv rows: the C++ default (1000 steps)
        "output": {"interval": 20000, "progress_seconds": 60},
    }
    if parameters != "crushdem":
        s["parameters"] = parameters
    if backend != "cpu":
        s["backend"] = backend
    if quick:
        s["sample"] = {"count": 500, "void_ratio": 0.75, "seed": 3, "stress": 100e3,
                       "grading": NE34}
        # Faster loading and shearing: the inertial number stays below 1e-3 (about 8.6e-4 and
        # 7e-4, reported in summary.json); shear to 15 % only (q still rises slowly there).
        s["oedometric"]["strain_rate"] = 25.0
        s["triaxial"].update(strain_rate=100.0, axial_strain=0.15)
        s["age"].update(min_cycles=10000, n_break=3)
        # A phase must be long enough for the lateral servo to restore sigma_3 after the grains
        # of a jump break; the quick sample needs a few tenths of a percent of lateral strain.
        # At the default limit (10 /s) a 10,000-cycle phase (dt about 6.6e-9 s) allows 0.07 %
        # (the study's 150,000 cycles about 1 %); with 3,000 cycles even 100 /s left the walls at
        # their limit for the whole phase and sigma_3 16 % low. Hence 10,000 cycles and 100 /s
        # (inertial number below 4e-4), in the age stage only.
        s["age_stage"] = {"max_strain_rate": 100.0}
        s["record_interval"] = 500
        s["output"] = {"interval": 1000, "progress_seconds": 0}
    return s


def with_earlier_defaults(settings: Mapping[str, Any]) -> Dict[str, Any]:
    """Settings written before the engine's defaults became crushdem's set named neither
    contact.rotation nor crushing.d0 where they ran the engine's earlier defaults, free rotation
    and d0 = d50 (0): ``settings`` with those two keys filled in where absent, to compare with
    settings of today."""
    out = json.loads(json.dumps(settings))
    if isinstance(out.get("contact"), dict):
        out["contact"].setdefault("rotation", TABLE1_CONTACT["rotation"])
    if isinstance(out.get("crushing"), dict):
        out["crushing"].setdefault("d0", TABLE1_CRUSHING["d0"])
    return out


# Sections of settings() that --set may change, and whether it may add keys to them (the
# configuration sections are checked by the engine's reader, which names a bad key).
SETTABLE = {"material": True, "contact": True, "crushing": True, "age_stage": True,
            "sample": False, "oedometric": False, "triaxial": False, "relaxation": False,
            "age": False}


def apply_overrides(cfg: Dict[str, Any], overrides: Sequence[str]) -> Dict[str, Any]:
    """``cfg`` with each "SECTION.KEY=VALUE" of ``overrides`` set; VALUE is read as a TOML value
    (``0.3``, ``true``, ``"blocked"``), or taken as a string when it is not one."""
    import tomllib

    for item in overrides:
        target, sep, text = item.partition("=")
        section, dot, key = target.strip().partition(".")
        if not sep or not dot or not key:
            raise ValueError(f"--set {item!r}: expected SECTION.KEY=VALUE "
                             "(e.g. contact.rotation=blocked)")
        if section not in SETTABLE:
            raise ValueError(f"--set {item!r}: unknown section '{section}' (expected one of "
                             f"{', '.join(SETTABLE)})")
        if not SETTABLE[section] and key not in cfg[section]:
            raise ValueError(f"--set {item!r}: unknown key '{key}' in '{section}' (expected one "
                             f"of {', '.join(cfg[section])})")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        cfg[section][key] = value
    return cfg


def settings_changes(before: Mapping[str, Any], after: Mapping[str, Any]
                     ) -> Dict[str, List[Any]]:
    """The dotted keys whose values differ between two settings dicts: {key: [before, after]}
    (None where a key is absent), sorted by key."""
    fa, fb = _flat(before), _flat(after)
    return {k: [fa.get(k), fb.get(k)] for k in sorted(set(fa) | set(fb))
            if fa.get(k) != fb.get(k)}


def show_setting(v: Any) -> str:
    """A setting's value as the messages show it: JSON, or "(unset)" for None."""
    return "(unset)" if v is None else json.dumps(v)


def _flat(cfg: Mapping[str, Any], prefix: str = "") -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for k, v in cfg.items():
        if isinstance(v, Mapping):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def recipe(cfg: Mapping[str, Any]) -> Dict[str, Any]:
    """The settings apart from the sample: what a test does to whichever sample it gets."""
    return {k: v for k, v in cfg.items() if k != "sample"}


def sample_recipe(cfg: Mapping[str, Any]) -> Optional[Dict[str, Any]]:
    """How the settings prepare their own sample, apart from the seed (None for a --sample
    file, made elsewhere)."""
    sample = cfg.get("sample") or {}
    if "file" in sample:
        return None
    return {k: v for k, v in sample.items() if k != "seed"}
