"""Checks every source's series pass before any transform: finite values and strictly
increasing time, each refused with the topic or column and the time of the first bad
sample."""

from __future__ import annotations

import numpy as np

from echogym.robotdata.errors import NonFiniteError, NonMonotonicTimeError

__all__ = ["check_finite", "check_increasing"]


def check_increasing(source: object, where: str, t: np.ndarray) -> None:
    """Refuse time that repeats or goes back (a ROS clock jump, a logger restart)."""
    if len(t) and not np.all(np.isfinite(t)):
        i = int(np.argmin(np.isfinite(t)))
        raise NonFiniteError(source, f"time stamp {i} is not finite", where=where)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        i = int(bad[0])
        raise NonMonotonicTimeError(
            source, f"time does not increase: sample {i + 1} is stamped {t[i + 1]:.6f} s after "
            f"{t[i]:.6f} s ({len(bad)} such step(s)); sort or de-duplicate the log",
            where=where, time_s=float(t[i + 1]))


def check_finite(source: object, where: str, t: np.ndarray, values: np.ndarray) -> None:
    """Refuse NaN or infinite samples, naming where the first run of them starts and ends."""
    good = np.all(np.isfinite(values.reshape(len(values), -1)), axis=1)
    if good.all():
        return
    first = int(np.argmin(good))
    end = first
    while end < len(good) and not good[end]:
        end += 1
    raise NonFiniteError(
        source, f"{int((~good).sum())} sample(s) are NaN or infinite, the first run "
        f"{end - first} long (t {t[first]:.6f}–{t[end - 1]:.6f} s); drop or repair them",
        where=where, time_s=float(t[first]))
