"""The ``crushdem`` console command (python/crushdem/__main__.py): every command, the Python ones
(plot, reproduce, sensitivity) and the C++ ones (run, resume, check, bench), answers -h/--help
with its usage and exit status 0, and --version works after any command."""

import pytest

import crushdem
from crushdem.__main__ import main


def _run(args, capfd):
    with pytest.raises(SystemExit) as stop:
        main(list(args))
    out, err = capfd.readouterr()
    return stop.value.code, out, err


@pytest.mark.parametrize("command, option", [
    ("plot", "DIR"), ("reproduce", "--set"), ("sensitivity", "--only"), ("run", "--overwrite"),
    ("resume", "DIR"), ("check", "CONFIG"), ("bench", "--settle")])
def test_every_command_has_help(command, option, capfd):
    for flag in ("-h", "--help"):
        code, out, _ = _run([command, flag], capfd)
        assert code == 0
        assert "crushdem " + command in out and option in out


def test_top_level_help_lists_every_command(capfd):
    code, out, _ = _run(["--help"], capfd)
    assert code == 0
    for command in ("run", "resume", "check", "bench", "plot", "reproduce", "sensitivity"):
        assert command in out


@pytest.mark.parametrize("args", [["--version"], ["plot", "DIR", "--version"],
                                  ["run", "x.toml", "--version"]])
def test_version_anywhere(args, capfd):
    code, out, _ = _run(args, capfd)
    assert code == 0
    assert out.strip() == f"crushdem {crushdem.__version__}"


def test_misuse_exits_with_2_and_names_the_option(capfd):
    code, _, err = _run(["run", "a.toml", "--out", "d", "--stepz", "3"], capfd)
    assert code == 2 and "--stepz" in err


def test_backends_are_named_and_an_unknown_or_missing_one_is_refused(tmp_path, capfd):
    from crushdem import _core

    names = _core.backends()
    assert names in ("cpu or emulated", "cpu, emulated or cuda")
    config = tmp_path / "tiny.toml"
    config.write_text("[box]\nmin = [0.0, 0.0, 0.0]\nmax = [1e-3, 1e-3, 1e-3]\n"
                      "[particles.generate]\ncount = 10\ndiameter_min = 1e-4\n"
                      "diameter_max = 2e-4\n[run]\nsteps = 20\n[output]\ninterval = 10\n")
    code, _, err = _run(["run", str(config), "--out", str(tmp_path / "a"), "--backend", "gpu"],
                        capfd)
    assert code == 2 and "--backend" in err and "gpu" in err and names in err
    # cuda: refused in a build without CUDA, or stopped with a clear message without a device;
    # either way before anything runs.
    code, _, err = _run(["run", str(config), "--out", str(tmp_path / "b"), "--backend", "cuda"],
                        capfd)
    assert code in (1, 2) and "cuda" in err.lower()
    assert not (tmp_path / "b" / "summary.json").exists()
    # The emulated device runs it.
    code, _, _ = _run(["run", str(config), "--out", str(tmp_path / "c"), "--backend",
                       "emulated", "--quiet"], capfd)
    assert code == 0 and (tmp_path / "c" / "summary.json").exists()
    assert '"backend": "emulated"' in (tmp_path / "c" / "timing.json").read_text()
