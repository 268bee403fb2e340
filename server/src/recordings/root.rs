//! Where recordings may be written: every `record.dir` lies inside one root.
//!
//! A client names the folder; the daemon writes there with its own rights. So the folder
//! is resolved against the server's recordings root (`serve --recordings-root`, default
//! the server's working directory): relative folders are joined to it, absolute ones
//! must already lie inside it, and `..` is refused outright (no escape by climbing).
//! Symbolic links inside the root are checked when the dataset is created.

use std::path::{Component, Path, PathBuf};
use std::sync::OnceLock;

static ROOT: OnceLock<PathBuf> = OnceLock::new();

/// Set the recordings root for this process (the daemon, once at start). Later calls
/// are ignored; without one the working directory is the root.
pub fn set_root(root: &Path) {
    let _ = ROOT.set(normalize(root));
}

/// The recordings root.
pub fn root() -> PathBuf {
    ROOT.get().cloned().unwrap_or_else(|| {
        std::env::current_dir().map_or_else(|_| PathBuf::from("."), |d| normalize(&d))
    })
}

/// `dir` resolved inside the root, or why it cannot be.
pub fn resolve(dir: &Path) -> Result<PathBuf, String> {
    if dir.as_os_str().is_empty() {
        return Err("is empty".into());
    }
    if dir.components().any(|c| c == Component::ParentDir) {
        return Err(format!("{} contains `..`", dir.display()));
    }
    let root = root();
    let resolved = if dir.is_absolute() {
        normalize(dir)
    } else {
        normalize(&root.join(dir))
    };
    if !resolved.starts_with(&root) {
        return Err(format!(
            "{} lies outside the server's recordings root {} (serve --recordings-root)",
            dir.display(),
            root.display()
        ));
    }
    Ok(resolved)
}

/// Whether `created` (an existing folder) still lies inside the root once symbolic links
/// are followed.
pub fn still_inside(created: &Path) -> bool {
    let root = std::fs::canonicalize(root()).unwrap_or_else(|_| root());
    std::fs::canonicalize(created).is_ok_and(|real| real.starts_with(root))
}

/// `path` with `.` components removed (lexically; `..` never reaches here).
fn normalize(path: &Path) -> PathBuf {
    path.components()
        .filter(|c| *c != Component::CurDir)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_resolve_inside_the_root_only() {
        let root = root();
        assert_eq!(resolve(Path::new("runs/a")).unwrap(), root.join("runs/a"));
        assert_eq!(resolve(Path::new("./runs")).unwrap(), root.join("runs"));
        assert_eq!(resolve(&root.join("x")).unwrap(), root.join("x"));
        assert!(
            resolve(Path::new("../elsewhere"))
                .unwrap_err()
                .contains("..")
        );
        assert!(resolve(Path::new("runs/../../etc")).is_err());
        assert!(
            resolve(Path::new("/etc/echogym"))
                .unwrap_err()
                .contains("outside")
        );
        assert!(resolve(Path::new("")).is_err());
    }
}
