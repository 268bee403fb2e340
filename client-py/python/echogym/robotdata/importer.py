"""``echogym import``: robot logs (ROS 2 bags, MCAP, CSV) → an ``echogym-recordings/1``
dataset that ``echogym calibrate`` reads. One function, :func:`import_logs`; the steps
are the modules beside this one (read → align → frames → gravity → contact → sites →
split → write), each recorded in the dataset's ``provenance``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from echogym.robotdata import contact as contact_mod
from echogym.robotdata import gravity
from echogym.robotdata.bag_source import is_bag, read_bag
from echogym.robotdata.csv_source import read_csv
from echogym.robotdata.dataset_out import FORMAT, RecordingOut, write_dataset
from echogym.robotdata.errors import LogFormatError, MappingError, RobotDataError
from echogym.robotdata.frames import tip_positions, wrench_in_tool, wrench_to_world
from echogym.robotdata.options import ImportOptions
from echogym.robotdata.recording_split import classify_protocol, split
from echogym.robotdata.rotations import matrix_from_quaternion
from echogym.robotdata.series import SourceLog
from echogym.robotdata.sites import fit_torso_center, name_sites
from echogym.robotdata.timebase import align, gap_threshold, stretches

__all__ = ["ImportResult", "import_logs", "read_source"]

#: Free-air samples this close to a contact are not used for estimates [s].
CONTACT_MARGIN_S = 0.2
#: Stamps this large are wall-clock (epoch) times, comparable across files [s].
EPOCH_S = 1e8


@dataclass
class ImportResult:
    """The dataset written: its folder and ``dataset.json`` as written."""

    out: Path
    meta: dict

    @property
    def recordings(self) -> list[dict]:
        return self.meta["recordings"]


def read_source(path: str | Path, options: ImportOptions) -> SourceLog:
    """A source file read by the reader its kind needs (``.csv``, or a bag / MCAP)."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(path, "no such file or folder")
    if path.suffix.lower() in (".csv", ".txt", ".tsv"):
        return read_csv(path, options)
    if is_bag(path):
        return read_bag(path, options)
    raise LogFormatError(path, "unknown kind of log: expected a ROS 2 bag folder (with "
                         "metadata.yaml), a .mcap, .db3 or .bag file, or a .csv")


@dataclass
class _Prepared:
    log: SourceLog
    t: np.ndarray
    tip: np.ndarray
    force: np.ndarray
    torque: np.ndarray | None
    contacts: list[contact_mod.Contact]
    notes: dict


def _dilate(mask: np.ndarray, t: np.ndarray, margin: float) -> np.ndarray:
    """``mask`` widened by ``margin`` seconds either side of every true sample."""
    out = mask.copy()
    idx = np.flatnonzero(mask)
    if len(idx):
        lo = np.searchsorted(t, t[idx] - margin)
        hi = np.searchsorted(t, t[idx] + margin, side="right")
        delta = np.zeros(len(t) + 1, int)
        np.add.at(delta, lo, 1)
        np.add.at(delta, hi, -1)
        out = np.cumsum(delta)[:-1] > 0
    return out


def _prepare(path: str | Path, options: ImportOptions) -> _Prepared:
    """One source on one clock, in the world frame, gravity compensated (its contacts are
    found afterwards, against the whole session's free-air level)."""
    log = read_source(path, options)
    a = align(path, log.wrench, log.pose, options.rate_hz, options.pose_reach_s)
    rotation = matrix_from_quaternion(a.quaternion)
    frame = options.wrench_frame
    if frame == "auto":
        frame = "world" if log.wrench.frame and log.wrench.frame == log.pose.parent else "tool"
    if frame == "world":
        sign = float(options.wrench_sign)
        f_world = sign * a.force
        tq_world = None if a.torque is None else sign * a.torque
        f_tool = np.einsum("nji,nj->ni", rotation, f_world)
        tq_tool = None if tq_world is None else np.einsum("nji,nj->ni", rotation, tq_world)
    else:
        f_tool, tq_tool = wrench_in_tool(a.force, a.torque, options.sensor_rotation_rpy,
                                         float(options.wrench_sign))
        f_world = wrench_to_world(f_tool, a.quaternion)
        tq_world = None if tq_tool is None else wrench_to_world(tq_tool, a.quaternion)
    tip = tip_positions(a.position, a.quaternion, options.tool_offset)

    # Free air before compensation: the probe's weight is near constant in world z while
    # it points down; contact only pushes fz up.
    _, sigma = contact_mod.free_air_level(f_world[:, 2])
    threshold = options.contact_threshold_n or max(0.5, 6 * sigma)
    contacts, mask = contact_mod.contact_runs(a.t, f_world[:, 2], threshold)
    free = ~_dilate(mask, a.t, CONTACT_MARGIN_S)
    surface = options.surface_z if options.surface_z is not None else \
        contact_mod.surface_estimate(tip[:, 2], contacts)
    if surface is not None:
        clear = free & (tip[:, 2] > surface + contact_mod.FREE_AIR_CLEARANCE_M)
        if clear.sum() >= 0.5 * free.sum():
            free = clear
    mass = options.probe_mass
    if mass == "none":
        model = gravity.GravityModel("none")
    elif mass == "estimate":
        model = gravity.estimate(path, log.wrench.name, a.t, f_tool, tq_tool, rotation, free)
    else:
        model = gravity.GravityModel("given", mass_kg=float(mass),
                                     notes={"torques": "not compensated (centre of mass unknown)"})
    f_world, tq_world = gravity.compensate(f_world, tq_world, rotation, model)
    notes = {**log.provenance, "alignment": a.notes, "wrench_frame": frame,
             "gravity": model.describe()}
    return _Prepared(log, a.t, tip, f_world, tq_world, [], notes)


