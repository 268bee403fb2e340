//! Why a server could not start.

use echogym_protocol::{InvalidServerName, IpcLocationError};

use crate::pool::PoolStartError;
use echogym_protocol::services::ServiceError;

/// A server could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The server name cannot be used in service names.
    #[error(transparent)]
    Name(#[from] InvalidServerName),
    /// The ipc prefix or root is unusable.
    #[error(transparent)]
    Location(#[from] IpcLocationError),
    /// Another live server already uses this name.
    #[error("a server named {name:?} is already running{}; stop it with `echogym stop --name {name}` or pick another --name", pid.map(|p| format!(" (pid {p})")).unwrap_or_default())]
    AlreadyRunning {
        /// The name.
        name: String,
        /// The other server's pid, when known.
        pid: Option<u32>,
    },
    /// The iceoryx2 node could not be created.
    #[error("cannot create the iceoryx2 node: {0}")]
    Node(String),
    /// A service could not be created.
    #[error(transparent)]
    Service(#[from] ServiceError),
    /// The worker threads could not start.
    #[error(transparent)]
    Pool(#[from] PoolStartError),
    /// The env builder thread could not start.
    #[error("cannot start the env builder thread: {0}")]
    Builder(std::io::Error),
    /// The medium lane's thread could not start.
    #[error("cannot start the medium lane's thread: {0}")]
    Lane(std::io::Error),
}
