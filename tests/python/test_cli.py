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
