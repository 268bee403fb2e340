"""Contact with the body from the force alone: a sample is in contact when the (gravity
compensated) world ``fz`` stands above its free-air level by more than a threshold. The
body's surface is the median tip height at contact onsets; the torso's centre the
centroid of the contacts' centroids (each contact weighs the same, however long)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Contact", "FREE_AIR_CLEARANCE_M", "contact_runs", "free_air_level", "surface_estimate"]

#: Free air for estimates: the tip this far above the surface (the calibration's own rule).
FREE_AIR_CLEARANCE_M = 0.004
#: Contacts separated by less than this are one contact (a bounce, a noisy onset) [s].
MERGE_S = 0.2
#: Contacts shorter than this are noise [s].
MIN_CONTACT_S = 0.1


@dataclass
class Contact:
    """Sample indices ``[start, end)`` of one contact."""

    start: int
    end: int

    def centroid(self, position: np.ndarray) -> np.ndarray:
        return position[self.start:self.end, :2].mean(axis=0)


def free_air_level(fz: np.ndarray) -> tuple[float, float]:
    """``(level, noise σ)`` of ``fz`` away from contact. Contact only ever pushes ``fz`` up,
    so free air is the low end: the level is the median of the samples within 1 N of the
    10th percentile, σ their robust spread (1.4826 × MAD)."""
    low = np.percentile(fz, 10)
    near = fz[fz <= low + 1.0]
    level = float(np.median(near))
    sigma = float(1.4826 * np.median(np.abs(near - level)))
    return level, sigma


def contact_runs(t: np.ndarray, fz: np.ndarray, threshold: float,
                 level: float | None = None) -> tuple[list[Contact], np.ndarray]:
    """The contacts and the in-contact mask (after merging and dropping short ones);
    ``level`` is the free-air level (default: :func:`free_air_level` of ``fz``)."""
    if level is None:
        level, _ = free_air_level(fz)
    above = fz - level > threshold
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(int), [0]])))
    runs = [Contact(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]
    merged: list[Contact] = []
    for run in runs:
        if merged and t[run.start] - t[merged[-1].end - 1] < MERGE_S:
            merged[-1] = Contact(merged[-1].start, run.end)
        else:
            merged.append(run)
    kept = [c for c in merged if t[c.end - 1] - t[c.start] >= MIN_CONTACT_S]
    mask = np.zeros(len(t), bool)
    for c in kept:
        mask[c.start:c.end] = True
    return kept, mask


def surface_estimate(z: np.ndarray, contacts: list[Contact]) -> float | None:
    """Median tip height at the onsets of contacts that start from above (a contact at the
    first sample of a stretch did not start there)."""
    onsets = [z[c.start] for c in contacts if c.start > 0]
    return float(np.median(onsets)) if onsets else None
