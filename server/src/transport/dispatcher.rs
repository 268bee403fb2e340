//! The dispatcher: the server thread that polls every port and answers control requests.
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
//!
//! # Exchanges off the dispatcher
//! A lease's exchange that costs at most [`INLINE_BUDGET_NS`] (measured, per op) runs on
//! the dispatcher thread. Any other is handed to the worker pool with its batch and
//! samples ([`Handoff`]): the worker returns the batch through a channel, then
//! publishes; the dispatcher keeps polling meanwhile, so a big batch delays no other
//! lease's exchange (ARCHITECTURE.md, "Exchanges off the dispatcher"). While a big
//! exchange (above the lane budget, or of unknown cost) is on the pool, a medium one
//! (above the inline budget, at most the lane budget) runs on the medium lane
//! ([`crate::pool::Lane`]) instead of queueing behind it.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::{Duration, Instant};

use echogym_protocol::{
    ActionHeader, ControlReply, ControlRequest, IpcLocation, ObsHeader, Op, PROTOCOL_VERSION,
    ServiceNames, StepStatus,
};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;

use super::Ipc;
use super::builder::Builder;
use super::error::StartError;
use super::lease::{Lease, publish};
use super::pending::PendingAttach;
use super::reply::{
    CONTROL_RESPONSES, ControlRequestHandle, MAX_LOANS_PER_REPLY, MAX_REPLY_BYTES, Unsent, error,
    parse_control, respond,
};
use super::shutdown::Shutdown;
use crate::envs::EnvRegistry;
use crate::pool::{EnvBatch, ExchangeError, Exchanged, Lane, Runner, WorkerPool};
/// How often the dispatcher looks for finished builds while it would otherwise block.
const BUILD_POLL: Duration = Duration::from_millis(1);

/// An exchange measured to cost at most this on one thread runs on the dispatcher
/// thread itself (waking a worker and handing the samples over costs more than it
/// saves); anything else, or an exchange of unknown cost, goes to the pool. It is what
/// one cheap lease can delay the others by.
pub(super) const INLINE_BUDGET_NS: f64 = 100_000.0;

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
    /// Nice value of the worker threads (and of the medium lane).
    pub worker_nice: i32,
    /// Exchanges above the inline budget and at most this (serial cost) run on the
    /// medium lane while a bigger one is on the pool; zero: no lane.
    pub lane_budget: Duration,
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
    pub(super) iox_config: Config,
    pub(super) registry: Arc<EnvRegistry>,
    pub(super) builder: Builder,
    pub(super) pending: Vec<PendingAttach>,
    pub(super) next_ticket: u64,
    pub(super) pool: Arc<WorkerPool>,
    /// The medium lane (`None` when `lane_budget` is zero).
    lane: Option<Lane>,
    /// Big exchanges (above the lane budget or of unknown cost) on the pool, running or
    /// queued: while there is one, medium exchanges go to the lane.
    big_in_flight: usize,
    pub(super) leases: Vec<Lease>,
    /// Leases detached or reclaimed while their exchange ran on the pool: closed when
    /// the batch comes back.
    pub(super) closing: Vec<Lease>,
    /// Exchanges running on the pool.
    in_flight: usize,
    completed_tx: Sender<Completed>,
    completed: Receiver<Completed>,
    pub(super) started: Instant,
    pub(super) instance: u32,
    pub(super) next_lease: u32,
    pub(super) env_steps: u64,
    /// Env steps truncated for a physics error over the server's life.
    pub(super) physics_errors: u64,
    /// Env steps and resets that failed inside the env (flagged) over the server's life.
    pub(super) env_errors: u64,
    pub(super) reclaimed: u64,
    pub(super) shutdown: Shutdown,
    last_reply: Instant,
    /// Replies that found no free reply sample (see [`CONTROL_RESPONSES`]).
    unsent: Vec<Unsent>,
    control:
        Server<Ipc, [u8], echogym_protocol::ControlHeader, [u8], echogym_protocol::ControlHeader>,
    wake: Listener<Ipc>,
    _control_service: ControlService<Ipc>,
    _wake_service: EventService<Ipc>,
    /// Says this server answers requests (see `ServiceNames::server_up`).
    _up_service: EventService<Ipc>,
    pub(super) node: Node<Ipc>,
}

/// Where an exchange off the dispatcher runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Route {
    /// On the pool, at most the lane budget (no big exchange was on the pool).
    Pool,
    /// On the pool, above the lane budget or of unknown cost.
    Big,
    /// On the medium lane, serially.
    Lane,
}

/// An exchange handed to the pool or the lane: the batch and both samples travel with it.
struct Handoff {
    lease: u64,
    route: Route,
    op: Op,
    batch: EnvBatch,
    action: Sample<Ipc, [u8], ActionHeader>,
    obs: SampleMut<Ipc, [u8], ObsHeader>,
    notifier: Arc<Notifier<Ipc>>,
}

