//! Control requests answered at once: detach, spec, envs, status, stop (attach: `attach.rs`).

use echogym_protocol::{
    BuildStatus, ControlErrorKind, ControlReply, ControlRequest, LeaseStatus, PROTOCOL_VERSION,
    ServerStatus,
};

use super::dispatcher::Dispatcher;
use super::reply::error;

impl Dispatcher {
    /// Answer a control request other than attach.
    pub(super) fn handle_control(&mut self, request: ControlRequest) -> ControlReply {
        match request {
            ControlRequest::Attach(_) => error(
                ControlErrorKind::Internal,
                "attach is answered by the attach stage",
            ),
            ControlRequest::Detach {
                lease_id,
                client_node_id,
            } => self.detach(lease_id, &client_node_id),
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

    /// Detach `lease_id` if `client_node_id` (decimal) attached it: a same-user process
    /// cannot take another client's envs away.
    fn detach(&mut self, lease_id: u64, client_node_id: &str) -> ControlReply {
        match self.leases.iter().position(|l| l.id == lease_id) {
            Some(index)
                if client_node_id.parse::<u128>().ok() != Some(self.leases[index].client_node) =>
            {
                let owner = &self.leases[index];
                tracing::warn!(lease = lease_id, owner = %owner.client_label, "detach refused: not the lease's client");
                error(
                    ControlErrorKind::NotOwner,
                    format!(
                        "lease {lease_id} belongs to another client ({}); only the client that attached it can detach it",
                        owner.client_label
                    ),
                )
            }
            Some(index) => {
                let lease = self.leases.remove(index);
                tracing::info!(lease = lease_id, client = %lease.client_label, "lease detached");
                self.retire(lease);
                ControlReply::Detached { lease_id }
            }
            None => error(
                ControlErrorKind::UnknownLease,
                format!("no lease {lease_id} (already detached or reclaimed)"),
            ),
        }
    }

    fn status(&self) -> ServerStatus {
        let pids = self.client_pids();
        ServerStatus {
            name: self.options.name.clone(),
            pid: std::process::id(),
            version: env!("CARGO_PKG_VERSION").to_owned(),
            protocol_version: PROTOCOL_VERSION,
            uptime_s: self.started.elapsed().as_secs_f64(),
            threads: self.pool.threads(),
            env_steps: self.env_steps,
            physics_errors: self.physics_errors,
            env_errors: self.env_errors,
            reclaimed_leases: self.reclaimed,
            leases: self
                .leases
                .iter()
                .map(|l| LeaseStatus {
                    lease_id: l.id,
                    env_id: l.env_id.clone(),
                    num_envs: l.num_envs(),
                    client_label: l.client_label.clone(),
                    exchanges: l.exchanges,
                    age_s: l.created.elapsed().as_secs_f64(),
                    env_steps: l.env_steps,
                    physics_errors: l.physics_errors,
                    env_errors: l.env_errors,
                    lane_exchanges: l.lane_exchanges,
                    idle_s: l.last_activity.elapsed().as_secs_f64(),
                    client_pid: pids.get(&l.client_node).copied(),
                })
                .collect(),
            building: self
                .pending
                .iter()
                .map(|p| BuildStatus {
                    env_id: p.env_id.clone(),
                    num_envs: p.num_envs,
                    client_label: p.client_label.clone(),
                    waited_s: p.started.elapsed().as_secs_f64(),
                })
                .collect(),
        }
    }

    /// Process ids of the live echogym client nodes (`echogym-client-<pid>`), by node id.
    fn client_pids(&self) -> std::collections::HashMap<u128, u32> {
        use iceoryx2::node::NodeView;
        use iceoryx2::prelude::*;
        let mut pids = std::collections::HashMap::new();
        let _ = Node::<super::Ipc>::list(&self.iox_config, |state| {
            if let NodeState::Alive(view) = &state
                && let Some(details) = view.details()
                && let Some(pid) = details
                    .name()
                    .to_string()
                    .strip_prefix("echogym-client-")
                    .and_then(|p| p.parse().ok())
            {
                pids.insert(view.id().value(), pid);
            }
            CallbackProgression::Continue
        });
        pids
    }
}
