"""Gymnasium spaces from an echogym env spec."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces


def _bound(value: float | None, default: float) -> float:
    return default if value is None else value


def field_space(field: dict[str, Any]) -> spaces.Box:
    """The Box of one observation field."""
    dtype = np.dtype(field["dtype"])
    shape = tuple(field["shape"])
    if dtype.kind == "f":
        low = _bound(field["low"], -np.inf)
        high = _bound(field["high"], np.inf)
    else:
        info = np.iinfo(dtype)
        low = _bound(field["low"], info.min)
        high = _bound(field["high"], info.max)
    return spaces.Box(low=low, high=high, shape=shape, dtype=dtype)


def observation_space(spec: dict[str, Any]) -> spaces.Space:
    """One env's observation space: a Box for a single field, else a Dict by field name."""
    fields = spec["observation"]
    if len(fields) == 1:
        return field_space(fields[0])
    return spaces.Dict({f["name"]: field_space(f) for f in fields})


def action_space(spec: dict[str, Any]) -> spaces.Box:
    """One env's action space (float32 Box with the spec's bounds)."""
    action = spec["action"]
    return spaces.Box(
        low=np.asarray(action["low"], dtype=np.float32),
        high=np.asarray(action["high"], dtype=np.float32),
        dtype=np.float32,
    )


def obs_from_fields(spec: dict[str, Any], fields: tuple[np.ndarray, ...]) -> Any:
    """Batch observation in the space's structure: the array, or a dict of arrays."""
    if len(fields) == 1:
        return fields[0]
    return {f["name"]: a for f, a in zip(spec["observation"], fields)}
