"""The server's ``scene_state`` fields of one env, decoded: what a viewer draws.

An env created with ``scene_state=True`` (or ``render_mode="rerun"``) delivers four extra
float32 fields every step (docs/viewer.md has the layout): every collider's shape, part,
colour and world pose; the torso's surface mesh and its indentation; the probe's contact
point and force. :meth:`SceneState.from_fields` turns one env's slice of them into
numpy arrays and names.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from echogym.render import SCENE_FIELDS

__all__ = ["SHAPE_KINDS", "Collider", "SceneState", "part_name"]

#: ``scene_colliders[:, 0]`` codes.
SHAPE_KINDS = {0: "box", 1: "capsule", 2: "sphere", 3: "cylinder", 4: "torso_mesh"}

_PARTS = {0: "table", 1: "torso", 2: "probe", 3: "object"}


def part_name(code: int) -> str:
    """``scene_colliders[:, 1]`` as a name: ``table``, ``torso``, ``probe``, ``object``,
    or ``link<k>`` (arm link ``k`` from the base)."""
    return _PARTS.get(code, f"link{code - 4}")


@dataclass(frozen=True)
class Collider:
    """One collider: ``dims`` are half extents (box), ``[radius, half length]``
    (capsule, cylinder; axis along the pose's z) or ``[radius]`` (sphere)."""

    kind: str
    part: str
    colour: np.ndarray
    dims: np.ndarray
    position: np.ndarray
    quaternion_xyzw: np.ndarray


@dataclass(frozen=True)
class SceneState:
    """One env's scene at one step (world frame, metres, newtons)."""

    colliders: list[Collider]
    #: Surface vertices ``(V, 3)`` and their indentation ``(V,)`` (positive pressed in).
    torso_vertices: np.ndarray
    torso_indentation: np.ndarray
    #: Vertex indices ``(T, 3)``.
    torso_triangles: np.ndarray
    contact_point: np.ndarray
    #: Contact force on the probe (noise-free).
    contact_force: np.ndarray
    in_contact: bool
    #: Force along the probe axis (positive pressing).
    axial_force: float

    @classmethod
    def from_fields(cls, fields: Mapping[str, np.ndarray]) -> SceneState:
        """Decode one env's fields (no batch axis). Raises ``KeyError`` naming the
        missing fields when the env was made without ``scene_state=True``."""
        missing = [name for name in SCENE_FIELDS if name not in fields]
        if missing:
            raise KeyError(f"no scene-state fields {missing}: create the env with scene_state=True "
                           "(or render_mode='rerun')")
        colliders = []
        for row in np.asarray(fields["scene_colliders"], dtype=np.float64):
            if row[0] < 0:
                continue
            colliders.append(Collider(
                kind=SHAPE_KINDS.get(int(row[0]), "box"),
                part=part_name(int(row[1])),
                colour=row[2:5].copy(),
                dims=row[5:8].copy(),
                position=row[8:11].copy(),
                quaternion_xyzw=row[11:15].copy(),
            ))
        # The vertices in use are those the triangles in use index (a prefix).
        triangles = np.asarray(fields["torso_triangles"]).reshape(-1, 3)
        triangles = triangles[triangles[:, 0] >= 0].astype(np.uint32)
        count = int(triangles.max()) + 1 if len(triangles) else 0
        vertices = np.asarray(fields["torso_vertices"]).reshape(-1, 4)[:count]
        contact = np.asarray(fields["scene_contact"], dtype=np.float64)
        return cls(
            colliders=colliders,
            torso_vertices=vertices[:, :3].astype(np.float32),
            torso_indentation=vertices[:, 3].astype(np.float32),
            torso_triangles=triangles,
            contact_point=contact[0:3].copy(),
            contact_force=contact[3:6].copy(),
            in_contact=bool(contact[6] > 0.5),
            axial_force=float(contact[7]),
        )

    def torso_normals(self) -> np.ndarray:
        """Unit vertex normals of the torso's surface (area-weighted), ``(V, 3)``."""
        v = self.torso_vertices.astype(np.float64)
        t = self.torso_triangles.astype(np.int64)
        normals = np.zeros_like(v)
        if len(t):
            face = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
            corners = t.reshape(-1)
            for axis in range(3):
                normals[:, axis] = np.bincount(corners, np.repeat(face[:, axis], 3), minlength=len(v))
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        return (normals / np.where(length > 0, length, 1.0)).astype(np.float32)
