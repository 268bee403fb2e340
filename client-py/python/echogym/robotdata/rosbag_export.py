"""Episodes → a ROS 2 bag (MCAP or sqlite3 storage) or a bare ``.mcap`` file, with the
message types a UR5e or Franka with a wrist F/T sensor publishes under ROS 2, so Foxglove
opens it and ``echogym import`` reads it back:

=============================  ===================================  =====================
topic                          type                                 from
=============================  ===================================  =====================
``/echogym/wrench``            ``geometry_msgs/WrenchStamped``      ``ft`` (frame
                                                                    ``probe_tip``) or the
                                                                    recorder's world force
``/echogym/probe_pose``        ``geometry_msgs/PoseStamped``        ``probe_pose`` / tip
``/tf``                        ``tf2_msgs/TFMessage``               world → probe_tip
``/joint_states``              ``sensor_msgs/JointState``           ``joint_pos``, ``joint_vel``
``/echogym/<cam>/image_raw``   ``sensor_msgs/Image`` (rgb8)         camera images
``/echogym/<cam>/depth``       ``sensor_msgs/Image`` (32FC1)        depth images
``/echogym/ultrasound/image``  ``sensor_msgs/Image`` (mono8)        the B-mode image
``/echogym/action``            ``std_msgs/Float64MultiArray``       the action
``/echogym/reward``            ``std_msgs/Float64``                 the reward
``/echogym/info/<key>``        ``std_msgs/Float64``                 numeric info
``/echogym/episode``           ``std_msgs/Int32``                   episode index, at its start
=============================  ===================================  =====================

Episodes follow one another on one clock (``start_time_s``, default 1.7e9 s, then each
episode ``gap_s`` after the previous one ends), so the importer sees one session with
gaps. The recorder's CSV carries no orientation: its pose is written upright (tool z
down, the calibration press's probe) and its wrench in the ``world`` frame, which the
importer then takes as is."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

from echogym.robotdata.episodes import Episode, EpisodeSource
from echogym.robotdata.errors import ExportError

__all__ = ["JOINT_NAMES", "export_rosbag"]

#: Joint names of the built-in arms, as their ROS 2 drivers publish them.
JOINT_NAMES = {
    6: ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
        "wrist_2_joint", "wrist_3_joint"],
    7: [f"panda_joint{i}" for i in range(1, 8)],
}
#: The probe upright (tool z pointing down), x, y, z, w.
UPRIGHT = (1.0, 0.0, 0.0, 0.0)
WORLD, TIP = "world", "probe_tip"


def export_rosbag(source: EpisodeSource, out: str | Path, storage: str = "mcap",
                  bare: bool = False, start_time_s: float = 1.7e9, gap_s: float = 1.0) -> Path:
    """Write ``source``'s episodes as a ROS 2 bag folder at ``out`` (``storage`` ``mcap``
    or ``sqlite3``), or with ``bare`` a single ``.mcap`` file at ``out``."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    out = Path(out)
    if out.exists():
        raise ExportError(out, "exists; exports go to a new path")
    if storage not in ("mcap", "sqlite3") or (bare and storage != "mcap"):
        raise ExportError(out, f"storage must be mcap or sqlite3 (bare files: mcap), not "
                          f"{storage!r}", where="storage")
    if not source.episodes:
        raise ExportError(source.path, "no episodes to export")
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    temp = out.with_name(f".{out.name}.partial-{os.getpid()}")
    shutil.rmtree(temp, ignore_errors=True)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3

    def stamp(t: float):
        sec = int(np.floor(t))
        return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))

    def header(t: float, frame: str):
        return T["std_msgs/msg/Header"](stamp=stamp(t), frame_id=frame)

    def vector(v) -> object:
        return T["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quaternion(q) -> object:
        return T["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))

    try:
        with Writer(temp, version=9, storage_plugin=plugin) as writer:
            connections: dict[str, object] = {}

            def write(topic: str, msgtype: str, t: float, msg: object) -> None:
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, msgtype, typestore=ts)
                writer.write(connections[topic], int(round(t * 1e9)), ts.serialize_cdr(msg, msgtype))

            clock = start_time_s
            for episode in source.episodes:
                _write_episode(episode, clock, write, header, vector, quaternion, T)
                clock += float(episode.t[-1]) + gap_s
        if bare:
            (mcap,) = temp.glob("*.mcap")
            mcap.rename(out)
            shutil.rmtree(temp)
        else:
            temp.rename(out)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    return out


def _write_episode(ep: Episode, start: float, write, header, vector, quaternion, T) -> None:
    f = ep.fields
    world = ep.frames == "world"
    write("/echogym/episode", "std_msgs/msg/Int32", start, T["std_msgs/msg/Int32"](data=ep.index))
    images = {name: a for name, a in f.items() if a.dtype == np.uint8 and a.ndim in (3, 4)}
    depths = {name: a for name, a in f.items() if name.endswith("_depth") and a.ndim == 3}
    joint_pos, joint_vel = f.get("joint_pos"), f.get("joint_vel")
    names = None
    if joint_pos is not None:
        n = joint_pos.shape[1]
        names = JOINT_NAMES.get(n, [f"joint_{i + 1}" for i in range(n)])
    for k in range(ep.length):
        t = start + float(ep.t[k])
        if world:
            position, orientation = f["tip"][k], (1.0, 0.0, 0.0, 0.0)
            force = f["force"][k]
            torque = f["torque"][k] if "torque" in f else np.zeros(3)
            wrench_frame = "world"
        else:
            pose = f["probe_pose"][k]
            position, orientation = pose[:3], pose[3:7]
            force, torque, wrench_frame = f["ft"][k][:3], f["ft"][k][3:6], TIP
        write("/echogym/wrench", "geometry_msgs/msg/WrenchStamped", t,
              T["geometry_msgs/msg/WrenchStamped"](
                  header=header(t, wrench_frame),
                  wrench=T["geometry_msgs/msg/Wrench"](force=vector(force), torque=vector(torque))))
        pose_msg = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(position[0]), y=float(position[1]),
                                                  z=float(position[2])),
            orientation=quaternion(orientation))
        write("/echogym/probe_pose", "geometry_msgs/msg/PoseStamped", t,
              T["geometry_msgs/msg/PoseStamped"](header=header(t, "world"), pose=pose_msg))
        write("/tf", "tf2_msgs/msg/TFMessage", t, T["tf2_msgs/msg/TFMessage"](transforms=[
            T["geometry_msgs/msg/TransformStamped"](
                header=header(t, "world"), child_frame_id=TIP,
                transform=T["geometry_msgs/msg/Transform"](translation=vector(position),
                                                           rotation=quaternion(orientation)))]))
        if names is not None:
            write("/joint_states", "sensor_msgs/msg/JointState", t, T["sensor_msgs/msg/JointState"](
                header=header(t, ""), name=names,
                position=joint_pos[k].astype(np.float64),
                velocity=(joint_vel[k] if joint_vel is not None else np.zeros(len(names))).astype(np.float64),
                effort=np.zeros(0)))
        for name, frames in images.items():
            img = frames[k]
            encoding = "mono8" if img.ndim == 2 else "rgb8"
            topic = "/echogym/ultrasound/image" if name == "ultrasound" else \
                f"/echogym/{name.removesuffix('_rgb')}/image_raw"
            write(topic, "sensor_msgs/msg/Image", t, T["sensor_msgs/msg/Image"](
                header=header(t, name), height=img.shape[0], width=img.shape[1], encoding=encoding,
                is_bigendian=0, step=img.shape[1] * (1 if img.ndim == 2 else 3),
                data=np.ascontiguousarray(img).reshape(-1)))
        for name, frames in depths.items():
            img = np.ascontiguousarray(frames[k], dtype="<f4")
            write(f"/echogym/{name.removesuffix('_depth')}/depth", "sensor_msgs/msg/Image", t,
                  T["sensor_msgs/msg/Image"](header=header(t, name), height=img.shape[0],
                                             width=img.shape[1], encoding="32FC1", is_bigendian=0,
                                             step=img.shape[1] * 4, data=img.view(np.uint8).reshape(-1)))
        if ep.action is not None:
            write("/echogym/action", "std_msgs/msg/Float64MultiArray", t,
                  T["std_msgs/msg/Float64MultiArray"](
                      layout=T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                      data=ep.action[k].astype(np.float64)))
        if ep.reward is not None:
            write("/echogym/reward", "std_msgs/msg/Float64", t,
                  T["std_msgs/msg/Float64"](data=float(ep.reward[k])))
        for key, values in ep.info.items():
            write(f"/echogym/info/{key}", "std_msgs/msg/Float64", t,
                  T["std_msgs/msg/Float64"](data=float(values[k])))
