"""Synthetic robot sessions for the import tests, written by the real format libraries: a
probe pointing down presses a spring-damper body at named sites, seen as a UR5e + wrist
F/T driver would log it — the wrench in the sensor frame with the probe's weight in it,
the flange's pose (the tip lies ``TOOL_OFFSET`` further along the tool's z), each topic at
its own rate with jittered stamps."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

G = 9.80665
SURFACE_Z = 0.12
TORSO_CENTER = (0.45, -0.05)
STIFFNESS = 900.0  # N/m
DAMPING = 30.0  # N·s/m
PROBE_MASS = 0.25  # kg
TOOL_OFFSET = (0.0, 0.0, 0.11)  # tip in the flange frame (along the tool's z)
#: The probe upright: tool z pointing down (rotation of π about x), as quaternion x,y,z,w.
DOWN = np.array([1.0, 0.0, 0.0, 0.0])


@dataclass
class Session:
    """Ground truth on a fine clock: tip position, the body's force on the probe (world)."""

    t: np.ndarray
    tip: np.ndarray
    force: np.ndarray
    sites: list[tuple[str, float, float]]  # (site, t_start, t_end) of each press


def session(sites: list[str], seed: int = 0, dt: float = 1e-3, depth: float = 0.008) -> Session:
    """Presses at ``sites`` (of the seed's five): approach in free air, press ``depth`` below
    the surface at 1 cm/s, hold 0.5 s, withdraw, move on. Starts at t = 1.7e9 s (epoch)."""
    from echogym.robotdata.sites import SEED_SITES

    rng = np.random.default_rng(seed)
    points: list[tuple[float, np.ndarray]] = []
    clock = 0.0
    above = SURFACE_Z + 0.01
    spans = []
    for site in sites:
        xy = np.array(TORSO_CENTER) + np.array(SEED_SITES[site]) + rng.normal(0, 0.001, 2)
        start = np.array([*xy, above])
        bottom = np.array([*xy, SURFACE_Z - depth])
        if points:
            clock += 1.5  # travel in free air
        points.append((clock, start))
        t0 = clock
        clock += 0.5
        points.append((clock, start))  # settle in free air (gravity estimate, noise floor)
        clock += (above - bottom[2]) / 0.01
        points.append((clock, bottom))
        clock += 0.5
        points.append((clock, bottom))
        clock += (above - bottom[2]) / 0.01
        points.append((clock, start))
        clock += 0.5
        points.append((clock, start))
        spans.append((site, t0, clock))
    knots_t = np.array([p[0] for p in points])
    knots = np.array([p[1] for p in points])
    t = np.arange(0.0, knots_t[-1], dt)
    tip = np.stack([np.interp(t, knots_t, knots[:, k]) for k in range(3)], axis=1)
    v = np.gradient(tip[:, 2], t)
    depth_now = np.maximum(SURFACE_Z - tip[:, 2], 0.0)
    fz = np.where(depth_now > 0, np.maximum(STIFFNESS * depth_now - DAMPING * v, 0.0), 0.0)
    force = np.zeros_like(tip)
    force[:, 2] = fz
    base = 1.7e9
    return Session(t + base, tip, force, [(s, a + base, b + base) for s, a, b in spans])


def sensor_reading(force_world: np.ndarray, bias: float = 0.0) -> np.ndarray:
    """What the wrist sensor reports in its frame (tool z down): the body's force plus the
    probe's weight, rotated into the tool frame; ``bias`` added to its z."""
    weight = np.array([0.0, 0.0, -PROBE_MASS * G])
    world = force_world + weight
    # R(π about x)ᵀ: (x, y, z) → (x, −y, −z)
    tool = world * np.array([1.0, -1.0, -1.0])
    tool[:, 2] += bias
    return tool


def flange_positions(tip: np.ndarray) -> np.ndarray:
    """The flange sits TOOL_OFFSET back along the tool's z, i.e. above the tip."""
    return tip + np.array([0.0, 0.0, TOOL_OFFSET[2]])


def jittered_stamps(t0: float, t1: float, rate: float, jitter: float, rng) -> np.ndarray:
    n = int((t1 - t0) * rate)
    stamps = t0 + np.arange(n) / rate + rng.uniform(-jitter, jitter, n) / rate
    return np.sort(stamps)


def sample(s: Session, stamps: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(stamps, s.t, values[:, k]) for k in range(values.shape[1])], axis=1)


