"""Every configuration in examples/ passes `crushdem check`: the examples are the documented way
in, and a renamed or retyped key must not leave one of them failing at its first run (hours
later, for the study-scale ones)."""

import glob
import os
import shutil

import pytest

import crushdem

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


def test_there_are_examples():
    assert len(EXAMPLES) >= 10


@pytest.mark.parametrize("path", EXAMPLES, ids=os.path.basename)
def test_example_passes_check(path, tmp_path, capfd):
    (tmp_path / "examples").mkdir()
    target = tmp_path / "examples" / os.path.basename(path)
    shutil.copy(path, target)
    sample = tmp_path / "runs" / "sample_rev" / "sample.txt"
    sample.parent.mkdir(parents=True)
    sample.write_text(SAMPLE)
    rc = crushdem.cli_main(["check", str(target)])
    assert rc == 0, capfd.readouterr().err
