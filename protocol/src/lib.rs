//! The wire contract between `echogym serve` and its clients.
//!
//! Everything both sides must agree on byte for byte lives here and nowhere else:
//! the protocol version, the `#[repr(C)]` headers of the shared-memory samples, the
//! env spec a client discovers at attach time, the layout of a batch inside the
//! action and observation samples, the control messages, the service names, and how
//! each iceoryx2 service is opened ([`services`]: iceoryx2 refuses a client whose
//! settings differ from the server's) and paced ([`pacing`]).
//!
//! No physics, no Python, no server or client logic: both `echogym` (the server) and
//! `echogym-client` depend on this crate and on nothing of each other.

mod control;
mod ipc_location;
mod layout;
pub mod pacing;
mod service_names;
pub mod services;
mod spec;
mod status;
mod version;
mod wire;

pub use control::{
    AttachReply, AttachRequest, BuildStatus, ControlError, ControlErrorKind, ControlReply,
    ControlRequest, EnvInfo, LeaseStatus, ServerStatus,
};
pub use ipc_location::{
    DEFAULT_PREFIX, IpcLocation, IpcLocationError, PREFIX_ENV, ROOT_ENV, default_prefix,
};
pub use layout::{
    ActionLayout, BatchLayout, FieldView, LayoutError, ObsLayout, PAYLOAD_ALIGN, contiguous_strides,
};
pub use service_names::{InvalidServerName, ServiceNames};
pub use spec::{
    ActionSpec, AutoresetMode, DType, ENV_ERROR_KEY, EnvSpec, EnvSpecBuilder, ObsField, ScalarSpec,
};
pub use status::{Op, ResetFlag, StepStatus};
pub use version::PROTOCOL_VERSION;
pub use wire::{ActionHeader, ControlHeader, ObsHeader};

/// Let only iceoryx2's errors through its logger. iceoryx2 logs warnings as debug dumps
/// of its internals (kilobytes per line); echogym reports what matters through its own
/// typed errors and `tracing`. Called by server and client before they open a node.
pub fn quiet_iceoryx_logs() {
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
}
