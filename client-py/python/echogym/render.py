"""What the render modes add to an env's config, and which fields they hide.

``render_mode="rgb_array"`` adds a viewing camera (``VIEW_CAMERA``: a 256 × 256,
smooth-shaded view of the whole scene rendered by the server next to the physics);
``render_mode="rerun"`` turns on the server's ``scene_state`` fields (arm and probe shapes
and poses, the torso's surface, the contact). Both are for watching, not for the policy:
the fields they add are hidden from the observation space, so a policy trained without a
render mode runs unchanged with one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "RENDER_MODES",
    "SCENE_FIELDS",
    "VIEW_CAMERA",
    "render_config",
    "render_fps",
    "visible_fields",
]

#: The render modes of :class:`echogym.EchoEnv` and :class:`echogym.EchoVectorEnv`.
RENDER_MODES = ("rgb_array", "rerun")

#: The server's scene-state fields (``scene_state=True``; docs/viewer.md).
SCENE_FIELDS = ("scene_colliders", "torso_vertices", "torso_triangles", "scene_contact")

#: The camera ``render_mode="rgb_array"`` adds (override keys with ``render_camera={...}``).
VIEW_CAMERA: dict[str, Any] = {
    "name": "viewer",
    "preset": "overview",
    "width": 256,
    "height": 256,
    "depth": False,
    "shading": "smooth",
}


def render_config(
    config: dict[str, Any], render_mode: str | None, render_camera: dict[str, Any] | None = None
) -> tuple[dict[str, Any], frozenset[str]]:
    """``config`` with what ``render_mode`` needs, and the names of the fields that adds.

    Raises ``ValueError`` for an unknown mode, a ``render_camera`` without ``render_mode
    ="rgb_array"``, or a configured camera already named like the viewing camera.
    """
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, got {render_mode!r}")
    if render_camera is not None and render_mode != "rgb_array":
        raise ValueError("render_camera is only used with render_mode='rgb_array'")
    config = dict(config)
    added: set[str] = set()
    if render_mode == "rgb_array":
        camera = {**VIEW_CAMERA, **(render_camera or {})}
        cameras = list(config.get("cameras") or [])
        if any(isinstance(c, dict) and c.get("name") == camera["name"] for c in cameras):
            raise ValueError(f"render_mode='rgb_array' adds a camera named {camera['name']!r}; "
                             "rename yours or pass render_camera={'name': ...}")
        config["cameras"] = [*cameras, camera]
        added.add(f"{camera['name']}_rgb")
        if camera.get("depth", True):
            added.add(f"{camera['name']}_depth")
    if render_mode == "rerun" and not config.get("scene_state", False):
        config["scene_state"] = True
        added.update(SCENE_FIELDS)
    return config, frozenset(added)


def visible_fields(spec: dict[str, Any], hidden: frozenset[str]) -> tuple[dict[str, Any], list[int]]:
    """The spec as the policy sees it (``hidden`` fields removed) and the indices of the
    remaining fields in the server's field order."""
    keep = [i for i, f in enumerate(spec["observation"]) if f["name"] not in hidden]
    return {**spec, "observation": [spec["observation"][i] for i in keep]}, keep


def render_fps(spec: dict[str, Any]) -> dict[str, int]:
    """``{"render_fps": N}``: frames per second of a video with one frame per env step;
    empty for envs without simulated time (``dt_s`` 0, e.g. ``echogym/Null-v0``)."""
    dt = float(spec.get("dt_s") or 0.0)
    return {"render_fps": max(1, int(np.round(1.0 / dt)))} if dt > 0 else {}
