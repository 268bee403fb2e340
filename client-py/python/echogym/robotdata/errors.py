"""Errors of reading a robot's log or writing an export. Each names the file and, where
one is at fault, the topic or column and the time, so a user can find the bad stretch."""

from __future__ import annotations

__all__ = [
    "ExportError",
    "GravityEstimateError",
    "LogFormatError",
    "MappingError",
    "MissingColumnError",
    "MissingTopicError",
    "NoPoseInReachError",
    "NonFiniteError",
    "NonMonotonicTimeError",
    "RobotDataError",
    "UnknownMessageTypeError",
]


class RobotDataError(ValueError):
    """Base class: a log that cannot be imported, or an export that cannot be written.

    ``source`` is the file, ``where`` the topic or column (``None`` when the whole file is
    at fault) and ``time_s`` the time of the first bad sample on the source's clock
    (``None`` when no sample is)."""

    def __init__(self, source: object, message: str, *, where: str | None = None,
                 time_s: float | None = None) -> None:
        self.source = str(source)
        self.where = where
        self.time_s = time_s
        place = self.source + (f", {where}" if where else "")
        at = f" at t = {time_s:.6f} s" if time_s is not None else ""
        super().__init__(f"{place}{at}: {message}")


class LogFormatError(RobotDataError):
    """The file is not a log this importer reads (not a bag, MCAP or CSV, or damaged)."""


class MappingError(RobotDataError):
    """The mapping (options or TOML file) is wrong: an unknown key, a bad value; ``where``
    names the key."""


class MissingTopicError(RobotDataError):
    """A topic named by the mapping is not in the bag; the message lists those that are."""


class UnknownMessageTypeError(RobotDataError):
    """A topic carries a message type this importer cannot use for its role."""


class MissingColumnError(RobotDataError):
    """A CSV column named by the mapping is not in the file's header."""


class NonMonotonicTimeError(RobotDataError):
    """Time stamps of a topic or column go backwards or repeat."""


class NonFiniteError(RobotDataError):
    """NaN or infinite values in a topic or column."""


class NoPoseInReachError(RobotDataError):
    """Wrench samples have no probe pose close enough in time to place them."""


class GravityEstimateError(RobotDataError):
    """The probe's weight cannot be estimated (too little free air); give the mass."""


class ExportError(RobotDataError):
    """An episode source cannot be exported (unknown folder, missing fields)."""
