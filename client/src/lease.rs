//! [`Lease`]: a batch of server-side envs, stepped with one exchange per call.

use std::time::Duration;

use echogym_protocol::{
    ActionHeader, AttachReply, AttachRequest, AutoresetMode, BatchLayout, ControlErrorKind,
    ControlReply, ControlRequest, ENV_ERROR_KEY, EnvSpec, ObsHeader, Op, PROTOCOL_VERSION,
    ResetFlag, StepStatus,
};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;

use super::connection::{Connection, node_alive};
use super::error::{ControlCallError, LeaseError};
use super::wait::spin_then_block;
use echogym_protocol::services::{
    Access, ActionService, EventService, ObsService, event_service, lease_channel,
};

/// What to lease.
#[derive(Debug, Clone)]
pub struct AttachOptions {
    /// Versioned env id, e.g. `echogym/Null-v0`.
    pub env_id: String,
    /// Envs in the batch (K).
    pub num_envs: usize,
    /// Env config; unknown keys are refused by the server.
    pub config: serde_json::Map<String, serde_json::Value>,
    /// What happens to envs whose episode ended.
    pub autoreset_mode: AutoresetMode,
}

/// A leased batch of envs. Observations returned by [`Lease::step`] / [`Lease::reset`]
/// are the server's shared-memory sample itself, valid until the next exchange.
pub struct Lease {
    reply: AttachReply,
    seq: u64,
    /// The sequence number of the exchange sent and not yet received, if any.
    in_flight: Option<u64>,
    current: Option<Sample<ipc_threadsafe::Service, [u8], ObsHeader>>,
    /// Why the lease is unusable: `Closed` after `close`, or the error that ended it.
    ended: Option<LeaseError>,
    publisher: Publisher<ipc_threadsafe::Service, [u8], ActionHeader>,
    subscriber: Subscriber<ipc_threadsafe::Service, [u8], ObsHeader>,
    listener: Listener<ipc_threadsafe::Service>,
    _action_service: ActionService<ipc_threadsafe::Service>,
    obs_service: ObsService<ipc_threadsafe::Service>,
    _ready_service: EventService<ipc_threadsafe::Service>,
    connection: Connection,
}

impl Connection {
    /// Lease `options.num_envs` envs. The envs start un-reset: call [`Lease::reset`].
    pub fn attach(&self, options: &AttachOptions) -> Result<Lease, ControlCallError> {
        let request = ControlRequest::Attach(AttachRequest {
            env_id: options.env_id.clone(),
            num_envs: options.num_envs,
            config: options.config.clone(),
            autoreset_mode: options.autoreset_mode,
            client_node_id: self.node_id().to_string(),
            client_label: self.options().label.clone(),
        });
        let reply = match self.request(&request)? {
            ControlReply::Attached(reply) => reply,
            other => return Err(ControlCallError::Malformed(format!("{other:?}"))),
        };
        let lease_id = reply.lease_id;
        match Lease::open(self.clone(), reply) {
            Ok(lease) => Ok(lease),
            Err(e) => {
                let _ = self.request(&ControlRequest::Detach {
                    lease_id,
                    client_node_id: self.node_id().to_string(),
                });
                Err(e)
            }
        }
    }
}

