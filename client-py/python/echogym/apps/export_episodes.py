"""``echogym export``: recorded episodes → a LeRobot dataset, a ROS 2 bag or an MCAP file
(docs/data.md)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    from echogym.robotdata import RobotDataError
    from echogym.robotdata.export import FORMATS, export_episodes

    parser = argparse.ArgumentParser(
        prog="echogym export",
        description="Export recorded episodes: a folder written by "
                    "echogym.robotdata.RecordEpisodes (echogym-episodes/1) or by an env's "
                    "record={'dir': ...} (echogym-recordings/1).",
        epilog="formats: " + "; ".join(f"{k}: {v}" for k, v in FORMATS.items()))
    parser.add_argument("source", help="episode or recordings folder")
    parser.add_argument("--to", required=True, choices=list(FORMATS))
    parser.add_argument("--out", required=True)
    parser.add_argument("--robot-type", help="LeRobot's robot_type (e.g. ur5e)")
    args = parser.parse_args(argv)
    try:
        path = export_episodes(args.source, args.out, args.to, robot_type=args.robot_type)
    except RobotDataError as exc:
        print(f"echogym export: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
