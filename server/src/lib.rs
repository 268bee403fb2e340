//! echogym: a simulation server for robot-assisted ultrasound learning.
//!
//! Module dependencies run one way: [`envs`] ← [`pool`] ← [`transport`] ←
//! [`daemon`]/[`cli`]. [`client`] is the Rust side of the client (used by the Python
//! extension and by the end-to-end tests); it shares only the wire contract
//! (`echogym-protocol`) and the service builders with the server.

pub mod calibrate;
pub mod cli;
pub mod client;
pub mod config;
pub mod daemon;
pub mod envs;
pub mod pool;
pub mod recordings;
pub mod sim;
mod spin;
pub mod testing;
pub mod transport;

/// iceoryx2 logs warnings as debug dumps of its internals (kilobytes per line); echogym
/// reports what matters through its own typed errors and `tracing`, so only iceoryx2's
/// errors are let through.
pub(crate) fn quiet_iceoryx_logs() {
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
}

/// The names most users need.
pub mod prelude {
    pub use crate::client::{AttachOptions, Connection, Lease};
    pub use crate::config::ServeConfig;
    pub use crate::daemon::run;
    pub use crate::transport::Shutdown;
    pub use echogym_protocol::{AutoresetMode, EnvSpec, PROTOCOL_VERSION};
}
