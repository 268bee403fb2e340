"""Forward kinematics of a serial chain read from a URDF, for logs that carry joint
states rather than the tool's pose: ``sensor_msgs/JointState`` plus the robot's URDF give
the tip pose in the base link's frame."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from echogym.robotdata.errors import MappingError
from echogym.robotdata.rotations import matrix_from_rpy

__all__ = ["Chain", "load_chain"]


@dataclass(frozen=True)
class _Joint:
    name: str
    kind: str  # revolute, continuous, prismatic, fixed
    origin: np.ndarray  # 4×4 in the parent link
    axis: np.ndarray


@dataclass(frozen=True)
class Chain:
    """The joints from ``base_link`` to ``tip_link`` in order; ``moving`` names the ones a
    joint state must give."""

    base_link: str
    tip_link: str
    joints: tuple[_Joint, ...]

    @property
    def moving(self) -> list[str]:
        return [j.name for j in self.joints if j.kind != "fixed"]

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Tip poses ``[N, 4, 4]`` in the base link for joint positions ``q [N, len(moving)]``
        (rad, or m for prismatic joints) in :attr:`moving` order."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        k = 0
        for joint in self.joints:
            out = out @ joint.origin
            if joint.kind == "fixed":
                continue
            motion = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
            if joint.kind == "prismatic":
                motion[:, :3, 3] = q[:, k, None] * joint.axis
            else:
                motion[:, :3, :3] = _axis_angle(joint.axis, q[:, k])
            out = out @ motion
            k += 1
        return out


def _axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for a unit ``axis`` and ``angle [N]`` → ``[N, 3, 3]``."""
    x, y, z = axis
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def _floats(text: str | None, default: str, path: Path, where: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in (text or default).split()])
    except ValueError:
        raise MappingError(path, f"not three numbers: {text!r}", where=where) from None
    if values.shape != (3,):
        raise MappingError(path, f"not three numbers: {text!r}", where=where)
    return values


def load_chain(path: str | Path, base_link: str | None = None,
               tip_link: str | None = None) -> Chain:
    """The chain of the URDF at ``path`` from ``base_link`` (default: the root link) to
    ``tip_link`` (default: the leaf reached through the most joints)."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise MappingError(path, f"cannot read the URDF: {exc}", where="robot.urdf") from None
    by_child: dict[str, tuple[str, _Joint]] = {}
    for element in root.findall("joint"):
        name = element.get("name", "?")
        kind = element.get("type", "fixed")
        if kind not in ("revolute", "continuous", "prismatic", "fixed"):
            raise MappingError(path, f"joint type {kind!r} is not part of a serial arm",
                               where=f"joint {name}")
        parent = element.find("parent")
        child = element.find("child")
        if parent is None or child is None:
            raise MappingError(path, "joint without parent or child", where=f"joint {name}")
        origin = element.find("origin")
        xyz = _floats(origin.get("xyz") if origin is not None else None, "0 0 0", path, name)
        rpy = _floats(origin.get("rpy") if origin is not None else None, "0 0 0", path, name)
        axis_el = element.find("axis")
        axis = _floats(axis_el.get("xyz") if axis_el is not None else None, "1 0 0", path, name)
        transform = np.eye(4)
        transform[:3, :3] = matrix_from_rpy(rpy)
        transform[:3, 3] = xyz
        by_child[child.get("link", "")] = (parent.get("link", ""),
                                          _Joint(name, kind, transform, axis / np.linalg.norm(axis)))
    links = {el.get("name", "") for el in root.findall("link")}
    if not by_child:
        raise MappingError(path, "no joints", where="robot.urdf")

    def ancestry(link: str) -> list[str]:
        chain = [link]
        while chain[-1] in by_child:
            chain.append(by_child[chain[-1]][0])
        return chain

    if tip_link is None:
        leaves = links - {p for p, _ in by_child.values()}
        tip_link = max(sorted(leaves), key=lambda link: len(ancestry(link)))
    if tip_link not in links:
        raise MappingError(path, f"no link {tip_link!r}", where="robot.tip_link")
    lineage = ancestry(tip_link)
    base_link = base_link or lineage[-1]
    if base_link not in lineage:
        raise MappingError(path, f"{base_link!r} is not an ancestor of {tip_link!r}",
                           where="robot.base_link")
    joints = [by_child[link][1] for link in lineage[: lineage.index(base_link)]]
    return Chain(base_link, tip_link, tuple(reversed(joints)))
