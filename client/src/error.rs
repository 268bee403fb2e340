//! Client errors, one enum per kind of operation.

use echogym_protocol::ControlErrorKind;

/// [`super::Connection::connect`] failed.
#[derive(Debug, thiserror::Error)]
pub enum ConnectError {
    /// No server with that name is running at that ipc location.
    #[error(
        "no echogym server named {name:?} is running (ipc prefix {prefix:?}, root {root:?}); start one with `echogym serve --name {name}`"
    )]
    ServerNotRunning {
        /// The server name.
        name: String,
        /// The ipc prefix searched.
        prefix: String,
        /// The ipc root searched.
        root: String,
    },
    /// The name or ipc location is invalid.
    #[error("invalid connection options: {0}")]
    InvalidOptions(String),
    /// iceoryx2 refused a resource.
    #[error("shared-memory transport error: {0}")]
    Ipc(String),
}

/// A control request (attach, detach, status, ...) failed.
#[derive(Debug, thiserror::Error)]
pub enum ControlCallError {
    /// The server refused the request.
    #[error("{message}")]
    Refused {
        /// The category.
        kind: ControlErrorKind,
        /// The server's message (names the offending key or value).
        message: String,
    },
    /// The server did not answer in time.
    #[error("the server did not answer within {0:?}")]
    Timeout(std::time::Duration),
    /// The server is gone.
    #[error("the server stopped")]
    ServerStopped,
    /// The server answered something that is not a valid reply.
    #[error("malformed reply from the server: {0}")]
    Malformed(String),
    /// iceoryx2 refused a resource.
    #[error("shared-memory transport error: {0}")]
    Ipc(String),
}

/// A step or reset failed. Unless stated, nothing was stepped and the lease is usable.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum LeaseError {
    /// The action array has the wrong number of elements.
    #[error("action has {got} elements, expected {expected} ({num_envs} envs x {action_size})")]
    ActionShape {
        /// Elements given.
        got: usize,
        /// Elements expected.
        expected: usize,
        /// Envs in the lease.
        num_envs: usize,
        /// Elements per env.
        action_size: usize,
    },
    /// An action element is NaN or infinite.
    #[error("action of env {env} element {element} is not finite")]
    NonFiniteAction {
        /// The env.
        env: usize,
        /// The element.
        element: usize,
    },
    /// The reset mask or seeds have the wrong length or a bad value.
    #[error("invalid reset request: {0}")]
    BadReset(String),
    /// The env's episode ended (or never started) and it must be reset first.
    #[error("env {env} must be reset before it can step (its episode ended or never started)")]
    NeedsReset {
        /// The env.
        env: usize,
    },
    /// The exchange failed outside any one env, so nothing came back (`env` names
    /// one if it was concerned). One env failing in its step or reset is not this:
    /// the exchange returns with that env flagged (see [`crate::Lease::failed_envs`]).
    #[error("the exchange failed inside the server and returned nothing (env {env})")]
    EnvFailure {
        /// The env.
        env: usize,
    },
    /// Client and server speak different protocol versions.
    #[error("protocol version mismatch between client and server")]
    VersionMismatch,
    /// No observation came within the step deadline although the server lives; the
    /// lease is unusable (its answer may still arrive later).
    #[error("no observation within {0:?} (ConnectOptions::step_timeout / ECHOGYM_STEP_TIMEOUT_S)")]
    Timeout(std::time::Duration),
    /// The server stopped; the lease is gone.
    #[error("the server stopped")]
    ServerStopped,
    /// The server no longer knows this lease (detached or reclaimed).
    #[error("the lease is gone (detached or reclaimed by the server)")]
    LeaseLost,
    /// The lease was closed by this client.
    #[error("the env is closed")]
    Closed,
    /// The server answered with a status this client does not know.
    #[error("the server answered with unexpected status {0}")]
    Protocol(u32),
    /// An asynchronous send or receive that does not fit what is in flight (an env sent
    /// twice, env ids that split a group, a receive with nothing in flight).
    #[error("invalid asynchronous exchange: {0}")]
    Async(String),
    /// iceoryx2 refused a resource.
    #[error("shared-memory transport error: {0}")]
    Ipc(String),
}
