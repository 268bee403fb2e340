//! echogym: a simulation server for robot-assisted ultrasound learning.
//!
//! Module dependencies run one way: [`sim`] ← [`envs`] ← [`pool`] ← [`transport`] ←
//! [`daemon`]/[`cli`]. The wire contract and the iceoryx2 service settings live in
//! `echogym-protocol`; the client is its own crate, `echogym-client`, which the CLI uses
//! for `status` and `stop` (the server itself never opens a client).

pub mod calibrate;
pub mod cli;
pub mod config;
pub mod daemon;
pub mod envs;
pub mod pool;
pub mod recordings;
pub mod sim;
pub mod transport;

/// The names most users need.
pub mod prelude {
    pub use crate::config::ServeConfig;
    pub use crate::daemon::run;
    pub use crate::transport::Shutdown;
    pub use echogym_protocol::{AutoresetMode, EnvSpec, PROTOCOL_VERSION};
}
