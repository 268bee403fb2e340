//! An attach waiting for its envs: what the dispatcher keeps until the build is back.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use echogym_protocol::AutoresetMode;

use super::reply::ControlRequestHandle;

/// An attach whose envs are being built.
pub(super) struct PendingAttach {
    /// Where the reply goes (its client port goes away when the client gives up, see
    /// `Dispatcher::client_waiting`).
    pub request: ControlRequestHandle,
    pub ticket: u64,
    pub cancel: Arc<AtomicBool>,
    pub client_node: u128,
    pub client_label: String,
    pub env_id: String,
    pub num_envs: usize,
    /// Bytes of shared memory its lease will preallocate.
    pub shm_bytes: u64,
    pub mode: AutoresetMode,
    pub started: Instant,
}
