"""``python -m echogym ...`` runs the echogym command line."""

import sys

from echogym.cli import main

sys.exit(main())
