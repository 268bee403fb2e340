"""The scripted sweep policy of ``echogym demo`` and ``echogym ultrasound``, for
``echogym/UltrasoundScan-v0`` under the hybrid force/motion controller: motion in the
skin's plane towards the moving target point (with look-ahead), the probe turned back to
upright; the controller holds the force along the probe axis."""

from __future__ import annotations

import numpy as np

#: The probe upright (face down, array along world y) as a quaternion (x, y, z, w).
UPRIGHT = np.array([1.0, 0.0, 0.0, 0.0])
#: Look-ahead of the scripted policy along the target's motion [s].
LEAD_S = 0.2
#: The controller's default ``position_limit`` [m]: the translation of a full-scale action.
POSITION_LIMIT = 0.05
#: The controller's default ``rotation_limit`` [rad]: the rotation of a full-scale action.
ROTATION_LIMIT = 0.5


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (x, y, z, w) quaternions, batched over the first axis."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ], axis=-1)


def rotation_to_upright(quat: np.ndarray) -> np.ndarray:
    """Axis-angle (world frame, rad) that turns each probe orientation into upright."""
    conj = quat * np.array([-1.0, -1.0, -1.0, 1.0])
    err = _quat_mul(np.broadcast_to(UPRIGHT, quat.shape), conj)
    err = np.where(err[..., 3:4] < 0, -err, err)
    vec = err[..., :3]
    norm = np.linalg.norm(vec, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(norm, err[..., 3:4])
    return np.where(norm > 1e-12, vec / np.maximum(norm, 1e-12) * angle, 0.0)


def scripted_action(obs: dict[str, np.ndarray]) -> np.ndarray:
    """The batch of actions ``(num_envs, 6)`` for a batch of observations (``task_errors``
    and ``probe_pose`` fields), clipped to ±1."""
    errors = obs["task_errors"].astype(np.float64)
    n = errors.shape[0]
    action = np.zeros((n, 6))
    action[:, 0:2] = (-errors[:, 0:2] + LEAD_S * errors[:, 6:8]) / POSITION_LIMIT
    action[:, 3:6] = rotation_to_upright(obs["probe_pose"][:, 3:7].astype(np.float64)) / ROTATION_LIMIT
    return np.clip(action, -1.0, 1.0).astype(np.float32)
