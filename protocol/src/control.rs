//! Control messages: attach, detach, spec discovery, status, stop.
//!
//! These travel as JSON in the payload of the control request-response service, after a
//! [`crate::ControlHeader`] carrying the protocol version. They are rare (once per lease),
//! so they may be serialized; the step path never is.

use serde::{Deserialize, Serialize};

use crate::layout::BatchLayout;
use crate::spec::{AutoresetMode, EnvSpec};

/// A control request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum ControlRequest {
    /// Lease a batch of envs.
    Attach(AttachRequest),
    /// Give a lease back.
    Detach {
        /// The lease.
        lease_id: u64,
        /// The asking client's iceoryx2 node id: only the node that attached a lease may
        /// detach it (empty from an old client: refused as not the owner).
        #[serde(default)]
        client_node_id: String,
    },
    /// Resolve an env's spec for a config without leasing anything.
    Spec {
        /// Versioned env id.
        env_id: String,
        /// Env config (unknown keys are rejected).
        #[serde(default)]
        config: serde_json::Map<String, serde_json::Value>,
    },
    /// List the registered envs.
    ListEnvs,
    /// Report the server's state.
    Status,
    /// Shut the server down gracefully.
    Stop,
}

/// Lease `num_envs` envs of `env_id` built from `config`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttachRequest {
    /// Versioned env id, e.g. `echogym/Null-v0`.
    pub env_id: String,
    /// Envs in the batch.
    pub num_envs: usize,
    /// Env config (unknown keys are rejected).
    #[serde(default)]
    pub config: serde_json::Map<String, serde_json::Value>,
    /// What happens to envs whose episode ended.
    #[serde(default)]
    pub autoreset_mode: AutoresetMode,
    /// The client's iceoryx2 node id; the lease is reclaimed when that node dies.
    pub client_node_id: String,
    /// Human-readable client description for `echogym status` (e.g. `pid 1234 python`).
    #[serde(default)]
    pub client_label: String,
}

/// The server's answer to a successful attach.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttachReply {
    /// The lease id (also in every action header).
    pub lease_id: u64,
    /// The env spec.
    pub spec: EnvSpec,
    /// Where everything lives in the samples.
    pub layout: BatchLayout,
    /// The lease's autoreset mode.
    pub autoreset_mode: AutoresetMode,
    /// The server's spin budget in microseconds (clients spin about as long).
    pub server_spin_us: u64,
    /// The server's iceoryx2 node id (decimal), so a client can tell a dead server.
    pub server_node_id: String,
}

/// A registered env.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvInfo {
    /// Versioned id.
    pub env_id: String,
    /// One-line description.
    pub description: String,
}

/// One lease as shown by `echogym status`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LeaseStatus {
    /// The lease id.
    pub lease_id: u64,
    /// The env id.
    pub env_id: String,
    /// Envs in the batch.
    pub num_envs: usize,
    /// The owning client's label.
    pub client_label: String,
    /// Exchanges (steps and resets) served.
    pub exchanges: u64,
    /// Seconds since attach.
    pub age_s: f64,
    /// Env steps served (summed over the batch).
    #[serde(default)]
    pub env_steps: u64,
    /// Env steps truncated for a physics error (non-finite state).
    #[serde(default)]
    pub physics_errors: u64,
    /// Env steps and resets that failed inside the env (flagged `env_error`).
    #[serde(default)]
    pub env_errors: u64,
    /// Exchanges that ran on the medium lane (a medium exchange while a big one was on
    /// the worker pool).
    #[serde(default)]
    pub lane_exchanges: u64,
    /// Seconds since the last exchange (or since attach, before the first).
    #[serde(default)]
    pub idle_s: f64,
    /// The owning client's process id, from its iceoryx2 node name (`None` for a
    /// client that is not echogym's, or whose node is gone).
    #[serde(default)]
    pub client_pid: Option<u32>,
}

/// An attach whose envs are being built, as shown by `echogym status`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BuildStatus {
    /// The env id.
    pub env_id: String,
    /// Envs asked for.
    pub num_envs: usize,
    /// The waiting client's label.
    pub client_label: String,
    /// Seconds since the request.
    pub waited_s: f64,
}

/// The server's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServerStatus {
    /// Server name.
    pub name: String,
    /// Process id.
    pub pid: u32,
    /// Crate version of the server.
    pub version: String,
    /// Protocol version.
    pub protocol_version: u32,
    /// Seconds since start.
    pub uptime_s: f64,
    /// Worker threads.
    pub threads: usize,
    /// Env steps served since start (summed over envs).
    pub env_steps: u64,
    /// Env steps truncated for a physics error (non-finite state) since start.
    #[serde(default)]
    pub physics_errors: u64,
    /// Env steps and resets that failed inside the env (flagged `env_error`) since start.
    #[serde(default)]
    pub env_errors: u64,
    /// Leases reclaimed from dead clients since start.
    pub reclaimed_leases: u64,
    /// Live leases.
    pub leases: Vec<LeaseStatus>,
    /// Attaches whose envs are being built.
    #[serde(default)]
    pub building: Vec<BuildStatus>,
}

/// Category of a failed control request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlErrorKind {
    /// Client and server speak different protocol versions.
    VersionMismatch,
    /// No env is registered under that id.
    UnknownEnv,
    /// The env config has an unknown key or an out-of-range value.
    InvalidConfig,
    /// The request could not be parsed or is inconsistent.
    InvalidRequest,
    /// The server's lease or env limit is reached.
    CapacityExceeded,
    /// No such lease (already detached or reclaimed).
    UnknownLease,
    /// The lease belongs to another client.
    NotOwner,
    /// The server is shutting down.
    ShuttingDown,
    /// The server failed to create shared-memory resources.
    Internal,
}

/// A failed control request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlError {
    /// Category.
    pub kind: ControlErrorKind,
    /// What went wrong, naming the offending key or value.
    pub message: String,
}

/// A control reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "reply", rename_all = "snake_case")]
pub enum ControlReply {
    /// The lease is ready.
    Attached(AttachReply),
    /// The lease is gone.
    Detached {
        /// The lease id.
        lease_id: u64,
    },
    /// An env spec.
    Spec(EnvSpec),
    /// The registered envs.
    Envs {
        /// One per env id.
        envs: Vec<EnvInfo>,
    },
    /// The server's state.
    Status(ServerStatus),
    /// The server is shutting down.
    Stopping,
    /// The request failed.
    Error(ControlError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_tagged_by_op() {
        let text =
            r#"{"op":"attach","env_id":"echogym/Null-v0","num_envs":4,"client_node_id":"42"}"#;
        let request: ControlRequest = serde_json::from_str(text).unwrap();
        let ControlRequest::Attach(attach) = request else {
            panic!("not an attach: {request:?}");
        };
        assert_eq!(attach.num_envs, 4);
        assert_eq!(attach.autoreset_mode, AutoresetMode::Disabled);
        assert!(attach.config.is_empty());
        let stop: ControlRequest = serde_json::from_str(r#"{"op":"stop"}"#).unwrap();
        assert_eq!(stop, ControlRequest::Stop);
    }

    #[test]
    fn errors_serialize_with_kind() {
        let reply = ControlReply::Error(ControlError {
            kind: ControlErrorKind::InvalidConfig,
            message: "unknown key `obs_sise`".into(),
        });
        let text = serde_json::to_string(&reply).unwrap();
        assert!(text.contains(r#""kind":"invalid_config""#), "{text}");
    }
}
