"""Several reproductions side by side (``crushdem-sand reproduce --summarize DIR...``): the triaxial
figures of samples of one recipe with their mean, standard deviation and standard error, and the
mean q_max against the study's; with ``--against``, two recipes paired by sample, the mean
difference with its standard error. Reads the reproduction directories; writes nothing."""

from __future__ import annotations

import json
import math
import os
from typing import Any, Dict, List, Mapping, Sequence, Tuple

import numpy as np

from .rundir import is_finished, read_summary
from .study import STUDY_Q_MAX_PA, recipe, sample_recipe, settings_changes
from .study_analysis import shear_plateau, triaxial_stage

SAMPLE_FIGURES = ("q_max_Pa", "axial_strain_at_q_max", "friction_angle_peak_deg",
                  "q_plateau_Pa", "q_ratio_1h", "q_ratio_1day", "r2", "sigma_v_ratio_1day",
                  "oedometric_r2")
# The relaxation figures --summarize reads from a directory's reproduce.json once the run has
# finished there: run -> {column: key in reproduce.json's entry of that run}.
RELAXATION_FIGURES = {
    "triaxial_relaxation": {"q_ratio_1h": "q_ratio_1h", "q_ratio_1day": "q_ratio_1day",
                            "r2": "r2"},
    "oedometric_relaxation": {"sigma_v_ratio_1day": "sigma_v_ratio_1day",
                              "oedometric_r2": "r2"}}
PAIRED_FIGURES = ("q_max_Pa", "q_plateau_Pa", "axial_strain_at_q_max")


def sample_of(d: str, cfg: Mapping[str, Any]) -> Dict[str, Any]:
    """The sample a reproduce directory ran on: the real path of its particle file
    (``sample_file``), its ``seed`` (None for a ``--sample`` file), a short ``label`` and the
    sample run's summary entry (``info``: grains, e). The file is DIR/sample/sample.txt, or the
    ``--sample`` file the settings name (its summary then the one beside it)."""
    sample = cfg.get("sample") or {}
    given = sample.get("file")
    path = os.path.realpath(given or os.path.join(d, "sample", "sample.txt"))
    info: Dict[str, Any] = {}
    if os.path.isfile(os.path.join(os.path.dirname(path), "summary.json")):
        info = read_summary(os.path.dirname(path)).get("sample") or {}
    seed = None if given else sample.get("seed")
    label = given or (f"seed {seed}" if seed is not None else path)
    return {"sample_file": path, "seed": seed, "label": label, "info": info}


def summarize_samples(out_dirs: Sequence[str]) -> Dict[str, Any]:
    """The triaxial figures of several ``crushdem-sand reproduce`` directories (samples of one
    recipe: ``--set sample.seed=K``, or prepared samples given by ``--sample``) side by side,
    with their mean, standard deviation (n - 1) and standard error, and the mean q_max against
    the study's.

    Each directory needs a finished triaxial shear; the relaxation figures (q(1 h)/q(0),
    q(1 day)/q(0), R^2) come from its reproduce.json when the triaxial relaxation has finished
    there, and are left empty otherwise. Raises ValueError naming a directory without a
    finished shear, or directories made with different settings apart from the sample."""
    if not out_dirs:
        raise ValueError("--summarize: expected one or more reproduce directories")
    rows: List[Dict[str, Any]] = []
    first = None
    first_sample = None
    for d in out_dirs:
        shear_dir = os.path.join(d, "triaxial_shear")
        if not is_finished(shear_dir):
            raise ValueError(f"{d}: no finished triaxial shear ({shear_dir}/summary.json)")
        settings_path = os.path.join(d, "settings.json")
        cfg: Dict[str, Any] = {}
        if os.path.isfile(settings_path):
            with open(settings_path) as f:
                cfg = json.load(f)
        same = recipe(cfg)
        if first is None:
            first = (d, same, cfg)
        elif same != first[1]:
            raise ValueError(f"{d}: made with other settings than {first[0]} (settings.json "
                             "differs in more than the sample); compare samples of one "
                             "recipe, or two recipes with --against")
        made = sample_recipe(cfg)
        if made is not None:
            if first_sample is None:
                first_sample = (d, made)
            elif made != first_sample[1]:
                raise ValueError(f"{d}: prepares its sample otherwise than {first_sample[0]} "
                                 "(settings.json sample differs in more than the seed)")
        shear = triaxial_stage(read_summary(shear_dir))
        used = sample_of(d, cfg)
        info = used["info"]
        row: Dict[str, Any] = {
            "dir": d, "sample": used["label"], "sample_file": used["sample_file"],
            "seed": used["seed"],
            "grains": info.get("grains"), "void_ratio": info.get("void_ratio"),
            "q_max_Pa": shear.get("q_max_Pa", math.nan),
            "axial_strain_at_q_max": shear.get("axial_strain_at_q_max", math.nan),
            "friction_angle_peak_deg": shear.get("friction_angle_peak_deg", math.nan),
            **shear_plateau(shear_dir)}
        drawn: Dict[str, Any] = {}
        try:
            with open(os.path.join(d, "reproduce.json")) as f:
                drawn = json.load(f)
        except (OSError, ValueError):
            drawn = {}
        for run, figures in RELAXATION_FIGURES.items():
            found = (drawn.get(run) or {}) if is_finished(os.path.join(d, run)) else {}
            for column_name, key in figures.items():
                v = found.get(key)
                row[column_name] = float(v) if isinstance(v, (int, float)) else math.nan
        rows.append(row)
    q = stats(rows, SAMPLE_FIGURES)
    return {"samples": rows, "stats": q, "settings": first[2] if first else {},
            "sample_recipe": first_sample[1] if first_sample else None,
            "study_q_max_Pa": STUDY_Q_MAX_PA,
            "q_max_mean_vs_study": q["q_max_Pa"]["mean"] / STUDY_Q_MAX_PA - 1.0,
            "q_max_sem_vs_study": q["q_max_Pa"]["sem"] / STUDY_Q_MAX_PA}


