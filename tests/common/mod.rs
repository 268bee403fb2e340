//! Harness shared by the end-to-end tests: a real `echogym serve` process in an
//! iceoryx2 location of its own, and helpers to drive it with the real Rust client.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use echogym_client::{AttachOptions, ConnectOptions, Connection, Lease};
use echogym_protocol::{AutoresetMode, IpcLocation};

static NEXT: AtomicUsize = AtomicUsize::new(0);

/// The `echogym` binary under test.
pub fn binary() -> &'static str {
    env!("CARGO_BIN_EXE_echogym")
}

/// A fresh iceoryx2 location for one test.
pub fn fresh_location() -> IpcLocation {
    let n = NEXT.fetch_add(1, Ordering::SeqCst);
    let tag = format!("egt{}x{n}", std::process::id());
    IpcLocation {
        prefix: format!("{tag}_"),
        root: PathBuf::from(format!("/tmp/echogym-test-{tag}/")),
    }
}

/// A running `echogym serve` process.
pub struct TestServer {
    pub name: String,
    pub location: IpcLocation,
    pub child: Option<Child>,
}

impl TestServer {
    /// Start a server called `name` in a fresh location and wait until it answers.
    pub fn start(name: &str) -> Self {
        Self::start_in(name, fresh_location(), &[])
    }

    /// Start a server in `location` with extra CLI flags.
    pub fn start_in(name: &str, location: IpcLocation, extra: &[&str]) -> Self {
        let child = spawn_server(name, &location, extra);
        let server = Self {
            name: name.to_owned(),
            location,
            child: Some(child),
        };
        server.wait_ready();
        server
    }

    fn wait_ready(&self) {
        let deadline = Instant::now() + Duration::from_secs(20);
        while Instant::now() < deadline {
            if Connection::connect(&self.options()).is_ok() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!("server {} did not come up", self.name);
    }

    /// Connection options for this server.
    pub fn options(&self) -> ConnectOptions {
        ConnectOptions {
            name: self.name.clone(),
            location: self.location.clone(),
            control_timeout: Duration::from_secs(30),
            ..ConnectOptions::default()
        }
    }

    /// A new connection.
    pub fn connect(&self) -> Connection {
        Connection::connect(&self.options()).expect("connect")
    }

    /// Send a signal to the server process.
    pub fn signal(&self, signal: &str) {
        let pid = self.child.as_ref().expect("running").id();
        let status = Command::new("kill")
            .args([format!("-{signal}"), pid.to_string()])
            .status()
            .expect("kill");
        assert!(status.success());
    }

    /// Wait for the server to exit; its exit code.
    pub fn wait(&mut self) -> Option<i32> {
        let mut child = self.child.take().expect("running");
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(status) = child.try_wait().expect("try_wait") {
                return status.code();
            }
            if Instant::now() > deadline {
                let _ = child.kill();
                let _ = child.wait();
                panic!("server did not exit within 10 s");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Run `echogym <args>` against this server's location.
    pub fn cli(&self, args: &[&str]) -> Output {
        Command::new(binary())
            .args(args)
            .env("ECHOGYM_IPC_PREFIX", &self.location.prefix)
            .env("ECHOGYM_IPC_ROOT", &self.location.root)
            .output()
            .expect("run echogym")
    }
}

impl Drop for TestServer {
    /// Stop the server gracefully and check it left no shared memory behind (clients
    /// declared after the server are dropped before it).
    fn drop(&mut self) {
        if std::thread::panicking() {
            if let Some(mut child) = self.child.take() {
                let _ = child.kill();
                let _ = child.wait();
            }
            return;
        }
        if self.child.is_some() {
            self.signal("TERM");
            assert_eq!(self.wait(), Some(0), "server exits 0 on SIGTERM");
        }
        assert_clean_and_remove(&self.location);
    }
}

/// Spawn `echogym serve` without waiting. Its output is kept from the test's unless
/// `ECHOGYM_TEST_SERVER_LOG` names a log filter (e.g. `echogym=debug`): then the server
/// logs at that level to the test's stdout and stderr.
pub fn spawn_server(name: &str, location: &IpcLocation, extra: &[&str]) -> Child {
    let log = std::env::var("ECHOGYM_TEST_SERVER_LOG").ok();
    let output = || {
        if log.is_some() {
            Stdio::inherit()
        } else {
            Stdio::piped()
        }
    };
    Command::new(binary())
        .args(["serve", "--name", name, "--threads", "2", "--log"])
        .arg(log.as_deref().unwrap_or("warn"))
        .args(extra)
        .env("ECHOGYM_IPC_PREFIX", &location.prefix)
        .env("ECHOGYM_IPC_ROOT", &location.root)
        .stdin(Stdio::null())
        .stdout(output())
        .stderr(output())
        .spawn()
        .expect("spawn echogym serve")
}

/// Lease `num_envs` Null envs with `config`.
pub fn attach_null(
    connection: &Connection,
    num_envs: usize,
    config: serde_json::Value,
    mode: AutoresetMode,
) -> Lease {
    connection
        .attach(&AttachOptions {
            env_id: "echogym/Null-v0".into(),
            num_envs,
            config: config.as_object().cloned().unwrap_or_default(),
            autoreset_mode: mode,
        })
        .expect("attach")
}

/// A bystander: one `Null-v0` env (default config, same-step autoreset), reset.
pub fn reset_bystander(connection: &Connection) -> Lease {
    let mut lease = attach_null(
        connection,
        1,
        serde_json::json!({}),
        AutoresetMode::SameStep,
    );
    lease.reset(None, None).expect("reset");
    lease
}

/// The float32 observation of env `env` (Null env: one field `obs`).
pub fn null_obs(lease: &Lease, payload: &[u8], env: usize) -> Vec<f32> {
    let layout = lease.layout();
    let field = &lease.spec().observation[0];
    let start = layout.obs.obs + env * layout.obs_record_bytes + field.offset;
    bytemuck::cast_slice::<u8, f32>(&payload[start..start + field.byte_len()]).to_vec()
}

/// Assert the location holds no shared memory besides the node counter, then remove it.
pub fn assert_clean_and_remove(location: &IpcLocation) {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let left = echogym_client::testing::leftover_segments(location);
        if left.is_empty() {
            break;
        }
        if Instant::now() > deadline {
            panic!("shared memory left behind: {left:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    echogym_client::testing::remove_location(location);
}

/// This test binary, re-run as a child process executing the ignored test `name` with
/// `env` set (child processes are real, separate iceoryx2 clients).
pub fn spawn_self(name: &str, env: &[(&str, String)]) -> Child {
    let mut command = Command::new(std::env::current_exe().expect("current exe"));
    command
        .args([
            "--exact",
            name,
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (key, value) in env {
        command.env(key, value);
    }
    command.spawn().expect("spawn child client")
}

/// The corpus files whose names start with `prefix`, with their bytes.
pub fn corpus(prefix: &str) -> Vec<(String, Vec<u8>)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/fuzz_corpus");
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("a corpus entry").path())
        .filter(|path| {
            path.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(prefix))
        })
        .map(|path| {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&path).expect("a corpus file"))
        })
        .collect();
    files.sort();
    files
}
