//! [`Connection`]: a client's attachment to one server (control channel and wake-ups).

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use echogym_protocol::{
    ControlHeader, ControlReply, ControlRequest, IpcLocation, PROTOCOL_VERSION, ServiceNames,
};
use iceoryx2::port::client::Client;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;

use super::error::{ConnectError, ControlCallError};
use echogym_protocol::services::{
    Access, ControlService, EventService, MAX_CLIENTS, control_service, event_service,
};

type ControlClient = Client<ipc_threadsafe::Service, [u8], ControlHeader, [u8], ControlHeader>;

/// How to reach a server.
#[derive(Debug, Clone)]
pub struct ConnectOptions {
    /// Server name. Default `"default"`.
    pub name: String,
    /// Where the server's iceoryx2 resources live. Default: [`IpcLocation::from_env`].
    pub location: IpcLocation,
    /// Busy-poll time before blocking while waiting for observations. Default 200 µs
    /// (the server's default too).
    pub spin: Duration,
    /// How long a control request may take. Default 120 s (building physics envs can
    /// take a while).
    pub control_timeout: Duration,
    /// How long a step or reset may wait for its observation while the server lives;
    /// beyond it the lease ends in [`crate::LeaseError::Timeout`]. Default 300 s, or
    /// `ECHOGYM_STEP_TIMEOUT_S` (a huge batch of heavy envs can take minutes per step).
    pub step_timeout: Duration,
    /// Shown by `echogym status`. Default `pid <pid>`.
    pub label: String,
}

/// The default step deadline: `ECHOGYM_STEP_TIMEOUT_S` seconds if set and valid, else 300.
fn default_step_timeout() -> Duration {
    std::env::var("ECHOGYM_STEP_TIMEOUT_S")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .map_or(Duration::from_secs(300), Duration::from_secs_f64)
}

impl Default for ConnectOptions {
    fn default() -> Self {
        Self {
            name: "default".to_owned(),
            location: IpcLocation::from_env(),
            spin: Duration::from_micros(200),
            control_timeout: Duration::from_secs(120),
            step_timeout: default_step_timeout(),
            label: format!("pid {}", std::process::id()),
        }
    }
}

pub(crate) struct Inner {
    pub options: ConnectOptions,
    pub names: ServiceNames,
    pub config: Config,
    /// The server node this connection reached. A server restarted under the same name
    /// is another node: requests to the old one end in `ServerStopped`.
    pub server: u128,
    control: Mutex<ControlClient>,
    pub wake: Notifier<ipc_threadsafe::Service>,
    _control_service: ControlService<ipc_threadsafe::Service>,
    _wake_service: EventService<ipc_threadsafe::Service>,
    pub node: Node<ipc_threadsafe::Service>,
}

/// A connection to a running server. Cheap to clone; every lease keeps it alive.
#[derive(Clone)]
pub struct Connection {
    pub(crate) inner: Arc<Inner>,
}

impl Connection {
    /// Attach to the running server named `options.name`. A server still starting (its
    /// node alive, its ports not yet up) is waited for, up to 10 s.
    pub fn connect(options: &ConnectOptions) -> Result<Self, ConnectError> {
        echogym_protocol::quiet_iceoryx_logs();
        let names = ServiceNames::new(&options.name)
            .map_err(|e| ConnectError::InvalidOptions(e.to_string()))?;
        let config = options
            .location
            .iceoryx_config()
            .map_err(|e| ConnectError::InvalidOptions(e.to_string()))?;
        let not_running = || ConnectError::ServerNotRunning {
            name: options.name.clone(),
            prefix: options.location.prefix.clone(),
            root: options.location.root.display().to_string(),
        };
        let control_name = ServiceName::new(&names.control())
            .map_err(|e| ConnectError::InvalidOptions(format!("{e:?}")))?;
        let exists = ipc_threadsafe::Service::does_exist(
            &control_name,
            &config,
            MessagingPattern::RequestResponse,
        )
        .map_err(|e| ConnectError::Ipc(format!("{e:?}")))?;
        if !exists {
            return Err(not_running());
        }
        let node = NodeBuilder::new()
            .config(&config)
            .name(
                &NodeName::new(&format!("echogym-client-{}", std::process::id()))
                    .map_err(|e| ConnectError::InvalidOptions(format!("{e:?}")))?,
            )
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc_threadsafe::Service>()
            .map_err(|e| ConnectError::Ipc(format!("{e:?}")))?;
        let Some(server) = server_node(&config, &options.name) else {
            return Err(not_running());
        };
        if !server_is_up(&config, &names, server) {
            return Err(not_running());
        }
        let control_service =
            control_service(&node, &names.control(), Access::Open).map_err(|_| not_running())?;
        let control = new_control_client(&control_service).map_err(ConnectError::Ipc)?;
        let wake_service = event_service(&node, &names.wake(), MAX_CLIENTS, Access::Open)
            .map_err(|_| not_running())?;
        let wake = wake_service
            .notifier_builder()
            .create()
            .map_err(|e| ConnectError::Ipc(format!("{e:?}")))?;
        Ok(Self {
            inner: Arc::new(Inner {
                options: options.clone(),
                names,
                config,
                server,
                control: Mutex::new(control),
                wake,
                _control_service: control_service,
                _wake_service: wake_service,
                node,
            }),
        })
    }

    /// The options this connection was made with.
    pub fn options(&self) -> &ConnectOptions {
        &self.inner.options
    }

    /// This client's iceoryx2 node id (the server reclaims leases when it dies).
    pub fn node_id(&self) -> u128 {
        self.inner.node.id().value()
    }

    /// Send a control request and wait for its reply. Refusals come back as
    /// [`ControlCallError::Refused`].
    pub fn request(&self, request: &ControlRequest) -> Result<ControlReply, ControlCallError> {
        self.request_with_version(PROTOCOL_VERSION, request)
    }

