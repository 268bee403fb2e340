//! The daemon entry point: run a server until its shutdown token fires.

use crate::config::ServeConfig;
use crate::envs::EnvRegistry;
use crate::transport::{Dispatcher, Shutdown, StartError};

/// Start a server from `config` with every built-in env and serve until `shutdown`
/// is requested (signal, `echogym stop`, or the embedding code). Returns once every
/// lease was told the server stopped and every shared-memory resource was removed.
pub fn run(config: &ServeConfig, shutdown: Shutdown) -> Result<(), StartError> {
    let root = match &config.recordings_root {
        Some(root) => root.clone(),
        None => std::env::current_dir().unwrap_or_else(|_| ".".into()),
    };
    crate::recordings::root::set_root(&root);
    tracing::info!(root = %root.display(), "recordings root");
    let registry = if config.fault_injection {
        EnvRegistry::with_fault_injection()
    } else {
        EnvRegistry::default()
    };
    let dispatcher = Dispatcher::start(config.dispatcher_options(), registry, shutdown)?;
    dispatcher.run();
    Ok(())
}
