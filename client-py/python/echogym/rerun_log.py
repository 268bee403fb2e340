"""`RerunLogger`: echogym steps as a rerun recording (3-D scene, time series, images).

Everything lands on two timelines, ``step`` (env steps since the logger started) and
``sim_time`` (seconds of simulated time). Per env ``i``:

* ``world/env_i/...`` — the 3-D scene: the table, each arm link's capsules, the probe
  (their real collision shapes, posed every step), the torso's deforming surface as a mesh
  coloured by indentation (skin → blue at 1 cm), the contact point and the contact force
  on the probe as an arrow (1 cm per N). Envs sit side by side, ``spacing`` metres apart.
* ``env_i/ft`` (lines ``fx fy fz tx ty tz``), ``env_i/force`` (``axial``, ``target``),
  ``env_i/reward`` (``total`` and each term), ``env_i/joints`` (``q0``...),
  ``env_i/info`` (the other info values) — time series, one entity per plot with a named
  line per value.
* ``env_i/cameras/<name>`` (RGB and depth), ``env_i/ultrasound`` — images.
* ``env_i/events`` — episode ends.

Logs go to the given ``recording``, else rerun's current one (``rr.init``, or a
``with recording:`` block; when there is none, one named ``echogym`` that spawns the
viewer, like rerun's own examples).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from echogym.render import SCENE_FIELDS
from echogym.scene_state import SceneState

__all__ = ["RerunLogger", "import_rerun"]

_FT = ("fx", "fy", "fz", "tx", "ty", "tz")
_SKIN = np.array([0.93, 0.71, 0.60])
_PRESSED = np.array([0.15, 0.30, 0.90])
#: Indentation shown fully blue [m].
_FULL_INDENTATION = 0.01
#: Arrow length per newton of contact force [m/N].
_ARROW_M_PER_N = 0.01


def import_rerun() -> Any:
    """The ``rerun`` module, or an ``ImportError`` saying how to install it."""
    try:
        import rerun
    except ImportError as exc:
        raise ImportError("the rerun viewer needs rerun-sdk: pip install 'echogym[viewer]'") from exc
    return rerun


def _rgba(colour: np.ndarray) -> np.ndarray:
    # The server's part colours are linear; rerun takes sRGB bytes.
    return np.append(np.clip(colour, 0, 1) ** (1 / 2.2) * 255, 255).astype(np.uint8)


def target_force(spec: Mapping[str, Any]) -> float | None:
    """The env's force target [N]: the task's ``target_force``, else the hybrid
    controller's; ``None`` when it has none."""
    config = spec.get("config") or {}
    for section in ("task", "controller"):
        value = (config.get(section) or {}).get("target_force")
        if isinstance(value, (int, float)):
            return float(value)
    return None


