"""matplotlib for the applications' figures: headless (Agg), and a clear message when
the ``[plots]`` extra is not installed."""

from __future__ import annotations

import sys
from types import ModuleType

#: What to install for the figures.
PLOTS_EXTRA = "pip install 'echogym[plots]'"


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the Agg backend (files only, no display).

    Raises:
        ImportError: matplotlib is not installed; the message names the extra.
    """
    try:
        import matplotlib
    except ImportError as exc:
        raise ImportError(f"echogym's figures need matplotlib: {PLOTS_EXTRA}") from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plots_available(app: str) -> bool:
    """Whether matplotlib can be loaded; if not, say so on stderr as ``echogym APP: ...``
    (an application checks before it runs, not after minutes of work)."""
    try:
        pyplot()
    except ImportError as exc:
        print(f"echogym {app}: {exc}", file=sys.stderr)
        return False
    return True