def stats(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> Dict[str, Dict[str, Any]]:
    """Per key: n, mean, standard deviation (n - 1) and standard error over the finite
    values."""
    out: Dict[str, Dict[str, Any]] = {}
    for k in keys:
        v = np.array([float(r[k]) if r.get(k) is not None else math.nan for r in rows])
        v = v[np.isfinite(v)]
        std = float(np.std(v, ddof=1)) if v.size > 1 else math.nan
        out[k] = {"n": int(v.size), "mean": float(np.mean(v)) if v.size else math.nan,
                  "std": std, "sem": std / math.sqrt(v.size) if v.size > 1 else math.nan}
    return out


def compare_recipes(variant_dirs: Sequence[str], base_dirs: Sequence[str]) -> Dict[str, Any]:
    """Two recipes on the same samples: each directory of ``variant_dirs`` is paired with the
    one of ``base_dirs`` that ran on the same sample (the same particle file: a base's own
    DIR/sample/sample.txt given to the variant by ``--sample``, or the same seed), and the
    differences variant - base of q_max, the plateau and the strain at q_max are averaged with
    their standard error. On one packing the sample-to-sample scatter cancels, so a change of
    a choice shows with fewer runs. Raises ValueError for a variant without a base on its
    sample, or when the two recipes have the same settings."""
    variant = summarize_samples(variant_dirs)
    base = summarize_samples(base_dirs)
    changed = settings_changes(recipe(base["settings"]), recipe(variant["settings"]))
    if not changed:
        raise ValueError("--against: the two groups were made with the same settings; "
                         "--summarize them together instead")
    # One seed of one sample recipe is one packing (preparation is deterministic).
    same_recipe = (variant["sample_recipe"] is not None and
                   variant["sample_recipe"] == base["sample_recipe"])

    def keys(r: Mapping[str, Any]) -> List[Tuple[str, Any]]:
        out: List[Tuple[str, Any]] = [("file", r["sample_file"])]
        if same_recipe and r["seed"] is not None:
            out.append(("seed", r["seed"]))
        return out

    by_sample: Dict[Tuple[str, Any], Mapping[str, Any]] = {}
    for r in base["samples"]:
        for k in keys(r):
            if k in by_sample:
                raise ValueError(f"{r['dir']} and {by_sample[k]['dir']}: both ran on "
                                 f"{r['sample']}; give one directory per sample")
            by_sample[k] = r
    pairs: List[Dict[str, Any]] = []
    for r in variant["samples"]:
        b = next((by_sample[k] for k in keys(r) if k in by_sample), None)
        if b is None:
            raise ValueError(f"{r['dir']}: no directory of --against ran on its sample "
                             f"({r['sample']})")
        if any(p["base_dir"] == b["dir"] for p in pairs):
            raise ValueError(f"{r['dir']}: another directory ran on its sample "
                             f"({r['sample']}); give one directory per sample")
        pair: Dict[str, Any] = {"sample": b["sample"], "base_dir": b["dir"], "dir": r["dir"]}
        for k in PAIRED_FIGURES:
            pair[f"base_{k}"], pair[k] = b[k], r[k]
            pair[f"delta_{k}"] = float(r[k]) - float(b[k])
        pairs.append(pair)
    return {"changed": changed, "pairs": pairs,
            "stats": stats(pairs, [f"delta_{k}" for k in PAIRED_FIGURES]),
            "variant": variant, "base": base}