class RerunLogger:
    """Logs batches of echogym fields (``{name: (num_envs, ...)}``) to rerun.

    Args:
        spec: The env's spec (``env.unwrapped.echo_spec``); needs the ``scene_state``
            fields for the 3-D scene (time series and images are logged without).
        num_envs: Envs in each batch.
        recording: A ``rerun.RecordingStream`` (default: rerun's global recording).
        envs: Which envs to log (default all).
        every: Log every ``every``-th step (the scene at 500 Hz is more than a viewer
            shows; 10 gives 50 frames/s).
        spacing: Distance between envs in the 3-D view [m].
    """

    def __init__(self, spec: Mapping[str, Any], num_envs: int = 1, *, recording: Any = None,
                 envs: Sequence[int] | None = None, every: int = 1, spacing: float = 1.5) -> None:
        rr = import_rerun()
        self._rr = rr
        if recording is None:
            recording = rr.get_data_recording()
            if recording is None:
                rr.init("echogym", spawn=True)
                recording = rr.get_data_recording()
        self.recording = recording
        if every < 1:
            raise ValueError(f"every must be ≥ 1, got {every}")
        self.every = every
        self.envs = list(range(num_envs) if envs is None else envs)
        if any(not 0 <= i < num_envs for i in self.envs):
            raise ValueError(f"envs {self.envs} outside 0..{num_envs - 1}")
        self.spacing = spacing
        self.dt = float(spec["dt_s"])
        names = [f["name"] for f in spec["observation"]]
        self.has_scene = all(name in names for name in SCENE_FIELDS)
        self.target_force = target_force(spec)
        self.step = 0
        self._episodes = np.zeros(num_envs, dtype=np.int64)
        self._static_logged = False
        self._named: set[str] = set()
        self._triangles: dict[int, np.ndarray] = {}

    # --- public -------------------------------------------------------------------------

    def log_reset(self, fields: Mapping[str, np.ndarray], infos: Mapping[str, Any],
                  mask: np.ndarray | None = None) -> None:
        """Log the state after a reset (of the envs in ``mask``, default all)."""
        self._set_time()
        self._log(fields, None, infos)

    def log_step(self, fields: Mapping[str, np.ndarray], reward: np.ndarray, terminated: np.ndarray,
                 truncated: np.ndarray, infos: Mapping[str, Any]) -> None:
        """Log one step of every env (every ``every``-th call)."""
        self.step += 1
        done = np.asarray(terminated) | np.asarray(truncated)
        if done.any():
            self._set_time()
            for i in np.flatnonzero(done):
                self._episodes[i] += 1
                if i in self.envs:
                    how = "terminated" if terminated[i] else "truncated"
                    self.recording.log(f"env_{i}/events", self._rr.TextLog(
                        f"episode {self._episodes[i]} {how} at step {self.step}", level="INFO"))
        if self.step % self.every:
            return
        self._set_time()
        self._log(fields, np.asarray(reward), infos)

    # --- internals ----------------------------------------------------------------------

    def _set_time(self) -> None:
        self.recording.set_time("step", sequence=self.step)
        self.recording.set_time("sim_time", duration=self.step * self.dt)

    def _log(self, fields: Mapping[str, np.ndarray], reward: np.ndarray | None,
             infos: Mapping[str, Any]) -> None:
        for i in self.envs:
            one = {name: np.asarray(batch[i]) for name, batch in fields.items()}
            if self.has_scene:
                self._log_scene(i, SceneState.from_fields(one))
            self._log_series(i, one, reward, infos)
            self._log_images(i, one)
        self._static_logged = True

    def _log_scene(self, i: int, scene: SceneState) -> None:
        rr, rec = self._rr, self.recording
        root = f"world/env_{i}"
        if not self._static_logged:
            rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            rec.log(root, rr.Transform3D(translation=[0.0, i * self.spacing, 0.0]), static=True)
        counts: dict[str, int] = {}
        for c in scene.colliders:
            if c.kind == "torso_mesh":
                continue
            k = counts.get(c.part, 0)
            counts[c.part] = k + 1
            group = "arm/" if c.part.startswith("link") else ""
            path = f"{root}/{group}{c.part}/{k}"
            if not self._static_logged:
                rec.log(path, self._shape(c), static=True)
            rec.log(path, rr.Transform3D(translation=c.position,
                                         quaternion=rr.Quaternion(xyzw=c.quaternion_xyzw)))
        if len(scene.torso_vertices):
            t = np.clip(scene.torso_indentation / _FULL_INDENTATION, 0.0, 1.0)[:, None]
            colours = ((_SKIN * (1 - t) + _PRESSED * t) ** (1 / 2.2) * 255).astype(np.uint8)
            # The topology changes only with a reshaped torso (a new episode's draw): log the
            # triangles then, the vertices every time (the viewer joins the latest of each).
            last = self._triangles.get(i)
            fresh = last is None or not np.array_equal(last, scene.torso_triangles)
            if fresh:
                self._triangles[i] = scene.torso_triangles
            rec.log(f"{root}/torso", rr.Mesh3D.from_fields(
                vertex_positions=scene.torso_vertices,
                triangle_indices=scene.torso_triangles if fresh else None,
                vertex_normals=scene.torso_normals(),
                vertex_colors=colours,
            ))
        if scene.in_contact:
            point = scene.contact_point[None]
            force = scene.contact_force[None] * _ARROW_M_PER_N
            label = f"{np.linalg.norm(scene.contact_force):.1f} N"
        else:
            point = np.zeros((0, 3))
            force = np.zeros((0, 3))
            label = None
        rec.log(f"{root}/contact", rr.Points3D(point, radii=0.004, colors=[255, 40, 40]))
        rec.log(f"{root}/contact/force", rr.Arrows3D(
            origins=point, vectors=force, colors=[255, 200, 0], radii=0.002,
            labels=None if label is None else [label]))

    def _shape(self, c: Any) -> Any:
        rr = self._rr
        colour = _rgba(c.colour)
        r, h = float(c.dims[0]), float(c.dims[1])
        if c.kind == "capsule":
            return rr.Capsules3D(lengths=[2 * h], radii=[r], translations=[[0.0, 0.0, -h]],
                                 colors=[colour], fill_mode="solid")
        if c.kind == "sphere":
            return rr.Ellipsoids3D(half_sizes=[[r, r, r]], colors=[colour], fill_mode="solid")
        if c.kind == "cylinder":
            return rr.Cylinders3D(lengths=[2 * h], radii=[r], colors=[colour], fill_mode="solid")
        return rr.Boxes3D(half_sizes=[c.dims], colors=[colour], fill_mode="solid")

    def _series(self, path: str, names: list[str], values: Any) -> None:
        """One time-series entity with a named line per value (one log call for all)."""
        if path not in self._named:
            self._named.add(path)
            self.recording.log(path, self._rr.SeriesLines(names=names), static=True)
        self.recording.log(path, self._rr.Scalars(np.asarray(values, dtype=np.float64)))

    def _log_series(self, i: int, one: Mapping[str, np.ndarray], reward: np.ndarray | None,
                    infos: Mapping[str, Any]) -> None:
        if "ft" in one:
            self._series(f"env_{i}/ft", list(_FT), one["ft"])
        if "scene_contact" in one:
            names, values = ["axial"], [one["scene_contact"][7]]
            if self.target_force is not None:
                names.append("target")
                values.append(self.target_force)
            self._series(f"env_{i}/force", names, values)
        if "joint_pos" in one:
            q = one["joint_pos"]
            self._series(f"env_{i}/joints", [f"q{k}" for k in range(len(q))], q)
        keys = [k for k in infos if not k.startswith("_") and k not in ("final_obs", "final_info")]
        terms = [k for k in keys if k.startswith("reward_")]
        if reward is not None:
            self._series(f"env_{i}/reward", ["total", *(k[len("reward_"):] for k in terms)],
                         [reward[i], *(np.asarray(infos[k])[i] for k in terms)])
        others = [k for k in keys if k not in terms]
        if others:
            self._series(f"env_{i}/info", others, [np.asarray(infos[k])[i] for k in others])

    def _log_images(self, i: int, one: Mapping[str, np.ndarray]) -> None:
        rr, rec = self._rr, self.recording
        for name, value in one.items():
            if name.endswith("_rgb"):
                rec.log(f"env_{i}/cameras/{name[:-4]}/rgb", rr.Image(value))
            elif name.endswith("_depth"):
                rec.log(f"env_{i}/cameras/{name[:-6]}/depth", rr.DepthImage(value, meter=1.0))
            elif name == "ultrasound":
                rec.log(f"env_{i}/ultrasound", rr.Image(value))
