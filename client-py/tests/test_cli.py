"""The `echogym` console script's dispatch table: the Rust CLI gets every command line
unchanged, the Python applications the arguments after their name; the step after a
Rust command reads its options as the Rust CLI does (`--out DIR` and `--out=DIR` alike),
and runs only when the Rust command succeeded; `echogym --help` is the Rust help plus
the Python commands."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from echogym import cli


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> list:
    """What the Rust CLI, the plots after `calibrate` and the applications were called with."""
    seen: list = []
    monkeypatch.setattr(cli, "run_rust", lambda argv: seen.append(("rust", list(argv))) or 0)

    def plot_report(out):
        seen.append(("plots", Path(out)))
        return [Path(out) / "residual_map.png"]

    import echogym.apps.calibration_plots

    monkeypatch.setattr(echogym.apps.calibration_plots, "plot_report", plot_report)
    monkeypatch.setattr(cli.App, "run", lambda self, argv: seen.append((self.help, list(argv))) or 0)
    return seen


@pytest.mark.parametrize("out", [["--out=OUT"], ["--out", "OUT"]])
def test_calibrate_out_in_either_form_draws_the_plots(calls, capsys, out):
    argv = ["calibrate", "DATASET", *out, "--seed", "3"]
    assert cli.main(argv) == 0
    assert calls == [("rust", argv), ("plots", Path("OUT"))]
    assert "plots: OUT/residual_map.png" in capsys.readouterr().out


def test_options_before_the_dataset_and_quiet_are_read(calls):
    argv = ["calibrate", "--quiet", "--out=runs/cal", "--seed=1", "DATASET"]
    assert cli.main(argv) == 0
    assert calls == [("rust", argv), ("plots", Path("runs/cal"))]


@pytest.mark.parametrize("argv", [
    ["calibrate", "synth", "--effect", "sensor_bias", "--out=DIR"],  # a generator, no report
    ["calibrate", "--help"],
    ["calibrate", "DATASET"],  # no --out: the Rust CLI refuses it
    ["calibrate", "DATASET", "--ou", "DIR"],  # clap does not abbreviate; neither do we
])
def test_no_plots_without_a_report(calls, argv):
    assert cli.main(argv) == 0
    assert calls == [("rust", argv)]


def test_no_plots_when_the_rust_command_fails(calls, monkeypatch):
    monkeypatch.setattr(cli, "run_rust", lambda argv: calls.append(("rust", list(argv))) or 1)
    assert cli.main(["calibrate", "DATASET", "--out=OUT"]) == 1
    assert calls == [("rust", ["calibrate", "DATASET", "--out=OUT"])]


@pytest.mark.parametrize("argv", [
    ["serve", "--name", "lab", "--threads", "2"],
    ["status", "--json"],
    ["--version"],
    ["calibrate", "DATASET", "--out"],  # malformed: the Rust CLI says so
    ["no-such-command", "--out=x"],
])
def test_rust_commands_are_forwarded_unchanged(calls, argv):
    assert cli.main(argv) == 0
    assert calls == [("rust", argv)]


def test_applications_get_the_arguments_after_their_name(calls):
    assert cli.main(["demo", "--num-envs", "4", "--out=demo-out"]) == 0
    assert cli.main(["train", "--help"]) == 0
    assert cli.main(["help", "ultrasound"]) == 0
    assert calls == [
        (cli.APPS["demo"].help, ["--num-envs", "4", "--out=demo-out"]),
        (cli.APPS["train"].help, ["--help"]),
        (cli.APPS["ultrasound"].help, ["--help"]),
    ]


def test_help_is_the_rust_help_then_the_python_commands():
    done = subprocess.run([sys.executable, "-m", "echogym", "--help"], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    rust, _, python = done.stdout.partition("Python commands")
    assert "serve" in rust and "calibrate" in rust and "Usage: echogym" in rust
    for name in cli.APPS:
        assert f"  {name} [--help]" in python


def test_demo_help_comes_from_the_demo():
    done = subprocess.run([sys.executable, "-m", "echogym", "demo", "--help"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "usage: echogym demo" in done.stdout and "--num-envs" in done.stdout
