//! The server side of the shared-memory transport.
//!
//! One dispatcher thread owns every iceoryx2 port, polls the leases' action
//! subscribers, runs cheap exchanges itself and hands the others (batch and samples) to
//! the [`crate::pool`], whose worker publishes the observation. Waiting is
//! spin-then-block on both sides: see `dispatcher.rs` for the wake-up protocol.

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

/// The iceoryx2 service variant of every server port: `ipc_threadsafe` (the same shared
/// memory and files as `ipc`, which clients may use) so samples can move to a worker.
pub(crate) type Ipc = iceoryx2::prelude::ipc_threadsafe::Service;
pub use error::StartError;
pub use shutdown::Shutdown;
