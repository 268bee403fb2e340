//! The dispatcher: the server's one thread that owns every port.
//!
//! # Wake-up protocol (spin, then block)
//! iceoryx2 events coalesce: after a listener drains, the first `notify` sends one
//! datagram and later ones only bump a shared counter (≈ 40 ns). So both sides always
//! notify after publishing, and the waiting side
//! 1. polls its subscribers for the spin budget (≈ 0.1 µs a poll),
//! 2. then drains its listener, polls once more (anything published before the drain is
//!    seen now; anything published after it sends a datagram), and
//! 3. blocks on the listener until woken or until the next housekeeping tick.
//!
//! Housekeeping (every `housekeeping` interval, default 100 ms) reclaims leases of dead
//! clients, reacts to shutdown requests and to the death of a parent process.

use std::sync::Arc;
use std::time::{Duration, Instant};

use echogym_protocol::{
    ActionHeader, ControlReply, ControlRequest, IpcLocation, ObsHeader, Op, PROTOCOL_VERSION,
    ServiceNames, StepStatus,
};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;
use rayon::prelude::*;

use super::builder::Builder;
use super::error::StartError;
use super::lease::Lease;
use super::pending::PendingAttach;
use super::reply::{error, parse_control, respond};
use super::shutdown::Shutdown;
use crate::envs::EnvRegistry;
use crate::pool::WorkerPool;
/// How often the dispatcher looks for finished builds while it would otherwise block.
const BUILD_POLL: Duration = Duration::from_millis(1);

use echogym_protocol::services::{
    Access, ControlService, EventService, MAX_CLIENTS, ServiceError, control_service, event_service,
};

/// What the dispatcher needs to know; see `crate::config::ServeConfig` for meanings
/// and defaults.
#[derive(Debug, Clone)]
pub struct DispatcherOptions {
    /// Server name.
    pub name: String,
    /// Where iceoryx2 resources live.
    pub location: IpcLocation,
    /// Worker threads (0 = one per core).
    pub threads: usize,
    /// Busy-poll time before blocking.
    pub spin: Duration,
    /// Housekeeping period.
    pub housekeeping: Duration,
    /// Most leases at once.
    pub max_leases: usize,
    /// Most envs at once, over all leases.
    pub max_envs: usize,
    /// Most leases one client holds.
    pub max_leases_per_client: usize,
    /// Most envs one client holds.
    pub max_envs_per_client: usize,
    /// Most bytes of lease shared memory at once, over all leases.
    pub max_shm_bytes: u64,
    /// Most bytes of lease shared memory one client holds.
    pub max_shm_bytes_per_client: u64,
    /// Stop when this process is no longer our parent (private servers).
    pub parent_pid: Option<u32>,
}

/// The running server: every port, lease and counter.
pub struct Dispatcher {
    pub(super) options: DispatcherOptions,
    pub(super) names: ServiceNames,
    pub(super) iox_config: Config,
    pub(super) registry: Arc<EnvRegistry>,
    pub(super) builder: Builder,
    pub(super) pending: Vec<PendingAttach>,
    pub(super) next_ticket: u64,
    pub(super) pool: WorkerPool,
    pub(super) leases: Vec<Lease>,
    pub(super) started: Instant,
    pub(super) instance: u32,
    pub(super) next_lease: u32,
    pub(super) env_steps: u64,
    /// Env steps truncated for a physics error over the server's life.
    pub(super) physics_errors: u64,
    pub(super) reclaimed: u64,
    pub(super) shutdown: Shutdown,
    last_reply: Instant,
    control: Server<
        ipc::Service,
        [u8],
        echogym_protocol::ControlHeader,
        [u8],
        echogym_protocol::ControlHeader,
    >,
    wake: Listener<ipc::Service>,
    _control_service: ControlService<ipc::Service>,
    _wake_service: EventService<ipc::Service>,
    pub(super) node: Node<ipc::Service>,
}

/// One ready exchange: the lease, its action sample and the loaned observation sample.
struct Ready {
    lease: usize,
    op: Op,
    action: Sample<ipc::Service, [u8], ActionHeader>,
    obs: SampleMut<ipc::Service, [u8], ObsHeader>,
}

