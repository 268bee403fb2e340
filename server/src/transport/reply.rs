//! Control replies: parsing a request, refusing it, and sending the answer.

use super::Ipc;
use echogym_protocol::{
    ControlError, ControlErrorKind, ControlHeader, ControlReply, ControlRequest, PROTOCOL_VERSION,
};
use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::LoanError;
use std::time::{Duration, Instant};

/// A received control request, kept until it is answered.
pub(super) type ControlRequestHandle = ActiveRequest<Ipc, [u8], ControlHeader, [u8], ControlHeader>;

/// A refusal, logged at debug level.
pub(super) fn refusal(kind: ControlErrorKind, message: impl Into<String>) -> ControlError {
    let mut message = message.into();
    // A refusal may quote the request (serde names an unknown variant, an env id): it
    // never echoes more than a screenful of it back.
    if let Some((end, _)) = message.char_indices().nth(MAX_REFUSAL_CHARS) {
        let total = message.len();
        message.truncate(end);
        message.push_str(&format!("… ({total} bytes in all)"));
    }
    tracing::debug!(?kind, %message, "control request refused");
    ControlError { kind, message }
}

/// The most characters of a refusal's message.
const MAX_REFUSAL_CHARS: usize = 2048;

/// A refusal as a reply.
pub(super) fn error(kind: ControlErrorKind, message: impl Into<String>) -> ControlReply {
    ControlReply::Error(refusal(kind, message))
}

/// Control replies the server's port preallocates (iceoryx2's default for 512 clients is
/// 12,288), in one fixed segment of [`MAX_REPLY_BYTES`] slots.
///
/// A client's disconnection made the dispatcher sweep one flag per reply slot, per
/// channel, per possible segment (255 with a growable segment): 18 M flags, 125–180 ms
/// during which no lease was served, after every client that went away (found by the
/// head-of-line benchmark; it was the soak's bystander tail). With one fixed segment of
/// 64 slots the sweep is ≈ 400 flags. A slot is in use from a reply's send until its
/// client takes it (microseconds: each client has one request at a time), so 64 suffice;
/// a reply that finds none free waits on the dispatcher (`unsent`) until one is. (A
/// growable segment with fewer slots is not an option: iceoryx2 0.10 then panics when the
/// slots run out, found by `tests/isolation.rs`.)
pub(super) const CONTROL_RESPONSES: usize = 64;

/// Loans one reply may try. iceoryx2 0.10 counts a loan that failed for want of a free
/// sample against the request's loans and never gives it back, so after this many failed
/// tries (retried with back-off up to 0.5 s: ≈ 8 min) the reply is given up and its
/// client times out. (With iceoryx2's default of 2, a reply that found no free sample
/// twice could never be sent, found by `tests/isolation.rs`.)
pub(super) const MAX_LOANS_PER_REPLY: usize = 1024;

/// Longest control reply \[bytes\]: a status of 4,096 leases (≈ 400 B each) or an attach
/// reply echoing a 1 MiB config fit. A longer one is answered with an `Internal` error
/// naming its size. Slots are touched only as far as written, so the 64 × 4 MiB segment
/// costs memory only for the replies actually sent.
pub(super) const MAX_REPLY_BYTES: usize = 4 << 20;

/// A reply that found no free reply sample: kept by the dispatcher and sent on a later
/// pass (see `CONTROL_RESPONSES`), or dropped once its client stops waiting.
pub(super) struct Unsent {
    pub request: ControlRequestHandle,
    text: Vec<u8>,
    /// When to try again (backing off from 1 ms to 0.5 s).
    next_try: Instant,
    backoff: Duration,
}

