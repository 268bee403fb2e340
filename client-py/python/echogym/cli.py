"""The ``echogym`` console script: the Rust CLI (serve, status, stop, envs) in-process,
plus ``echogym demo`` (the force-controlled sweep demo, in Python)."""

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
    code = cli_main(argv)
    if len(argv) > 1 and argv[1] in ("-h", "--help", "help"):
        print("\nAlso: echogym demo [--help]   the force-controlled ultrasound sweep demo")
    return code


if __name__ == "__main__":
    sys.exit(main())
