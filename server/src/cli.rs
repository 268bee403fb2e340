//! The `echogym` command line: `serve`, `status`, `stop`, `envs`, `calibrate`.
//!
//! Shared by the Rust binary and the Python console script (which calls
//! [`main_with_args`] through the native module), so both behave identically.

use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use echogym_client::{ConnectOptions, Connection, ControlCallError};
use echogym_protocol::{ControlReply, ControlRequest, IpcLocation};

use crate::config::ServeConfig;
use crate::envs::EnvRegistry;
use crate::transport::Shutdown;

/// echogym: simulation server for robot-assisted ultrasound learning.
///
/// Logging: `RUST_LOG` (tracing env-filter syntax, e.g. `echogym=debug`) sets what every
/// command logs to stderr; `serve --log` overrides it for the server.
#[derive(Debug, Parser)]
#[command(name = "echogym", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a server in the foreground until SIGINT/SIGTERM or `echogym stop`.
    Serve(ServeArgs),
    /// Show a running server's leases and counters.
    Status {
        #[command(flatten)]
        target: Target,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Ask a running server to stop gracefully.
    Stop {
        #[command(flatten)]
        target: Target,
    },
    /// List the registered env ids.
    Envs,
    /// Calibrate the simulator against recordings: locate the mismatch, name the physics
    /// left out, model it, show the fit improve on test recordings, or say what remains
    /// unexplained (`calibrate synth` makes test datasets; RUST_LOG=echogym=debug logs
    /// each fit).
    #[command(args_conflicts_with_subcommands = true)]
    Calibrate(CalibrateArgs),
}

