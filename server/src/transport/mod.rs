//! The server side of the shared-memory transport.
//!
//! One dispatcher thread owns every iceoryx2 port (`ipc::Service` ports are `!Send`),
//! polls the leases' action subscribers, runs exchanges on the [`crate::pool`] and
//! publishes observations. Waiting is spin-then-block on both sides: see
//! `dispatcher.rs` for the wake-up protocol.

mod attach;
mod builder;
mod control;
mod dispatcher;
mod error;
mod lease;
mod pending;
mod permissions;
mod reply;
mod shutdown;

pub use dispatcher::{Dispatcher, DispatcherOptions};
pub use error::StartError;
pub use shutdown::Shutdown;
