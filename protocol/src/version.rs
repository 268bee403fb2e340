/// Version of the wire contract. Bumped on any change to a `#[repr(C)]` type, to the
/// batch layout or to the control messages. Client and server refuse to talk across
/// versions, with a typed error naming both numbers.
pub const PROTOCOL_VERSION: u32 = 1;