impl Unsent {
    /// Try again if it is time; `Some` while there is still no free sample. `waiting`
    /// says whether the request's client still waits (`Dispatcher::client_waiting`).
    pub fn retry(
        mut self,
        now: Instant,
        waiting: impl Fn(&ControlRequestHandle) -> bool,
    ) -> Option<Unsent> {
        if !waiting(&self.request) {
            tracing::debug!("a held control reply was dropped: its client stopped waiting");
            return None;
        }
        if now < self.next_try {
            return Some(self);
        }
        let (request, text) = (self.request, self.text);
        send(request, text).map(|mut unsent| {
            self.backoff = (self.backoff * 2).min(Duration::from_millis(500));
            unsent.backoff = self.backoff;
            unsent.next_try = now + self.backoff;
            unsent
        })
    }
}

/// Send `reply` to the client of `request` (a client that went away is only logged).
/// `Some` when no reply sample was free: keep it and [`Unsent::retry`] later.
#[must_use = "a reply that found no free sample must be kept and retried"]
pub(super) fn respond(request: ControlRequestHandle, reply: &ControlReply) -> Option<Unsent> {
    let text = serde_json::to_vec(reply).unwrap_or_else(|e| {
        serde_json::to_vec(&ControlReply::Error(ControlError {
            kind: ControlErrorKind::Internal,
            message: format!("the reply did not serialize: {e}"),
        }))
        .unwrap_or_default()
    });
    if text.len() > MAX_REPLY_BYTES {
        tracing::warn!(len = text.len(), "a control reply was too long to send");
        let error = ControlReply::Error(ControlError {
            kind: ControlErrorKind::Internal,
            message: format!(
                "the reply is {} bytes, over the {} bytes a reply can carry",
                text.len(),
                MAX_REPLY_BYTES
            ),
        });
        return send(request, serde_json::to_vec(&error).unwrap_or_default());
    }
    send(request, text)
}

fn send(request: ControlRequestHandle, text: Vec<u8>) -> Option<Unsent> {
    let Ok(payload_len) = u32::try_from(text.len()) else {
        tracing::error!(len = text.len(), "a control reply over 4 GiB was not sent");
        return None;
    };
    let response = match request.loan_slice_uninit(text.len()) {
        Ok(response) => response,
        Err(LoanError::OutOfMemory) => {
            return Some(Unsent {
                request,
                text,
                next_try: Instant::now() + Duration::from_millis(1),
                backoff: Duration::from_millis(1),
            });
        }
        Err(e) => {
            // `ExceedsMaxLoans` after `MAX_LOANS_PER_REPLY` failed tries: given up.
            tracing::warn!(error = ?e, "a control reply could not be sent; its client times out");
            return None;
        }
    };
    let mut response = response;
    *response.user_header_mut() = ControlHeader {
        protocol_version: PROTOCOL_VERSION,
        payload_len,
    };
    if let Err(e) = response.write_from_slice(&text).send() {
        tracing::debug!(error = ?e, "sending a control reply failed");
    }
    None
}

/// Largest control request the server parses \[bytes\]. Requests are a few hundred bytes
/// (a config of a few keys); the client's request segment grows on demand, so without a
/// cap one client could make the dispatcher parse gigabytes while everyone waits.
pub(super) const MAX_CONTROL_REQUEST_BYTES: usize = 1 << 20;

/// Parse one control request (header already received, payload is JSON).
pub(super) fn parse_control(
    header: ControlHeader,
    payload: &[u8],
) -> Result<ControlRequest, ControlError> {
    if header.protocol_version != PROTOCOL_VERSION {
        return Err(refusal(
            ControlErrorKind::VersionMismatch,
            format!(
                "client speaks protocol {}, server speaks {PROTOCOL_VERSION}; install matching echogym versions",
                header.protocol_version
            ),
        ));
    }
    let len = (header.payload_len as usize).min(payload.len());
    if len > MAX_CONTROL_REQUEST_BYTES {
        return Err(refusal(
            ControlErrorKind::InvalidRequest,
            format!(
                "control request of {len} bytes refused: at most {MAX_CONTROL_REQUEST_BYTES} (a config is a few keys)"
            ),
        ));
    }
    serde_json::from_slice(&payload[..len]).map_err(|e| {
        refusal(
            ControlErrorKind::InvalidRequest,
            format!("malformed request: {e}"),
        )
    })
}
