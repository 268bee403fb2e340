"""Reading a ROS 2 bag (a folder with ``metadata.yaml``, sqlite3 or MCAP storage), a bare
``.mcap`` or ``.db3`` file, or a ROS 1 ``.bag`` with the pure-Python ``rosbags`` package: no
ROS installation. Message definitions come from the bag when it embeds them (MCAP does),
else from ROS 2 Humble's standard types."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from echogym.robotdata.checks import check_finite, check_increasing
from echogym.robotdata.errors import (
    LogFormatError,
    MappingError,
    MissingTopicError,
    UnknownMessageTypeError,
)
from echogym.robotdata.options import ImportOptions
from echogym.robotdata.rotations import quaternion_from_matrix
from echogym.robotdata.series import PoseSeries, SourceLog, WrenchSeries
from echogym.robotdata.urdf_chain import load_chain

__all__ = ["POSE_TYPES", "WRENCH_TYPES", "is_bag", "read_bag"]

WRENCH_TYPES = ("geometry_msgs/msg/WrenchStamped",)
POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TransformStamped",
              "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/JointState")
#: Header clocks of two topics further apart than this are different clocks [s].
CLOCK_DISAGREEMENT_S = 0.5


def is_bag(path: Path) -> bool:
    """Whether ``path`` looks like something :func:`read_bag` reads."""
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix in (".mcap", ".db3", ".bag")


def _stamp(header: object) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9  # type: ignore[attr-defined]


def _frame(name: str) -> str:
    return name.lstrip("/")


def read_bag(path: str | Path, options: ImportOptions) -> SourceLog:
    """The wrench and pose topics of the bag at ``path`` as series on one clock."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if options.wrench_topic is None or options.pose_topic is None:
        raise MappingError(path, "a bag needs --wrench-topic and --pose-topic (or [topics] in "
                           "the mapping file)", where="topics")
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises several reader errors, not one base class
        raise LogFormatError(path, f"not a readable bag: {exc}") from None
    try:
        found = {c.topic: c.msgtype for c in reader.connections}

        def connections(topic: str, role: str, allowed: tuple[str, ...]) -> list:
            if topic not in found:
                listed = ", ".join(f"{t} ({m})" for t, m in sorted(found.items())) or "none"
                raise MissingTopicError(path, f"no such topic in the bag (the {role}); topics: "
                                        f"{listed}", where=topic)
            if found[topic] not in allowed:
                raise UnknownMessageTypeError(
                    path, f"{found[topic]} cannot be the {role}; expected one of "
                    f"{', '.join(allowed)}", where=topic)
            return [c for c in reader.connections if c.topic == topic]

        wrench_conns = connections(options.wrench_topic, "wrench", WRENCH_TYPES)
        pose_conns = connections(options.pose_topic, "pose", POSE_TYPES)
        wrench_rows: list[tuple[float, float, list[float], str]] = []
        pose_rows: list[tuple[float, float, list[float], str]] = []
        joint_rows: list[tuple[float, float, list[str], list[float]]] = []
        pose_type = found[options.pose_topic]
        for conn, received_ns, raw in reader.messages(connections=wrench_conns + pose_conns):
            msg = reader.deserialize(raw, conn.msgtype)
            received = received_ns * 1e-9
            if conn.topic == options.wrench_topic:
                w = msg.wrench
                wrench_rows.append((_stamp(msg.header), received,
                                    [w.force.x, w.force.y, w.force.z,
                                     w.torque.x, w.torque.y, w.torque.z],
                                    _frame(msg.header.frame_id)))
            elif pose_type == "geometry_msgs/msg/PoseStamped":
                p, o = msg.pose.position, msg.pose.orientation
                pose_rows.append((_stamp(msg.header), received,
                                  [p.x, p.y, p.z, o.x, o.y, o.z, o.w], _frame(msg.header.frame_id)))
            elif pose_type == "geometry_msgs/msg/TransformStamped":
                pose_rows.append(_transform_row(msg, received))
            elif pose_type == "tf2_msgs/msg/TFMessage":
                for transform in msg.transforms:
                    if (_frame(transform.header.frame_id) == _frame(options.tf_parent or "")
                            and _frame(transform.child_frame_id) == _frame(options.tf_child or "")):
                        pose_rows.append(_transform_row(transform, received))
            else:
                joint_rows.append((_stamp(msg.header), received, list(msg.name),
                                   list(msg.position)))
    finally:
        reader.close()

    topic_w, topic_p = options.wrench_topic, options.pose_topic
    if pose_type == "tf2_msgs/msg/TFMessage" and (options.tf_parent is None
                                                   or options.tf_child is None):
        raise MappingError(path, "a tf2_msgs/TFMessage pose topic needs tf_parent and tf_child "
                           "(--tf-frames PARENT,CHILD)", where=topic_p)
    if pose_type == "sensor_msgs/msg/JointState":
        pose_rows = _joint_poses(path, topic_p, joint_rows, options)
    for rows, topic in ((wrench_rows, topic_w), (pose_rows, topic_p)):
        if not rows:
            extra = (f" with transform {options.tf_parent} → {options.tf_child}"
                     if topic == topic_p and pose_type == "tf2_msgs/msg/TFMessage" else "")
            raise MissingTopicError(path, f"no messages{extra}", where=topic)

    stamp_w = np.array([r[0] for r in wrench_rows])
    recv_w = np.array([r[1] for r in wrench_rows])
    stamp_p = np.array([r[0] for r in pose_rows])
    recv_p = np.array([r[1] for r in pose_rows])
    t_w, t_p, clock_note = _choose_clock(options.clock, stamp_w, recv_w, stamp_p, recv_p)
    t_p = t_p + options.pose_time_offset_s
    wrench = np.array([r[2] for r in wrench_rows], dtype=float)
    pose = np.array([r[2] for r in pose_rows], dtype=float)
    check_increasing(path, topic_w, t_w)
    check_increasing(path, topic_p, t_p)
    check_finite(path, topic_w, t_w, wrench)
    check_finite(path, topic_p, t_p, pose)
    frames_w = sorted({r[3] for r in wrench_rows})
    return SourceLog(
        path=str(path),
        wrench=WrenchSeries(t_w, wrench[:, :3], wrench[:, 3:],
                            frames_w[0] if len(frames_w) == 1 else "", topic_w),
        pose=PoseSeries(t_p, pose[:, :3], pose[:, 3:], pose_rows[0][3], topic_p),
        provenance={"file": str(path), "kind": "ros bag",
                    "wrench": {"topic": topic_w, "type": found[topic_w],
                               "frame_id": frames_w,
                               "messages": len(wrench_rows)},
                    "pose": {"topic": topic_p, "type": pose_type, "frame_id": pose_rows[0][3],
                             "messages": len(pose_rows)},
                    "clock": clock_note},
    )