impl Lease {
    fn open(connection: Connection, reply: AttachReply) -> Result<Self, ControlCallError> {
        let inner = &connection.inner;
        let ipc = |e: &dyn std::fmt::Debug| ControlCallError::Ipc(format!("{e:?}"));
        let id = reply.lease_id;
        let action_service = lease_channel::<_, ActionHeader>(
            &inner.node,
            &inner.names.lease_action(id),
            Access::Open,
        )
        .map_err(|e| ipc(&e))?;
        let obs_service =
            lease_channel::<_, ObsHeader>(&inner.node, &inner.names.lease_obs(id), Access::Open)
                .map_err(|e| ipc(&e))?;
        let ready_service =
            event_service(&inner.node, &inner.names.lease_ready(id), 1, Access::Open)
                .map_err(|e| ipc(&e))?;
        let publisher = action_service
            .publisher_builder()
            .initial_max_slice_len(reply.layout.action.total)
            .allocation_strategy(AllocationStrategy::Static)
            .create()
            .map_err(|e| ipc(&e))?;
        let subscriber = obs_service
            .subscriber_builder()
            .create()
            .map_err(|e| ipc(&e))?;
        let listener = ready_service
            .listener_builder()
            .create()
            .map_err(|e| ipc(&e))?;
        Ok(Self {
            reply,
            seq: 0,
            in_flight: None,
            current: None,
            ended: None,
            publisher,
            subscriber,
            listener,
            _action_service: action_service,
            obs_service,
            _ready_service: ready_service,
            connection,
        })
    }

    /// The lease id.
    pub fn id(&self) -> u64 {
        self.reply.lease_id
    }

    /// The env spec.
    pub fn spec(&self) -> &EnvSpec {
        &self.reply.spec
    }

    /// Where everything lives in the samples.
    pub fn layout(&self) -> &BatchLayout {
        &self.reply.layout
    }

    /// Envs in the batch.
    pub fn num_envs(&self) -> usize {
        self.reply.layout.num_envs
    }

    /// The autoreset mode.
    pub fn autoreset_mode(&self) -> AutoresetMode {
        self.reply.autoreset_mode
    }

