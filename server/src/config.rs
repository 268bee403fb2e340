//! `echogym serve` configuration: defaults, then a TOML file, then CLI flags.

use std::path::{Path, PathBuf};
use std::time::Duration;

use echogym_protocol::IpcLocation;
use serde::{Deserialize, Serialize};

use crate::transport::DispatcherOptions;

/// The server's configuration. Every field has a default; a TOML file may set any of
/// them (unknown keys are errors), and CLI flags override the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ServeConfig {
    /// Server name; clients connect by name. Default `"default"`.
    pub name: String,
    /// Worker threads stepping env batches; 0 means one per core. Default 0.
    pub threads: usize,
    /// Nice value of the worker threads (0–19). Default 5: when every core is busy, the
    /// dispatcher (which runs small leases' exchanges itself) and the client processes
    /// get a core first, so a big batch stepping on the workers does not hold back a
    /// small lease's step (measured: docs/results/benchmarks.md, "Head of line"); with
    /// idle cores it changes nothing.
    pub worker_nice: i32,
    /// Microseconds: an exchange measured to cost more than the dispatcher's inline
    /// budget (100 µs) but at most this on one thread is "medium"; while a bigger
    /// exchange is on the worker pool, medium ones run on the medium lane, a thread of
    /// their own, instead of queueing behind it. 0 turns the lane off (every exchange
    /// above the inline budget queues on the pool). Default 2000 (2 ms: the longest
    /// one medium exchange holds back another on the lane).
    pub lane_budget_us: u64,
    /// Microseconds to busy-poll for work before blocking on an event. Default 200:
    /// long enough to catch a client's next step without a ≈ 50 µs wake-up, short
    /// enough that an idle server costs nothing.
    pub spin_us: u64,
    /// Milliseconds between housekeeping passes (dead-client reclaim, shutdown checks).
    /// Default 100, which bounds the reclaim delay well under 2 s.
    pub housekeeping_ms: u64,
    /// Most leases held at once. Default 256.
    pub max_leases: usize,
    /// Most envs held at once, over all leases. Default 65,536.
    pub max_envs: usize,
    /// Most leases one client process holds at once. Default 64 (a quarter of
    /// `max_leases`: one client cannot take the whole server).
    pub max_leases_per_client: usize,
    /// Most envs one client process holds at once. Default 16,384.
    pub max_envs_per_client: usize,
    /// Most bytes of lease shared memory (action and observation samples) held at once,
    /// over all leases. Default 16 GiB.
    pub max_shm_bytes: u64,
    /// Most bytes of lease shared memory one client process holds at once. Default
    /// 4 GiB (a quarter of `max_shm_bytes`).
    pub max_shm_bytes_per_client: u64,
    /// The folder every env's `record.dir` must lie in (relative ones are joined to it).
    /// Default: the server's working directory at start.
    pub recordings_root: Option<std::path::PathBuf>,
    /// Log filter (`tracing` env-filter syntax). Default `"info"`.
    pub log: String,
    /// Where iceoryx2 resources live. Default prefix `echogym_<uid>_`, root
    /// `/tmp/echogym-<uid>/`; `ECHOGYM_IPC_PREFIX` / `ECHOGYM_IPC_ROOT` override both.
    pub ipc: IpcLocation,
    /// Stop when this pid is no longer the parent (set for private auto-started servers).
    #[serde(skip)]
    pub parent_pid: Option<u32>,
    /// Register `echogym/Faulty-v0`, an env that panics on request (tests only).
    #[serde(skip)]
    pub fault_injection: bool,
}

impl Default for ServeConfig {
    fn default() -> Self {
        Self {
            name: "default".to_owned(),
            threads: 0,
            worker_nice: 5,
            lane_budget_us: 2000,
            spin_us: 200,
            housekeeping_ms: 100,
            max_leases: 256,
            max_envs: 65_536,
            max_leases_per_client: 64,
            max_envs_per_client: 16_384,
            max_shm_bytes: 16 << 30,
            max_shm_bytes_per_client: 4 << 30,
            recordings_root: None,
            log: "info".to_owned(),
            ipc: IpcLocation::from_env(),
            parent_pid: None,
            fault_injection: false,
        }
    }
}

