//! The wire contract between `echogym serve` and its clients.
//!
//! Everything both sides must agree on byte for byte lives here and nowhere else:
//! the protocol version, the `#[repr(C)]` headers of the shared-memory samples, the
//! env spec a client discovers at attach time, the layout of a batch inside the
//! action and observation samples, the control messages, and the service names.
//!
//! No physics, no Python, no transport logic: this crate only describes.

mod control;
mod ipc_location;
mod layout;
mod service_names;
mod spec;
mod status;
mod version;
mod wire;

pub use control::{
    AttachReply, AttachRequest, ControlError, ControlErrorKind, ControlReply, ControlRequest,
    EnvInfo, LeaseStatus, ServerStatus,
};
pub use ipc_location::{DEFAULT_PREFIX, IpcLocation, IpcLocationError, PREFIX_ENV, ROOT_ENV};
pub use layout::{
    ActionLayout, BatchLayout, FieldView, LayoutError, ObsLayout, PAYLOAD_ALIGN, contiguous_strides,
};
pub use service_names::{InvalidServerName, ServiceNames};
pub use spec::{ActionSpec, AutoresetMode, DType, EnvSpec, EnvSpecBuilder, ObsField, ScalarSpec};
pub use status::{Op, ResetFlag, StepStatus};
pub use version::PROTOCOL_VERSION;
pub use wire::{ActionHeader, ControlHeader, ObsHeader};
