"""What ``echogym import`` needs to know about a log: :class:`ImportOptions`, set by keyword,
by command-line flags or by a TOML mapping file (:func:`load_mapping`), whose sections and
keys are listed in :data:`MAPPING_KEYS` (docs/data.md shows a full file)."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from echogym.robotdata.errors import MappingError

__all__ = ["CsvColumns", "ImportOptions", "MAPPING_KEYS", "load_mapping"]

#: Unit names → factor to SI.
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
FORCE_UNITS = {"N": 1.0, "mN": 1e-3, "kN": 1e3}
TORQUE_UNITS = {"N*m": 1.0, "Nm": 1.0, "N*mm": 1e-3, "Nmm": 1e-3}


@dataclass
class CsvColumns:
    """Which CSV columns hold what, and their units. Orientation comes from ``quaternion``
    (x, y, z, w columns), or ``rpy`` (roll, pitch, yaw columns in rad), or is the fixed
    ``orientation_rpy`` when neither is given (a probe held upright, say)."""

    time: str = "t"
    time_unit: str = "s"
    position: list[str] = field(default_factory=lambda: ["px", "py", "pz"])
    position_unit: str = "m"
    quaternion: list[str] | None = None
    rpy: list[str] | None = None
    #: Default: the probe upright, its z axis pointing down (π about x).
    orientation_rpy: list[float] = field(default_factory=lambda: [math.pi, 0.0, 0.0])
    force: list[str] = field(default_factory=lambda: ["fx", "fy", "fz"])
    force_unit: str = "N"
    torque: list[str] | None = None
    torque_unit: str = "N*m"
    delimiter: str = ","


@dataclass
class ImportOptions:
    """How to read and transform a log. Every field has a default but the topics of a bag.

    Bags and MCAP: ``wrench_topic`` (``geometry_msgs/WrenchStamped``) and ``pose_topic``
    (``PoseStamped``, ``TransformStamped``, ``tf2_msgs/TFMessage`` with ``tf_parent`` and
    ``tf_child``, or ``sensor_msgs/JointState`` with ``urdf``). The rest applies to every
    source (see docs/data.md for what each transform assumes)."""

    wrench_topic: str | None = None
    pose_topic: str | None = None
    tf_parent: str | None = None
    tf_child: str | None = None
    urdf: str | None = None
    base_link: str | None = None
    tip_link: str | None = None
    #: Probe tip in the frame the pose gives (flange → tip) [m].
    tool_offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    #: Fixed rotation sensor → tool frame, roll-pitch-yaw [rad].
    sensor_rotation_rpy: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    #: ``auto`` (the pose's parent frame when the wrench's frame_id names it, else the
    #: tool), ``tool`` or ``world``.
    wrench_frame: str = "auto"
    #: +1: the wrench is the load on the probe (echogym's convention); −1 flips it.
    wrench_sign: float = 1.0
    #: Probe mass [kg], ``"estimate"`` (from free air) or ``"none"`` (no compensation).
    probe_mass: float | str = "estimate"
    #: ``header`` stamps, ``receive`` (bag) time, or ``auto`` (header stamps, put onto the
    #: receive clock when the topics' header clocks disagree).
    clock: str = "auto"
    #: Added to the pose's time stamps [s] (a known clock offset or latency).
    pose_time_offset_s: float = 0.0
    #: Resample onto this uniform rate [Hz]; ``None`` keeps the wrench's own stamps (or
    #: 1000 Hz when those are faster than the format's 2000 Hz).
    rate_hz: float | None = None
    #: Longest pose interval a wrench sample may be placed in [s]; ``None``: max(5 × the
    #: pose topic's median interval, 0.05 s), the recordings format's gap rule.
    pose_reach_s: float | None = None
    surface_z: float | None = None
    torso_center: list[float] | None = None
    #: Named sites as xy offsets from the torso centre [m]; ``None``: the seed's five;
    #: ``"cluster"``: clusters of contact positions named ``site_1``, ``site_2``, ….
    sites: dict[str, list[float]] | str | None = None
    #: Protocol written for every recording; ``None``: classified (press, slide, chirp).
    protocol: str | None = None
    #: ``auto``: split at gaps and where consecutive contacts are at different sites;
    #: ``gaps``: at gaps only (one recording per file and gap-free stretch).
    split: str = "auto"
    #: Contact threshold on the compensated force [N]; ``None``: max(0.5, 6 σ of free air).
    contact_threshold_n: float | None = None
    csv: CsvColumns = field(default_factory=CsvColumns)

    def check(self, source: object = "options") -> None:
        """Refuse values out of their domain, naming the option."""
        if self.wrench_frame not in ("auto", "tool", "world"):
            raise MappingError(source, f"must be auto, tool or world, not {self.wrench_frame!r}",
                               where="wrench_frame")
        if self.clock not in ("auto", "header", "receive"):
            raise MappingError(source, f"must be auto, header or receive, not {self.clock!r}",
                               where="clock")
        if self.split not in ("auto", "gaps"):
            raise MappingError(source, f"must be auto or gaps, not {self.split!r}", where="split")
        if self.wrench_sign not in (1, -1, 1.0, -1.0):
            raise MappingError(source, "must be 1 or -1", where="wrench_sign")
        if isinstance(self.probe_mass, str) and self.probe_mass not in ("estimate", "none"):
            raise MappingError(source, f"must be a mass in kg, estimate or none, not "
                               f"{self.probe_mass!r}", where="probe_mass")
        if not isinstance(self.probe_mass, str) and not 0 <= float(self.probe_mass) < 50:
            raise MappingError(source, "must be 0–50 kg", where="probe_mass")
        if self.rate_hz is not None and not 50 <= self.rate_hz <= 2000:
            raise MappingError(source, "must be 50–2000 Hz (the recordings format's range)",
                               where="rate_hz")
        for name, size in (("tool_offset", 3), ("sensor_rotation_rpy", 3)):
            if len(getattr(self, name)) != size:
                raise MappingError(source, f"needs {size} numbers", where=name)
        if self.torso_center is not None and len(self.torso_center) != 2:
            raise MappingError(source, "needs x, y", where="torso_center")
        if isinstance(self.sites, str) and self.sites != "cluster":
            raise MappingError(source, "must be a table of name = [x, y] or \"cluster\"",
                               where="sites")
        c = self.csv
        for key, table, unit in (("csv.time_unit", TIME_UNITS, c.time_unit),
                                 ("csv.position_unit", LENGTH_UNITS, c.position_unit),
                                 ("csv.force_unit", FORCE_UNITS, c.force_unit),
                                 ("csv.torque_unit", TORQUE_UNITS, c.torque_unit)):
            if unit not in table:
                raise MappingError(source, f"unknown unit {unit!r}; one of {sorted(table)}",
                                   where=key)


#: TOML mapping file: section → key → :class:`ImportOptions` field (``csv`` keys are
#: :class:`CsvColumns` fields).
MAPPING_KEYS: dict[str, dict[str, str]] = {
    "topics": {"wrench": "wrench_topic", "pose": "pose_topic", "tf_parent": "tf_parent",
               "tf_child": "tf_child"},
    "robot": {"urdf": "urdf", "base_link": "base_link", "tip_link": "tip_link"},
    "probe": {"tool_offset": "tool_offset", "sensor_rotation_rpy": "sensor_rotation_rpy",
              "wrench_frame": "wrench_frame", "wrench_sign": "wrench_sign", "mass": "probe_mass"},
    "time": {"clock": "clock", "pose_offset_s": "pose_time_offset_s", "rate_hz": "rate_hz",
             "pose_reach_s": "pose_reach_s"},
    "scene": {"surface_z": "surface_z", "torso_center": "torso_center", "sites": "sites",
              "protocol": "protocol", "split": "split",
              "contact_threshold_n": "contact_threshold_n"},
    "csv": {f.name: f.name for f in dataclasses.fields(CsvColumns)},
}


def load_mapping(path: str | Path, base: ImportOptions | None = None) -> ImportOptions:
    """Read a TOML mapping file onto ``base`` (default: the defaults). Unknown sections
    or keys raise :class:`MappingError` naming them; a relative ``robot.urdf`` is taken
    relative to the mapping file."""
    path = Path(path)
    try:
        data: dict[str, Any] = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise MappingError(path, f"cannot read the mapping: {exc}") from None
    options = dataclasses.replace(base or ImportOptions())
    options.csv = dataclasses.replace(options.csv)
    for section, values in data.items():
        keys = MAPPING_KEYS.get(section)
        if keys is None or not isinstance(values, dict):
            raise MappingError(path, f"unknown section; known: {sorted(MAPPING_KEYS)}",
                               where=f"[{section}]")
        for key, value in values.items():
            if key not in keys:
                raise MappingError(path, f"unknown key; [{section}] knows {sorted(keys)}",
                                   where=f"{section}.{key}")
            target = options.csv if section == "csv" else options
            setattr(target, keys[key], value)
    if options.urdf is not None and not Path(options.urdf).is_absolute():
        options.urdf = str(path.parent / options.urdf)
    options.check(path)
    return options
