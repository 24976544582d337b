"""Every configuration in examples/ passes `crushdem-sand check`: the examples are the documented
way in, and a renamed or retyped key must not leave one of them failing at its first run (hours
later, for the study-scale ones)."""

import glob
import os
import re
import shutil
import tomllib

import pytest

import crushdem_sand

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXAMPLES = sorted(glob.glob(os.path.join(ROOT, "examples", "*.toml")))

# The *_rev examples read the prepared REV (`runs/sample_rev/sample.txt`); a few grains in a
# file of the same format stand in for it, so that the check covers everything else.
SAMPLE = """# box_xmin=0.0005
# box_xmax=0.0045
# box_ymin=0.0005
# box_ymax=0.0045
# box_zmin=0.0005
# box_zmax=0.0045
0 0.0015 0.0015 0.0015 0.00013
1 0.0030 0.0030 0.0030 0.00012
"""


PAGES = sorted(glob.glob(os.path.join(ROOT, "docs", "*.md"))) + [os.path.join(ROOT, "README.md")]


def _expand(name):
    """"examples/{a,b}_rev.toml" -> ["examples/a_rev.toml", "examples/b_rev.toml"]."""
    m = re.search(r"\{([^{}]*)\}", name)
    if not m:
        return [name]
    return [n for alt in m.group(1).split(",")
            for n in _expand(name[:m.start()] + alt + name[m.end():])]


def _named_in_the_docs():
    named = set()
    for page in PAGES:
        with open(page, encoding="utf-8") as f:
            text = f.read()
        for m in re.finditer(r"(?<![\w/{},.-])((?:examples/)?[\w{},.-]+\.toml)", text):
            named |= {os.path.basename(n) for n in _expand(m.group(1))}
    return named


def test_every_example_says_what_it_is_and_a_page_names_it():
    assert len(EXAMPLES) >= 10
    named = _named_in_the_docs()
    assert {"sample_rev.toml", "isotropic_small.toml"} <= named  # braces expanded too
    for path in EXAMPLES:
        with open(path) as f:
            first = f.readline()
        assert first.startswith("# ") and len(first) > 40, path
        assert os.path.basename(path) in named, f"{path}: no page of docs/ or README names it"


@pytest.mark.parametrize("path", EXAMPLES, ids=os.path.basename)
def test_example_is_the_study_material_at_the_scale_its_name_says(path):
    # Every example is the reference study's quartz (crushdem_sand.study: Table 1, the NE34 grading,
    # the grain strength); *_rev ones run on the 4 mm REV (prepared by sample_rev.toml), *_small
    # ones on at most 1,500 grains, *_crushing ones break grains.
    from crushdem_sand import study

    with open(path, "rb") as f:
        cfg = tomllib.load(f)
    name = os.path.basename(path)
    assert cfg["material"] == study.MATERIAL
    assert {k: v for k, v in cfg["contact"].items() if k in study.ROUGH_LAW} == study.ROUGH_LAW
    sample, particles = cfg.get("sample", {}), cfg.get("particles", {})
    if "grading" in sample:
        assert sample["grading"] == study.NE34
    strength = {k: v for k, v in cfg.get("crushing", {}).items() if k in ("sigma_lim0", "weibull_m",
                                                                          "var", "distribution")}
    assert strength == {k: study.TABLE1_CRUSHING[k] for k in strength}
    if "_rev" in name:
        if name == "sample_rev.toml":
            assert sample["side"] == 4e-3
        else:
            assert particles["file"] == "../runs/sample_rev/sample.txt"
    if "_small" in name:
        count = sample.get("count", particles.get("generate", {}).get("count"))
        assert count is not None and count <= 1500
    if "crushing" in name:
        assert "crushing" in cfg and cfg["crushing"].get("enabled", True), name


@pytest.mark.parametrize("path", EXAMPLES, ids=os.path.basename)
def test_example_passes_check(path, tmp_path, capfd):
    (tmp_path / "examples").mkdir()
    target = tmp_path / "examples" / os.path.basename(path)
    shutil.copy(path, target)
    # The prepared sample it reads (the REV's, the K0 chamber's), stood in for by a few grains.
    with open(path, "rb") as f:
        file = tomllib.load(f).get("particles", {}).get("file", "../runs/sample_rev/sample.txt")
    sample = tmp_path / "examples" / file
    sample.parent.mkdir(parents=True, exist_ok=True)
    sample.write_text(SAMPLE)
    rc = crushdem_sand.cli_main(["check", str(target)])
    out, err = capfd.readouterr()
    assert rc == 0, err
    # Every example runs crushdem's parameter set, and check says so.
    assert 'parameters = "crushdem" (the default)' in out, out
