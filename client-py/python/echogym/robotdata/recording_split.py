"""Cutting an aligned log into recordings: at gaps (as the recordings format would), and,
where consecutive contacts lie at different sites, in the middle of the free air between
them, so that each recording has one site. Pieces without contact carry nothing to fit
and are dropped (the provenance counts them); so are pieces under the format's 10
samples. Each recording's protocol is classified from its motion in contact."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from echogym.robotdata.contact import Contact

__all__ = ["Piece", "classify_protocol", "split"]

MIN_SAMPLES = 10
#: Travel along the surface in one contact that makes a slide [m].
SLIDE_TRAVEL_M = 0.02
#: Depth reversals in one contact that make a chirp (oscillation) rather than a press.
CHIRP_REVERSALS = 6


@dataclass
class Piece:
    """Samples ``[start, end)`` of one recording; ``why`` says where its ends came from."""

    start: int
    end: int
    site: str
    contacts: list[Contact]
    why: str


def classify_protocol(t: np.ndarray, position: np.ndarray, contacts: list[Contact]) -> str:
    """``slide`` when the tip travels ≥ 2 cm sideways in a contact, ``chirp`` when the
    depth reverses ≥ 6 times by more than 0.2 mm in a contact, else ``press``."""
    for c in contacts:
        xy = position[c.start:c.end, :2]
        if np.linalg.norm(xy.max(axis=0) - xy.min(axis=0)) >= SLIDE_TRAVEL_M:
            return "slide"
    for c in contacts:
        z = position[c.start:c.end, 2]
        reversals, extreme, direction = 0, z[0], 0
        for value in z[1:]:
            step = value - extreme
            if direction >= 0 and step < -2e-4:
                reversals, direction, extreme = reversals + (direction > 0), -1, value
            elif direction <= 0 and step > 2e-4:
                reversals, direction, extreme = reversals + (direction < 0), 1, value
            elif (direction > 0 and value > extreme) or (direction < 0 and value < extreme):
                extreme = value
        if reversals >= CHIRP_REVERSALS:
            return "chirp"
    return "press"


def split(stretches: list[slice], contacts: list[Contact], sites: list[str],
          by_site: bool) -> tuple[list[Piece], dict]:
    """The recordings of one source: ``stretches`` are its gap-free index ranges,
    ``contacts`` (with ``sites``, one name each) its contacts in time order."""
    pieces: list[Piece] = []
    dropped = {"without_contact": 0, "too_short": 0}
    for k, stretch in enumerate(stretches):
        inner = [(c, s) for c, s in zip(contacts, sites)
                 if c.start >= stretch.start and c.end <= stretch.stop]
        if not inner:
            dropped["without_contact"] += 1
            continue
        why = "whole file" if len(stretches) == 1 else f"stretch {k + 1} of {len(stretches)} between gaps"
        start = stretch.start
        group = [inner[0]]
        for (prev, prev_site), (cur, site) in zip(inner, inner[1:]):
            if by_site and site != prev_site:
                cut = (prev.end + cur.start) // 2
                pieces.append(Piece(start, cut, prev_site, [c for c, _ in group], why))
                start, group, why = cut, [], "site changed in free air"
            group.append((cur, site))
        pieces.append(Piece(start, stretch.stop, group[0][1], [c for c, _ in group], why))
    kept = [p for p in pieces if p.end - p.start >= MIN_SAMPLES]
    dropped["too_short"] = len(pieces) - len(kept)
    return kept, dropped
