"""Progress bars of the applications (the demo, training): tqdm, drawn only on a terminal.

Redirected to a file, a pipe or a CI log a bar writes nothing at all (no carriage
returns, no escape codes); the applications print their results as plain lines.
"""

from __future__ import annotations

import sys
from typing import Any, TextIO

from tqdm import tqdm


def progress_bar(total: int, *, enabled: bool = True, file: TextIO | None = None,
                 **options: Any) -> tqdm:
    """A tqdm bar of ``total`` units on ``file`` (default stderr).

    It draws when ``enabled`` and ``file`` is a terminal, and is a silent no-op otherwise;
    ``options`` go to tqdm (``unit``, ``initial``, ``smoothing``, ...).
    """
    return tqdm(total=total, file=sys.stderr if file is None else file,
                disable=None if enabled else True, dynamic_ncols=True, **options)
