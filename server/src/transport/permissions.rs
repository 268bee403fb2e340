//! Owner-only permissions for everything a server leaves on disk or in `/dev/shm`.
//!
//! iceoryx2 already creates segments 0600 and files 0400/0600, but leaves its root
//! directories 0750 and its per-prefix node counter (`…global_mgmt`) 0666 on purpose
//! (shared across users). echogym servers are single-user, so both are tightened.

use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::path::Path;

use echogym_protocol::IpcLocation;

/// Make the root directories 0700 and our node counter segment 0600.
pub(crate) fn harden(location: &IpcLocation) {
    let uid = std::fs::metadata("/proc/self").map(|m| m.uid()).ok();
    for dir in [
        location.root.clone(),
        location.root.join("nodes"),
        location.root.join("services"),
    ] {
        restrict(&dir, 0o700, uid);
    }
    let Ok(entries) = std::fs::read_dir("/dev/shm") else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(&location.prefix) && name.ends_with(".global_mgmt") {
            restrict(&entry.path(), 0o600, uid);
        }
    }
}

fn restrict(path: &Path, mode: u32, uid: Option<u32>) {
    let Ok(meta) = std::fs::metadata(path) else {
        return;
    };
    if Some(meta.uid()) != uid || meta.permissions().mode() & 0o777 == mode {
        return;
    }
    if let Err(e) = std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)) {
        tracing::debug!(path = %path.display(), error = %e, "cannot tighten permissions");
    }
}
