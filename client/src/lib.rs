//! echogym's Rust client: connect to an `echogym serve` daemon by name, lease envs,
//! exchange batches.
//!
//! Depends on the wire contract (`echogym-protocol`) only, never on the server: the
//! Python extension and the end-to-end tests build on it.
//!
//! Ports use `ipc_threadsafe` so a [`Lease`] can be moved across threads (the Python
//! extension releases the GIL while waiting). Observations stay in the server's
//! shared-memory sample until the next exchange; nothing is copied or serialized.

mod async_batch;
mod connection;
mod error;
mod lease;
pub mod testing;
mod wait;

pub use async_batch::AsyncBatch;
pub use connection::{ConnectOptions, Connection};
pub use error::{ConnectError, ControlCallError, LeaseError};
pub use lease::{AttachOptions, Lease};
