"""Timing a collector: the frames it delivered and the seconds they took, after a warm-up
(shared by :mod:`echogym.train.throughput` and :mod:`echogym.train.scale_out`)."""

from __future__ import annotations

import time
from typing import Any


def timed_collection(collector: Any, warmup: int) -> tuple[int, float]:
    """Run `collector` to its end: the frames of the batches after the first `warmup`
    and the seconds they took (timed from the end of the last warm-up batch). Shuts the
    collector down."""
    frames = 0
    start = 0.0
    try:
        for i, data in enumerate(collector):
            if i == warmup - 1:
                start = time.monotonic()
            elif i >= warmup:
                frames += data.numel()
        return frames, time.monotonic() - start
    finally:
        collector.shutdown()
