"""``echogym export``'s library side: one call from an episode folder (``echogym-episodes/1``
from :class:`~echogym.robotdata.recorder.RecordEpisodes`, or the server recorder's
``echogym-recordings/1``) to a LeRobot dataset, a ROS 2 bag or a bare MCAP file."""

from __future__ import annotations

from pathlib import Path

from echogym.robotdata.episodes import read_episodes
from echogym.robotdata.errors import ExportError
from echogym.robotdata.lerobot_export import export_lerobot
from echogym.robotdata.rosbag_export import export_rosbag

__all__ = ["FORMATS", "export_episodes"]

#: ``to`` → what is written.
FORMATS = {
    "lerobot": "a LeRobot dataset folder (codebase v3.0)",
    "mcap": "one .mcap file (ROS 2 messages; opens in Foxglove)",
    "rosbag2": "a ROS 2 bag folder, MCAP storage",
    "rosbag2-sqlite3": "a ROS 2 bag folder, sqlite3 storage",
}


def export_episodes(source: str | Path, out: str | Path, to: str,
                    robot_type: str | None = None) -> Path:
    """Export the episodes in the folder ``source`` to ``out`` as ``to`` (see
    :data:`FORMATS`)."""
    if to not in FORMATS:
        raise ExportError(out, f"unknown format {to!r}; one of {', '.join(FORMATS)}", where="to")
    episodes = read_episodes(source)
    if to == "lerobot":
        return export_lerobot(episodes, out, robot_type=robot_type)
    if to == "mcap":
        return export_rosbag(episodes, out, storage="mcap", bare=True)
    return export_rosbag(episodes, out, storage="sqlite3" if to.endswith("sqlite3") else "mcap")