    /// The envs flagged [`ENV_ERROR_KEY`] in the observation `payload` of this lease:
    /// their step or reset failed inside the server (the other envs' results are
    /// valid). A failed env's row is zeros, a failed step is truncated, and the env
    /// needs a reset (same-step autoreset tries one; if it failed too, a step of the
    /// env answers [`LeaseError::NeedsReset`]).
    pub fn failed_envs(&self, payload: &[u8]) -> Vec<usize> {
        let layout = &self.reply.layout;
        let Some(key) = self
            .reply
            .spec
            .info_keys
            .iter()
            .position(|k| k == ENV_ERROR_KEY)
        else {
            return Vec::new();
        };
        (0..layout.num_envs)
            .filter(|env| {
                let at = layout.obs.info + (env * layout.info_len + key) * 4;
                payload
                    .get(at..at + 4)
                    .is_some_and(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]) != 0.0)
            })
            .collect()
    }

    /// True once [`Lease::close`] ran, or the server stopped or dropped the lease.
    pub fn is_closed(&self) -> bool {
        self.ended.is_some()
    }

    /// Step every env with `actions` (`num_envs × action_size`, row-major). Envs flagged
    /// in `reset` (optional, one [`ResetFlag`] byte per env) are reset instead.
    /// Returns the observation sample payload (see [`BatchLayout`]).
    pub fn step(&mut self, actions: &[f32], reset: Option<&[u8]>) -> Result<&[u8], LeaseError> {
        self.send_step(actions, reset)?;
        self.recv()
    }

    /// The first half of [`Lease::step`]: send the actions and return at once, without
    /// waiting for the observations; [`Lease::try_recv`] or [`Lease::recv`] takes them.
    /// One exchange at a time per lease; the previous observation is released here.
    pub fn send_step(&mut self, actions: &[f32], reset: Option<&[u8]>) -> Result<(), LeaseError> {
        let layout = &self.reply.layout;
        let expected = layout.num_envs * layout.action_size;
        if actions.len() != expected {
            return Err(LeaseError::ActionShape {
                got: actions.len(),
                expected,
                num_envs: layout.num_envs,
                action_size: layout.action_size,
            });
        }
        self.send(Op::Step, Some(actions), reset, None)
    }

    /// Reset the envs whose `mask` byte is nonzero (all when `mask` is `None`); envs with
    /// a seed in `seeds` (one per env, `None` = keep the stream) are reseeded. Envs not
    /// reset report their current observation.
    pub fn reset(
        &mut self,
        mask: Option<&[bool]>,
        seeds: Option<&[Option<u64>]>,
    ) -> Result<&[u8], LeaseError> {
        self.send_reset(mask, seeds)?;
        self.recv()
    }

    /// The first half of [`Lease::reset`] (see [`Lease::send_step`]).
    pub fn send_reset(
        &mut self,
        mask: Option<&[bool]>,
        seeds: Option<&[Option<u64>]>,
    ) -> Result<(), LeaseError> {
        let k = self.num_envs();
        if mask.is_some_and(|m| m.len() != k) || seeds.is_some_and(|s| s.len() != k) {
            return Err(LeaseError::BadReset(format!(
                "mask and seeds need one entry per env ({k})"
            )));
        }
        let flags: Vec<u8> = (0..k)
            .map(|i| {
                let selected = mask.is_none_or(|m| m[i]);
                let seeded = seeds.is_some_and(|s| s[i].is_some());
                match (selected, seeded) {
                    (false, _) => ResetFlag::Keep as u8,
                    (true, false) => ResetFlag::Reset as u8,
                    (true, true) => ResetFlag::ResetWithSeed as u8,
                }
            })
            .collect();
        let seeds: Vec<u64> = (0..k)
            .map(|i| seeds.and_then(|s| s[i]).unwrap_or(0))
            .collect();
        self.send(Op::Reset, None, Some(&flags), Some(&seeds))
    }

    /// True while an exchange was sent and its observations not yet received.
    pub fn in_flight(&self) -> bool {
        self.in_flight.is_some()
    }

    fn send(
        &mut self,
        op: Op,
        actions: Option<&[f32]>,
        flags: Option<&[u8]>,
        seeds: Option<&[u64]>,
    ) -> Result<(), LeaseError> {
        if let Some(reason) = &self.ended {
            return Err(reason.clone());
        }
        if self.in_flight.is_some() {
            return Err(LeaseError::Async(format!(
                "lease {} already has an exchange in flight; receive it first",
                self.reply.lease_id
            )));
        }
        // Release the previous observation before asking for the next one.
        self.current = None;
        self.seq += 1;
        let seq = self.seq;
        let layout = &self.reply.layout;
        let ipc = |e: &dyn std::fmt::Debug| LeaseError::Ipc(format!("{e:?}"));

        let mut sample = self
            .publisher
            .loan_slice_uninit(layout.action.total)
            .map_err(|e| ipc(&e))?
            .write_from_fn(|_| 0u8);
        *sample.user_header_mut() = ActionHeader {
            protocol_version: PROTOCOL_VERSION,
            op: op as u32,
            seq,
            lease_id: self.reply.lease_id,
            num_envs: layout.num_envs as u32,
            reserved: 0,
        };
        let payload = sample.payload_mut();
        if let Some(actions) = actions {
            let bytes: &[u8] = bytemuck::cast_slice(actions);
            payload[layout.action.actions..layout.action.actions + bytes.len()]
                .copy_from_slice(bytes);
        }
        if let Some(flags) = flags {
            payload[layout.action.reset..layout.action.reset + flags.len()].copy_from_slice(flags);
        }
        if let Some(seeds) = seeds {
            let bytes: &[u8] = bytemuck::cast_slice(seeds);
            payload[layout.action.seeds..layout.action.seeds + bytes.len()].copy_from_slice(bytes);
        }
        let reached = sample.send().map_err(|e| ipc(&e))?;
        if reached == 0 {
            return Err(self.gone());
        }
        let _ = self.connection.inner.wake.notify();
        self.in_flight = Some(seq);
        Ok(())
    }

    /// Wait for the observations of the exchange in flight (spin, then block; the step
    /// deadline and the server's liveness are checked while blocked).
    pub fn recv(&mut self) -> Result<&[u8], LeaseError> {
        let Some(seq) = self.expect_in_flight()? else {
            unreachable!("expect_in_flight returns Some or an error")
        };
        let spin = self.connection.inner.options.spin;
        let subscriber = &self.subscriber;
        let obs_service = &self.obs_service;
        let config = &self.connection.inner.config;
        let server_node: u128 = self.reply.server_node_id.parse().unwrap_or(0);
        let deadline = std::time::Instant::now() + self.connection.inner.options.step_timeout;
        let step_timeout = self.connection.inner.options.step_timeout;
        let received = spin_then_block(
            spin,
            &self.listener,
            || take_reply(subscriber, seq),
            || {
                if obs_service.dynamic_config().number_of_publishers() == 0
                    || !node_alive(config, server_node)
                {
                    Err(LeaseError::ServerStopped)
                } else if std::time::Instant::now() > deadline {
                    Err(LeaseError::Timeout(step_timeout))
                } else {
                    Ok(())
                }
            },
        );
        match received {
            Ok(sample) => self.accept(sample),
            Err(e) => {
                if matches!(e, LeaseError::ServerStopped | LeaseError::Timeout(_)) {
                    self.ended = Some(e.clone());
                }
                Err(e)
            }
        }
    }

    /// The observations of the exchange in flight if they have arrived (never blocks).
    /// `Ok(None)`: not yet. The server's liveness is not checked here: a caller polling
    /// several leases blocks in [`crate::AsyncBatch::recv`], which checks it.
    pub fn try_recv(&mut self) -> Result<Option<&[u8]>, LeaseError> {
        let Some(seq) = self.expect_in_flight()? else {
            unreachable!("expect_in_flight returns Some or an error")
        };
        match take_reply(&self.subscriber, seq)? {
            Some(sample) => self.accept(sample).map(Some),
            None => Ok(None),
        }
    }

    /// The seq in flight, or why there is none to receive.
    fn expect_in_flight(&self) -> Result<Option<u64>, LeaseError> {
        match (&self.ended, self.in_flight) {
            (_, Some(seq)) => Ok(Some(seq)),
            (Some(reason), None) => Err(reason.clone()),
            (None, None) => Err(LeaseError::Async(format!(
                "lease {} has no exchange in flight to receive",
                self.reply.lease_id
            ))),
        }
    }

    /// Check a received observation sample's status and keep it as the current one.
    fn accept(
        &mut self,
        sample: Sample<ipc_threadsafe::Service, [u8], ObsHeader>,
    ) -> Result<&[u8], LeaseError> {
        self.in_flight = None;
        let header = *sample.user_header();
        let env = header.env_index as usize;
        let element = header.element_index as usize;
        let error = match StepStatus::from_u32(header.status) {
            Some(StepStatus::Ok) => None,
            Some(StepStatus::NonFiniteAction) => Some(LeaseError::NonFiniteAction { env, element }),
            Some(StepStatus::NeedsReset) => Some(LeaseError::NeedsReset { env }),
            Some(StepStatus::EnvFailure) => Some(LeaseError::EnvFailure { env }),
            Some(StepStatus::BadResetFlag) => Some(LeaseError::BadReset(format!(
                "bad reset flag for env {env}"
            ))),
            Some(StepStatus::VersionMismatch) => Some(LeaseError::VersionMismatch),
            Some(StepStatus::ServerStopped) => {
                self.ended = Some(LeaseError::ServerStopped);
                Some(LeaseError::ServerStopped)
            }
            Some(StepStatus::UnknownOp | StepStatus::ShapeMismatch) | None => {
                Some(LeaseError::Protocol(header.status))
            }
        };
        if let Some(error) = error {
            return Err(error);
        }
        Ok(self.current.insert(sample).payload())
    }

    /// Whether the server of this lease still lives and the step deadline of an
    /// exchange sent at `sent` has not passed.
    pub(crate) fn check_alive(&mut self, sent: std::time::Instant) -> Result<(), LeaseError> {
        let inner = &self.connection.inner;
        let server_node: u128 = self.reply.server_node_id.parse().unwrap_or(0);
        let error = if self.obs_service.dynamic_config().number_of_publishers() == 0
            || !node_alive(&inner.config, server_node)
        {
            Some(LeaseError::ServerStopped)
        } else if sent.elapsed() > inner.options.step_timeout {
            Some(LeaseError::Timeout(inner.options.step_timeout))
        } else {
            None
        };
        match error {
            Some(e) => {
                self.ended = Some(e.clone());
                Err(e)
            }
            None => Ok(()),
        }
    }

    /// The listener the server notifies when this lease's observations are published.
    pub(crate) fn listener(&self) -> &Listener<ipc_threadsafe::Service> {
        &self.listener
    }

    /// The client's spin budget before blocking.
    pub(crate) fn spin(&self) -> Duration {
        self.connection.inner.options.spin
    }

    /// Why nobody received our action: the server stopped, or it dropped this lease.
    fn gone(&mut self) -> LeaseError {
        let inner = &self.connection.inner;
        // A stopping server tells every lease before dropping it: look for that first.
        let mut stopped = false;
        while let Ok(Some(sample)) = self.subscriber.receive() {
            stopped |= sample.user_header().status == StepStatus::ServerStopped as u32;
        }
        // The server this lease belongs to, not any server of that name: a restarted
        // one does not know this lease.
        let server_node: u128 = self.reply.server_node_id.parse().unwrap_or(0);
        let reason = if !stopped && node_alive(&inner.config, server_node) {
            LeaseError::LeaseLost
        } else {
            LeaseError::ServerStopped
        };
        self.ended = Some(reason.clone());
        reason
    }

    /// The observation payload of the last successful exchange, if any.
    pub fn current(&self) -> Option<&[u8]> {
        self.current.as_ref().map(|s| s.payload())
    }

    /// Give the lease back to the server. Idempotent; errors from a server that is
    /// already gone are ignored.
    pub fn close(&mut self) {
        if self.ended.is_some() {
            return;
        }
        self.ended = Some(LeaseError::Closed);
        self.current = None;
        let request = ControlRequest::Detach {
            lease_id: self.reply.lease_id,
            client_node_id: self.connection.node_id().to_string(),
        };
        match self
            .connection
            .inner
            .request(PROTOCOL_VERSION, &request, Duration::from_secs(5))
        {
            Ok(ControlReply::Detached { .. }) => {}
            Ok(ControlReply::Error(e)) if e.kind == ControlErrorKind::UnknownLease => {}
            Ok(other) => tracing::debug!(?other, "unexpected reply to detach"),
            Err(e) => tracing::debug!(error = %e, "detach failed"),
        }
    }
}

/// The answer to exchange `seq` if it has arrived; stale answers (to an exchange
/// abandoned by an error) are skipped.
fn take_reply(
    subscriber: &Subscriber<ipc_threadsafe::Service, [u8], ObsHeader>,
    seq: u64,
) -> Result<Option<Sample<ipc_threadsafe::Service, [u8], ObsHeader>>, LeaseError> {
    loop {
        match subscriber.receive() {
            Ok(Some(sample)) => {
                let header = *sample.user_header();
                if header.seq == seq || header.status == StepStatus::ServerStopped as u32 {
                    return Ok(Some(sample));
                }
            }
            Ok(None) => return Ok(None),
            Err(e) => return Err(LeaseError::Ipc(format!("{e:?}"))),
        }
    }
}

impl std::fmt::Debug for Lease {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lease")
            .field("id", &self.reply.lease_id)
            .field("env_id", &self.reply.spec.env_id)
            .field("num_envs", &self.reply.layout.num_envs)
            .field("autoreset_mode", &self.reply.autoreset_mode)
            .field("ended", &self.ended)
            .finish()
    }
}

impl Drop for Lease {
    fn drop(&mut self) {
        self.close();
    }
}
