//! Support for tests that give each case its own iceoryx2 location.
//!
//! Every prefix leaves one tiny node-counter segment (`…global_mgmt`) by iceoryx2's
//! design; everything else must be gone once servers and clients stopped.

use echogym_protocol::IpcLocation;
use iceoryx2::prelude::ipc;

/// Shared-memory segments under `location.prefix` other than the node counter.
pub fn leftover_segments(location: &IpcLocation) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir("/dev/shm") else {
        return Vec::new();
    };
    let mut names: Vec<String> = entries
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&location.prefix) && !n.ends_with(".global_mgmt"))
        .collect();
    names.sort();
    names
}

/// Remove the node counter of `location` and its root directory. Call only once no
/// server or client of this location runs any more.
pub fn remove_location(location: &IpcLocation) {
    if let Ok(config) = location.iceoryx_config() {
        // SAFETY: no node of this prefix is alive (the caller's contract).
        let _ = unsafe { iceoryx2::testing::remove_global_mgmt_segment::<ipc::Service>(&config) };
    }
    let _ = std::fs::remove_dir_all(&location.root);
}
