"""The ``crushdem-sand`` console command (python/crushdem_sand/__main__.py): every command, the
Python ones (plot, reproduce, sensitivity) and the C++ ones (run, resume, check, bench), answers
-h/--help with its usage and exit status 0, and --version works after any command; ``--backend``
names the backends, refuses others, and the emulated device follows the CPU to rounding."""

import csv
import os
import re

import numpy as np
import pytest

import crushdem_sand
from _data import DATA, data_text
from crushdem_sand.__main__ import main


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
        assert "crushdem-sand " + command in out and option in out


def test_top_level_help_lists_every_command(capfd):
    from crushdem_sand._cli import COMMANDS

    code, out, _ = _run(["--help"], capfd)
    assert code == 0
    # One list: the Python package's commands among the C++ ones, each with its description.
    listed = out[out.index("Subcommands:"):]
    for command in ("run", "resume", "check", "bench"):
        assert f"\n  {command} " in listed, out
    for command, description in COMMANDS.items():
        assert f"\n  {command} " in listed and description in listed, out
    assert "come with the Python package" not in out


C_COMMANDS = ("run", "resume", "check", "bench")
PY_COMMANDS = ("plot", "reproduce", "sensitivity", "sweep", "calibrate", "pile")


@pytest.mark.parametrize("command", C_COMMANDS + PY_COMMANDS)
def test_one_help_style(command, capfd):
    """Every command's help has CLI11's layout, whichever language parses it: the one-line
    description, the usage, the positionals with their type, the options with -h,--help first
    and the value's type and REQUIRED beside each name."""
    code, out, _ = _run([command, "--help"], capfd)
    assert code == 0
    lines = out.splitlines()
    assert lines[1].startswith(f"Usage: crushdem-sand {command} [OPTIONS]"), out
    assert lines[2] == "", out
    assert "\nOptions:\n  -h,--help                   Print this help message and exit\n" in out
    if command in PY_COMMANDS:
        from crushdem_sand._cli import COMMANDS

        assert lines[0] == COMMANDS[command]
    assert "usage:" not in out and "optional arguments" not in out and "options:" not in out
    # A required option says so, as CLI11 writes it.
    if command in ("run", "sensitivity", "sweep", "calibrate", "pile"):
        assert re.search(r"\n  --out \S+ REQUIRED", out), out


@pytest.mark.parametrize("args", [["run", "a.toml", "--out", "d", "--bogus"],
                                  ["reproduce", "--bogus"], ["pile", "c.toml", "--bogus"],
                                  ["plot"], ["sweep", "s.toml"]])
def test_misuse_reads_the_same_in_every_command(args, capfd):
    code, out, err = _run(args, capfd)
    assert code == 2, (out, err)
    command = args[0]
    assert err.startswith(f"crushdem-sand {command}: error: "), err
    assert err.endswith(f"Run 'crushdem-sand {command} --help' for the options.\n"), err


@pytest.mark.parametrize("args", [["--version"], ["plot", "DIR", "--version"],
                                  ["run", "x.toml", "--version"]])
def test_version_anywhere(args, capfd):
    code, out, _ = _run(args, capfd)
    assert code == 0
    assert out.strip() == f"crushdem-sand {crushdem_sand.__version__}"


def test_misuse_exits_with_2_and_names_the_option(capfd):
    code, _, err = _run(["run", "a.toml", "--out", "d", "--stepz", "3"], capfd)
    assert code == 2 and "--stepz" in err


def test_backends_are_named_and_an_unknown_or_missing_one_is_refused(tmp_path, capfd):
    from crushdem_sand import _core

    names = _core.backends()  # the engine's sentence, which its messages use
    assert names in ("cpu or emulated", "cpu, emulated or cuda")
    # The package's: a tuple of the names, each a --backend value.
    assert crushdem_sand.backends() == (("cpu", "emulated") if names == "cpu or emulated"
                                   else ("cpu", "emulated", "cuda"))
    config = tmp_path / "tiny.toml"
    config.write_text(data_text("tiny_run.toml"))
    code, _, err = _run(["run", str(config), "--out", str(tmp_path / "a"), "--backend", "gpu"],
                        capfd)
    assert code == 2 and "--backend" in err and "gpu" in err and names in err
    # cuda: refused in a build without CUDA, or stopped with a clear message without a device;
    # either way before anything runs.
    code, _, err = _run(["run", str(config), "--out", str(tmp_path / "b"), "--backend", "cuda"],
                        capfd)
    assert code in (1, 2) and "cuda" in err.lower()
    assert not (tmp_path / "b" / "summary.json").exists()


