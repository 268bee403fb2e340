"""Gravity compensation of the probe: the sensor between flange and probe reads the probe's
weight, ``m·g`` turning with the tool, on top of what the body does.

In the tool frame a free-air reading is ``f = m·Rᵀg + b`` (``R`` the tool's orientation,
``b`` the sensor's bias), torques ``τ = (m·c) × Rᵀg + b_τ`` (``c`` the probe's centre of
mass). Least squares over free-air samples gives ``m``, ``b`` (and ``m·c``, ``b_τ``) when
the tool turned enough between them (≥ :data:`MIN_TILT_SPREAD_DEG`) for the weight and the
bias to be told apart; then only the weight is removed and the bias stays for the
calibration to name. A probe that never turned (most ultrasound logs: it points down)
cannot tell them apart: the free-air mean reading is removed (a tare), taking any bias
with it, and the provenance says so. A given mass removes exactly ``m·g`` (forces only:
the centre of mass is unknown then)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from echogym.robotdata.errors import GravityEstimateError
from echogym.robotdata.rotations import angle_between

__all__ = ["G", "GravityModel", "MIN_FREE_AIR_S", "MIN_TILT_SPREAD_DEG", "compensate", "estimate"]

G = 9.80665
GRAVITY_WORLD = np.array([0.0, 0.0, -G])
#: Tilt spread of the free-air samples needed to separate weight from bias [deg].
MIN_TILT_SPREAD_DEG = 10.0
#: Free air needed to estimate anything [s].
MIN_FREE_AIR_S = 0.5


@dataclass
class GravityModel:
    """What is removed: ``method`` is ``given``, ``estimated``, ``tare`` or ``none``."""

    method: str
    mass_kg: float = 0.0
    force_tare: np.ndarray = field(default_factory=lambda: np.zeros(3))
    torque_tare: np.ndarray = field(default_factory=lambda: np.zeros(3))
    mass_moment: np.ndarray | None = None  # m·c in the tool frame [kg·m]
    notes: dict = field(default_factory=dict)

    def describe(self) -> dict:
        out: dict = {"method": self.method, **self.notes}
        if self.method in ("given", "estimated"):
            out["mass_kg"] = round(self.mass_kg, 6)
        if self.method == "tare":
            out["tare_force_tool_n"] = [round(v, 6) for v in self.force_tare]
        if self.mass_moment is not None and self.mass_kg > 0:
            out["centre_of_mass_tool_m"] = [round(v / self.mass_kg, 6) for v in self.mass_moment]
        return out


def estimate(source: object, where: str, t: np.ndarray, f_tool: np.ndarray,
             torque_tool: np.ndarray | None, rotation: np.ndarray, free: np.ndarray) -> GravityModel:
    """Fit the probe's weight (and the sensor's bias) on the free-air samples ``free``."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    free_s = float(free.sum()) * dt
    if free_s < MIN_FREE_AIR_S:
        raise GravityEstimateError(
            source, f"only {free_s:.2f} s of free air (at least {MIN_FREE_AIR_S} s needed) to "
            "estimate the probe's weight; give the mass (--probe-mass KG, or none)",
            where=where, time_s=float(t[0]))
    r = rotation[free]
    g_tool = np.einsum("nji,j->ni", r, GRAVITY_WORLD)  # Rᵀg
    tilt = angle_between(r[:1].repeat(len(r), 0), r)
    spread = float(np.degrees(tilt.max()))
    notes = {"free_air_s": round(free_s, 3), "tilt_spread_deg": round(spread, 2)}
    if spread < MIN_TILT_SPREAD_DEG:
        notes["why"] = (f"the tool turned only {spread:.1f}° in free air (< "
                        f"{MIN_TILT_SPREAD_DEG}°): weight and sensor bias cannot be told apart, "
                        "so the free-air mean was removed (a tare) and any sensor bias with it; "
                        "give --probe-mass to keep the bias")
        return GravityModel("tare", force_tare=f_tool[free].mean(axis=0),
                            torque_tare=(torque_tool[free].mean(axis=0) if torque_tool is not None
                                         else np.zeros(3)), notes=notes)
    n = len(r)
    a = np.zeros((3 * n, 4))
    a[:, 0] = g_tool.reshape(-1)
    a[:, 1:] = np.tile(np.eye(3), (n, 1))
    solution, *_ = np.linalg.lstsq(a, f_tool[free].reshape(-1), rcond=None)
    mass, bias = float(solution[0]), solution[1:]
    notes["sensor_bias_tool_n"] = [round(v, 6) for v in bias]
    notes["why"] = "weight and bias fitted on free air; the weight removed, the bias kept"
    moment = None
    if torque_tool is not None:
        # τ = (m·c) × gₜ + b_τ = −[gₜ]× (m·c) + b_τ
        gx, gy, gz = g_tool.T
        skew = np.zeros((n, 3, 3))
        skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 0] = -gz, gy, gz
        skew[:, 1, 2], skew[:, 2, 0], skew[:, 2, 1] = -gx, -gy, gx
        b = np.zeros((3 * n, 6))
        b[:, :3] = (-skew).reshape(3 * n, 3)
        b[:, 3:] = np.tile(np.eye(3), (n, 1))
        sol, *_ = np.linalg.lstsq(b, torque_tool[free].reshape(-1), rcond=None)
        moment = sol[:3]
    return GravityModel("estimated", mass_kg=mass, mass_moment=moment, notes=notes)


def compensate(force_world: np.ndarray, torque_world: np.ndarray | None, rotation: np.ndarray,
               model: GravityModel) -> tuple[np.ndarray, np.ndarray | None]:
    """Remove what ``model`` says from world-frame forces and torques."""
    f = force_world.copy()
    tq = None if torque_world is None else torque_world.copy()
    if model.method == "tare":
        f -= np.einsum("nij,j->ni", rotation, model.force_tare)
        if tq is not None:
            tq -= np.einsum("nij,j->ni", rotation, model.torque_tare)
    elif model.method in ("given", "estimated"):
        f -= model.mass_kg * GRAVITY_WORLD
        if tq is not None and model.mass_moment is not None:
            moment_world = np.einsum("nij,j->ni", rotation, model.mass_moment)
            tq -= np.cross(moment_world, GRAVITY_WORLD)
    return f, tq
