//! `#[repr(C)]` user headers of the shared-memory samples.
//!
//! The payload of every sample is a byte slice whose layout is described by
//! [`crate::BatchLayout`]; these headers say what the payload means.

use iceoryx2::prelude::ZeroCopySend;

/// Header of an action sample (client → server, one per lease and exchange).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("echogym::ActionHeader")]
pub struct ActionHeader {
    /// Must equal [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u32,
    /// A [`crate::Op`] value.
    pub op: u32,
    /// Client-chosen sequence number, echoed in the matching [`ObsHeader`].
    pub seq: u64,
    /// The lease this exchange belongs to.
    pub lease_id: u64,
    /// Number of envs in the batch; must equal the lease's size.
    pub num_envs: u32,
    /// Zero.
    pub reserved: u32,
}

/// Header of an observation sample (server → client).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("echogym::ObsHeader")]
pub struct ObsHeader {
    /// Echo of [`ActionHeader::seq`].
    pub seq: u64,
    /// A [`crate::StepStatus`] value; anything but `Ok` means the payload holds no data.
    pub status: u32,
    /// For errors about one env (e.g. a NaN action): its index in the batch, else `u32::MAX`.
    pub env_index: u32,
    /// For errors about one action element: its index within the env's action, else `u32::MAX`.
    pub element_index: u32,
    /// Number of envs in the batch.
    pub num_envs: u32,
}

/// Header of a control request or reply (JSON payload follows).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("echogym::ControlHeader")]
pub struct ControlHeader {
    /// The sender's [`crate::PROTOCOL_VERSION`]; checked before the payload is parsed.
    pub protocol_version: u32,
    /// Byte length of the JSON payload.
    pub payload_len: u32,
}

#[cfg(test)]
mod golden {
    //! Golden layouts: the Python side and older builds read these bytes directly.
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    #[test]
    fn action_header_layout() {
        assert_eq!(size_of::<ActionHeader>(), 32);
        assert_eq!(align_of::<ActionHeader>(), 8);
        assert_eq!(offset_of!(ActionHeader, protocol_version), 0);
        assert_eq!(offset_of!(ActionHeader, op), 4);
        assert_eq!(offset_of!(ActionHeader, seq), 8);
        assert_eq!(offset_of!(ActionHeader, lease_id), 16);
        assert_eq!(offset_of!(ActionHeader, num_envs), 24);
        assert_eq!(offset_of!(ActionHeader, reserved), 28);
    }

    #[test]
    fn obs_header_layout() {
        assert_eq!(size_of::<ObsHeader>(), 24);
        assert_eq!(align_of::<ObsHeader>(), 8);
        assert_eq!(offset_of!(ObsHeader, seq), 0);
        assert_eq!(offset_of!(ObsHeader, status), 8);
        assert_eq!(offset_of!(ObsHeader, env_index), 12);
        assert_eq!(offset_of!(ObsHeader, element_index), 16);
        assert_eq!(offset_of!(ObsHeader, num_envs), 20);
    }

    #[test]
    fn control_header_layout() {
        assert_eq!(size_of::<ControlHeader>(), 8);
        assert_eq!(align_of::<ControlHeader>(), 4);
        assert_eq!(offset_of!(ControlHeader, protocol_version), 0);
        assert_eq!(offset_of!(ControlHeader, payload_len), 4);
    }
}