# How far the emulated device may land from the CPU on lattice_pushed.toml, relative to each
# column's largest magnitude in the CPU run: the device sums a grain's forces in another order,
# so the runs part by rounding and the parting grows with the contacts; measured 5e-10 at the
# last row (docs/performance.md, "Backends": 2e-11 of the mean radius over 2,000 steps of 300
# grains).
EMULATED_TOLERANCE = 1e-8


def _columns(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_the_emulated_device_follows_the_cpu(tmp_path, capfd):
    config = os.path.join(DATA, "lattice_pushed.toml")  # its grains: a path relative to it
    runs = {}
    for backend in ("cpu", "emulated"):
        out = tmp_path / backend
        code, _, err = _run(["run", config, "--out", str(out), "--backend", backend, "--quiet"],
                            capfd)
        assert code == 0, err
        assert f'"backend": "{backend}"' in (out / "timing.json").read_text()
        runs[backend] = _columns(out / "timeseries.csv")
    cpu, emulated = runs["cpu"], runs["emulated"]
    assert list(cpu) == list(emulated)
    np.testing.assert_array_equal(emulated["step"], cpu["step"])
    np.testing.assert_array_equal(emulated["n_contacts"], cpu["n_contacts"])
    assert cpu["n_contacts"][-1] > 40  # a contact network (48 here), not grains flying apart
    for name, values in cpu.items():
        scale = np.max(np.abs(values))
        assert np.max(np.abs(emulated[name] - values)) <= EMULATED_TOLERANCE * scale, name


def test_progress_lines_give_the_rate_and_the_share_done(tmp_path, capfd):
    # A hold of 2,000 steps on the 64-grain lattice, a progress line at every check (200 steps):
    # each line gives the steps per second and the share of the stage done, rising to 100 %.
    config = tmp_path / "hold.toml"
    config.write_text(f'[contact]\nlaw = "hertz"\n[particles]\nfile = "{DATA}/lattice_64.txt"\n'
                      '[[stage]]\ntype = "hold"\nname = "rest"\nsteps = 2000\n'
                      '[output]\ninterval = 500\nprogress_seconds = 1e-9\n')
    code, _, err = _run(["run", str(config), "--out", str(tmp_path / "run")], capfd)
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if ln.startswith("[crushdem] rest  step")]
    assert len(lines) >= 5, err
    shares = []
    for ln in lines:
        assert " steps/s" in ln, ln
        shares.append(float(ln.split("% done")[0].split()[-1]))
    assert shares == sorted(shares) and shares[0] > 0 and shares[-1] == 100.0, shares
    assert any(", ETA " in ln for ln in lines), lines


def test_the_command_parser_writes_types_choices_lists_and_percent_signs_as_cli11_does():
    from crushdem_sand._cli import CommandParser

    parser = CommandParser("plot", "More text.")
    parser.add_argument("count", type=int, metavar="N", help="grains")
    parser.add_argument("--rate", type=float, required=True, help="%(default)s at 100 %%")
    parser.add_argument("--law", choices=("hertz", "rough"), default="hertz")
    parser.add_argument("--set", action="append", metavar="KEY=VALUE", help="repeatable")
    parser.add_argument("--a-rather-long-option-name", metavar="VALUE", help="on the next line")
    text = parser.format_help()
    assert "\n  N INT REQUIRED              grains\n" in text
    assert "\n  --rate FLOAT REQUIRED       None at 100 %\n" in text
    assert "\n  --law TEXT:{hertz,rough}\n" in text
    assert "\n  --set KEY=VALUE ...         repeatable\n" in text
    assert ("\n  --a-rather-long-option-name VALUE\n" + " " * 30 + "on the next line\n") in text
    assert text.endswith("\nMore text.\n")
    assert parser.parse_args(["3", "--rate", "2"]).count == 3


def test_the_python_and_cpp_front_ends_name_the_command_alike():
    """The command's name and the old name's note live in src/crushdem/cli/cli.hpp (kCommand,
    kAliasNote) and in python/crushdem_sand/_cli.py (PROG, ALIAS_NOTE): the Python front end
    runs without the C++ one's constants, so the two copies are held equal here."""
    from crushdem_sand import _cli

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with open(os.path.join(root, "src", "crushdem", "cli", "cli.hpp")) as f:
        text = f.read()

    def constant(name):
        m = re.search(r"constexpr const char\* " + name + r"\s*=\s*((?:\s*\"(?:[^\"\\]|\\.)*\")+);",
                      text)
        assert m, name
        parts = re.findall(r"\"((?:[^\"\\]|\\.)*)\"", m.group(1))
        return "".join(parts).encode().decode("unicode_escape")

    assert constant("kCommand") == _cli.PROG
    assert constant("kAliasNote") == _cli.ALIAS_NOTE
