"""The ``echogym`` console script: the Rust CLI (serve, status, stop, envs, calibrate)
in-process, plus ``echogym demo`` (the force-controlled sweep demo, in Python),
``echogym ultrasound`` (figures of the synthetic B-mode image) and ``echogym train``
(PPO with torchrl, :mod:`echogym.train`); after a
successful ``echogym calibrate DATASET --out OUT`` it draws the report's plots."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Run ``echogym`` with ``argv`` (default ``sys.argv``); the exit code."""
    from echogym._native import cli_main

    argv = list(sys.argv if argv is None else argv)
    argv[0] = "echogym"
    if len(argv) > 1 and argv[1] == "demo":
        from echogym.demo import main as demo_main

        return demo_main(argv[2:])
    if len(argv) > 1 and argv[1] == "train":
        from echogym.train.cli import main as train_main

        return train_main(argv[2:])
    if len(argv) > 1 and argv[1] == "ultrasound":
        from echogym.ultrasound import main as ultrasound_main

        return ultrasound_main(argv[2:])
    code = cli_main(argv)
    if code == 0 and len(argv) > 2 and argv[1] == "calibrate" and argv[2] != "synth" and "--out" in argv:
        from echogym.calibration import plot_report

        out = argv[argv.index("--out") + 1]
        paths = plot_report(out)
        print("plots: " + ", ".join(str(p) for p in paths))
    if len(argv) > 1 and argv[1] in ("-h", "--help", "help"):
        print("\nAlso: echogym demo [--help]         the force-controlled ultrasound sweep demo"
              "\n      echogym ultrasound [--help]   B-mode image figures: press, sites, sweep"
              "\n      echogym train [--help]        PPO training with torchrl (docs/training.md)")
    return code


if __name__ == "__main__":
    sys.exit(main())
