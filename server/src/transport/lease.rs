//! A lease on the server side: a batch of envs and the three services it talks over.

use std::sync::Arc;
use std::time::Instant;

use echogym_protocol::{ActionHeader, BatchLayout, ObsHeader, ServiceNames, StepStatus};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample_mut::SampleMut;

use super::Ipc;
use crate::pool::EnvBatch;
use echogym_protocol::services::{
    Access, ActionService, EventService, ObsService, ServiceError, event_service, lease_channel,
};

/// Server-side state of one lease.
pub(crate) struct Lease {
    pub id: u64,
    pub client_node: u128,
    pub client_label: String,
    pub created: Instant,
    pub exchanges: u64,
    pub env_steps: u64,
    /// Env steps truncated for a physics error.
    pub physics_errors: u64,
    /// Env steps and resets that failed inside the env (flagged `env_error`).
    pub env_errors: u64,
    /// Exchanges that ran on the medium lane.
    pub lane_exchanges: u64,
    pub last_activity: Instant,
    /// The env id (kept here: the batch is away while its exchange runs on the pool).
    pub env_id: String,
    layout: BatchLayout,
    /// The envs; `None` while an exchange of theirs runs on the worker pool.
    batch: Option<EnvBatch>,
    /// An action received while no observation sample could be loaned (the client
    /// still holds them all): kept and served on a later pass, never dropped.
    held_action: Option<iceoryx2::sample::Sample<Ipc, [u8], ActionHeader>>,
    subscriber: Subscriber<Ipc, [u8], ActionHeader>,
    publisher: Publisher<Ipc, [u8], ObsHeader>,
    /// Shared with the worker that publishes an exchange run on the pool.
    notifier: Arc<Notifier<Ipc>>,
    // Services last: ports must drop before the services they belong to.
    _action_service: ActionService<Ipc>,
    _obs_service: ObsService<Ipc>,
    _ready_service: EventService<Ipc>,
}

impl Lease {
    /// Create the lease's services and ports (on failure, the batch comes back with
    /// the error).
    pub fn open(
        node: &Node<Ipc>,
        names: &ServiceNames,
        id: u64,
        batch: EnvBatch,
        client_node: u128,
        client_label: String,
    ) -> Result<Self, Box<(ServiceError, EnvBatch)>> {
        let obs_bytes = batch.layout().obs.total;
        let opened = || -> Result<_, ServiceError> {
            let action_name = names.lease_action(id);
            let obs_name = names.lease_obs(id);
            let ready_name = names.lease_ready(id);
            let action_service =
                lease_channel::<_, ActionHeader>(node, &action_name, Access::Create)?;
            let obs_service = lease_channel::<_, ObsHeader>(node, &obs_name, Access::Create)?;
            let ready_service = event_service(node, &ready_name, 1, Access::Create)?;
            let subscriber = action_service
                .subscriber_builder()
                .create()
                .map_err(|e| ServiceError::new(&action_name, e))?;
            let publisher = obs_service
                .publisher_builder()
                .initial_max_slice_len(obs_bytes)
                .allocation_strategy(AllocationStrategy::Static)
                .create()
                .map_err(|e| ServiceError::new(&obs_name, e))?;
            let notifier = ready_service
                .notifier_builder()
                .create()
                .map_err(|e| ServiceError::new(&ready_name, e))?;
            Ok((
                (subscriber, publisher, notifier),
                (action_service, obs_service, ready_service),
            ))
        };
        let ((subscriber, publisher, notifier), (action_service, obs_service, ready_service)) =
            match opened() {
                Ok(opened) => opened,
                Err(e) => return Err(Box::new((e, batch))),
            };
        Ok(Self {
            id,
            client_node,
            client_label,
            created: Instant::now(),
            exchanges: 0,
            env_steps: 0,
            physics_errors: 0,
            env_errors: 0,
            lane_exchanges: 0,
            last_activity: Instant::now(),
            env_id: batch.spec().env_id.clone(),
            layout: batch.layout().clone(),
            batch: Some(batch),
            held_action: None,
            subscriber,
            publisher,
            notifier: Arc::new(notifier),
            _action_service: action_service,
            _obs_service: obs_service,
            _ready_service: ready_service,
        })
    }

