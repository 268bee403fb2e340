"""The ``echogym`` console script: one dispatch table over the Rust command line.

The Rust CLI (``serve``, ``status``, ``stop``, ``envs``, ``calibrate``; linked into the
native module, the same code as the ``echogym`` binary) receives every command line with
its arguments unchanged, except the Python applications of :data:`APPS` (``demo``,
``ultrasound``, ``train``, ``view``), which get the arguments after their name. After a Rust
command succeeds, the step :data:`AFTER` names for it runs on the arguments argparse read
(``calibrate DATASET --out OUT`` / ``--out=OUT``: the report's plots). ``echogym --help``
and ``echogym help`` print the Rust help, then the Python commands; ``echogym help demo``
the demo's.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["AFTER", "APPS", "App", "build_parser", "main", "run_rust"]


@dataclass(frozen=True)
class App:
    """A Python command: ``target`` is ``"module:function"``, a function that takes the
    arguments after the command's name and returns the exit code."""

    help: str
    target: str

    def run(self, argv: Sequence[str]) -> int:
        """Import the application and run it on ``argv``; its exit code."""
        module, function = self.target.split(":")
        return int(getattr(importlib.import_module(module), function)(list(argv)) or 0)


#: The Python commands, by name (a name here shadows a Rust command of the same name).
APPS: dict[str, App] = {
    "demo": App("the force-controlled ultrasound sweep demo", "echogym.apps.demo:main"),
    "ultrasound": App("B-mode image figures: press, sites, sweep", "echogym.apps.ultrasound:main"),
    "train": App("PPO training with torchrl (docs/training.md)", "echogym.train.cli:main"),
    "import": App("robot logs (ROS 2 bags, MCAP, CSV) → a calibration dataset (docs/data.md)",
                  "echogym.apps.import_logs:main"),
    "export": App("recorded episodes → a LeRobot dataset, a ROS 2 bag or MCAP (docs/data.md)",
                  "echogym.apps.export_episodes:main"),
    "view": App("watch envs in the rerun viewer, live or saved to .rrd", "echogym.apps.view:main"),
}


def _plot_calibration(args: argparse.Namespace) -> int:
    """After ``echogym calibrate DATASET --out OUT``: the report's plots, into ``OUT``."""
    # `synth` is the Rust CLI's dataset generator (a subcommand), not a dataset.
    if args.dataset is None or args.dataset == "synth" or args.out is None:
        return 0
    try:
        from echogym.apps.calibration_plots import plot_report

        paths = plot_report(args.out)
    except ImportError as exc:
        print(f"plots skipped: {exc}", file=sys.stderr)
        return 0
    print("plots: " + ", ".join(str(p) for p in paths))
    return 0


#: What runs after a Rust command exits 0, by command: a function of the parsed arguments
#: returning the exit code.
AFTER: dict[str, Callable[[argparse.Namespace], int]] = {"calibrate": _plot_calibration}


def _subparser(commands: argparse._SubParsersAction, name: str) -> argparse.ArgumentParser:
    # No help of their own (`--help` reaches the application or the Rust CLI), no
    # abbreviated options (clap has none), errors raised rather than printed.
    return commands.add_parser(name, add_help=False, allow_abbrev=False, exit_on_error=False)


def build_parser() -> argparse.ArgumentParser:
    """The parser of the dispatch table. It reads what the Python side needs (the command,
    the options of :data:`AFTER`'s steps) and leaves every other argument unread."""
    parser = argparse.ArgumentParser(prog="echogym", add_help=False, allow_abbrev=False,
                                     exit_on_error=False)
    parser.add_argument("-h", "--help", action="store_true")
    commands = parser.add_subparsers(dest="command")
    for name in APPS:
        _subparser(commands, name)
    topic = _subparser(commands, "help")
    topic.add_argument("topic", nargs="?")
    # The options of `echogym calibrate` (server/src/cli.rs, `CalibrateArgs`).
    calibrate = _subparser(commands, "calibrate")
    calibrate.add_argument("dataset", nargs="?")
    calibrate.add_argument("--out", type=Path)
    calibrate.add_argument("--seed")
    calibrate.add_argument("--quiet", action="store_true")
    return parser


def run_rust(argv: Sequence[str]) -> int:
    """The Rust CLI on ``argv`` (the arguments after ``echogym``), in this process."""
    from echogym._native import cli_main

    sys.stdout.flush()
    return cli_main(["echogym", *argv])


def _python_commands() -> str:
    width = max(len(name) for name in APPS) + len(" [--help]")
    lines = [f"  {name + ' [--help]':<{width}}  {app.help}" for name, app in APPS.items()]
    return "\nPython commands (this console script):\n" + "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``echogym`` with ``argv`` (the arguments after the program name; default
    ``sys.argv[1:]``); the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args, rest = build_parser().parse_known_args(argv)
    except argparse.ArgumentError:
        # Not a command line the table reads (an unknown command, a malformed option):
        # the Rust CLI has the authoritative grammar and error messages.
        return run_rust(argv)
    if args.command in APPS:
        return APPS[args.command].run(rest)
    if args.command == "help" and args.topic in APPS:
        return APPS[args.topic].run(["--help"])
    code = run_rust(argv)
    if code == 0 and args.command in AFTER:
        code = AFTER[args.command](args)
    if (args.help and args.command is None) or (args.command == "help" and args.topic is None):
        print(_python_commands())
    return code


if __name__ == "__main__":
    sys.exit(main())
