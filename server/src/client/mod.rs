//! The Rust client: connect to a server by name, lease envs, exchange batches.
//!
//! Ports use `ipc_threadsafe` so a [`Lease`] can be moved across threads (the Python
//! extension releases the GIL while waiting). Observations stay in the server's
//! shared-memory sample until the next exchange; nothing is copied or serialized.

mod connection;
mod error;
mod lease;
mod wait;

pub use connection::{ConnectOptions, Connection};
pub use error::{ConnectError, ControlCallError, LeaseError};
pub use lease::{AttachOptions, Lease};