def _transform_row(msg: object, received: float) -> tuple[float, float, list[float], str]:
    tr = msg.transform  # type: ignore[attr-defined]
    p, o = tr.translation, tr.rotation
    return (_stamp(msg.header), received, [p.x, p.y, p.z, o.x, o.y, o.z, o.w],  # type: ignore[attr-defined]
            _frame(msg.header.frame_id))  # type: ignore[attr-defined]


def _joint_poses(path: Path, topic: str, rows: list, options: ImportOptions) -> list:
    """Forward kinematics of every joint state to the URDF chain's tip."""
    if options.urdf is None:
        raise MappingError(path, "a sensor_msgs/JointState pose topic needs the robot's URDF "
                           "(--urdf)", where=topic)
    chain = load_chain(options.urdf, options.base_link, options.tip_link)
    q = np.empty((len(rows), len(chain.moving)))
    for i, (stamp, _, names, positions) in enumerate(rows):
        index = {n: k for k, n in enumerate(names)}
        for j, joint in enumerate(chain.moving):
            if joint not in index or index[joint] >= len(positions):
                raise MappingError(path, f"joint state lacks joint {joint!r} of the URDF chain "
                                   f"{chain.base_link} → {chain.tip_link} (has {names})",
                                   where=topic, time_s=stamp)
            q[i, j] = positions[index[joint]]
    tips = chain.forward(q)
    quat = quaternion_from_matrix(tips[:, :3, :3])
    return [(r[0], r[1], [*tips[i, :3, 3], *quat[i]], chain.base_link) for i, r in enumerate(rows)]


def _choose_clock(clock: str, stamp_w: np.ndarray, recv_w: np.ndarray, stamp_p: np.ndarray,
                  recv_p: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """Both topics' times on one clock, and a note of what was done for the provenance."""
    if clock == "receive":
        return recv_w, recv_p, {"used": "receive", "why": "asked"}
    unstamped = [name for name, s in (("wrench", stamp_w), ("pose", stamp_p)) if np.all(s == 0)]
    if unstamped:
        if clock == "header":
            return stamp_w, stamp_p, {"used": "header", "why": "asked"}
        return recv_w, recv_p, {"used": "receive", "why": f"{', '.join(unstamped)} header "
                                "stamps are all zero"}
    lag_w = float(np.median(recv_w - stamp_w))
    lag_p = float(np.median(recv_p - stamp_p))
    if clock == "header" or abs(lag_w - lag_p) <= CLOCK_DISAGREEMENT_S:
        return stamp_w, stamp_p, {"used": "header", "why": "asked" if clock == "header" else
                                  "the topics' header clocks agree", "receive_minus_header_s":
                                  {"wrench": lag_w, "pose": lag_p}}
    # Different clocks (a robot controller's and a PC's): keep each topic's own stamps
    # (even spacing, no network jitter) but shift them onto the recorder's receive clock.
    return stamp_w + lag_w, stamp_p + lag_p, {
        "used": "header shifted to receive clock",
        "why": f"header clocks differ by {abs(lag_w - lag_p):.3f} s (receive − header: wrench "
               f"{lag_w:.3f} s, pose {lag_p:.3f} s)",
        "shift_s": {"wrench": lag_w, "pose": lag_p}}