def _find_contacts(prepared: list[_Prepared], options: ImportOptions) -> dict:
    """Contacts of every source against one free-air level pooled over the session (one
    sensor): a source that never leaves the body (a chirp, a slide) has no free air of
    its own to judge by."""
    level, sigma = contact_mod.free_air_level(np.concatenate([p.force[:, 2] for p in prepared]))
    threshold = options.contact_threshold_n or max(0.5, 6 * sigma)
    for p in prepared:
        # Within each gap-free stretch: a contact never spans a gap (each side of it
        # becomes its own recording).
        p.contacts = []
        for piece in stretches(p.t, gap_threshold(p.t)):
            found, _ = contact_mod.contact_runs(p.t[piece], p.force[piece, 2], threshold, level)
            p.contacts += [contact_mod.Contact(c.start + piece.start, c.end + piece.start)
                           for c in found]
        p.notes["contacts"] = len(p.contacts)
    return {"free_air_fz_n": round(level, 4), "noise_n": round(sigma, 4),
            "threshold_n": round(threshold, 4),
            "how": "given" if options.contact_threshold_n else "max(0.5 N, 6 σ of free air)"}


def _check_force_sign(prepared: list[_Prepared], source: str | Path) -> None:
    """Contact pushes up and happens below free air: if the samples taken for contact lie
    higher than the rest, the force's sign (or frame) is wrong, and every later step would
    be nonsense."""
    inside, outside = [], []
    for p in prepared:
        mask = np.zeros(len(p.t), bool)
        for c in p.contacts:
            mask[c.start:c.end] = True
        inside.append(p.tip[mask, 2])
        outside.append(p.tip[~mask, 2])
    z_in, z_out = np.concatenate(inside), np.concatenate(outside)
    if len(z_in) and len(z_out) and np.median(z_in) > np.median(z_out):
        raise MappingError(source, "the force rises when the probe goes up (median tip height "
                           f"{np.median(z_in):.4f} m where the force is high, {np.median(z_out):.4f} m "
                           "elsewhere): the wrench's sign or frame is wrong; try wrench_sign = -1, "
                           "or check sensor_rotation_rpy and wrench_frame", where="wrench_sign")


