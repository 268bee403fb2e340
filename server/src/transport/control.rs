//! Handling of control requests (attach, detach, spec, envs, status, stop).

use echogym_protocol::{
    BuildStatus, ControlError, ControlErrorKind, ControlHeader, ControlReply, ControlRequest,
    LeaseStatus, PROTOCOL_VERSION, ServerStatus,
};

use super::attach::ControlRequestHandle;
use super::dispatcher::Dispatcher;

/// A refusal, logged at debug level.
pub(super) fn refusal(kind: ControlErrorKind, message: impl Into<String>) -> ControlError {
    let message = message.into();
    tracing::debug!(?kind, %message, "control request refused");
    ControlError { kind, message }
}

/// A refusal as a reply.
pub(super) fn error(kind: ControlErrorKind, message: impl Into<String>) -> ControlReply {
    ControlReply::Error(refusal(kind, message))
}

/// Send `reply` to the client of `request` (a client that went away is only logged).
pub(super) fn respond(request: &ControlRequestHandle, reply: &ControlReply) {
    let text = serde_json::to_vec(reply).unwrap_or_else(|e| {
        serde_json::to_vec(&ControlReply::Error(ControlError {
            kind: ControlErrorKind::Internal,
            message: format!("the reply did not serialize: {e}"),
        }))
        .unwrap_or_default()
    });
    let Ok(payload_len) = u32::try_from(text.len()) else {
        tracing::error!(len = text.len(), "a control reply over 4 GiB was not sent");
        return;
    };
    let sent = request
        .loan_slice_uninit(text.len())
        .map(|mut response| {
            *response.user_header_mut() = ControlHeader {
                protocol_version: PROTOCOL_VERSION,
                payload_len,
            };
            response.write_from_slice(&text)
        })
        .map_err(|e| format!("{e:?}"))
        .and_then(|response| response.send().map_err(|e| format!("{e:?}")));
    if let Err(e) = sent {
        tracing::debug!(error = ?e, "sending a control reply failed");
    }
}

/// Parse one control request (header already received, payload is JSON).
pub(super) fn parse_control(
    header: ControlHeader,
    payload: &[u8],
) -> Result<ControlRequest, ControlError> {
    if header.protocol_version != PROTOCOL_VERSION {
        return Err(refusal(
            ControlErrorKind::VersionMismatch,
            format!(
                "client speaks protocol {}, server speaks {PROTOCOL_VERSION}; install matching echogym versions",
                header.protocol_version
            ),
        ));
    }
    let len = (header.payload_len as usize).min(payload.len());
    serde_json::from_slice(&payload[..len]).map_err(|e| {
        refusal(
            ControlErrorKind::InvalidRequest,
            format!("malformed request: {e}"),
        )
    })
}

impl Dispatcher {
    /// Answer a control request other than attach.
    pub(super) fn handle_control(&mut self, request: ControlRequest) -> ControlReply {
        match request {
            ControlRequest::Attach(_) => error(
                ControlErrorKind::Internal,
                "attach is answered by the attach stage",
            ),
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

    fn detach(&mut self, lease_id: u64) -> ControlReply {
        match self.leases.iter().position(|l| l.id == lease_id) {
            Some(index) => {
                let lease = self.leases.remove(index);
                tracing::info!(lease = lease_id, client = %lease.client_label, "lease detached");
                self.builder.discard(lease.close());
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
                    env_steps: l.env_steps,
                    idle_s: l.last_activity.elapsed().as_secs_f64(),
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
}
