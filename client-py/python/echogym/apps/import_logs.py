"""``echogym import``: a robot's logs (ROS 2 bags, MCAP, CSV) → an ``echogym-recordings/1``
dataset for ``echogym calibrate`` (docs/data.md). Flags override the mapping file."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

__all__ = ["build_parser", "main"]


def _floats(count: int):
    def parse(text: str) -> list[float]:
        values = [float(v) for v in text.split(",")]
        if len(values) != count:
            raise argparse.ArgumentTypeError(f"needs {count} comma-separated numbers")
        return values
    return parse


def _names(text: str) -> list[str]:
    return [v.strip() for v in text.split(",") if v.strip()]


def _mass(text: str) -> float | str:
    return text if text in ("estimate", "none") else float(text)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="echogym import",
        description="Import robot logs into an echogym-recordings/1 dataset that `echogym "
                    "calibrate` reads. One recording per source file, cut at gaps and where "
                    "the probe moved to another site through free air (the summary says which).")
    p.add_argument("sources", nargs="+", help="ROS 2 bag folders, .mcap/.db3/.bag files, CSVs")
    p.add_argument("--out", required=True, help="dataset folder to create")
    p.add_argument("--mapping", help="TOML mapping file (topics, robot, probe, time, scene, csv)")
    bag = p.add_argument_group("bags and MCAP")
    bag.add_argument("--wrench-topic", help="geometry_msgs/WrenchStamped topic")
    bag.add_argument("--pose-topic", help="PoseStamped, TransformStamped, tf2_msgs/TFMessage or "
                     "sensor_msgs/JointState topic")
    bag.add_argument("--tf-frames", type=_names, metavar="PARENT,CHILD",
                     help="the transform to take from a TFMessage topic")
    bag.add_argument("--urdf", help="robot URDF for a JointState topic")
    bag.add_argument("--base-link", help="URDF chain start (default: the root)")
    bag.add_argument("--tip-link", help="URDF chain end (default: the deepest leaf)")
    bag.add_argument("--clock", choices=["auto", "header", "receive"])
    csv = p.add_argument_group("CSV columns (comma-separated names) and units")
    csv.add_argument("--csv-time")
    csv.add_argument("--time-unit", choices=["s", "ms", "us", "ns"])
    csv.add_argument("--csv-position", type=_names)
    csv.add_argument("--position-unit", choices=["m", "cm", "mm", "um"])
    csv.add_argument("--csv-quaternion", type=_names, metavar="QX,QY,QZ,QW")
    csv.add_argument("--csv-rpy", type=_names, metavar="ROLL,PITCH,YAW")
    csv.add_argument("--csv-force", type=_names)
    csv.add_argument("--force-unit", choices=["N", "mN", "kN"])
    csv.add_argument("--csv-torque", type=_names)
    csv.add_argument("--torque-unit", choices=["N*m", "Nm", "N*mm", "Nmm"])
    tr = p.add_argument_group("transforms")
    tr.add_argument("--tool-offset", type=_floats(3), metavar="X,Y,Z",
                    help="probe tip in the pose's frame, m (flange → tip)")
    tr.add_argument("--sensor-rotation", type=_floats(3), metavar="R,P,Y",
                    help="fixed rotation sensor → tool, roll-pitch-yaw in rad")
    tr.add_argument("--wrench-frame", choices=["auto", "tool", "world"])
    tr.add_argument("--wrench-sign", type=float, choices=[1.0, -1.0])
    tr.add_argument("--probe-mass", type=_mass, metavar="KG|estimate|none")
    tr.add_argument("--pose-time-offset", type=float, metavar="S")
    tr.add_argument("--rate", type=float, metavar="HZ", help="resample onto this uniform rate")
    sc = p.add_argument_group("scene")
    sc.add_argument("--surface-z", type=float, metavar="Z")
    sc.add_argument("--torso-center", type=_floats(2), metavar="X,Y")
    sc.add_argument("--sites", choices=["seed", "cluster"],
                    help="name contacts after the seed's five sites (default) or cluster them; "
                         "a site map goes in the mapping file's [scene] sites")
    sc.add_argument("--protocol", help="protocol for every recording (default: classified)")
    sc.add_argument("--split", choices=["auto", "gaps"])
    sc.add_argument("--contact-threshold", type=float, metavar="N")
    return p


#: argparse destination → ImportOptions field (None: a CsvColumns field of the same name).
_FIELDS = {
    "wrench_topic": "wrench_topic", "pose_topic": "pose_topic", "urdf": "urdf",
    "base_link": "base_link", "tip_link": "tip_link", "clock": "clock",
    "tool_offset": "tool_offset", "sensor_rotation": "sensor_rotation_rpy",
    "wrench_frame": "wrench_frame", "wrench_sign": "wrench_sign", "probe_mass": "probe_mass",
    "pose_time_offset": "pose_time_offset_s", "rate": "rate_hz", "surface_z": "surface_z",
    "torso_center": "torso_center", "protocol": "protocol", "split": "split",
    "contact_threshold": "contact_threshold_n",
}
_CSV = {"csv_time": "time", "time_unit": "time_unit", "csv_position": "position",
        "position_unit": "position_unit", "csv_quaternion": "quaternion", "csv_rpy": "rpy",
        "csv_force": "force", "force_unit": "force_unit", "csv_torque": "torque",
        "torque_unit": "torque_unit"}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from echogym.robotdata import ImportOptions, RobotDataError, import_logs, load_mapping

    try:
        options = load_mapping(args.mapping) if args.mapping else ImportOptions()
        for dest, name in _FIELDS.items():
            if getattr(args, dest) is not None:
                setattr(options, name, getattr(args, dest))
        for dest, name in _CSV.items():
            if getattr(args, dest) is not None:
                setattr(options.csv, name, getattr(args, dest))
        if args.tf_frames:
            if len(args.tf_frames) != 2:
                print("echogym import: --tf-frames needs PARENT,CHILD", file=sys.stderr)
                return 2
            options.tf_parent, options.tf_child = args.tf_frames
        if args.sites == "cluster":
            options.sites = "cluster"
        elif args.sites == "seed":
            options.sites = None
        result = import_logs(args.sources, args.out, options)
    except RobotDataError as exc:
        print(f"echogym import: {exc}", file=sys.stderr)
        return 1
    meta = result.meta
    print(f"wrote {result.out}: {len(result.recordings)} recording(s); surface z "
          f"{meta['nominal_surface_z']:.4f} m ({meta['provenance']['estimated']['nominal_surface_z']}), "
          f"torso centre {meta['torso_center_xy'][0]:.4f}, {meta['torso_center_xy'][1]:.4f} m")
    for source in meta["provenance"]["sources"]:
        g = source["gravity"]
        mass = f", {g['mass_kg']:.3f} kg" if "mass_kg" in g else ""
        print(f"  {source['file']}: gravity {g['method']}{mass}; {source['contacts']} contact(s)")
    for entry in result.recordings:
        src = entry["source"]
        print(f"  {entry['file']}: {entry['site']}, {entry['protocol']}, "
              f"{src['t_end'] - src['t_start']:.1f} s ({src['cut']})")
    print(f"next: echogym calibrate {result.out} --out {result.out}-calibration")
    return 0


if __name__ == "__main__":
    sys.exit(main())
