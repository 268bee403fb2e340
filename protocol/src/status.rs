//! Operation and status codes carried in the sample headers.

/// What an action sample asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Op {
    /// Step every env with its action; envs flagged in the reset mask are reset instead.
    Step = 1,
    /// Reset the envs flagged in the reset mask; the actions are ignored.
    Reset = 2,
}

impl Op {
    /// Decode a header value.
    pub fn from_u32(value: u32) -> Option<Self> {
        match value {
            1 => Some(Self::Step),
            2 => Some(Self::Reset),
            _ => None,
        }
    }
}

/// Per-env byte in the reset mask of an action sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ResetFlag {
    /// Leave this env alone on `Reset`; step it on `Step`.
    Keep = 0,
    /// Reset this env, continuing its seed stream.
    Reset = 1,
    /// Reset this env and reseed it with the seed given in the seed block.
    ResetWithSeed = 2,
}

impl ResetFlag {
    /// Decode a mask byte.
    pub fn from_u8(value: u8) -> Option<Self> {
        match value {
            0 => Some(Self::Keep),
            1 => Some(Self::Reset),
            2 => Some(Self::ResetWithSeed),
            _ => None,
        }
    }
}

/// Outcome of one exchange, in [`crate::ObsHeader::status`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum StepStatus {
    /// The payload holds the new observations.
    Ok = 0,
    /// An action element was NaN or infinite (`env_index`, `element_index` say where).
    NonFiniteAction = 1,
    /// The header's op code is unknown.
    UnknownOp = 2,
    /// The header's `num_envs` differs from the lease, or the payload is too short.
    ShapeMismatch = 3,
    /// A reset-mask byte is not a [`ResetFlag`] (`env_index` says where).
    BadResetFlag = 4,
    /// The header's protocol version differs from the server's.
    VersionMismatch = 5,
    /// An env was stepped before its first reset or after its episode ended
    /// without a reset (`env_index` says which).
    NeedsReset = 6,
    /// The server is shutting down; no further exchanges will be answered.
    ServerStopped = 7,
    /// The exchange failed outside any one env's step or reset, so nothing could be
    /// returned (`env_index` says which env, if one). A failure inside one env's step
    /// or reset is not this: the exchange answers `Ok` with that env flagged
    /// ([`crate::ENV_ERROR_KEY`]). The lease stays usable.
    EnvFailure = 8,
}

impl StepStatus {
    /// Decode a header value; unknown values map to `None`.
    pub fn from_u32(value: u32) -> Option<Self> {
        Some(match value {
            0 => Self::Ok,
            1 => Self::NonFiniteAction,
            2 => Self::UnknownOp,
            3 => Self::ShapeMismatch,
            4 => Self::BadResetFlag,
            5 => Self::VersionMismatch,
            6 => Self::NeedsReset,
            7 => Self::ServerStopped,
            8 => Self::EnvFailure,
            _ => return None,
        })
    }
}