    /// [`Connection::request`] claiming protocol `version` (tests of version checks).
    #[doc(hidden)]
    pub fn request_with_version(
        &self,
        version: u32,
        request: &ControlRequest,
    ) -> Result<ControlReply, ControlCallError> {
        let reply = self
            .inner
            .request(version, request, self.inner.options.control_timeout)?;
        match reply {
            ControlReply::Error(e) => Err(ControlCallError::Refused {
                kind: e.kind,
                message: e.message,
            }),
            reply => Ok(reply),
        }
    }
}

impl Inner {
    pub(crate) fn request(
        &self,
        version: u32,
        request: &ControlRequest,
        timeout: Duration,
    ) -> Result<ControlReply, ControlCallError> {
        // A server restarted under the same name adopts the control service this
        // connection holds, and would answer it; but this connection (its leases, its
        // liveness checks) belongs to the server it reached, so a request through it
        // after that server died ends in `ServerStopped`, not in the new server.
        if !node_alive(&self.config, self.server) {
            return Err(ControlCallError::ServerStopped);
        }
        let text = serde_json::to_vec(request).expect("requests serialize");
        let mut control = self.control.lock().unwrap_or_else(|p| p.into_inner());
        let mut loan = control
            .loan_slice_uninit(text.len())
            .map_err(|e| ControlCallError::Ipc(format!("{e:?}")))?;
        *loan.user_header_mut() = ControlHeader {
            protocol_version: version,
            payload_len: text.len() as u32,
        };
        let pending = loan
            .write_from_slice(&text)
            .send()
            .map_err(|e| ControlCallError::Ipc(format!("{e:?}")))?;
        let _ = self.wake.notify();

        let started = Instant::now();
        let mut pause = Duration::from_micros(10);
        let mut next_check = started + super::wait::LIVENESS_TICK;
        loop {
            match pending.receive() {
                Ok(Some(response)) => {
                    let header = *response.user_header();
                    let len = (header.payload_len as usize).min(response.payload().len());
                    return serde_json::from_slice(&response.payload()[..len])
                        .map_err(|e| ControlCallError::Malformed(e.to_string()));
                }
                Ok(None) => {}
                Err(e) => return Err(ControlCallError::Ipc(format!("{e:?}"))),
            }
            let now = Instant::now();
            if now.duration_since(started) > timeout {
                // Give up visibly: the server cancels work for a request whose client
                // port is gone (the request's own "connected" state is not reliable in
                // iceoryx2 0.10, see the server's `client_waiting`), so this port goes
                // and a fresh one serves the next request.
                drop(pending);
                match new_control_client(&self._control_service) {
                    Ok(fresh) => *control = fresh,
                    Err(e) => tracing::debug!(error = %e, "could not renew the control port"),
                }
                return Err(ControlCallError::Timeout(timeout));
            }
            if now >= next_check {
                if !node_alive(&self.config, self.server) {
                    return Err(ControlCallError::ServerStopped);
                }
                next_check = now + super::wait::LIVENESS_TICK;
            }
            std::thread::sleep(pause);
            pause = (pause * 2).min(Duration::from_millis(1));
        }
    }
}

/// A client port on the control service.
fn new_control_client(
    service: &ControlService<ipc_threadsafe::Service>,
) -> Result<ControlClient, String> {
    service
        .client_builder()
        .initial_max_slice_len(4096)
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .create()
        .map_err(|e| format!("{e:?}"))
}

/// The node id of the live server called `name`, if one runs.
pub(crate) fn server_node(config: &Config, name: &str) -> Option<u128> {
    use iceoryx2::node::NodeView;
    let prefix = format!("echogym-serve-{name}-");
    let mut found = None;
    let _ = Node::<ipc_threadsafe::Service>::list(config, |state| {
        if let NodeState::Alive(view) = &state
            && view
                .details()
                .as_ref()
                .is_some_and(|d| is_server_node(&d.name().to_string(), &prefix))
        {
            found = Some(view.id().value());
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    found
}

/// Longest wait for a server whose node is alive to bring its ports up (it cleans up
/// what dead nodes left first, which a long churn makes slow).
const SERVER_UP_WAIT: Duration = Duration::from_secs(10);

/// Wait until the server with node id `server` has its ports up (its
/// [`ServiceNames::server_up`] service exists); false if it died or took longer than
/// [`SERVER_UP_WAIT`]. A request sent before would reach no server port and never be
/// answered: seen after a restart in the soak, where the bystander's first attach to
/// the new server waited 120 s with no trace in the server's log.
fn server_is_up(config: &Config, names: &ServiceNames, server: u128) -> bool {
    let Ok(up) = ServiceName::new(&names.server_up(server)) else {
        return false;
    };
    let started = Instant::now();
    loop {
        let exists = ipc_threadsafe::Service::does_exist(&up, config, MessagingPattern::Event)
            .unwrap_or(false);
        if exists {
            return true;
        }
        if started.elapsed() > SERVER_UP_WAIT || !node_alive(config, server) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// `echogym-serve-<name>-<pid>` exactly (so `a` does not match server `a-b`).
fn is_server_node(node_name: &str, prefix: &str) -> bool {
    node_name
        .strip_prefix(prefix)
        .is_some_and(|pid| pid.parse::<u32>().is_ok())
}

/// Whether the node with id `node_id` is alive.
pub(crate) fn node_alive(config: &Config, node_id: u128) -> bool {
    use iceoryx2::node::NodeView;
    let mut alive = false;
    let _ = Node::<ipc_threadsafe::Service>::list(config, |state| {
        if let NodeState::Alive(view) = &state
            && view.id().value() == node_id
        {
            alive = true;
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    alive
}
