"""Putting the wrench and the pose on one clock: the output time base (the wrench's own
stamps, or a uniform rate), the wrench resampled onto it, and the pose interpolated at
each of its instants (position linearly, orientation by slerp) where a pose lies within
reach. Samples with no pose in reach are dropped, which leaves a gap that the recordings
format reads as a segment break."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from echogym.robotdata.errors import NoPoseInReachError, RobotDataError
from echogym.robotdata.rotations import slerp
from echogym.robotdata.series import PoseSeries, WrenchSeries

__all__ = ["Aligned", "GAP_FACTOR", "GAP_MIN_S", "align", "gap_threshold", "stretches"]

#: The recordings format's gap rule (server/src/recordings/recording.rs): an interval
#: over max(5 × median, 0.05 s) is a gap.
GAP_FACTOR = 5.0
GAP_MIN_S = 0.05
#: The format's rate range [Hz].
RATE_RANGE_HZ = (50.0, 2000.0)
#: Rate a wrench faster than the format's range is resampled to [Hz].
FAST_WRENCH_RATE_HZ = 1000.0


def gap_threshold(t: np.ndarray) -> float:
    """The interval above which ``t`` has a gap [s]."""
    return max(GAP_FACTOR * float(np.median(np.diff(t))), GAP_MIN_S) if len(t) > 1 else GAP_MIN_S


def stretches(t: np.ndarray, gap: float) -> list[slice]:
    """Index ranges of ``t`` between intervals longer than ``gap``."""
    cuts = np.flatnonzero(np.diff(t) > gap) + 1
    edges = [0, *cuts.tolist(), len(t)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


@dataclass
class Aligned:
    """Wrench and pose on the output time base (source clock, seconds)."""

    t: np.ndarray
    force: np.ndarray
    torque: np.ndarray | None
    position: np.ndarray
    quaternion: np.ndarray
    notes: dict


def _resample(t: np.ndarray, values: np.ndarray, grid: np.ndarray, window: float) -> np.ndarray:
    """``values`` at ``grid``: the mean over ``window`` around each instant when the source
    is denser than that (anti-aliasing), else linear interpolation."""
    out = np.empty((len(grid), values.shape[1]))
    source_dt = float(np.median(np.diff(t)))
    if source_dt < window / 2:
        cumulative = np.vstack([np.zeros(values.shape[1]), np.cumsum(values, axis=0)])
        lo = np.searchsorted(t, grid - window / 2)
        hi = np.searchsorted(t, grid + window / 2)
        hi = np.maximum(hi, lo + 1).clip(max=len(t))
        lo = np.minimum(lo, hi - 1)
        out[:] = (cumulative[hi] - cumulative[lo]) / (hi - lo)[:, None]
    else:
        for k in range(values.shape[1]):
            out[:, k] = np.interp(grid, t, values[:, k])
    return out


def _output_grid(source: object, wrench: WrenchSeries, rate_hz: float | None) -> tuple[np.ndarray, dict]:
    t = wrench.t
    if len(t) < 2:
        raise RobotDataError(source, "fewer than two wrench samples", where=wrench.name)
    median_rate = 1.0 / float(np.median(np.diff(t)))
    low, high = RATE_RANGE_HZ
    if rate_hz is None and median_rate < low * 0.99:
        raise RobotDataError(
            source, f"the wrench arrives at {median_rate:.1f} Hz (median), below the "
            f"{low:.0f} Hz the calibration needs to see a press; log it faster",
            where=wrench.name, time_s=float(t[0]))
    if rate_hz is None and median_rate <= high * 1.01:
        return t.copy(), {"time_base": "wrench stamps", "wrench_rate_hz": median_rate}
    rate = rate_hz if rate_hz is not None else FAST_WRENCH_RATE_HZ
    grid = []
    for piece in stretches(t, gap_threshold(t)):
        a, b = t[piece][0], t[piece][-1]
        grid.append(a + np.arange(int(np.floor((b - a) * rate)) + 1) / rate)
    return np.concatenate(grid), {"time_base": f"uniform {rate:g} Hz", "wrench_rate_hz": median_rate}


def align(source: object, wrench: WrenchSeries, pose: PoseSeries, rate_hz: float | None,
          reach_s: float | None) -> Aligned:
    """The wrench and pose on one time base (see the module doc)."""
    grid, notes = _output_grid(source, wrench, rate_hz)
    if len(grid) != len(wrench.t) or not np.array_equal(grid, wrench.t):
        window = float(np.median(np.diff(grid)))
        keep = np.zeros(len(grid), bool)
        force = np.empty((len(grid), 3))
        torque = None if wrench.torque is None else np.empty((len(grid), 3))
        gap = gap_threshold(wrench.t)
        for piece in stretches(wrench.t, gap):
            tw = wrench.t[piece]
            inside = (grid >= tw[0]) & (grid <= tw[-1])
            keep |= inside
            force[inside] = _resample(tw, wrench.force[piece], grid[inside], window)
            if torque is not None:
                torque[inside] = _resample(tw, wrench.torque[piece], grid[inside], window)
        grid, force = grid[keep], force[keep]
        torque = torque[keep] if torque is not None else None
    else:
        force, torque = wrench.force.copy(), None if wrench.torque is None else wrench.torque.copy()

    tp = pose.t
    reach = reach_s if reach_s is not None else gap_threshold(tp)
    notes["pose_reach_s"] = reach
    j = np.searchsorted(tp, grid, side="right")  # pose j-1 ≤ t < pose j
    inside = (j > 0) & (j < len(tp))
    exact_end = grid == tp[-1]
    j = np.where(exact_end, len(tp) - 1, j)
    inside |= exact_end
    jc = j.clip(1, len(tp) - 1)
    interval = tp[jc] - tp[jc - 1]
    in_reach = inside & (interval <= reach)
    if not in_reach.any():
        raise NoPoseInReachError(
            source, f"no wrench sample has a pose within {reach:.3f} s: the wrench spans "
            f"{wrench.t[0]:.3f}–{wrench.t[-1]:.3f} s, the pose ({pose.name}) "
            f"{tp[0]:.3f}–{tp[-1]:.3f} s on the clock used; set the clock or "
            "pose_time_offset_s", where=wrench.name, time_s=float(wrench.t[0]))
    before = int((grid < tp[0]).sum())
    after = int((grid > tp[-1]).sum())
    holes = int((inside & ~in_reach).sum())
    notes.update(dropped_before_pose=before, dropped_after_pose=after,
                 dropped_in_pose_gaps=holes)
    grid, force = grid[in_reach], force[in_reach]
    torque = torque[in_reach] if torque is not None else None
    jc = jc[in_reach]
    u = ((grid - tp[jc - 1]) / np.maximum(tp[jc] - tp[jc - 1], 1e-12)).clip(0, 1)
    position = pose.position[jc - 1] + u[:, None] * (pose.position[jc] - pose.position[jc - 1])
    quaternion = slerp(pose.quaternion[jc - 1], pose.quaternion[jc], u)
    return Aligned(grid, force, torque, position, quaternion, notes)
