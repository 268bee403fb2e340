//! Handling of control requests (attach, detach, spec, envs, status, stop).

use echogym_protocol::{
    AttachReply, AttachRequest, ControlError, ControlErrorKind, ControlHeader, ControlReply,
    ControlRequest, LeaseStatus, PROTOCOL_VERSION, ServerStatus,
};

use super::dispatcher::Dispatcher;
use super::lease::Lease;
use crate::pool::EnvBatch;

fn error(kind: ControlErrorKind, message: impl Into<String>) -> ControlReply {
    let message = message.into();
    tracing::debug!(?kind, %message, "control request refused");
    ControlReply::Error(ControlError { kind, message })
}

impl Dispatcher {
    /// Answer one control request (header already received, payload is JSON).
    pub(super) fn handle_control(&mut self, header: ControlHeader, payload: &[u8]) -> ControlReply {
        if header.protocol_version != PROTOCOL_VERSION {
            return error(
                ControlErrorKind::VersionMismatch,
                format!(
                    "client speaks protocol {}, server speaks {PROTOCOL_VERSION}; install matching echogym versions",
                    header.protocol_version
                ),
            );
        }
        let len = (header.payload_len as usize).min(payload.len());
        let request: ControlRequest = match serde_json::from_slice(&payload[..len]) {
            Ok(request) => request,
            Err(e) => {
                return error(
                    ControlErrorKind::InvalidRequest,
                    format!("malformed request: {e}"),
                );
            }
        };
        match request {
            ControlRequest::Attach(attach) => self.attach(attach),
            ControlRequest::Detach { lease_id } => self.detach(lease_id),
            ControlRequest::Spec { env_id, config } => match self.registry.get(&env_id) {
                Err(e) => error(ControlErrorKind::UnknownEnv, e.to_string()),
                Ok(factory) => match factory.spec(&config) {
                    Ok(spec) => ControlReply::Spec(spec),
                    Err(e) => error(ControlErrorKind::InvalidConfig, e.to_string()),
                },
            },
            ControlRequest::ListEnvs => ControlReply::Envs {
                envs: self.registry.list(),
            },
            ControlRequest::Status => ControlReply::Status(self.status()),
            ControlRequest::Stop => {
                tracing::info!("stop requested by a client");
                self.shutdown.request();
                ControlReply::Stopping
            }
        }
    }

    fn attach(&mut self, request: AttachRequest) -> ControlReply {
        if self.shutdown.is_requested() {
            return error(
                ControlErrorKind::ShuttingDown,
                "the server is shutting down",
            );
        }
        let Ok(client_node) = request.client_node_id.parse::<u128>() else {
            return error(
                ControlErrorKind::InvalidRequest,
                format!(
                    "client_node_id {:?} is not a node id",
                    request.client_node_id
                ),
            );
        };
        let factory = match self.registry.get(&request.env_id) {
            Ok(factory) => factory,
            Err(e) => return error(ControlErrorKind::UnknownEnv, e.to_string()),
        };
        let spec = match factory.spec(&request.config) {
            Ok(spec) => spec,
            Err(e) => return error(ControlErrorKind::InvalidConfig, e.to_string()),
        };
        if self.leases.len() >= self.options.max_leases {
            return error(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "the server holds its maximum of {} leases",
                    self.options.max_leases
                ),
            );
        }
        let envs_in_use: usize = self.leases.iter().map(|l| l.batch.len()).sum();
        if envs_in_use + request.num_envs > self.options.max_envs {
            return error(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "{} more envs would exceed the server's max_envs of {} ({envs_in_use} in use)",
                    request.num_envs, self.options.max_envs
                ),
            );
        }
        let batch = match EnvBatch::new(factory, spec, request.num_envs, request.autoreset_mode) {
            Ok(batch) => batch,
            Err(e) => return error(ControlErrorKind::InvalidRequest, e.to_string()),
        };
        let lease_id = (u64::from(self.instance) << 32) | u64::from(self.next_lease);
        self.next_lease += 1;
        let lease = match Lease::open(
            &self.node,
            &self.names,
            lease_id,
            batch,
            client_node,
            request.client_label.clone(),
        ) {
            Ok(lease) => lease,
            Err(e) => return error(ControlErrorKind::Internal, e.to_string()),
        };
        let reply = AttachReply {
            lease_id,
            spec: lease.batch.spec().clone(),
            layout: lease.batch.layout().clone(),
            autoreset_mode: request.autoreset_mode,
            server_spin_us: self.options.spin.as_micros() as u64,
            server_node_id: self.node.id().value().to_string(),
        };
        tracing::info!(
            lease = lease_id,
            env = %request.env_id,
            num_envs = request.num_envs,
            client = %request.client_label,
            "lease attached"
        );
        self.leases.push(lease);
        ControlReply::Attached(reply)
    }

    fn detach(&mut self, lease_id: u64) -> ControlReply {
        match self.leases.iter().position(|l| l.id == lease_id) {
            Some(index) => {
                let lease = self.leases.remove(index);
                tracing::info!(lease = lease_id, client = %lease.client_label, "lease detached");
                ControlReply::Detached { lease_id }
            }
            None => error(
                ControlErrorKind::UnknownLease,
                format!("no lease {lease_id} (already detached or reclaimed)"),
            ),
        }
    }

    fn status(&self) -> ServerStatus {
        ServerStatus {
            name: self.options.name.clone(),
            pid: std::process::id(),
            version: env!("CARGO_PKG_VERSION").to_owned(),
            protocol_version: PROTOCOL_VERSION,
            uptime_s: self.started.elapsed().as_secs_f64(),
            threads: self.pool.threads(),
            env_steps: self.env_steps,
            reclaimed_leases: self.reclaimed,
            leases: self
                .leases
                .iter()
                .map(|l| LeaseStatus {
                    lease_id: l.id,
                    env_id: l.batch.spec().env_id.clone(),
                    num_envs: l.batch.len(),
                    client_label: l.client_label.clone(),
                    exchanges: l.exchanges,
                    age_s: l.created.elapsed().as_secs_f64(),
                })
                .collect(),
        }
    }
}
