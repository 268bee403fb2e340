//! How every echogym service is built, shared by server and client so both sides open
//! services with identical settings (iceoryx2 refuses mismatches).

use crate::{ActionHeader, ControlHeader, ObsHeader, PAYLOAD_ALIGN};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{
    event::PortFactory as EventFactory, publish_subscribe::PortFactory as PubSubFactory,
    request_response::PortFactory as RequestResponseFactory,
};

/// Clients (processes) one server accepts at once.
pub const MAX_CLIENTS: usize = 512;

/// The action service of a lease.
pub type ActionService<S> = PubSubFactory<S, [u8], ActionHeader>;
/// The observation service of a lease.
pub type ObsService<S> = PubSubFactory<S, [u8], ObsHeader>;
/// The control service of a server.
pub type ControlService<S> = RequestResponseFactory<S, [u8], ControlHeader, [u8], ControlHeader>;
/// An event service (wake or ready).
pub type EventService<S> = EventFactory<S>;

/// Failure to create or open one service.
#[derive(Debug, thiserror::Error)]
#[error("service {service}: {reason}")]
pub struct ServiceError {
    /// The service name.
    pub service: String,
    /// What iceoryx2 said.
    pub reason: String,
}

impl ServiceError {
    /// A failure of `service` with iceoryx2's `reason`.
    pub fn new(service: &str, reason: impl std::fmt::Debug) -> Self {
        Self {
            service: service.to_owned(),
            reason: format!("{reason:?}"),
        }
    }
}

/// Whether to create a service (server) or open an existing one (client).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Create the service (the server).
    Create,
    /// Open the server's service (a client).
    Open,
    /// Open the service if it exists, else create it: a server taking over the
    /// services of a dead predecessor that live clients still hold open.
    OpenOrCreate,
}

/// Finish a service `builder` as `access` says. The three builder types share no trait,
/// and each of their methods fails with its own error type, hence a macro.
macro_rules! with_access {
    ($builder:expr, $access:expr, $name:expr) => {
        match $access {
            Access::Create => $builder.create().map_err(|e| ServiceError::new($name, e)),
            Access::Open => $builder.open().map_err(|e| ServiceError::new($name, e)),
            Access::OpenOrCreate => $builder
                .open_or_create()
                .map_err(|e| ServiceError::new($name, e)),
        }
    };
}

fn service_name(name: &str) -> Result<ServiceName, ServiceError> {
    ServiceName::new(name).map_err(|e| ServiceError::new(name, e))
}

fn alignment() -> Alignment {
    Alignment::new(PAYLOAD_ALIGN).expect("power of two")
}

/// Samples iceoryx2 preallocates per lease channel (see [`lease_channel`]): its
/// subscriber's buffer and borrows (2 + 2) plus the publisher's loans (2, iceoryx2's
/// default); no history.
pub const LEASE_CHANNEL_SAMPLES: usize = 6;

/// A lease's pub-sub service (action or obs): one publisher, one subscriber, one
/// exchange in flight, so two buffered samples are plenty.
pub fn lease_channel<S: Service, H: std::fmt::Debug + ZeroCopySend>(
    node: &Node<S>,
    name: &str,
    access: Access,
) -> Result<PubSubFactory<S, [u8], H>, ServiceError> {
    let builder = node
        .service_builder(&service_name(name)?)
        .publish_subscribe::<[u8]>()
        .user_header::<H>()
        .payload_alignment(alignment())
        .max_publishers(1)
        .max_subscribers(1)
        .max_nodes(2)
        .history_size(0)
        .subscriber_max_buffer_size(2)
        .subscriber_max_borrowed_samples(2);
    with_access!(builder, access, name)
}

/// An event service with `notifiers` notifiers and one listener.
pub fn event_service<S: Service>(
    node: &Node<S>,
    name: &str,
    notifiers: usize,
    access: Access,
) -> Result<EventService<S>, ServiceError> {
    let builder = node
        .service_builder(&service_name(name)?)
        .event()
        .max_notifiers(notifiers)
        .max_listeners(1)
        .max_nodes(notifiers + 1);
    with_access!(builder, access, name)
}

/// The control service: JSON requests from up to [`MAX_CLIENTS`] clients.
pub fn control_service<S: Service>(
    node: &Node<S>,
    name: &str,
    access: Access,
) -> Result<ControlService<S>, ServiceError> {
    let builder = node
        .service_builder(&service_name(name)?)
        .request_response::<[u8], [u8]>()
        .request_user_header::<ControlHeader>()
        .response_user_header::<ControlHeader>()
        .max_servers(1)
        .max_clients(MAX_CLIENTS)
        .max_nodes(MAX_CLIENTS + 1)
        .max_active_requests_per_client(2)
        .max_response_buffer_size(2);
    with_access!(builder, access, name)
}