def import_logs(sources: list[str | Path] | str | Path, out: str | Path,
                options: ImportOptions | None = None, **overrides: object) -> ImportResult:
    """Import ``sources`` into the dataset folder ``out`` (see docs/data.md).

    ``options`` (default :class:`ImportOptions`) with ``overrides`` applied by field
    name, e.g. ``import_logs("run.mcap", "dataset", wrench_topic="/ft/wrench",
    pose_topic="/tcp_pose", probe_mass=0.21)``. Raises a
    :class:`~echogym.robotdata.errors.RobotDataError` naming the file, topic or column and
    time of a problem; nothing is written then."""
    if isinstance(sources, (str, Path)):
        sources = [sources]
    if not sources:
        raise RobotDataError(out, "no source files given")
    known = {f.name for f in dataclasses.fields(ImportOptions)}
    for name in overrides:
        if name not in known:
            raise MappingError("options", f"unknown option; known: {sorted(known)}", where=name)
    options = dataclasses.replace(options or ImportOptions(), **overrides)  # type: ignore[arg-type]
    options.check()
    prepared = [_prepare(path, options) for path in sources]
    contact_note = _find_contacts(prepared, options)
    _check_force_sign(prepared, sources[0])
    all_contacts = [(p, c) for p in prepared for c in p.contacts]
    if not all_contacts:
        raise RobotDataError(sources[0], "no contact with the body found in any source (force "
                             "never rose above the contact threshold); check wrench_sign and "
                             "the wrench topic")
    onsets = [p.tip[c.start, 2] for p, c in all_contacts if c.start > 0]
    if options.surface_z is not None:
        surface, surface_how = float(options.surface_z), "given"
    elif onsets:
        surface, surface_how = float(np.median(onsets)), f"median tip height at {len(onsets)} contact onsets"
    else:
        surface = float(np.median([p.tip[c.start, 2] for p, c in all_contacts]))
        surface_how = "median tip height at the first contact sample (no onset from free air)"
    centroids = np.array([c.centroid(p.tip) for p, c in all_contacts])
    if options.torso_center is not None:
        centre, centre_how = np.asarray(options.torso_center, float), "given"
    elif isinstance(options.sites, str):
        centre, centre_how = centroids.mean(axis=0), f"centroid of {len(centroids)} contacts"
    else:
        centre = fit_torso_center(centroids, options.sites)
        centre_how = (f"centroid of {len(centroids)} contacts, each taken relative to its "
                      "nearest named site")
    names, site_table = name_sites(centroids, centre, options.sites)

    session_t0 = min(float(p.t[0]) for p in prepared)
    common_clock = len(prepared) == 1 or all(p.t[0] > EPOCH_S for p in prepared)
    recordings: list[RecordingOut] = []
    sources_note = []
    k = 0
    for p in prepared:
        mine = [names[i] for i, (q, _) in enumerate(all_contacts) if q is p]
        pieces, dropped = split(stretches(p.t, gap_threshold(p.t)), p.contacts, mine,
                                by_site=options.split == "auto")
        stem = Path(p.log.path).stem or Path(p.log.path).name
        made = []
        for piece in pieces:
            k += 1
            sl = slice(piece.start, piece.end)
            protocol = options.protocol or classify_protocol(p.t, p.tip, piece.contacts)
            t0 = float(p.t[piece.start])
            entry = {"file": f"{k:03d}_{stem}_{piece.site}_{protocol}.csv", "site": piece.site,
                     "protocol": protocol}
            if common_clock:
                entry["session_time_s"] = round(t0 - session_t0, 9)
            entry["source"] = {"file": p.log.path, "t_start": t0, "t_end": float(p.t[piece.end - 1]),
                               "cut": piece.why, "contacts": len(piece.contacts)}
            recordings.append(RecordingOut(p.t[sl] - t0, p.tip[sl], p.force[sl],
                                           None if p.torque is None else p.torque[sl], entry))
            made.append(entry["file"])
        sources_note.append({**p.notes, "recordings": made, "dropped_pieces": dropped})
    if not recordings:
        raise RobotDataError(sources[0], "no recording left: every piece was free air only or "
                             "under 10 samples")
    meta = {
        "description": f"imported by echogym import from {len(sources)} source(s)",
        "nominal_surface_z": surface,
        "torso_center_xy": [float(centre[0]), float(centre[1])],
        "provenance": {
            "tool": "echogym import",
            "sources": sources_note,
            "transforms": {
                "wrench_frame": options.wrench_frame,
                "sensor_rotation_rpy": list(options.sensor_rotation_rpy),
                "wrench_sign": options.wrench_sign,
                "tool_offset_m": list(options.tool_offset),
                "probe_mass": options.probe_mass,
                "clock": options.clock,
                "pose_time_offset_s": options.pose_time_offset_s,
                "rate_hz": options.rate_hz,
                "split": options.split,
            },
            "estimated": {"nominal_surface_z": surface_how, "torso_center_xy": centre_how},
            "contact": contact_note,
            "sites": {"named_by": ("clusters" if isinstance(options.sites, str) else
                                   "site map" if options.sites else "the seed's five sites"),
                      "world_xy": site_table},
        },
    }
    path = write_dataset(out, meta, recordings)
    return ImportResult(path, {"format": FORMAT, **meta,
                               "recordings": [r.entry for r in recordings]})
