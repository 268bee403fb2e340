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

/// Default file-name prefix of every shared-memory segment and file.
pub const DEFAULT_PREFIX: &str = "echogym_";

/// A prefix or root that iceoryx2 cannot use.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum IpcLocationError {
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
            prefix: DEFAULT_PREFIX.to_owned(),
            root: default_root(),
        }
    }
}

fn default_root() -> PathBuf {
    use std::os::unix::fs::MetadataExt;
    let uid = std::fs::metadata("/proc/self")
        .map(|m| m.uid())
        .unwrap_or(0);
    PathBuf::from(format!("/tmp/echogym-{uid}/"))
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
