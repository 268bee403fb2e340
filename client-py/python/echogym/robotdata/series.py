"""What a source yields before any transform: time-stamped wrenches and probe poses, on the
source's own clock, in the source's units already converted to SI."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["PoseSeries", "SourceLog", "WrenchSeries"]


@dataclass
class WrenchSeries:
    """Force [N] and torque [N·m] as the sensor reported them, ``[N, 3]`` each.

    ``frame`` is the frame they are expressed in as the source says (a ROS ``frame_id`` or
    the CSV mapping's frame); ``name`` the topic or columns, for error messages."""

    t: np.ndarray
    force: np.ndarray
    torque: np.ndarray | None
    frame: str
    name: str


@dataclass
class PoseSeries:
    """Probe poses: ``position [N, 3]`` in m and ``quaternion [N, 4]`` (x, y, z, w), of the
    frame the pose topic or columns name, in ``parent`` (the world the recording uses)."""

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    parent: str
    name: str


@dataclass
class SourceLog:
    """One source file read: its wrench and pose series and how they were found
    (``provenance``: file, topics or columns, message types, clocks)."""

    path: str
    wrench: WrenchSeries
    pose: PoseSeries
    provenance: dict = field(default_factory=dict)
