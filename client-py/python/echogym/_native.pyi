"""Type stubs of the native extension `echogym._native` (pyo3 + rust-numpy)."""

from os import PathLike
from typing import final

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "__version__",
    "PROTOCOL_VERSION",
    "NativeClient",
    "NativeLease",
    "SampleMemory",
    "cli_main",
    "resolve_spec",
    "registered_envs",
    "read_recordings",
    "leftover_segments",
    "remove_location",
    "EchogymError",
    "ServerNotRunningError",
    "VersionMismatchError",
    "ServerStoppedError",
    "LeaseLostError",
    "EnvClosedError",
    "InvalidActionError",
    "UnknownEnvError",
    "InvalidConfigError",
    "CapacityError",
    "NeedsResetError",
    "EnvFailureError",
    "TransportError",
    "ControlTimeoutError",
]

__version__: str
PROTOCOL_VERSION: int

_BatchViews = tuple[
    tuple[np.ndarray, ...],  # obs: one read-only array per field, shape (num_envs, *field_shape)
    NDArray[np.float32],  # reward (num_envs,)
    NDArray[np.bool_],  # terminated (num_envs,)
    NDArray[np.bool_],  # truncated (num_envs,)
    NDArray[np.float32],  # info (num_envs, len(info_keys))
    tuple[np.ndarray, ...] | None,  # final_obs (same_step autoreset only)
    NDArray[np.float32] | None,  # final_info (same_step autoreset only)
]

@final
class NativeClient:
    def __new__(
        cls,
        name: str = "default",
        prefix: str | None = None,
        root: str | PathLike[str] | None = None,
        spin_us: int = 200,
        label: str | None = None,
    ) -> NativeClient: ...
    def request(self, request_json: str, protocol_version: int | None = None) -> str: ...
    def attach(
        self,
        env_id: str,
        num_envs: int,
        config_json: str = "{}",
        autoreset_mode: str = "disabled",
    ) -> NativeLease: ...
    @property
    def name(self) -> str: ...
    @property
    def node_id(self) -> str: ...

@final
class NativeLease:
    def step(self, actions: NDArray[np.float32]) -> _BatchViews: ...
    def reset(
        self, mask: NDArray[np.bool_] | None = None, seeds: list[int | None] | None = None
    ) -> _BatchViews: ...
    def close(self) -> None: ...
    @property
    def closed(self) -> bool: ...
    @property
    def lease_id(self) -> int: ...
    @property
    def num_envs(self) -> int: ...
    @property
    def spec_json(self) -> str: ...
    @property
    def layout_json(self) -> str: ...

@final
class SampleMemory:
    """The shared-memory observation sample the numpy views of a step point into (kept
    alive by them; exposes the buffer protocol)."""

def cli_main(argv: list[str]) -> int: ...
def resolve_spec(env_id: str, config_json: str) -> str: ...
def registered_envs() -> list[tuple[str, str]]: ...
def read_recordings(dir: str | PathLike[str]) -> str: ...
def leftover_segments(prefix: str) -> list[str]: ...
def remove_location(prefix: str, root: str | PathLike[str]) -> None: ...

class EchogymError(Exception): ...
class ServerNotRunningError(EchogymError): ...
class VersionMismatchError(EchogymError): ...
class ServerStoppedError(EchogymError): ...
class LeaseLostError(EchogymError): ...
class EnvClosedError(EchogymError): ...
class InvalidActionError(EchogymError): ...
class UnknownEnvError(EchogymError): ...
class InvalidConfigError(EchogymError): ...
class CapacityError(EchogymError): ...
class NeedsResetError(EchogymError): ...
class EnvFailureError(EchogymError): ...
class TransportError(EchogymError): ...
class ControlTimeoutError(EchogymError): ...
