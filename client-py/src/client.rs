//! `NativeClient`: a connection to one server.

use std::path::PathBuf;
use std::time::Duration;

use echogym_client::{AttachOptions, ConnectOptions, Connection};
use echogym_protocol::{AutoresetMode, ControlRequest, IpcLocation};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::async_batch::NativeAsyncBatch;
use crate::errors::{connect_error, control_error};
use crate::lease::NativeLease;

/// What to lease, from the Python arguments.
fn attach_options(
    env_id: &str,
    num_envs: usize,
    config_json: &str,
    autoreset_mode: &str,
) -> PyResult<AttachOptions> {
    let config: serde_json::Map<String, serde_json::Value> = serde_json::from_str(config_json)
        .map_err(|e| PyValueError::new_err(format!("config must be a JSON object: {e}")))?;
    let autoreset_mode = match autoreset_mode {
        "disabled" => AutoresetMode::Disabled,
        "same_step" => AutoresetMode::SameStep,
        other => {
            return Err(PyValueError::new_err(format!(
                "autoreset_mode must be 'disabled' or 'same_step', got {other:?}"
            )));
        }
    };
    Ok(AttachOptions {
        env_id: env_id.to_owned(),
        num_envs,
        config,
        autoreset_mode,
    })
}

/// A connection to a running echogym server (control channel and wake-ups).
#[pyclass(module = "echogym._native", frozen)]
pub struct NativeClient {
    connection: Connection,
}

#[pymethods]
impl NativeClient {
    /// Connect to the server `name`. `prefix`/`root` default to `ECHOGYM_IPC_PREFIX` /
    /// `ECHOGYM_IPC_ROOT` or the built-in defaults.
    #[new]
    #[pyo3(signature = (name = "default", prefix = None, root = None, spin_us = 200, label = None))]
    fn new(
        py: Python<'_>,
        name: &str,
        prefix: Option<String>,
        root: Option<PathBuf>,
        spin_us: u64,
        label: Option<String>,
    ) -> PyResult<Self> {
        let mut location = IpcLocation::from_env();
        if let Some(prefix) = prefix {
            location.prefix = prefix;
        }
        if let Some(root) = root {
            location.root = root;
        }
        let mut options = ConnectOptions {
            name: name.to_owned(),
            location,
            spin: Duration::from_micros(spin_us),
            ..ConnectOptions::default()
        };
        if let Some(label) = label {
            options.label = label;
        }
        let connection = py
            .detach(|| Connection::connect(&options))
            .map_err(connect_error)?;
        Ok(Self { connection })
    }

    /// Send a JSON control request (`{"op": "status"}`, ...) and return the JSON reply.
    /// Refusals raise the matching `EchogymError` subclass. `protocol_version` overrides
    /// the version claimed (for tests of the version check).
    #[pyo3(signature = (request_json, protocol_version = None))]
    fn request(
        &self,
        py: Python<'_>,
        request_json: &str,
        protocol_version: Option<u32>,
    ) -> PyResult<String> {
        let request: ControlRequest = serde_json::from_str(request_json)
            .map_err(|e| PyValueError::new_err(format!("malformed control request: {e}")))?;
        let version = protocol_version.unwrap_or(echogym_protocol::PROTOCOL_VERSION);
        let reply = py
            .detach(|| self.connection.request_with_version(version, &request))
            .map_err(control_error)?;
        Ok(serde_json::to_string(&reply).expect("replies serialize"))
    }

    /// Lease `num_envs` envs of `env_id` with `config_json` (a JSON object).
    /// `autoreset_mode` is `"disabled"` or `"same_step"`.
    #[pyo3(signature = (env_id, num_envs, config_json = "{}", autoreset_mode = "disabled"))]
    fn attach(
        &self,
        py: Python<'_>,
        env_id: &str,
        num_envs: usize,
        config_json: &str,
        autoreset_mode: &str,
    ) -> PyResult<NativeLease> {
        let options = attach_options(env_id, num_envs, config_json, autoreset_mode)?;
        let lease = py
            .detach(|| self.connection.attach(&options))
            .map_err(control_error)?;
        NativeLease::new(py, lease)
    }

    /// Lease `num_envs` envs as groups of `group_size` (one lease each) for asynchronous
    /// stepping: `send_step(actions, env_ids)` / `recv(min_envs)`.
    #[pyo3(signature = (env_id, num_envs, group_size, config_json = "{}", autoreset_mode = "disabled"))]
    fn attach_async(
        &self,
        py: Python<'_>,
        env_id: &str,
        num_envs: usize,
        group_size: usize,
        config_json: &str,
        autoreset_mode: &str,
    ) -> PyResult<NativeAsyncBatch> {
        let options = attach_options(env_id, num_envs, config_json, autoreset_mode)?;
        let batch = py
            .detach(|| self.connection.attach_async(&options, group_size))
            .map_err(control_error)?;
        NativeAsyncBatch::new(py, batch)
    }

    /// The server name.
    #[getter]
    fn name(&self) -> String {
        self.connection.options().name.clone()
    }

    /// This client's iceoryx2 node id.
    #[getter]
    fn node_id(&self) -> String {
        self.connection.node_id().to_string()
    }
}
