//! `echogym._native`: the Python extension over echogym's Rust client.
//!
//! Thin by design: `client::NativeClient` and `lease::NativeLease` wrap
//! `echogym_client` (`async_batch::NativeAsyncBatch` its asynchronous groups), `views` turns the server's shared-memory observation sample into
//! read-only numpy arrays without copying, `errors` defines the exception tree and
//! `cli_main` runs the `echogym` command line in-process (used by the console script and
//! by auto-started private servers).

mod async_batch;
mod client;
mod errors;
mod lease;
mod views;

use pyo3::prelude::*;

/// Run the `echogym` command line with `argv` (program name first); the exit code.
/// The GIL is released while it runs (a server runs until stopped).
#[pyfunction]
fn cli_main(py: Python<'_>, argv: Vec<String>) -> u8 {
    py.detach(|| echogym::cli::main_with_args(argv.into_iter().map(Into::into)))
}

/// Resolve the spec of `env_id` for `config_json` locally (no server), as JSON.
/// Unknown ids raise `UnknownEnvError`, bad configs `InvalidConfigError`.
#[pyfunction]
fn resolve_spec(env_id: &str, config_json: &str) -> PyResult<String> {
    let config: serde_json::Map<String, serde_json::Value> = serde_json::from_str(config_json)
        .map_err(|e| {
            pyo3::exceptions::PyValueError::new_err(format!("config must be a JSON object: {e}"))
        })?;
    let registry = echogym::envs::EnvRegistry::default();
    let factory = registry
        .get(env_id)
        .map_err(|e| errors::UnknownEnvError::new_err(e.to_string()))?;
    let spec = factory
        .spec(&config)
        .map_err(|e| errors::InvalidConfigError::new_err(e.to_string()))?;
    Ok(serde_json::to_string(&spec).expect("spec serializes"))
}

/// Read the `echogym-recordings/1` dataset in `dir` with the calibration tool's own
/// reader and summarise it as JSON: `nominal_surface_z`, `torso_center_xy` and per
/// recording (a file cut at gaps gives one per segment) `file`, `site`, `protocol`,
/// `samples`, `rate_hz`, `t_start`, `t_end`. A dataset the reader refuses raises
/// `ValueError` with its message (file, row).
#[pyfunction]
fn read_recordings(py: Python<'_>, dir: std::path::PathBuf) -> PyResult<String> {
    let dataset = py
        .detach(|| echogym::recordings::Dataset::read(&dir))
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    let recordings: Vec<serde_json::Value> = dataset
        .meta
        .recordings
        .iter()
        .zip(&dataset.recordings)
        .map(|(entry, rec)| {
            serde_json::json!({
                "file": entry.file,
                "site": entry.site,
                "protocol": entry.protocol,
                "samples": rec.len(),
                "rate_hz": rec.rate_hz(),
                "t_start": rec.t.first(),
                "t_end": rec.t.last(),
            })
        })
        .collect();
    Ok(serde_json::json!({
        "nominal_surface_z": dataset.meta.nominal_surface_z,
        "torso_center_xy": dataset.meta.torso_center_xy,
        "recordings": recordings,
    })
    .to_string())
}

/// The registered env ids with their one-line descriptions.
#[pyfunction]
fn registered_envs() -> Vec<(String, String)> {
    echogym::envs::EnvRegistry::default()
        .list()
        .into_iter()
        .map(|e| (e.env_id, e.description))
        .collect()
}

/// Shared-memory segments left under `prefix`, besides iceoryx2's node counter
/// (test support: must be empty once servers and clients of that prefix stopped).
#[pyfunction]
fn leftover_segments(prefix: &str) -> Vec<String> {
    let location = echogym_protocol::IpcLocation {
        prefix: prefix.to_owned(),
        ..echogym_protocol::IpcLocation::default()
    };
    echogym_client::testing::leftover_segments(&location)
}

/// Remove the node counter of `prefix` and the `root` directory (test support; call
/// only when no server or client of that location runs).
#[pyfunction]
fn remove_location(prefix: &str, root: std::path::PathBuf) {
    echogym_client::testing::remove_location(&echogym_protocol::IpcLocation {
        prefix: prefix.to_owned(),
        root,
    });
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("PROTOCOL_VERSION", echogym_protocol::PROTOCOL_VERSION)?;
    m.add_class::<client::NativeClient>()?;
    m.add_class::<lease::NativeLease>()?;
    m.add_class::<lease::SampleMemory>()?;
    m.add_class::<async_batch::NativeAsyncBatch>()?;
    m.add_function(wrap_pyfunction!(cli_main, m)?)?;
    m.add_function(wrap_pyfunction!(resolve_spec, m)?)?;
    m.add_function(wrap_pyfunction!(registered_envs, m)?)?;
    m.add_function(wrap_pyfunction!(read_recordings, m)?)?;
    m.add_function(wrap_pyfunction!(leftover_segments, m)?)?;
    m.add_function(wrap_pyfunction!(remove_location, m)?)?;
    errors::register(m)?;
    Ok(())
}
