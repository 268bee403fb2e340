//! Control replies: parsing a request, refusing it, and sending the answer.

use super::Ipc;
use echogym_protocol::{
    ControlError, ControlErrorKind, ControlHeader, ControlReply, ControlRequest, PROTOCOL_VERSION,
};
use iceoryx2::active_request::ActiveRequest;

/// A received control request, kept until it is answered.
pub(super) type ControlRequestHandle = ActiveRequest<Ipc, [u8], ControlHeader, [u8], ControlHeader>;

/// A refusal, logged at debug level.
pub(super) fn refusal(kind: ControlErrorKind, message: impl Into<String>) -> ControlError {
    let message = message.into();
    tracing::debug!(?kind, %message, "control request refused");
    ControlError { kind, message }
}

/// A refusal as a reply.
pub(super) fn error(kind: ControlErrorKind, message: impl Into<String>) -> ControlReply {
    ControlReply::Error(refusal(kind, message))
}

/// Send `reply` to the client of `request` (a client that went away is only logged).
pub(super) fn respond(request: &ControlRequestHandle, reply: &ControlReply) {
    let text = serde_json::to_vec(reply).unwrap_or_else(|e| {
        serde_json::to_vec(&ControlReply::Error(ControlError {
            kind: ControlErrorKind::Internal,
            message: format!("the reply did not serialize: {e}"),
        }))
        .unwrap_or_default()
    });
    let Ok(payload_len) = u32::try_from(text.len()) else {
        tracing::error!(len = text.len(), "a control reply over 4 GiB was not sent");
        return;
    };
    let sent = request
        .loan_slice_uninit(text.len())
        .map(|mut response| {
            *response.user_header_mut() = ControlHeader {
                protocol_version: PROTOCOL_VERSION,
                payload_len,
            };
            response.write_from_slice(&text)
        })
        .map_err(|e| format!("{e:?}"))
        .and_then(|response| response.send().map_err(|e| format!("{e:?}")));
    if let Err(e) = sent {
        tracing::debug!(error = ?e, "sending a control reply failed");
    }
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
