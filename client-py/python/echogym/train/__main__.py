"""``python -m echogym.train``: train, resume or evaluate a PPO policy (see ``--help``)."""

from __future__ import annotations

import sys

from echogym.train.cli import main

if __name__ == "__main__":
    sys.exit(main())
