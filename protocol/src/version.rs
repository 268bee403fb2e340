/// Version of the wire contract. Bumped on any change to a `#[repr(C)]` type, to the
/// batch layout or to the control messages. Client and server refuse to talk across
/// versions, with a typed error naming both numbers. (2: a detach names the asking
/// client, and only the lease's owner may detach it.)
pub const PROTOCOL_VERSION: u32 = 2;