impl Dispatcher {
    /// Create the node and the server-wide services. Fails if a live server already
    /// uses the name; stale resources of a dead one are cleaned first.
    pub fn start(
        options: DispatcherOptions,
        registry: EnvRegistry,
        shutdown: Shutdown,
    ) -> Result<Self, StartError> {
        let names = ServiceNames::new(&options.name)?;
        let iox_config = options.location.iceoryx_config()?;
        options.location.check_root()?;
        echogym_protocol::quiet_iceoryx_logs();
        let node_name = format!("echogym-serve-{}-{}", options.name, std::process::id());
        let node = NodeBuilder::new()
            .config(&iox_config)
            .name(&NodeName::new(&node_name).map_err(|e| StartError::Node(format!("{e:?}")))?)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| StartError::Node(format!("{e:?}")))?;
        node.try_cleanup_dead_nodes();
        super::permissions::harden(&options.location);

        // A live server of this name refuses us. A dead one's services may still be held
        // open by its clients: we adopt them (its stale ports were cleaned just above),
        // so a restart works while old clients live; their leases see their server gone.
        let already_running = |pid| StartError::AlreadyRunning {
            name: options.name.clone(),
            pid,
        };
        if let Some(pid) = running_server_pid(&iox_config, &options.name) {
            return Err(already_running(Some(pid)));
        }
        let control_service = control_service(&node, &names.control(), Access::OpenOrCreate)?;
        // A second server starting at the same moment gets here too; only one can hold
        // the single server port (and the single wake listener).
        let control = control_service
            .server_builder()
            .initial_max_slice_len(64 * 1024)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| match running_server_pid(&iox_config, &options.name) {
                Some(pid) => already_running(Some(pid)),
                None if format!("{e:?}").contains("ExceedsMaxSupported") => already_running(None),
                None => ServiceError::new(&names.control(), e).into(),
            })?;
        let wake_service = event_service(&node, &names.wake(), MAX_CLIENTS, Access::OpenOrCreate)?;
        let wake = wake_service
            .listener_builder()
            .create()
            .map_err(|e| ServiceError::new(&names.wake(), e))?;
        let pool = WorkerPool::new(options.threads)?;
        let registry = Arc::new(registry);
        let builder = Builder::start(registry.clone()).map_err(StartError::Builder)?;
        let instance = (std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos())
            ^ std::process::id().rotate_left(16))
            & 0x7fff_ffff;
        tracing::info!(
            name = %options.name,
            pid = std::process::id(),
            threads = pool.threads(),
            prefix = %options.location.prefix,
            root = %options.location.root.display(),
            "echogym server listening"
        );
        Ok(Self {
            names,
            iox_config,
            registry,
            builder,
            pending: Vec::new(),
            next_ticket: 1,
            pool,
            leases: Vec::new(),
            started: Instant::now(),
            instance,
            next_lease: 1,
            env_steps: 0,
            physics_errors: 0,
            reclaimed: 0,
            shutdown,
            last_reply: Instant::now(),
            control,
            wake,
            _control_service: control_service,
            _wake_service: wake_service,
            node,
            options,
        })
    }

    /// Serve until shutdown is requested, then stop cleanly: the exchange in flight
    /// finishes, every lease is told `ServerStopped`, every service is removed.
    pub fn run(mut self) {
        let spin = self.options.spin;
        let housekeeping = self.options.housekeeping;
        let mut last_work = Instant::now();
        let mut next_housekeeping = last_work + housekeeping;
        while !self.shutdown.is_requested() {
            if self.serve_once() {
                last_work = Instant::now();
            }
            let now = Instant::now();
            if now >= next_housekeeping {
                self.housekeeping();
                next_housekeeping = now + housekeeping;
            }
            let idle = now.duration_since(last_work);
            if idle < spin {
                echogym_protocol::pacing::pause(idle);
                continue;
            }
            // Drain, poll once more, then block (see the module docs for why this order).
            let _ = self.wake.try_wait(|_| {});
            if self.serve_once() {
                last_work = Instant::now();
                continue;
            }
            let mut timeout = next_housekeeping.saturating_duration_since(Instant::now());
            if !self.pending.is_empty() {
                // A build finishing does not ring the wake event: look again soon.
                timeout = timeout.min(BUILD_POLL);
            }
            let _ = self
                .wake
                .timed_wait(|_| {}, timeout.max(Duration::from_millis(1)));
            last_work = Instant::now();
        }
        self.stop();
    }

    /// Serve every waiting control request and exchange once; true if any was waiting.
    fn serve_once(&mut self) -> bool {
        let control = self.serve_control();
        let leases = self.serve_leases();
        let built = !self.pending.is_empty() && {
            self.cancel_abandoned(None);
            self.finish_builds()
        };
        control || leases || built
    }

    fn serve_control(&mut self) -> bool {
        let mut served = false;
        loop {
            let request = match self.control.receive() {
                Ok(Some(request)) => request,
                Ok(None) => break,
                Err(e) => {
                    tracing::debug!(error = ?e, "receiving a control request failed");
                    break;
                }
            };
            served = true;
            let reply = match parse_control(*request.user_header(), request.payload()) {
                Err(refusal) => ControlReply::Error(refusal),
                Ok(ControlRequest::Attach(attach)) => match self.begin_attach(attach) {
                    Err(refusal) => ControlReply::Error(refusal),
                    Ok(plan) => {
                        // Answered when the envs are built (finish_builds).
                        self.queue_attach(plan, request);
                        continue;
                    }
                },
                Ok(other) => self.handle_control(other),
            };
            respond(&request, &reply);
            self.last_reply = Instant::now();
        }
        served
    }

    fn serve_leases(&mut self) -> bool {
        let mut ready = Vec::new();
        for (index, lease) in self.leases.iter_mut().enumerate() {
            let Some(action) = lease.poll() else { continue };
            let header = *action.user_header();
            match check_header(&header, lease) {
                Err(status) => lease.publish_status(header.seq, status, None, None),
                Ok(op) => match lease.loan() {
                    Some(obs) => ready.push(Ready {
                        lease: index,
                        op,
                        action,
                        obs,
                    }),
                    None => lease.hold(action),
                },
            }
        }
        if ready.is_empty() {
            return false;
        }
        self.exchange_all(&mut ready);
        for ready in ready {
            let lease = &self.leases[ready.lease];
            lease.publish(ready.obs);
        }
        true
    }

    /// Run the exchanges of every ready lease, in parallel across leases when several
    /// are ready (each batch also parallelizes across its envs).
    fn exchange_all(&mut self, ready: &mut [Ready]) {
        let wanted: Vec<usize> = ready.iter().map(|r| r.lease).collect();
        let mut work: Vec<(Op, &[u8], &mut [u8], u64)> = ready
            .iter_mut()
            .map(|r| {
                let seq = r.action.user_header().seq;
                (r.op, r.action.payload(), r.obs.payload_mut(), seq)
            })
            .collect();
        let mut batches: Vec<&mut crate::pool::EnvBatch> = self
            .leases
            .iter_mut()
            .enumerate()
            .filter(|(index, _)| wanted.binary_search(index).is_ok())
            .map(|(_, lease)| &mut lease.batch)
            .collect();
        // `ready` is sorted by lease index already (built in order), so work and
        // batches line up.
        let pool = &self.pool;
        let results: Vec<(
            u64,
            Result<crate::pool::Exchanged, crate::pool::ExchangeError>,
        )> = if work.len() == 1 {
            let (op, action, obs, seq) = &mut work[0];
            vec![(*seq, batches[0].exchange(pool, *op, action, obs))]
        } else {
            pool.install(|| {
                work.par_iter_mut()
                    .zip(batches.par_iter_mut())
                    .map(|((op, action, obs, seq), batch)| {
                        (*seq, batch.exchange(pool, *op, action, obs))
                    })
                    .collect()
            })
        };
        drop(work);
        drop(batches);
        for (ready, (seq, result)) in ready.iter_mut().zip(results) {
            let lease = &mut self.leases[ready.lease];
            lease.exchanges += 1;
            lease.last_activity = Instant::now();
            let header = ready.obs.user_header_mut();
            header.seq = seq;
            header.num_envs = lease.batch.len() as u32;
            header.env_index = u32::MAX;
            header.element_index = u32::MAX;
            match result {
                Ok(done) => {
                    self.env_steps += done.steps;
                    lease.env_steps += done.steps;
                    self.physics_errors += done.physics_errors;
                    lease.physics_errors += done.physics_errors;
                    header.status = StepStatus::Ok as u32;
                }
                Err(e) => {
                    tracing::debug!(lease = lease.id, error = %e, "exchange refused");
                    header.status = e.status as u32;
                    header.env_index = e.env_index.map_or(u32::MAX, |i| i as u32);
                    header.element_index = e.element_index.map_or(u32::MAX, |i| i as u32);
                }
            }
        }
    }

    fn housekeeping(&mut self) {
        self.reclaim_dead_clients();
        if let Some(parent) = self.options.parent_pid
            && std::os::unix::process::parent_id() != parent
        {
            tracing::info!(parent, "parent process is gone; stopping");
            self.shutdown.request();
        }
    }

    /// Drop every lease whose client node is no longer alive.
    /// Reclaim the leases and pending attaches of dead clients, and remove what dead
    /// nodes left in `/dev/shm`. The listing runs even with no lease: a client killed
    /// while its lease was being closed leaves segments that only a later pass can
    /// remove (found by the soak benchmark: 7 segments per 5 kills otherwise).
    fn reclaim_dead_clients(&mut self) {
        let mut alive = Vec::new();
        let mut dead = 0usize;
        let listed = Node::<ipc::Service>::list(&self.iox_config, |state| {
            match &state {
                NodeState::Alive(view) => {
                    use iceoryx2::node::NodeView;
                    alive.push(view.id().value());
                }
                NodeState::Dead(_) => dead += 1,
                _ => {}
            }
            CallbackProgression::Continue
        });
        if let Err(e) = listed {
            tracing::debug!(error = ?e, "listing nodes failed");
            return;
        }
        self.cancel_abandoned(Some(&alive));
        let (kept, dead_leases): (Vec<Lease>, Vec<Lease>) = std::mem::take(&mut self.leases)
            .into_iter()
            .partition(|lease| alive.contains(&lease.client_node));
        self.leases = kept;
        self.reclaimed += dead_leases.len() as u64;
        for lease in dead_leases {
            tracing::info!(
                lease = lease.id,
                client = %lease.client_label,
                "reclaimed the lease of a dead client"
            );
            self.builder.discard(lease.close());
        }
        if dead > 0 {
            let cleaned = self.node.try_cleanup_dead_nodes();
            tracing::trace!(?cleaned, "cleaned resources of dead nodes");
        }
    }

    fn stop(mut self) {
        for pending in self.pending.drain(..) {
            pending
                .cancel
                .store(true, std::sync::atomic::Ordering::Relaxed);
            respond(
                &pending.request,
                &error(
                    echogym_protocol::ControlErrorKind::ShuttingDown,
                    "the server stopped before the envs were built",
                ),
            );
        }
        for lease in &self.leases {
            lease.publish_status(0, StepStatus::ServerStopped, None, None);
        }
        // Give clients time to take what was just sent (the last control reply, the
        // `ServerStopped` samples) before the ports, and their shared memory, go away.
        let grace = std::time::Duration::from_millis(100);
        if let Some(left) = grace.checked_sub(self.last_reply.elapsed()) {
            std::thread::sleep(left);
        }
        let leases = self.leases.len();
        for lease in std::mem::take(&mut self.leases) {
            self.builder.discard(lease.close());
        }
        // Dropping the builder waits for the queued drops (an env that panics while
        // being dropped is caught there, and the server still exits cleanly).
        tracing::info!(name = %self.options.name, leases, "echogym server stopped");
    }
}

/// Check an action header against its lease; the op on success.
fn check_header(header: &ActionHeader, lease: &Lease) -> Result<Op, StepStatus> {
    if header.protocol_version != PROTOCOL_VERSION {
        return Err(StepStatus::VersionMismatch);
    }
    if header.lease_id != lease.id || header.num_envs as usize != lease.batch.len() {
        return Err(StepStatus::ShapeMismatch);
    }
    Op::from_u32(header.op).ok_or(StepStatus::UnknownOp)
}

/// The pid of a live server node called `name`, if one exists.
fn running_server_pid(config: &Config, name: &str) -> Option<u32> {
    use iceoryx2::node::NodeView;
    let prefix = format!("echogym-serve-{name}-");
    let mut pid = None;
    let _ = Node::<ipc::Service>::list(config, |state| {
        if let NodeState::Alive(view) = &state
            && let Some(details) = view.details()
            && let Some(rest) = details.name().to_string().strip_prefix(&prefix)
        {
            pid = rest.parse().ok();
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    pid.filter(|&p| p != std::process::id())
}