/// A configuration could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read config file {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML or has unknown keys.
    #[error("invalid config file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the parser said (names the key).
        message: String,
    },
    /// A value is out of range.
    #[error("invalid config: `{key}` {message}")]
    Invalid {
        /// The key.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
}

impl ServeConfig {
    /// Defaults, overridden by the TOML file at `path` if given.
    pub fn load(path: Option<&Path>) -> Result<Self, ConfigError> {
        let Some(path) = path else {
            return Ok(Self::default());
        };
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        toml::from_str(&text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })
    }

    /// Check values that types alone do not bound.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let invalid = |key, message: &str| ConfigError::Invalid {
            key,
            message: message.to_owned(),
        };
        if self.housekeeping_ms == 0 || self.housekeeping_ms > 1000 {
            return Err(invalid("housekeeping_ms", "must be between 1 and 1000"));
        }
        if self.spin_us > 1_000_000 {
            return Err(invalid("spin_us", "must be at most 1,000,000"));
        }
        if self.max_leases == 0 || self.max_envs == 0 {
            return Err(invalid("max_leases", "and max_envs must be positive"));
        }
        if self.max_leases_per_client == 0 || self.max_envs_per_client == 0 {
            return Err(invalid(
                "max_leases_per_client",
                "and max_envs_per_client must be positive",
            ));
        }
        if self.max_shm_bytes == 0 || self.max_shm_bytes_per_client == 0 {
            return Err(invalid(
                "max_shm_bytes",
                "and max_shm_bytes_per_client must be positive",
            ));
        }
        if let Some(root) = &self.recordings_root
            && !root.is_absolute()
        {
            return Err(invalid("recordings_root", "must be an absolute path"));
        }
        if self.threads > 1024 {
            return Err(invalid("threads", "must be at most 1024"));
        }
        if !(0..=19).contains(&self.worker_nice) {
            return Err(invalid("worker_nice", "must be 0 to 19"));
        }
        if self.lane_budget_us > 1_000_000 {
            return Err(invalid("lane_budget_us", "must be at most 1,000,000 (1 s)"));
        }
        echogym_protocol::ServiceNames::new(&self.name).map_err(|e| ConfigError::Invalid {
            key: "name",
            message: e.to_string(),
        })?;
        self.ipc
            .iceoryx_config()
            .map_err(|e| ConfigError::Invalid {
                key: "ipc",
                message: e.to_string(),
            })?;
        Ok(())
    }

    /// The resolved configuration as TOML (for `--print-config`).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("config serializes")
    }

    /// Options for the dispatcher.
    pub fn dispatcher_options(&self) -> DispatcherOptions {
        DispatcherOptions {
            name: self.name.clone(),
            location: self.ipc.clone(),
            threads: self.threads,
            worker_nice: self.worker_nice,
            lane_budget: Duration::from_micros(self.lane_budget_us),
            spin: Duration::from_micros(self.spin_us),
            housekeeping: Duration::from_millis(self.housekeeping_ms),
            max_leases: self.max_leases,
            max_envs: self.max_envs,
            max_leases_per_client: self.max_leases_per_client,
            max_envs_per_client: self.max_envs_per_client,
            max_shm_bytes: self.max_shm_bytes,
            max_shm_bytes_per_client: self.max_shm_bytes_per_client,
            parent_pid: self.parent_pid,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_overrides_defaults_and_unknown_keys_fail() {
        let dir = std::env::temp_dir().join(format!("echogym-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = dir.join("good.toml");
        std::fs::write(
            &good,
            "name = \"lab\"\nspin_us = 5\n[ipc]\nprefix = \"p_\"\nroot = \"/tmp/r/\"\n",
        )
        .unwrap();
        let config = ServeConfig::load(Some(&good)).unwrap();
        assert_eq!(config.name, "lab");
        assert_eq!(config.spin_us, 5);
        assert_eq!(config.max_leases, 256);
        assert_eq!(config.ipc.prefix, "p_");
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "spin_uss = 5\n").unwrap();
        let err = ServeConfig::load(Some(&bad)).unwrap_err().to_string();
        assert!(err.contains("spin_uss"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn printed_config_parses_back() {
        let config = ServeConfig::default();
        let back: ServeConfig = toml::from_str(&config.to_toml()).unwrap();
        assert_eq!(back, config);
    }
}
