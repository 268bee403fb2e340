//! The iceoryx2 service-naming scheme, in one place.
//!
//! Every service of a server lives under `echogym/<server name>/`:
//! ```text
//! echogym/<name>/control                 request-response, JSON control messages
//! echogym/<name>/wake                    event, clients → server ("work is waiting")
//! echogym/<name>/up/<server node id>      event, created last by a server whose ports
//!                                         are up ("this server answers requests")
//! echogym/<name>/lease/<id>/action       publish-subscribe, client → server
//! echogym/<name>/lease/<id>/obs          publish-subscribe, server → client
//! echogym/<name>/lease/<id>/ready        event, server → client ("obs is waiting")
//! ```

/// A server name that cannot be used in service names.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("invalid server name {0:?}: use 1 to 64 characters from letters, digits, '-' and '_'")]
pub struct InvalidServerName(pub String);

/// Service names of one server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    server: String,
}

impl ServiceNames {
    /// Names for the server called `server` (validated).
    pub fn new(server: &str) -> Result<Self, InvalidServerName> {
        let valid = !server.is_empty()
            && server.len() <= 64
            && server
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
        if valid {
            Ok(Self {
                server: server.to_owned(),
            })
        } else {
            Err(InvalidServerName(server.to_owned()))
        }
    }

    /// The server name.
    pub fn server(&self) -> &str {
        &self.server
    }

    /// The control request-response service.
    pub fn control(&self) -> String {
        format!("echogym/{}/control", self.server)
    }

    /// The event service clients notify when work is waiting.
    pub fn wake(&self) -> String {
        format!("echogym/{}/wake", self.server)
    }

    /// The service a server creates once its control port and wake listener are up:
    /// a client that reached the server's node waits for it, so a request never goes
    /// to a restarted server's control service before its port exists (the request
    /// would reach nobody and never be answered). Named by the node id, so what a
    /// dead server of the same name left cannot stand in for it.
    pub fn server_up(&self, server_node: u128) -> String {
        format!("echogym/{}/up/{server_node:032x}", self.server)
    }

    /// The action service of a lease.
    pub fn lease_action(&self, lease_id: u64) -> String {
        format!("echogym/{}/lease/{lease_id}/action", self.server)
    }

    /// The observation service of a lease.
    pub fn lease_obs(&self, lease_id: u64) -> String {
        format!("echogym/{}/lease/{lease_id}/obs", self.server)
    }

    /// The event service the server notifies when a lease's observation is ready.
    pub fn lease_ready(&self, lease_id: u64) -> String {
        format!("echogym/{}/lease/{lease_id}/ready", self.server)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_scoped_by_server() {
        let names = ServiceNames::new("train-1").unwrap();
        assert_eq!(names.control(), "echogym/train-1/control");
        assert_eq!(names.wake(), "echogym/train-1/wake");
        assert_eq!(
            names.server_up(0xab),
            "echogym/train-1/up/000000000000000000000000000000ab"
        );
        assert_eq!(names.lease_action(7), "echogym/train-1/lease/7/action");
        assert_eq!(names.lease_obs(7), "echogym/train-1/lease/7/obs");
        assert_eq!(names.lease_ready(7), "echogym/train-1/lease/7/ready");
    }

    #[test]
    fn rejects_names_that_would_escape_the_scheme() {
        for bad in ["", "a/b", "a b", "ü", &"x".repeat(65)] {
            assert!(ServiceNames::new(bad).is_err(), "{bad:?}");
        }
    }
}
