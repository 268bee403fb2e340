"""Naming where each contact happened: the nearest of named sites (the seed's five, or a
user's site map), as xy offsets from the torso's centre, or clusters of contact positions
when no names are given."""

from __future__ import annotations

import numpy as np

__all__ = ["CLUSTER_RADIUS_M", "SEED_SITES", "fit_torso_center", "name_sites"]

#: The seed's five sites, offsets from the torso's centre [m] (upper = +y, the head end;
#: left = −x), as in server/src/envs/calibration_press.rs.
SEED_SITES: dict[str, tuple[float, float]] = {
    "upper_left": (-0.06, 0.08),
    "upper_right": (0.06, 0.08),
    "center": (0.0, 0.0),
    "lower_left": (-0.06, -0.08),
    "lower_right": (0.06, -0.08),
}
#: Contacts within this distance of a cluster's first member join it [m].
CLUSTER_RADIUS_M = 0.02


def name_sites(centroids: np.ndarray, torso_center: np.ndarray,
               sites: dict[str, list[float]] | str | None) -> tuple[list[str], dict]:
    """Site names for contact centroids ``[K, 2]`` (world xy), and the sites used with
    their world positions (for the provenance)."""
    if isinstance(sites, str):  # "cluster"
        centres: list[np.ndarray] = []
        names = []
        for c in centroids:
            dist = [np.linalg.norm(c - m) for m in centres]
            if dist and min(dist) <= CLUSTER_RADIUS_M:
                names.append(f"site_{int(np.argmin(dist)) + 1}")
            else:
                centres.append(c)
                names.append(f"site_{len(centres)}")
        return names, {f"site_{k + 1}": [round(float(v), 4) for v in m]
                       for k, m in enumerate(centres)}
    table = SEED_SITES if sites is None else {k: tuple(v) for k, v in sites.items()}
    labels = list(table)
    world = np.array([table[k] for k in labels], dtype=float) + torso_center
    names = [labels[int(np.argmin(np.linalg.norm(world - c, axis=1)))] for c in centroids]
    return names, {k: [round(float(v), 4) for v in w] for k, w in zip(labels, world)}


def fit_torso_center(centroids: np.ndarray, sites: dict[str, list[float]] | None,
                     iterations: int = 20) -> np.ndarray:
    """The torso centre that puts the contacts nearest to named sites: start at the
    contacts' centroid, name each contact's nearest site, move the centre to the mean of
    ``contact − site offset``, repeat until the naming settles. (The plain centroid is off
    when some sites were pressed more often than others.)"""
    table = SEED_SITES if sites is None else {k: tuple(v) for k, v in sites.items()}
    offsets = np.array(list(table.values()), dtype=float)
    centre = centroids.mean(axis=0)
    for _ in range(iterations):
        nearest = np.argmin(np.linalg.norm(centroids[:, None, :] - (offsets + centre)[None],
                                           axis=2), axis=1)
        moved = (centroids - offsets[nearest]).mean(axis=0)
        if np.allclose(moved, centre, atol=1e-7):
            break
        centre = moved
    return centre
