"""Rotations as numpy arrays: quaternions in ROS order ``(x, y, z, w)``, matrices acting on
column vectors (``v_world = R @ v_tool``), fixed-axis roll-pitch-yaw as in URDF."""

from __future__ import annotations

import numpy as np

__all__ = ["matrix_from_quaternion", "matrix_from_rpy", "quaternion_from_matrix", "slerp",
           "angle_between"]


def matrix_from_quaternion(q: np.ndarray) -> np.ndarray:
    """``[..., 4]`` quaternions (x, y, z, w; normalised here) → ``[..., 3, 3]`` matrices."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def quaternion_from_matrix(r: np.ndarray) -> np.ndarray:
    """``[..., 3, 3]`` rotation matrices → ``[..., 4]`` quaternions (x, y, z, w), w ≥ 0."""
    r = np.asarray(r, dtype=float)
    flat = r.reshape(-1, 3, 3)
    out = np.empty((len(flat), 4))
    for i, m in enumerate(flat):
        # Shepperd's method: pivot on the largest of w², x², y², z² for accuracy.
        t = np.trace(m)
        cands = [t, m[0, 0], m[1, 1], m[2, 2]]
        k = int(np.argmax(cands))
        if k == 0:
            s = 2 * np.sqrt(1 + t)
            q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
        elif k == 1:
            s = 2 * np.sqrt(1 + m[0, 0] - m[1, 1] - m[2, 2])
            q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
        elif k == 2:
            s = 2 * np.sqrt(1 + m[1, 1] - m[0, 0] - m[2, 2])
            q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
        else:
            s = 2 * np.sqrt(1 + m[2, 2] - m[0, 0] - m[1, 1])
            q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
        q = np.asarray(q)
        out[i] = -q if q[3] < 0 else q
    return out.reshape(r.shape[:-2] + (4,))


def matrix_from_rpy(rpy: np.ndarray | list[float]) -> np.ndarray:
    """Fixed-axis roll, pitch, yaw (URDF's ``rpy``: ``Rz(yaw) Ry(pitch) Rx(roll)``)."""
    roll, pitch, yaw = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def slerp(q0: np.ndarray, q1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Spherical interpolation between rows of ``q0`` and ``q1`` (``[N, 4]``) at ``u`` ∈ [0, 1]."""
    q0 = q0 / np.linalg.norm(q0, axis=-1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)  # the short way round
    dot = np.abs(dot).clip(max=1.0)
    theta = np.arccos(dot)
    small = theta < 1e-6
    sin = np.where(small, 1.0, np.sin(theta))
    a = np.where(small, 1 - u, np.sin((1 - u) * theta) / sin)
    b = np.where(small, u, np.sin(u * theta) / sin)
    q = a[:, None] * q0 + b[:, None] * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def angle_between(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """Rotation angle [rad] of ``r0ᵀ r1`` for stacks of matrices."""
    rel = np.einsum("...ji,...jk->...ik", r0, r1)
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1) / 2
    return np.arccos(np.clip(cos, -1.0, 1.0))
