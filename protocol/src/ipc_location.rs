//! Where a server's iceoryx2 resources live: a file-name prefix and a root directory.
//!
//! Client and server must agree on both or they cannot see each other. Tests give every
//! case its own pair so cases never collide; operators rarely change them.

use std::path::{Path, PathBuf};

use iceoryx2::prelude::Path as IoxPath;
use iceoryx2::prelude::{Config, FileName, SemanticString};

/// Environment variable overriding [`IpcLocation::prefix`] on both sides.
pub const PREFIX_ENV: &str = "ECHOGYM_IPC_PREFIX";
/// Environment variable overriding [`IpcLocation::root`] on both sides.
pub const ROOT_ENV: &str = "ECHOGYM_IPC_ROOT";

/// Start of the default file-name prefix of every shared-memory segment and file; the
/// default prefix is `echogym_<uid>_` (see [`default_prefix`]), so two users' default
/// servers never share `/dev/shm` names.
pub const DEFAULT_PREFIX: &str = "echogym_";

/// This process's uid (0 if `/proc` cannot tell).
fn uid() -> u32 {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self")
        .map(|m| m.uid())
        .unwrap_or(0)
}

/// The default prefix: `echogym_<uid>_`. `/dev/shm` is shared by every user, and
/// iceoryx2 names its segments after the prefix alone, so one user's default server
/// would otherwise collide with (or be refused by) another's.
pub fn default_prefix() -> String {
    format!("{DEFAULT_PREFIX}{}_", uid())
}

/// A prefix or root that iceoryx2 cannot use.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum IpcLocationError {
    /// The root directory exists but another user owns it, or others may write to it
    /// (anyone who can write there can plant or remove a server's files).
    #[error("ipc root {path:?} is unsafe: {why}; remove it or pick another with ECHOGYM_IPC_ROOT")]
    UnsafeRoot {
        /// The directory.
        path: String,
        /// What is wrong (owner or mode).
        why: String,
    },
    /// The prefix is not a valid file name.
    #[error("invalid ipc prefix {0:?}: use letters, digits, '-', '_' and '.'")]
    Prefix(String),
    /// The root is not a valid absolute path.
    #[error("invalid ipc root {0:?}: must be an absolute path ending in '/'")]
    Root(String),
}

/// The prefix and root directory of a server's iceoryx2 resources.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct IpcLocation {
    /// File-name prefix of shared-memory segments (`/dev/shm/<prefix>...`) and files.
    pub prefix: String,
    /// Directory for iceoryx2's node and service files (per user by default, because
    /// iceoryx2 keeps it owner-only).
    pub root: PathBuf,
}

impl Default for IpcLocation {
    fn default() -> Self {
        Self {
            prefix: default_prefix(),
            root: default_root(),
        }
    }
}

fn default_root() -> PathBuf {
    PathBuf::from(format!("/tmp/echogym-{}/", uid()))
}

impl IpcLocation {
    /// The default location, overridden by `ECHOGYM_IPC_PREFIX` / `ECHOGYM_IPC_ROOT`.
    pub fn from_env() -> Self {
        let mut location = Self::default();
        if let Ok(prefix) = std::env::var(PREFIX_ENV) {
            location.prefix = prefix;
        }
        if let Ok(root) = std::env::var(ROOT_ENV) {
            location.root = PathBuf::from(root);
        }
        location
    }

    /// The iceoryx2 config for this location.
    pub fn iceoryx_config(&self) -> Result<Config, IpcLocationError> {
        let mut config = Config::default();
        config.global.prefix = FileName::new(self.prefix.as_bytes())
            .map_err(|_| IpcLocationError::Prefix(self.prefix.clone()))?;
        let root = root_with_slash(&self.root);
        if !root.is_absolute() {
            return Err(IpcLocationError::Root(root.display().to_string()));
        }
        let root_text = root.to_string_lossy().into_owned();
        let path = IoxPath::new(root_text.as_bytes())
            .map_err(|_| IpcLocationError::Root(root_text.clone()))?;
        config.global.set_root_path(&path);
        Ok(config)
    }
}

impl IpcLocation {
    /// Check the root directory before a server trusts it: if it exists it must be a
    /// directory (not a symlink) owned by this user and writable by nobody else. A
    /// missing root is fine (iceoryx2 creates it owner-only).
    pub fn check_root(&self) -> Result<(), IpcLocationError> {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let unsafe_root = |why: String| IpcLocationError::UnsafeRoot {
            path: self.root.display().to_string(),
            why,
        };
        let meta = match std::fs::symlink_metadata(&self.root) {
            Ok(meta) => meta,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(unsafe_root(format!("cannot inspect it ({e})"))),
        };
        if meta.file_type().is_symlink() {
            return Err(unsafe_root("it is a symbolic link".into()));
        }
        if !meta.is_dir() {
            return Err(unsafe_root("it is not a directory".into()));
        }
        let me = uid();
        if meta.uid() != me {
            return Err(unsafe_root(format!(
                "it is owned by uid {}, not by this user (uid {me})",
                meta.uid()
            )));
        }
        let mode = meta.permissions().mode() & 0o777;
        if mode & 0o022 != 0 {
            return Err(unsafe_root(format!(
                "its mode {mode:o} lets other users write to it"
            )));
        }
        Ok(())
    }
}

fn root_with_slash(root: &Path) -> PathBuf {
    let mut text = root.to_string_lossy().into_owned();
    if !text.ends_with('/') {
        text.push('/');
    }
    PathBuf::from(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_config_for_valid_location() {
        let location = IpcLocation {
            prefix: "t_1".into(),
            root: PathBuf::from("/tmp/x"),
        };
        let config = location.iceoryx_config().unwrap();
        assert_eq!(config.global.prefix.to_string(), "t_1");
        assert_eq!(config.global.root_path().to_string(), "/tmp/x/");
    }

    #[test]
    fn the_default_prefix_names_the_user() {
        let prefix = IpcLocation::default().prefix;
        assert_eq!(prefix, format!("echogym_{}_", uid()));
        assert!(IpcLocation::default().iceoryx_config().is_ok());
    }

    #[test]
    fn a_root_others_can_write_or_a_symlink_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let base = std::env::temp_dir().join(format!("egroot-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(&base).unwrap();
        let location = |root: &Path| IpcLocation {
            prefix: "t_".into(),
            root: root.to_owned(),
        };
        // Missing: fine (created owner-only later).
        assert_eq!(location(&base.join("missing")).check_root(), Ok(()));
        let dir = base.join("dir");
        std::fs::create_dir(&dir).unwrap();
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).unwrap();
        assert_eq!(location(&dir).check_root(), Ok(()));
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
        let err = location(&dir).check_root().unwrap_err();
        assert!(err.to_string().contains("777"), "{err}");
        let link = base.join("link");
        std::os::unix::fs::symlink(&dir, &link).unwrap();
        let err = location(&link).check_root().unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        std::fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn rejects_bad_prefix_and_relative_root() {
        let bad_prefix = IpcLocation {
            prefix: "a/b".into(),
            ..IpcLocation::default()
        };
        assert!(matches!(
            bad_prefix.iceoryx_config(),
            Err(IpcLocationError::Prefix(_))
        ));
        let relative = IpcLocation {
            root: PathBuf::from("rel/dir"),
            ..IpcLocation::default()
        };
        assert!(matches!(
            relative.iceoryx_config(),
            Err(IpcLocationError::Root(_))
        ));
    }
}
