"""The echogym exception tree. Every error the client raises derives from `EchogymError`."""

from echogym._native import (
    CapacityError,
    ControlTimeoutError,
    EchogymError,
    EnvClosedError,
    EnvFailureError,
    InvalidActionError,
    InvalidConfigError,
    LeaseLostError,
    NeedsResetError,
    ServerNotRunningError,
    ServerStoppedError,
    TransportError,
    UnknownEnvError,
    VersionMismatchError,
)

__all__ = [
    "CapacityError",
    "ControlTimeoutError",
    "EchogymError",
    "EnvClosedError",
    "EnvFailureError",
    "InvalidActionError",
    "InvalidConfigError",
    "LeaseLostError",
    "NeedsResetError",
    "ServerNotRunningError",
    "ServerStoppedError",
    "TransportError",
    "UnknownEnvError",
    "VersionMismatchError",
]
