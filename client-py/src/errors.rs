//! The exception tree, rooted at `echogym.EchogymError`, and the mapping from Rust errors.

use echogym_client::{ConnectError, ControlCallError, LeaseError};
use echogym_protocol::ControlErrorKind;
use pyo3::create_exception;
use pyo3::prelude::*;

create_exception!(
    _native,
    EchogymError,
    pyo3::exceptions::PyException,
    "Base of every echogym error."
);
create_exception!(
    _native,
    ServerNotRunningError,
    EchogymError,
    "No server with that name is running."
);
create_exception!(
    _native,
    VersionMismatchError,
    EchogymError,
    "Client and server speak different protocol versions."
);
create_exception!(
    _native,
    ServerStoppedError,
    EchogymError,
    "The server stopped (SIGTERM, `echogym stop`, or it died)."
);
create_exception!(
    _native,
    LeaseLostError,
    EchogymError,
    "The server no longer holds this env's lease (detached or reclaimed)."
);
create_exception!(
    _native,
    EnvClosedError,
    EchogymError,
    "The env was closed by this client."
);
create_exception!(
    _native,
    InvalidActionError,
    EchogymError,
    "The action has the wrong shape or dtype, or a NaN/inf element."
);
create_exception!(
    _native,
    UnknownEnvError,
    EchogymError,
    "No env is registered under that id."
);
create_exception!(
    _native,
    InvalidConfigError,
    EchogymError,
    "The env config has an unknown key or an out-of-range value."
);
create_exception!(
    _native,
    CapacityError,
    EchogymError,
    "The server's lease or env limit is reached."
);
create_exception!(
    _native,
    NeedsResetError,
    EchogymError,
    "An env must be reset before it can step."
);
create_exception!(
    _native,
    EnvFailureError,
    EchogymError,
    "An exchange failed inside the server and returned nothing. (One env failing in its step or reset is not an error: that env is flagged in info[\"env_error\"], truncated, and needs a reset.)"
);
create_exception!(
    _native,
    TransportError,
    EchogymError,
    "The shared-memory transport failed or the server answered nonsense."
);
create_exception!(
    _native,
    ControlTimeoutError,
    EchogymError,
    "The server did not answer a control request in time."
);

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("EchogymError", py.get_type::<EchogymError>())?;
    m.add(
        "ServerNotRunningError",
        py.get_type::<ServerNotRunningError>(),
    )?;
    m.add(
        "VersionMismatchError",
        py.get_type::<VersionMismatchError>(),
    )?;
    m.add("ServerStoppedError", py.get_type::<ServerStoppedError>())?;
    m.add("LeaseLostError", py.get_type::<LeaseLostError>())?;
    m.add("EnvClosedError", py.get_type::<EnvClosedError>())?;
    m.add("InvalidActionError", py.get_type::<InvalidActionError>())?;
    m.add("UnknownEnvError", py.get_type::<UnknownEnvError>())?;
    m.add("InvalidConfigError", py.get_type::<InvalidConfigError>())?;
    m.add("CapacityError", py.get_type::<CapacityError>())?;
    m.add("NeedsResetError", py.get_type::<NeedsResetError>())?;
    m.add("EnvFailureError", py.get_type::<EnvFailureError>())?;
    m.add("TransportError", py.get_type::<TransportError>())?;
    m.add("ControlTimeoutError", py.get_type::<ControlTimeoutError>())?;
    Ok(())
}

pub(crate) fn connect_error(e: ConnectError) -> PyErr {
    let message = e.to_string();
    match e {
        ConnectError::ServerNotRunning { .. } => ServerNotRunningError::new_err(message),
        ConnectError::InvalidOptions(_) => pyo3::exceptions::PyValueError::new_err(message),
        ConnectError::Ipc(_) => TransportError::new_err(message),
    }
}

pub(crate) fn control_error(e: ControlCallError) -> PyErr {
    let message = e.to_string();
    match e {
        ControlCallError::Refused { kind, .. } => match kind {
            ControlErrorKind::VersionMismatch => VersionMismatchError::new_err(message),
            ControlErrorKind::UnknownEnv => UnknownEnvError::new_err(message),
            ControlErrorKind::InvalidConfig => InvalidConfigError::new_err(message),
            ControlErrorKind::InvalidRequest => pyo3::exceptions::PyValueError::new_err(message),
            ControlErrorKind::CapacityExceeded => CapacityError::new_err(message),
            ControlErrorKind::UnknownLease => LeaseLostError::new_err(message),
            ControlErrorKind::NotOwner => pyo3::exceptions::PyPermissionError::new_err(message),
            ControlErrorKind::ShuttingDown => ServerStoppedError::new_err(message),
            ControlErrorKind::Internal => TransportError::new_err(message),
        },
        ControlCallError::Timeout(_) => ControlTimeoutError::new_err(message),
        ControlCallError::ServerStopped => ServerStoppedError::new_err(message),
        ControlCallError::Malformed(_) | ControlCallError::Ipc(_) => {
            TransportError::new_err(message)
        }
    }
}

pub(crate) fn lease_error(e: LeaseError) -> PyErr {
    let message = e.to_string();
    match e {
        LeaseError::ActionShape { .. } | LeaseError::NonFiniteAction { .. } => {
            InvalidActionError::new_err(message)
        }
        LeaseError::BadReset(_) | LeaseError::Async(_) => {
            pyo3::exceptions::PyValueError::new_err(message)
        }
        LeaseError::NeedsReset { .. } => NeedsResetError::new_err(message),
        LeaseError::EnvFailure { .. } => EnvFailureError::new_err(message),
        LeaseError::VersionMismatch => VersionMismatchError::new_err(message),
        LeaseError::ServerStopped => ServerStoppedError::new_err(message),
        LeaseError::Timeout(_) => ControlTimeoutError::new_err(message),
        LeaseError::LeaseLost => LeaseLostError::new_err(message),
        LeaseError::Closed => EnvClosedError::new_err(message),
        LeaseError::Protocol(_) | LeaseError::Ipc(_) => TransportError::new_err(message),
    }
}
