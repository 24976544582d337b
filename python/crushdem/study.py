"""The reference study's parameters, written once ("Discrete modelling of stress relaxation in
crushable sands based on fracture theory"; docs/model.md): Table 1 (material, rough contact law,
grain strength and crack growth), the NE34 grading, crushdem's chosen parameter set, and the
study's own results that a reproduction is compared with. ``crushdem reproduce``,
``crushdem sensitivity`` and the tests read them from here."""

from __future__ import annotations

from typing import Any, Dict, Tuple

# Table 1 of the study (docs/model.md 1-3) with the first reconstruction choices: free rotation
# (no key: the engine's default) and d0 = d50 (no key). The crushing keys are those of
# examples/*crushing.toml.
MATERIAL = {"density": 2650.0, "shear_modulus": 32e9, "poisson_ratio": 0.19, "friction": 0.275}
TABLE1_CONTACT = {"law": "rough", "roughness_Sq": 0.6e-6, "k1": 0.05, "k2": 5.0}
NE34 = {"diameter": [0.12e-3, 0.15e-3, 0.18e-3, 0.21e-3, 0.23e-3, 0.25e-3, 0.27e-3],
        "passing": [0.0, 0.10, 0.30, 0.50, 0.70, 0.90, 1.0]}
# density_scaling as in examples/relaxation_small.toml and the runs of docs/crushing.md: the
# fragments keep the initial time step (14-fragment splitting would lower it about five times,
# which a one-day relaxation of 150,000-cycle phases cannot afford); only inertia changes, and the
# inertial number is reported per stage.
TABLE1_CRUSHING = {"sigma_lim0": 3.75e9, "weibull_m": 12.0, "var": 0.38, "distribution": "normal",
                   "r_prime": "R_star", "dc_ratio": 0.55, "d_min": 0.01e-3, "crack_growth": True,
                   "v0": 0.1, "n": 60.0, "density_scaling": True}
# crushdem's parameter set for the study, chosen by the decision study of docs/crushing.md
# ("Which rotation model and which grain strength"): Table 1 with rotation blocked (Table 1 lists
# no rotation model; free spheres cannot reach the study's strength) and d0 = 1.07 mm (a d50
# grain breaks between platens at F / d^2 = 0.50 GPa, the top of the 0.05-0.5 GPa accepted for
# quartz grains: the study's q_max needs the strongest grains the band allows).
CONTACT = {**TABLE1_CONTACT, "rotation": "blocked"}
CRUSHING = {**TABLE1_CRUSHING, "d0": 1.07e-3}
# Named parameter sets of `crushdem reproduce --parameters`: (contact, crushing, what it is).
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