#[derive(Debug, Args)]
struct CalibrateArgs {
    #[command(subcommand)]
    synth: Option<CalibrateCommand>,
    /// Dataset folder (`echogym-recordings/1`: dataset.json + one CSV per recording).
    dataset: Option<PathBuf>,
    /// Output folder (report.json, report.md, replay/, calibrated.toml, plots).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Seed of the train/validation/test split.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Debug, Subcommand)]
enum CalibrateCommand {
    /// Generate a dataset with concealed effects (ground truth in OUT/truth.json, the
    /// dataset in OUT/dataset).
    Synth {
        /// Effect to conceal (repeatable): nonlinear_stiffness, viscoelastic_relaxation,
        /// breathing_motion, tissue_inertia, sensor_bias, sensor_delay,
        /// site_heterogeneity, sliding_friction, sensor_filter, bias_drift,
        /// depth_dependent_damping. None: a dataset without hidden effects.
        #[arg(long = "effect")]
        effects: Vec<String>,
        /// Generator seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Effect size relative to the physiological ranges (e.g. 0.25 to probe the
        /// detection limit); in (0, 2].
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Which server to talk to.
#[derive(Debug, Args)]
struct Target {
    /// Server name.
    #[arg(long, default_value = "default", env = "ECHOGYM_SERVER")]
    name: String,
    /// iceoryx2 file prefix (default `echogym_<uid>_`).
    #[arg(long, env = "ECHOGYM_IPC_PREFIX")]
    ipc_prefix: Option<String>,
    /// iceoryx2 root directory (default `/tmp/echogym-<uid>/`).
    #[arg(long, env = "ECHOGYM_IPC_ROOT")]
    ipc_root: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct ServeArgs {
    /// TOML config file (CLI flags override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Server name; a second server with the same name is refused.
    #[arg(long)]
    name: Option<String>,
    /// Worker threads (0 = one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Nice value of the worker threads (0–19).
    #[arg(long)]
    worker_nice: Option<i32>,
    /// Microseconds: exchanges above the inline budget and at most this run on the
    /// medium lane while a bigger one is on the pool (0 = no lane).
    #[arg(long)]
    lane_budget_us: Option<u64>,
    /// Microseconds to busy-poll before blocking.
    #[arg(long)]
    spin_us: Option<u64>,
    /// Milliseconds between housekeeping passes.
    #[arg(long)]
    housekeeping_ms: Option<u64>,
    /// Most leases at once.
    #[arg(long)]
    max_leases: Option<usize>,
    /// Most envs at once.
    #[arg(long)]
    max_envs: Option<usize>,
    /// Most leases one client process holds.
    #[arg(long)]
    max_leases_per_client: Option<usize>,
    /// Most envs one client process holds.
    #[arg(long)]
    max_envs_per_client: Option<usize>,
    /// Most bytes of lease shared memory at once, over all leases.
    #[arg(long)]
    max_shm_bytes: Option<u64>,
    /// Most bytes of lease shared memory one client process holds.
    #[arg(long)]
    max_shm_bytes_per_client: Option<u64>,
    /// The folder every env's `record.dir` must lie in (default: the working directory).
    #[arg(long)]
    recordings_root: Option<PathBuf>,
    /// Log filter, e.g. `info` or `echogym=debug` (default: `RUST_LOG`, else the config
    /// file's `log`, else `info`).
    #[arg(long)]
    log: Option<String>,
    /// iceoryx2 file prefix.
    #[arg(long)]
    ipc_prefix: Option<String>,
    /// iceoryx2 root directory.
    #[arg(long)]
    ipc_root: Option<PathBuf>,
    /// Print the resolved configuration as TOML and exit.
    #[arg(long)]
    print_config: bool,
    /// Stop when this pid stops being the parent process (used by auto-started servers).
    #[arg(long, hide = true)]
    exit_with_parent: Option<u32>,
    /// Register `echogym/Faulty-v0`, which panics on request (tests of fault containment).
    #[arg(long, hide = true)]
    fault_injection: bool,
}

impl ServeArgs {
    fn resolve(&self) -> Result<ServeConfig, crate::config::ConfigError> {
        let mut config = ServeConfig::load(self.config.as_deref())?;
        if let Some(filter) = rust_log() {
            config.log = filter;
        }
        fn set<T: Clone>(slot: &mut T, value: &Option<T>) {
            if let Some(v) = value {
                *slot = v.clone();
            }
        }
        set(&mut config.name, &self.name);
        set(&mut config.threads, &self.threads);
        set(&mut config.worker_nice, &self.worker_nice);
        set(&mut config.lane_budget_us, &self.lane_budget_us);
        set(&mut config.spin_us, &self.spin_us);
        set(&mut config.housekeeping_ms, &self.housekeeping_ms);
        set(&mut config.max_leases, &self.max_leases);
        set(&mut config.max_envs, &self.max_envs);
        set(
            &mut config.max_leases_per_client,
            &self.max_leases_per_client,
        );
        set(&mut config.max_envs_per_client, &self.max_envs_per_client);
        set(&mut config.max_shm_bytes, &self.max_shm_bytes);
        set(
            &mut config.max_shm_bytes_per_client,
            &self.max_shm_bytes_per_client,
        );
        if let Some(root) = &self.recordings_root {
            config.recordings_root =
                Some(std::path::absolute(root).unwrap_or_else(|_| root.clone()));
        }
        set(&mut config.log, &self.log);
        set(&mut config.ipc.prefix, &self.ipc_prefix);
        set(&mut config.ipc.root, &self.ipc_root);
        config.parent_pid = self.exit_with_parent;
        config.fault_injection = self.fault_injection;
        config.validate()?;
        Ok(config)
    }
}

/// Run the CLI with `args` (including the program name); the process exit status
/// (0 success, 1 failure, 2 usage error).
pub fn main_with_args(args: impl IntoIterator<Item = OsString>) -> u8 {
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    if !matches!(cli.command, Command::Serve(_)) {
        // RUST_LOG=echogym=debug shows e.g. each calibration fit's convergence and time.
        init_logging(rust_log().as_deref().unwrap_or("warn"));
    }
    let result = match cli.command {
        Command::Serve(args) => serve(&args),
        Command::Status { target, json } => status(&target, json),
        Command::Stop { target } => stop(&target),
        Command::Envs => {
            for env in EnvRegistry::default().list() {
                println!("{:<28} {}", env.env_id, env.description);
            }
            Ok(())
        }
        Command::Calibrate(args) => calibrate(args),
    };
    match result {
        Ok(()) => 0,
        Err(message) => {
            eprintln!("echogym: {message}");
            1
        }
    }
}

/// `RUST_LOG`, when set to something.
fn rust_log() -> Option<String> {
    std::env::var("RUST_LOG")
        .ok()
        .filter(|v| !v.trim().is_empty())
}

/// Log to stderr with `filter` (a second call in one process, e.g. from Python, keeps the
/// first subscriber).
fn init_logging(filter: &str) {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::new(filter))
        .with_writer(std::io::stderr)
        .try_init();
}

fn calibrate(args: CalibrateArgs) -> Result<(), String> {
    use crate::calibrate::{CalibrateOptions, synth};
    if let Some(CalibrateCommand::Synth {
        effects,
        seed,
        scale,
        out,
    }) = args.synth
    {
        let truth = synth::generate(&effects, seed, scale, &out).map_err(|e| e.to_string())?;
        println!(
            "wrote {} ({} recordings; truth in {})",
            out.join("dataset").display(),
            truth.recordings.len(),
            out.join("truth.json").display()
        );
        return Ok(());
    }
    let (Some(dataset), Some(out)) = (args.dataset, args.out) else {
        return Err("usage: echogym calibrate DATASET_DIR --out OUT_DIR [--seed N]".into());
    };
    let started = std::time::Instant::now();
    let outcome = crate::calibrate::calibrate(&CalibrateOptions {
        dataset,
        out: out.clone(),
        seed: args.seed,
        progress: !args.quiet,
    })
    .map_err(|e| e.to_string())?;
    let names: Vec<&str> = outcome.accepted.iter().map(|a| a.name).collect();
    println!(
        "effects found: {}",
        if names.is_empty() {
            "none".to_owned()
        } else {
            names.join(", ")
        }
    );
    println!(
        "report: {} ({:.0} s)",
        out.join("report.md").display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

fn serve(args: &ServeArgs) -> Result<(), String> {
    let config = args.resolve().map_err(|e| e.to_string())?;
    if args.print_config {
        print!("{}", config.to_toml());
        return Ok(());
    }
    init_logging(&config.log);
    let shutdown = Shutdown::new();
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, shutdown.flag())
            .map_err(|e| format!("cannot install a handler for signal {signal}: {e}"))?;
    }
    crate::daemon::run(&config, shutdown).map_err(|e| e.to_string())
}

fn connect(target: &Target) -> Result<Connection, String> {
    let mut location = IpcLocation::from_env();
    if let Some(prefix) = &target.ipc_prefix {
        location.prefix = prefix.clone();
    }
    if let Some(root) = &target.ipc_root {
        location.root = root.clone();
    }
    let options = ConnectOptions {
        name: target.name.clone(),
        location,
        label: format!("echogym cli pid {}", std::process::id()),
        ..ConnectOptions::default()
    };
    Connection::connect(&options).map_err(|e| e.to_string())
}

fn status(target: &Target, json: bool) -> Result<(), String> {
    let connection = connect(target)?;
    let reply = connection
        .request(&ControlRequest::Status)
        .map_err(|e| e.to_string())?;
    let ControlReply::Status(status) = reply else {
        return Err(format!("unexpected reply: {reply:?}"));
    };
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&status).expect("status serializes")
        );
        return Ok(());
    }
    println!(
        "server {:?}: pid {}, version {} (protocol {}), up {:.1} s, {} threads, {} env steps, {} physics errors, {} env errors, {} leases reclaimed",
        status.name,
        status.pid,
        status.version,
        status.protocol_version,
        status.uptime_s,
        status.threads,
        status.env_steps,
        status.physics_errors,
        status.env_errors,
        status.reclaimed_leases
    );
    if status.leases.is_empty() {
        println!("no leases");
    }
    for lease in &status.leases {
        println!(
            "  lease {:>20}  {:<28} x{:<5} {:>10} exchanges {:>12} env steps {:>5} physics/{:<5} env errors  age {:>8.1} s  idle {:>7.1} s  pid {:<8} {}",
            lease.lease_id,
            lease.env_id,
            lease.num_envs,
            lease.exchanges,
            lease.env_steps,
            lease.physics_errors,
            lease.env_errors,
            lease.age_s,
            lease.idle_s,
            lease.client_pid.map_or("?".to_owned(), |p| p.to_string()),
            lease.client_label
        );
    }
    for build in &status.building {
        println!(
            "  building {:<28} x{:<5} for {:.1} s  {}",
            build.env_id, build.num_envs, build.waited_s, build.client_label
        );
    }
    Ok(())
}

fn stop(target: &Target) -> Result<(), String> {
    let connection = connect(target)?;
    let reply = match connection.request(&ControlRequest::Stop) {
        // The server may be gone before its reply reaches us: that is what we asked for.
        Err(ControlCallError::ServerStopped) => ControlReply::Stopping,
        other => other.map_err(|e| e.to_string())?,
    };
    match reply {
        ControlReply::Stopping => {
            // Wait for the server to go away so scripts can rely on it being gone.
            let deadline = std::time::Instant::now() + Duration::from_secs(10);
            drop(connection);
            while std::time::Instant::now() < deadline {
                if connect(target).is_err() {
                    println!("server {:?} stopped", target.name);
                    return Ok(());
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(format!("server {:?} did not stop within 10 s", target.name))
        }
        other => Err(format!("unexpected reply: {other:?}")),
    }
}