/// An exchange that ran on the pool, its batch back for the dispatcher.
struct Completed {
    lease: u64,
    route: Route,
    batch: EnvBatch,
    result: Result<Exchanged, ExchangeError>,
}

impl Handoff {
    /// Run on a worker (its envs in parallel on `pool`) or on the lane (`None`: on
    /// this thread): exchange, give the batch back, then publish (in that order, so the
    /// batch is back before the client can send its next action).
    fn run(self, pool: Option<&WorkerPool>, done: &Sender<Completed>) {
        let Self {
            lease,
            route,
            op,
            mut batch,
            action,
            mut obs,
            notifier,
        } = self;
        let runner = pool.map_or(Runner::Serial, Runner::Pool);
        let result = run_exchange(&mut batch, runner, op, &action, &mut obs);
        drop(action);
        if done
            .send(Completed {
                lease,
                route,
                batch,
                result,
            })
            .is_err()
        {
            tracing::debug!(
                lease,
                "the dispatcher is gone; an exchange's batch is dropped"
            );
        }
        publish(lease, obs, &notifier);
    }
}

/// Run one exchange of `batch` (where `runner` says) and write the observation
/// header. A panic outside every env's own step and reset (which the batch contains)
/// fails the whole exchange with `EnvFailure`: nothing could be returned.
fn run_exchange(
    batch: &mut EnvBatch,
    runner: Runner<'_>,
    op: Op,
    action: &Sample<Ipc, [u8], ActionHeader>,
    obs: &mut SampleMut<Ipc, [u8], ObsHeader>,
) -> Result<Exchanged, ExchangeError> {
    let seq = action.user_header().seq;
    let result = catch_unwind(AssertUnwindSafe(|| {
        batch.exchange(runner, op, action.payload(), obs.payload_mut())
    }))
    .unwrap_or_else(|payload| {
        tracing::warn!(
            message = %crate::pool::panic_message(payload.as_ref()),
            "an exchange panicked outside its envs"
        );
        Err(ExchangeError::new(StepStatus::EnvFailure))
    });
    let (status, env_index, element_index) = match &result {
        Ok(_) => (StepStatus::Ok, None, None),
        Err(e) => (e.status, e.env_index, e.element_index),
    };
    *obs.user_header_mut() = ObsHeader {
        seq,
        status: status as u32,
        env_index: env_index.map_or(u32::MAX, |i| i as u32),
        element_index: element_index.map_or(u32::MAX, |i| i as u32),
        num_envs: batch.len() as u32,
    };
    result
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
            .create::<Ipc>()
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
            .initial_max_slice_len(MAX_REPLY_BYTES)
            .allocation_strategy(AllocationStrategy::Static)
            .override_response_preallocation(|_| CONTROL_RESPONSES)
            .max_loaned_responses_per_request(MAX_LOANS_PER_REPLY)
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
        let pool = Arc::new(WorkerPool::new(options.threads, options.worker_nice)?);
        let lane = if options.lane_budget.is_zero() {
            None
        } else {
            Some(Lane::start(options.worker_nice).map_err(StartError::Lane)?)
        };
        let (completed_tx, completed) = channel();
        let registry = Arc::new(registry);
        // The builder opens new leases' services through a node of its own (a node is
        // not shared between threads).
        let builder_node = NodeBuilder::new()
            .config(&iox_config)
            .name(
                &NodeName::new(&format!(
                    "echogym-build-{}-{}",
                    options.name,
                    std::process::id()
                ))
                .map_err(|e| StartError::Node(format!("{e:?}")))?,
            )
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|e| StartError::Node(format!("{e:?}")))?;
        let builder = Builder::start(registry.clone(), builder_node, names.clone())
            .map_err(StartError::Builder)?;
        let instance = (std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos())
            ^ std::process::id().rotate_left(16))
            & 0x7fff_ffff;
        // Last: clients wait for this before their first request (see
        // `ServiceNames::server_up`).
        let up_name = names.server_up(node.id().value());
        let up_service = event_service(&node, &up_name, 1, Access::Create)?;
        tracing::info!(
            name = %options.name,
            pid = std::process::id(),
            threads = pool.threads(),
            prefix = %options.location.prefix,
            root = %options.location.root.display(),
            "echogym server listening"
        );
        Ok(Self {
            iox_config,
            registry,
            builder,
            pending: Vec::new(),
            next_ticket: 1,
            pool,
            lane,
            big_in_flight: 0,
            leases: Vec::new(),
            closing: Vec::new(),
            in_flight: 0,
            completed_tx,
            completed,
            started: Instant::now(),
            instance,
            next_lease: 1,
            env_steps: 0,
            physics_errors: 0,
            env_errors: 0,
            reclaimed: 0,
            shutdown,
            last_reply: Instant::now(),
            unsent: Vec::new(),
            control,
            wake,
            _control_service: control_service,
            _wake_service: wake_service,
            _up_service: up_service,
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
            if !self.pending.is_empty() || !self.unsent.is_empty() {
                // A build finishing, or a reply sample freed, rings no wake event: look
                // again soon.
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
        let mut served = self.retry_unsent();
        loop {
            let request = match self.control.receive() {
                Ok(Some(request)) => request,
                Ok(None) => break,
                Err(e) => {
                    tracing::warn!(error = ?e, "receiving a control request failed");
                    break;
                }
            };
            served = true;
            // A client that saw its observation may ask at once: its exchange's counts
            // (and batch) are in the channel before the observation is published, so
            // taking them back first makes `status` and `detach` exact.
            self.take_back_completed();
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
            self.answer(request, &reply);
        }
        served
    }

    /// Send `reply` to the client of `request`, or keep it until a reply sample is free.
    pub(super) fn answer(&mut self, request: ControlRequestHandle, reply: &ControlReply) {
        if let Some(unsent) = respond(request, reply) {
            tracing::debug!("no free control reply sample; the reply waits for one");
            self.unsent.push(unsent);
        }
        self.last_reply = Instant::now();
    }

    /// Send the replies that found no free sample, if they can go now; true if any went
    /// (or was dropped, its client gone).
    fn retry_unsent(&mut self) -> bool {
        if self.unsent.is_empty() {
            return false;
        }
        let (before, now) = (self.unsent.len(), Instant::now());
        let kept: Vec<Unsent> = std::mem::take(&mut self.unsent)
            .into_iter()
            .filter_map(|unsent| unsent.retry(now, |request| self.client_waiting(request)))
            .collect();
        self.unsent = kept;
        self.unsent.len() < before
    }

    /// Whether the client of `request` still waits for its reply: its control port is
    /// still there (a dead client's node is found by housekeeping; the Rust client drops
    /// its port when it gives up waiting). iceoryx2 0.10's `ActiveRequest::is_connected`
    /// is not asked: it turned false for live clients still waiting, after some other
    /// client died (found by the soak, one attach in a few hundred under kill -9 churn),
    /// and the dispatcher then dropped their attaches: they waited 120 s for nothing,
    /// while a reply sent anyway reached them.
    pub(super) fn client_waiting(&self, request: &ControlRequestHandle) -> bool {
        let origin = request.origin();
        let mut found = false;
        self._control_service
            .dynamic_config()
            .list_clients(|client| {
                found = client.client_id == origin;
                if found {
                    CallbackProgression::Stop
                } else {
                    CallbackProgression::Continue
                }
            });
        found
    }

    /// Take back the batches of exchanges that ended on the pool; true if any.
    fn take_back_completed(&mut self) -> bool {
        let mut any = false;
        while let Ok(done) = self.completed.try_recv() {
            self.complete(done);
            any = true;
        }
        any
    }

    /// Take back the batches of exchanges that ended on the pool, then start the
    /// exchange of every idle lease with an action waiting. True if anything happened.
    fn serve_leases(&mut self) -> bool {
        let mut served = self.take_back_completed();
        let lane_budget_ns = self.options.lane_budget.as_nanos() as f64;
        for lease in &mut self.leases {
            if lease.in_flight() {
                continue;
            }
            let Some(action) = lease.poll() else { continue };
            served = true;
            let header = *action.user_header();
            let op = match check_header(&header, lease) {
                Ok(op) => op,
                Err(status) => {
                    lease.publish_status(header.seq, status, None, None);
                    continue;
                }
            };
            let Some(mut obs) = lease.loan() else {
                lease.hold(action);
                continue;
            };
            let cost = lease.batch().and_then(|b| b.serial_cost_ns(op));
            let cheap = cost.is_some_and(|cost| cost <= INLINE_BUDGET_NS);
            if cheap && let Some(batch) = lease.batch_mut() {
                let result = run_exchange(batch, Runner::Inline, op, &action, &mut obs);
                drop(action);
                lease.publish(obs);
                let done = account(lease, &result);
                self.env_steps += done.steps;
                self.physics_errors += done.physics_errors;
                self.env_errors += done.env_errors;
                continue;
            }
            let Some(batch) = lease.take_batch() else {
                continue;
            };
            let medium = cost.is_some_and(|cost| cost <= lane_budget_ns);
            let route = match (medium, &self.lane) {
                (true, Some(_)) if self.big_in_flight > 0 => Route::Lane,
                (true, _) => Route::Pool,
                (false, _) => Route::Big,
            };
            let handoff = Handoff {
                lease: lease.id,
                route,
                op,
                batch,
                action,
                obs,
                notifier: lease.notifier(),
            };
            self.in_flight += 1;
            let done = self.completed_tx.clone();
            let on_lane = match (&self.lane, route) {
                (Some(lane), Route::Lane) => lane.spawn(Box::new(move || handoff.run(None, &done))),
                _ => {
                    self.big_in_flight += usize::from(route == Route::Big);
                    let pool = Arc::clone(&self.pool);
                    self.pool.spawn(move || handoff.run(Some(&pool), &done));
                    Ok(())
                }
            };
            if let Err(task) = on_lane {
                // The lane's thread is gone (not expected): the pool runs the task.
                self.pool.spawn(task);
            }
        }
        served
    }

    /// An exchange that ran on the pool ended: its batch returns to its lease (or, if
    /// the lease was detached meanwhile, is dropped off the dispatcher with it).
    fn complete(&mut self, done: Completed) {
        self.in_flight -= 1;
        let Completed {
            lease: id,
            route,
            batch,
            result,
        } = done;
        if route == Route::Big {
            self.big_in_flight -= 1;
        }
        if let Some(lease) = self.leases.iter_mut().find(|l| l.id == id) {
            lease.restore(batch);
            lease.lane_exchanges += u64::from(route == Route::Lane);
            let done = account(lease, &result);
            self.env_steps += done.steps;
            self.physics_errors += done.physics_errors;
            self.env_errors += done.env_errors;
        } else if let Some(at) = self.closing.iter().position(|l| l.id == id) {
            drop(self.closing.swap_remove(at));
            self.builder.discard(batch);
        } else {
            self.builder.discard(batch);
        }
    }

    /// Close `lease` now, or when its exchange on the pool ends.
    pub(super) fn retire(&mut self, lease: Lease) {
        if lease.in_flight() {
            self.closing.push(lease);
        } else if let Some(batch) = lease.close() {
            self.builder.discard(batch);
        }
    }

    /// Wait for every exchange on the pool to end (shutdown).
    fn drain_in_flight(&mut self) {
        while self.in_flight > 0 {
            match self.completed.recv_timeout(Duration::from_millis(100)) {
                Ok(done) => self.complete(done),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
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
        let listed = Node::<Ipc>::list(&self.iox_config, |state| {
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
            self.retire(lease);
        }
        if dead > 0 {
            let cleaned = self.node.try_cleanup_dead_nodes();
            tracing::trace!(?cleaned, "cleaned resources of dead nodes");
        }
    }

    fn stop(mut self) {
        self.drain_in_flight();
        for pending in self.pending.drain(..) {
            pending
                .cancel
                .store(true, std::sync::atomic::Ordering::Relaxed);
            // Best effort: a reply that finds no free sample is not waited for.
            let _unsent = respond(
                pending.request,
                &error(
                    echogym_protocol::ControlErrorKind::ShuttingDown,
                    "the server stopped before the envs were built",
                ),
            );
        }
        self.retry_unsent();
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
            self.retire(lease);
        }
        // Dropping the builder waits for the queued drops (an env that panics while
        // being dropped is caught there, and the server still exits cleanly).
        tracing::info!(name = %self.options.name, leases, "echogym server stopped");
    }
}

/// Count an exchange of `lease`; what it adds to the server's totals.
fn account(lease: &mut Lease, result: &Result<Exchanged, ExchangeError>) -> Exchanged {
    lease.exchanges += 1;
    lease.last_activity = Instant::now();
    match result {
        Ok(done) => {
            lease.env_steps += done.steps;
            lease.physics_errors += done.physics_errors;
            lease.env_errors += done.env_errors;
            *done
        }
        Err(e) => {
            tracing::debug!(lease = lease.id, error = %e, "exchange refused");
            Exchanged::default()
        }
    }
}

/// Check an action header against its lease; the op on success.
fn check_header(header: &ActionHeader, lease: &Lease) -> Result<Op, StepStatus> {
    if header.protocol_version != PROTOCOL_VERSION {
        return Err(StepStatus::VersionMismatch);
    }
    if header.lease_id != lease.id || header.num_envs as usize != lease.num_envs() {
        return Err(StepStatus::ShapeMismatch);
    }
    Op::from_u32(header.op).ok_or(StepStatus::UnknownOp)
}

/// The pid of a live server node called `name`, if one exists.
fn running_server_pid(config: &Config, name: &str) -> Option<u32> {
    use iceoryx2::node::NodeView;
    let prefix = format!("echogym-serve-{name}-");
    let mut pid = None;
    let _ = Node::<Ipc>::list(config, |state| {
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
