"""The ``echogym`` console script: the Rust CLI (serve, status, stop, envs) in-process."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Run ``echogym`` with ``argv`` (default ``sys.argv``); the exit code."""
    from echogym._native import cli_main

    argv = list(sys.argv if argv is None else argv)
    argv[0] = "echogym"
    return cli_main(argv)


if __name__ == "__main__":
    sys.exit(main())
