"""Frames: the wrench from the sensor frame into the world (through a fixed sensor → tool
rotation and the tool's orientation from the pose), and the probe tip from the pose's
frame (a flange, say) by a fixed tool offset.

Convention of the recordings format: world frame, z up, the force the body exerts on the
probe (pressing down reads ``fz > 0``). A sensor reporting the opposite (the load the
tool puts on the sensor) is flipped with ``wrench_sign = -1``."""

from __future__ import annotations

import numpy as np

from echogym.robotdata.rotations import matrix_from_quaternion, matrix_from_rpy

__all__ = ["tip_positions", "wrench_in_tool", "wrench_to_world"]


def wrench_in_tool(force: np.ndarray, torque: np.ndarray | None, sensor_rotation_rpy: list[float],
                   sign: float) -> tuple[np.ndarray, np.ndarray | None]:
    """The sensor's reading rotated into the tool frame (``R_tool_sensor``) and signed."""
    r = matrix_from_rpy(sensor_rotation_rpy)
    f = sign * force @ r.T
    return f, None if torque is None else sign * torque @ r.T


def wrench_to_world(vectors: np.ndarray, quaternion: np.ndarray) -> np.ndarray:
    """Tool-frame vectors ``[N, 3]`` rotated to the world by each sample's orientation."""
    return np.einsum("nij,nj->ni", matrix_from_quaternion(quaternion), vectors)


def tip_positions(position: np.ndarray, quaternion: np.ndarray, tool_offset: list[float]) -> np.ndarray:
    """The probe tip: the pose's origin plus ``tool_offset`` expressed in the pose's frame."""
    offset = np.asarray(tool_offset, dtype=float)
    if not offset.any():
        return position.copy()
    return position + wrench_to_world(np.broadcast_to(offset, position.shape), quaternion)
