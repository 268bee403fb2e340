//! Attaching a lease in two halves, so that no client waits on another's construction:
//! [`Dispatcher::begin_attach`] validates the request and queues the build on the
//! builder thread; [`Dispatcher::finish_builds`] opens the lease's services and answers
//! once the batch is back. A client that dies or stops waiting in between cancels its
//! build (checked every pass over the pending attaches).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use echogym_protocol::{
    AttachReply, AttachRequest, BatchLayout, ControlError, ControlErrorKind, ControlReply,
};

use super::builder::{AttachBuildError, BuildJob};
use super::dispatcher::Dispatcher;
use super::lease::Lease;
use super::pending::PendingAttach;
use super::reply::{ControlRequestHandle, error, refusal};
use crate::pool::BatchBuildError;

/// What an accepted attach request hands to [`Dispatcher::queue_attach`].
pub(super) struct AttachPlan {
    request: AttachRequest,
    client_node: u128,
    spec: echogym_protocol::EnvSpec,
    shm_bytes: u64,
}

impl Dispatcher {
    /// Validate an attach request: the plan to build, or the refusal to send.
    pub(super) fn begin_attach(&self, request: AttachRequest) -> Result<AttachPlan, ControlError> {
        if self.shutdown.is_requested() {
            return Err(refusal(
                ControlErrorKind::ShuttingDown,
                "the server is shutting down",
            ));
        }
        let Ok(client_node) = request.client_node_id.parse::<u128>() else {
            return Err(refusal(
                ControlErrorKind::InvalidRequest,
                format!(
                    "client_node_id {:?} is not a node id",
                    request.client_node_id
                ),
            ));
        };
        if request.num_envs == 0 {
            return Err(refusal(
                ControlErrorKind::InvalidRequest,
                "num_envs must be at least 1",
            ));
        }
        let factory = self
            .registry
            .get(&request.env_id)
            .map_err(|e| refusal(ControlErrorKind::UnknownEnv, e.to_string()))?;
        let spec = factory
            .spec(&request.config)
            .map_err(|e| refusal(ControlErrorKind::InvalidConfig, e.to_string()))?;
        // A client's own quota first: a request beyond it is refused naming the quota
        // whatever the others hold; then the server's limits.
        let (client_leases, client_envs, client_shm) = self.held_by(client_node);
        if client_leases >= self.options.max_leases_per_client {
            return Err(refusal(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "this client holds its maximum of {} leases (max_leases_per_client)",
                    self.options.max_leases_per_client
                ),
            ));
        }
        let fits_client = client_envs
            .checked_add(request.num_envs)
            .is_some_and(|total| total <= self.options.max_envs_per_client);
        if !fits_client {
            return Err(refusal(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "{} more envs would exceed this client's max_envs_per_client of {} ({client_envs} held or being built)",
                    request.num_envs, self.options.max_envs_per_client
                ),
            ));
        }
        let leases = self.leases.len() + self.pending.len();
        if leases >= self.options.max_leases {
            return Err(refusal(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "the server holds its maximum of {} leases ({} of them being built)",
                    self.options.max_leases,
                    self.pending.len()
                ),
            ));
        }
        let envs_in_use = self.envs_in_use();
        let fits = envs_in_use
            .checked_add(request.num_envs)
            .is_some_and(|total| total <= self.options.max_envs);
        if !fits {
            return Err(refusal(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "{} more envs would exceed the server's max_envs of {} ({envs_in_use} in use or being built)",
                    request.num_envs, self.options.max_envs
                ),
            ));
        }
        let layout = BatchLayout::new(&spec, request.num_envs, request.autoreset_mode)
            .map_err(|e| refusal(ControlErrorKind::InvalidConfig, e.to_string()))?;
        let shm_bytes = layout.shared_memory_bytes() as u64;
        if client_shm.saturating_add(shm_bytes) > self.options.max_shm_bytes_per_client {
            return Err(refusal(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "{} envs need {} of shared memory, which would exceed this client's max_shm_bytes_per_client of {} ({} held or being built)",
                    request.num_envs,
                    mib(shm_bytes),
                    mib(self.options.max_shm_bytes_per_client),
                    mib(client_shm)
                ),
            ));
        }
        let shm_in_use = self.shm_bytes_in_use();
        if shm_in_use.saturating_add(shm_bytes) > self.options.max_shm_bytes {
            return Err(refusal(
                ControlErrorKind::CapacityExceeded,
                format!(
                    "{} envs need {} of shared memory, which would exceed the server's max_shm_bytes of {} ({} in use or being built)",
                    request.num_envs,
                    mib(shm_bytes),
                    mib(self.options.max_shm_bytes),
                    mib(shm_in_use)
                ),
            ));
        }
        Ok(AttachPlan {
            request,
            client_node,
            spec,
            shm_bytes,
        })
    }

    /// Queue the build of an accepted attach; its reply is sent by
    /// [`Self::finish_builds`].
    pub(super) fn queue_attach(&mut self, plan: AttachPlan, request: ControlRequestHandle) {
        let ticket = self.next_ticket;
        self.next_ticket += 1;
        let cancel = Arc::new(AtomicBool::new(false));
        let AttachPlan {
            request: attach,
            client_node,
            spec,
            shm_bytes,
        } = plan;
        let lease_id = (u64::from(self.instance) << 32) | u64::from(self.next_lease);
        self.next_lease += 1;
        let queued = self.builder.build(BuildJob {
            ticket,
            spec,
            num_envs: attach.num_envs,
            mode: attach.autoreset_mode,
            cancel: cancel.clone(),
            lease_id,
            client_node,
            client_label: attach.client_label.clone(),
        });
        if !queued {
            self.answer(
                request,
                &error(ControlErrorKind::Internal, "the env builder is gone"),
            );
            return;
        }
        tracing::debug!(ticket, env = %attach.env_id, num_envs = attach.num_envs, "build queued");
        self.pending.push(PendingAttach {
            request,
            ticket,
            cancel,
            client_node,
            client_label: attach.client_label,
            env_id: attach.env_id,
            num_envs: attach.num_envs,
            shm_bytes,
            mode: attach.autoreset_mode,
            started: Instant::now(),
        });
    }

    /// Answer every attach whose build came back; true if any did.
    pub(super) fn finish_builds(&mut self) -> bool {
        let mut finished = false;
        while let Some(built) = self.builder.finished() {
            finished = true;
            let Some(index) = self.pending.iter().position(|p| p.ticket == built.ticket) else {
                continue;
            };
            let pending = self.pending.swap_remove(index);
            let lease = match built.result {
                Ok(lease) => lease,
                Err(AttachBuildError::Build(BatchBuildError::Cancelled { built, wanted })) => {
                    tracing::info!(
                        client = %pending.client_label,
                        env = %pending.env_id,
                        built,
                        wanted,
                        "attach cancelled: the client died or stopped waiting"
                    );
                    continue;
                }
                Err(e) => {
                    let kind = match e {
                        AttachBuildError::Build(BatchBuildError::Panicked { .. })
                        | AttachBuildError::Open(_) => ControlErrorKind::Internal,
                        AttachBuildError::Build(_) => ControlErrorKind::InvalidConfig,
                    };
                    tracing::warn!(client = %pending.client_label, error = %e, "attach failed");
                    self.answer(pending.request, &error(kind, e.to_string()));
                    continue;
                }
            };
            if !self.client_waiting(&pending.request) || pending.cancel.load(Ordering::Relaxed) {
                tracing::info!(
                    client = %pending.client_label,
                    env = %pending.env_id,
                    "attach dropped: the client stopped waiting before its envs were built"
                );
                self.retire(lease);
                continue;
            }
            let lease_id = lease.id;
            let Some(spec) = lease.batch().map(|b| b.spec().clone()) else {
                continue; // a new lease holds its batch
            };
            let reply = AttachReply {
                lease_id,
                spec,
                layout: lease.layout().clone(),
                autoreset_mode: pending.mode,
                server_spin_us: self.options.spin.as_micros() as u64,
                server_node_id: self.node.id().value().to_string(),
            };
            tracing::info!(
                lease = lease_id,
                env = %pending.env_id,
                num_envs = pending.num_envs,
                client = %pending.client_label,
                build_ms = built.elapsed.as_secs_f64() * 1e3,
                "lease attached"
            );
            self.leases.push(lease);
            self.answer(pending.request, &ControlReply::Attached(reply));
        }
        finished
    }

    /// Cancel the builds nobody waits for any more: the client stopped waiting (its
    /// request was dropped) or its node is not in `alive` (when given).
    pub(super) fn cancel_abandoned(&mut self, alive: Option<&[u128]>) {
        for pending in &self.pending {
            let dead = alive.is_some_and(|alive| !alive.contains(&pending.client_node));
            if (dead || !self.client_waiting(&pending.request))
                && !pending.cancel.swap(true, Ordering::Relaxed)
            {
                // Which of the two: a client wrongly judged gone waits for its attach
                // until its own deadline, so the log must tell them apart.
                tracing::info!(
                    ticket = pending.ticket,
                    client = %pending.client_label,
                    client_node = pending.client_node,
                    reason = if dead { "its node is not alive" } else { "its control port is gone" },
                    "cancelling a build"
                );
            }
        }
    }

    /// Leases and envs `client` holds or is having built.
    /// Leases, envs and bytes of shared memory a client holds or is having built.
    fn held_by(&self, client: u128) -> (usize, usize, u64) {
        let leases = self.leases.iter().filter(|l| l.client_node == client);
        let pending = self.pending.iter().filter(|p| p.client_node == client);
        let count = leases.clone().count() + pending.clone().count();
        let envs = leases.clone().map(|l| l.num_envs()).sum::<usize>()
            + pending.clone().map(|p| p.num_envs).sum::<usize>();
        let bytes =
            leases.map(lease_shm_bytes).sum::<u64>() + pending.map(|p| p.shm_bytes).sum::<u64>();
        (count, envs, bytes)
    }

    /// Bytes of lease shared memory held and being built.
    fn shm_bytes_in_use(&self) -> u64 {
        self.leases
            .iter()
            .chain(&self.closing)
            .map(lease_shm_bytes)
            .sum::<u64>()
            + self.pending.iter().map(|p| p.shm_bytes).sum::<u64>()
    }

    /// Envs held by leases and being built.
    pub(super) fn envs_in_use(&self) -> usize {
        let held: usize = self
            .leases
            .iter()
            .chain(&self.closing)
            .map(|l| l.num_envs())
            .sum();
        let building: usize = self.pending.iter().map(|p| p.num_envs).sum();
        held + building
    }
}

fn lease_shm_bytes(lease: &Lease) -> u64 {
    lease.layout().shared_memory_bytes() as u64
}

/// Bytes as MiB for messages.
fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / f64::from(1 << 20))
}