    /// Close the lease's ports and services (ports first, by field order) and hand back
    /// its envs, to be dropped off the dispatcher (`None` while they are on the pool:
    /// close such a lease when they come back, see [`Lease::in_flight`]).
    pub fn close(self) -> Option<EnvBatch> {
        let Self { batch, .. } = self;
        batch
    }

    /// Envs in the batch.
    pub fn num_envs(&self) -> usize {
        self.layout.num_envs
    }

    /// Where everything lives in the samples.
    pub fn layout(&self) -> &BatchLayout {
        &self.layout
    }

    /// The envs, unless an exchange of theirs runs on the pool.
    pub fn batch(&self) -> Option<&EnvBatch> {
        self.batch.as_ref()
    }

    /// The envs, unless an exchange of theirs runs on the pool.
    pub fn batch_mut(&mut self) -> Option<&mut EnvBatch> {
        self.batch.as_mut()
    }

    /// Whether an exchange of this lease runs on the pool (its batch is away).
    pub fn in_flight(&self) -> bool {
        self.batch.is_none()
    }

    /// Send the batch to the pool; [`Lease::restore`] takes it back.
    pub fn take_batch(&mut self) -> Option<EnvBatch> {
        self.batch.take()
    }

    /// The batch is back from the pool.
    pub fn restore(&mut self, batch: EnvBatch) {
        self.batch = Some(batch);
    }

    /// The notifier that wakes the client, for a worker that publishes.
    pub fn notifier(&self) -> Arc<Notifier<Ipc>> {
        Arc::clone(&self.notifier)
    }

    /// The next waiting action sample, if any (a held one first).
    pub fn poll(&mut self) -> Option<iceoryx2::sample::Sample<Ipc, [u8], ActionHeader>> {
        if let Some(held) = self.held_action.take() {
            return Some(held);
        }
        match self.subscriber.receive() {
            Ok(sample) => sample,
            Err(e) => {
                tracing::debug!(lease = self.id, error = ?e, "receiving an action failed");
                None
            }
        }
    }

    /// Keep `action` for a later pass (no observation sample was free).
    pub fn hold(&mut self, action: iceoryx2::sample::Sample<Ipc, [u8], ActionHeader>) {
        if self.held_action.is_none() {
            tracing::debug!(lease = self.id, "no free observation sample: action held");
        }
        self.held_action = Some(action);
    }

    /// Loan a zero-filled observation sample.
    pub fn loan(&self) -> Option<SampleMut<Ipc, [u8], ObsHeader>> {
        let total = self.layout.obs.total;
        match self.publisher.loan_slice_uninit(total) {
            Ok(sample) => Some(sample.write_from_fn(|_| 0u8)),
            Err(e) => {
                tracing::debug!(lease = self.id, error = ?e, "loaning an observation failed");
                None
            }
        }
    }

    /// Publish `sample` and wake the client.
    pub fn publish(&self, sample: SampleMut<Ipc, [u8], ObsHeader>) {
        publish(self.id, sample, &self.notifier);
    }

    /// Publish a status-only answer (an error, or the server stopping).
    pub fn publish_status(
        &self,
        seq: u64,
        status: StepStatus,
        env_index: Option<usize>,
        element_index: Option<usize>,
    ) {
        if let Some(mut sample) = self.loan() {
            *sample.user_header_mut() = ObsHeader {
                seq,
                status: status as u32,
                env_index: env_index.map_or(u32::MAX, |i| i as u32),
                element_index: element_index.map_or(u32::MAX, |i| i as u32),
                num_envs: self.num_envs() as u32,
            };
            self.publish(sample);
        }
    }
}

/// Publish `sample` of lease `id` and wake its client through `notifier` (from the
/// dispatcher or from the worker that ran the exchange).
pub fn publish(id: u64, sample: SampleMut<Ipc, [u8], ObsHeader>, notifier: &Notifier<Ipc>) {
    if let Err(e) = sample.send() {
        tracing::debug!(lease = id, error = ?e, "publishing an observation failed");
    }
    if let Err(e) = notifier.notify() {
        tracing::debug!(lease = id, error = ?e, "waking the client failed");
    }
}