def write_ros2_bag(path: Path, s: Session, storage: str, wrench_rate=500.0, pose_rate=125.0,
                   pose_kind="pose", bias=0.0, seed=0, receive_lag=0.002,
                   pose_clock_offset=0.0) -> None:
    """A ROS 2 bag written by rosbags' Writer (``storage`` ``sqlite3`` or ``mcap``):
    ``/ft_sensor/wrench`` (WrenchStamped, frame ``tool0``) and ``/tcp_pose`` (PoseStamped of
    the flange in ``base``), or ``/tf`` (``pose_kind="tf"``, base → tool0). The pose's
    header stamps may run on another clock (``pose_clock_offset`` s ahead); the bag's
    receive times are on the recorder's clock for both."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    Vector3 = ts.types["geometry_msgs/msg/Vector3"]
    rng = np.random.default_rng(seed)
    tw = jittered_stamps(s.t[0], s.t[-1], wrench_rate, 0.2, rng)
    tp = jittered_stamps(s.t[0], s.t[-1], pose_rate, 0.2, rng)
    reading = sensor_reading(sample(s, tw, s.force), bias)
    flange = flange_positions(sample(s, tp, s.tip))
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3

    def header(stamp: float, frame: str):
        sec = int(stamp)
        return Header(stamp=Time(sec=sec, nanosec=int(round((stamp - sec) * 1e9))), frame_id=frame)

    messages = []
    wrench_type = "geometry_msgs/msg/WrenchStamped"
    for stamp, f in zip(tw, reading):
        msg = ts.types[wrench_type](
            header=header(stamp, "tool0"),
            wrench=ts.types["geometry_msgs/msg/Wrench"](force=Vector3(x=f[0], y=f[1], z=f[2]),
                                                       torque=Vector3(x=0.0, y=0.0, z=0.0)))
        messages.append((stamp, "/ft_sensor/wrench", wrench_type, msg))
    for true_stamp, p in zip(tp, flange):
        stamp = true_stamp + pose_clock_offset
        pose = ts.types["geometry_msgs/msg/Pose"](
            position=ts.types["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
            orientation=ts.types["geometry_msgs/msg/Quaternion"](x=1.0, y=0.0, z=0.0, w=0.0))
        if pose_kind == "tf":
            tf = ts.types["geometry_msgs/msg/TransformStamped"](
                header=header(stamp, "base"), child_frame_id="tool0",
                transform=ts.types["geometry_msgs/msg/Transform"](
                    translation=Vector3(x=p[0], y=p[1], z=p[2]), rotation=pose.orientation))
            messages.append((true_stamp, "/tf", "tf2_msgs/msg/TFMessage",
                             ts.types["tf2_msgs/msg/TFMessage"](transforms=[tf])))
        else:
            messages.append((true_stamp, "/tcp_pose", "geometry_msgs/msg/PoseStamped",
                             ts.types["geometry_msgs/msg/PoseStamped"](header=header(stamp, "base"),
                                                                       pose=pose)))
    messages.sort(key=lambda m: m[0])
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conns = {}
        for _, topic, msgtype, _ in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
        for stamp, topic, msgtype, msg in messages:
            writer.write(conns[topic], int((stamp + receive_lag) * 1e9),
                         ts.serialize_cdr(msg, msgtype))


#: ROS 2 message definitions as `ros2 bag record` embeds them in MCAP (written out here, so
#: the bare-MCAP test does not lean on rosbags to produce its input).
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_SEP = "=" * 80 + "\n"
WRENCH_STAMPED_DEF = ("std_msgs/Header header\ngeometry_msgs/Wrench wrench\n" + _SEP + _HEADER
                      + _SEP + _TIME + _SEP + "MSG: geometry_msgs/Wrench\ngeometry_msgs/Vector3 "
                      "force\ngeometry_msgs/Vector3 torque\n" + _SEP
                      + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n")
POSE_STAMPED_DEF = ("std_msgs/Header header\ngeometry_msgs/Pose pose\n" + _SEP + _HEADER + _SEP
                    + _TIME + _SEP + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\n"
                    "geometry_msgs/Quaternion orientation\n" + _SEP
                    + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + _SEP
                    + "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\n"
                    "float64 w 1\n")


def write_bare_mcap(path: Path, s: Session, wrench_rate=1000.0, pose_rate=100.0, seed=1) -> None:
    """A bare ``.mcap`` (no metadata.yaml) written by the ``mcap`` package's ROS 2 writer."""
    from mcap_ros2.writer import Writer

    rng = np.random.default_rng(seed)
    tw = jittered_stamps(s.t[0], s.t[-1], wrench_rate, 0.2, rng)
    tp = jittered_stamps(s.t[0], s.t[-1], pose_rate, 0.2, rng)
    reading = sensor_reading(sample(s, tw, s.force))
    flange = flange_positions(sample(s, tp, s.tip))

    def header(stamp, frame):
        sec = int(stamp)
        return {"stamp": {"sec": sec, "nanosec": int(round((stamp - sec) * 1e9))}, "frame_id": frame}

    events = [(st, "w", f) for st, f in zip(tw, reading)] + [(st, "p", p) for st, p in zip(tp, flange)]
    events.sort(key=lambda e: e[0])
    with path.open("wb") as handle:
        writer = Writer(handle)
        wrench = writer.register_msgdef("geometry_msgs/msg/WrenchStamped", WRENCH_STAMPED_DEF)
        pose = writer.register_msgdef("geometry_msgs/msg/PoseStamped", POSE_STAMPED_DEF)
        for stamp, kind, v in events:
            ns = int(stamp * 1e9)
            if kind == "w":
                writer.write_message("/wrench", wrench, {
                    "header": header(stamp, "ft_sensor"),
                    "wrench": {"force": {"x": v[0], "y": v[1], "z": v[2]},
                               "torque": {"x": 0.0, "y": 0.0, "z": 0.0}}}, log_time=ns)
            else:
                writer.write_message("/flange_pose", pose, {
                    "header": header(stamp, "world"),
                    "pose": {"position": {"x": v[0], "y": v[1], "z": v[2]},
                             "orientation": {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0}}},
                    log_time=ns)
        writer.finish()
