//! One client cannot stall, starve or disturb the others: envs are built off the
//! dispatcher, a build nobody waits for any more is cancelled, quotas hold per client,
//! and a lease is detached only by its own client. Real server process, real clients.

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use common::{TestServer, attach_null, reset_bystander};
use echogym_client::{AttachOptions, ConnectOptions, Connection, ControlCallError};
use echogym_protocol::{AutoresetMode, ControlReply, ControlRequest, ServerStatus};

fn status(connection: &Connection) -> ServerStatus {
    match connection.request(&ControlRequest::Status).expect("status") {
        ControlReply::Status(status) => status,
        other => panic!("unexpected reply {other:?}"),
    }
}

fn scan(num_envs: usize) -> AttachOptions {
    AttachOptions {
        env_id: "echogym/UltrasoundScan-v0".into(),
        num_envs,
        config: serde_json::Map::new(),
        autoreset_mode: AutoresetMode::SameStep,
    }
}

/// One reset `Faulty-v0` env whose steps stall as `config` says (`stall_ms`).
fn slow_lease(connection: &Connection, config: serde_json::Value) -> echogym_client::Lease {
    let mut lease = connection
        .attach(&AttachOptions {
            env_id: "echogym/Faulty-v0".into(),
            num_envs: 1,
            config: config.as_object().cloned().unwrap_or_default(),
            autoreset_mode: AutoresetMode::SameStep,
        })
        .expect("attach");
    lease.reset(None, None).expect("reset");
    lease
}

#[test]
fn a_big_attach_does_not_stall_a_bystander() {
    let server = TestServer::start("isolation-stall");
    let options = server.options();
    let attaching = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicBool::new(false));

    // The bystander steps one Null env as fast as it can and records the slowest step
    // and how many steps it took while the other client's attach was under way.
    let bystander = {
        let (options, attaching, done) = (options.clone(), attaching.clone(), done.clone());
        std::thread::spawn(move || {
            let connection = Connection::connect(&options).expect("connect");
            let mut lease = reset_bystander(&connection);
            let (mut slowest, mut steps_during) = (Duration::ZERO, 0usize);
            while !done.load(Ordering::SeqCst) {
                let started = Instant::now();
                lease.step(&[0.0; 7], None).expect("step");
                if attaching.load(Ordering::SeqCst) {
                    slowest = slowest.max(started.elapsed());
                    steps_during += 1;
                }
            }
            (slowest, steps_during)
        })
    };
    std::thread::sleep(Duration::from_millis(200));

    let connection = server.connect();
    attaching.store(true, Ordering::SeqCst);
    let started = Instant::now();
    let lease = connection.attach(&scan(384)).expect("attach 384 scan envs");
    let attach_time = started.elapsed();
    attaching.store(false, Ordering::SeqCst);
    done.store(true, Ordering::SeqCst);
    let (slowest, steps_during) = bystander.join().expect("bystander");
    drop(lease);

    eprintln!(
        "attach of 384 scan envs: {:.0} ms; bystander: {steps_during} steps meanwhile, slowest {:.2} ms",
        attach_time.as_secs_f64() * 1e3,
        slowest.as_secs_f64() * 1e3
    );
    assert!(
        attach_time > Duration::from_millis(100),
        "the attach ({attach_time:?}) is too quick to show a stall"
    );
    assert!(
        steps_during >= 10,
        "the bystander stepped only {steps_during} times during the attach"
    );
    // Before building moved off the dispatcher, the slowest step was the whole build.
    // (Absolute latency under load is the soak benchmark's measure, not a test's: on a
    // loaded 2-core machine the scheduler alone can hold a step for tens of ms.)
    assert!(
        slowest < attach_time / 4,
        "a bystander step took {slowest:?} during a {attach_time:?} attach"
    );
}

#[test]
fn a_slow_exchange_does_not_stall_a_bystander() {
    // One `Faulty-v0` env that sleeps 400 ms in every step: its exchange runs on the
    // worker pool while the dispatcher serves the bystander. (Before exchanges left the
    // dispatcher, every bystander step waited for the slow one.)
    let server = TestServer::start_in(
        "isolation-slow",
        common::fresh_location(),
        &["--fault-injection"],
    );
    let slow_options = server.options();
    let stepping = Arc::new(AtomicBool::new(false));
    let slow = {
        let stepping = stepping.clone();
        std::thread::spawn(move || {
            let connection = Connection::connect(&slow_options).expect("connect");
            let mut lease = slow_lease(&connection, serde_json::json!({"stall_ms": 400}));
            stepping.store(true, Ordering::SeqCst);
            let started = Instant::now();
            for _ in 0..3 {
                lease.step(&[0.0], None).expect("slow step");
            }
            stepping.store(false, Ordering::SeqCst);
            started.elapsed()
        })
    };
    let connection = server.connect();
    let mut bystander = reset_bystander(&connection);
    while !stepping.load(Ordering::SeqCst) {
        bystander.step(&[0.0; 7], None).expect("step");
    }
    let (mut slowest, mut steps) = (Duration::ZERO, 0usize);
    while stepping.load(Ordering::SeqCst) {
        let started = Instant::now();
        bystander.step(&[0.0; 7], None).expect("step");
        slowest = slowest.max(started.elapsed());
        steps += 1;
    }
    let slow_time = slow.join().expect("slow client");
    eprintln!(
        "3 slow steps: {:.0} ms; bystander: {steps} steps meanwhile, slowest {:.2} ms",
        slow_time.as_secs_f64() * 1e3,
        slowest.as_secs_f64() * 1e3
    );
    assert!(steps >= 10, "the bystander stepped only {steps} times");
    // Generous: scheduling on a loaded machine, not the 400 ms exchange.
    assert!(
        slowest < Duration::from_millis(200),
        "a bystander step took {slowest:?} beside 400 ms exchanges"
    );
}

#[test]
fn an_attach_nobody_waits_for_is_cancelled() {
    let server = TestServer::start("isolation-cancel");
    let impatient = Connection::connect(&ConnectOptions {
        control_timeout: Duration::from_millis(300),
        ..server.options()
    })
    .expect("connect");
    // ≈ 1.5 ms per env: seconds of building, far beyond the client's 0.3 s patience.
    let started = Instant::now();
    match impatient.attach(&scan(4000)) {
        Err(ControlCallError::Timeout(_)) => {}
        Err(other) => panic!("expected a timeout, got {other}"),
        Ok(_) => panic!("4000 scan envs built within 0.3 s?"),
    }
    assert!(started.elapsed() < Duration::from_secs(2));

    let observer = server.connect();
    let deadline = Instant::now() + Duration::from_secs(3);
    loop {
        let now = status(&observer);
        assert!(now.leases.is_empty(), "a lease was made for nobody");
        if now.building.is_empty() {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the abandoned build still runs: {:?}",
            now.building
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // Cancelled, not finished: the builder is free again at once.
    let started = Instant::now();
    let lease = observer.attach(&scan(1)).expect("attach after cancel");
    assert!(
        started.elapsed() < Duration::from_secs(1),
        "the builder was still busy: {:?}",
        started.elapsed()
    );
    drop(lease);
    assert!(status(&observer).leases.is_empty());
}

#[test]
fn bad_attach_requests_are_refused_and_the_server_serves_on() {
    let server = TestServer::start("isolation-refuse");
    let connection = server.connect();
    for (options, expected) in [
        (
            AttachOptions {
                num_envs: 0,
                ..scan(1)
            },
            "num_envs",
        ),
        (
            AttachOptions {
                num_envs: usize::MAX,
                ..scan(1)
            },
            "max_envs",
        ),
    ] {
        match connection.attach(&options) {
            Err(ControlCallError::Refused { message, .. }) => {
                assert!(message.contains(expected), "{message}")
            }
            Err(other) => panic!("expected a refusal naming {expected}, got {other}"),
            Ok(_) => panic!("attach of {} envs accepted", options.num_envs),
        }
    }
    let mut lease = attach_null(
        &connection,
        2,
        serde_json::json!({}),
        AutoresetMode::SameStep,
    );
    lease.reset(None, None).expect("the server serves on");
}

#[test]
fn recordings_stay_inside_the_recordings_root() {
    let root = std::env::temp_dir().join(format!("echogym-root-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let server = TestServer::start_in(
        "isolation-root",
        common::fresh_location(),
        &["--recordings-root", root.to_str().unwrap()],
    );
    let connection = server.connect();
    let press = |dir: &str| AttachOptions {
        env_id: "echogym/CalibrationPress-v0".into(),
        num_envs: 1,
        config: serde_json::json!({"record": {"dir": dir}})
            .as_object()
            .cloned()
            .unwrap(),
        autoreset_mode: AutoresetMode::Disabled,
    };
    for (dir, expected) in [
        ("/tmp/echogym-escape", "outside"),
        ("../escape", ".."),
        ("runs/../../escape", ".."),
    ] {
        match connection.attach(&press(dir)) {
            Err(ControlCallError::Refused { kind, message }) => {
                assert_eq!(kind, echogym_protocol::ControlErrorKind::InvalidConfig);
                assert!(
                    message.contains("record.dir") && message.contains(expected),
                    "{message}"
                );
            }
            Err(other) => panic!("expected a refusal for {dir}, got {other}"),
            Ok(_) => panic!("record.dir {dir} accepted"),
        }
    }
    // Inside the root: relative, and absolute within it.
    for dir in ["runs", root.join("abs").to_str().unwrap()] {
        let mut lease = connection.attach(&press(dir)).expect("attach");
        lease.reset(None, None).expect("reset");
        let action = vec![0.0f32; lease.spec().action.size];
        for _ in 0..5 {
            lease.step(&action, None).expect("step");
        }
        drop(lease);
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    let datasets = |sub: &str| {
        std::fs::read_dir(root.join(sub))
            .map(|entries| {
                entries
                    .flatten()
                    .filter(|e| e.path().join("dataset.json").is_file())
                    .count()
            })
            .unwrap_or(0)
    };
    while (datasets("runs") == 0 || datasets("abs") == 0) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!((datasets("runs"), datasets("abs")), (1, 1));
    assert!(!std::path::Path::new("/tmp/echogym-escape").exists());
    drop(connection);
    drop(server);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn one_client_cannot_take_the_whole_server() {
    let server = TestServer::start_in(
        "isolation-quota",
        common::fresh_location(),
        &[
            "--max-leases",
            "6",
            "--max-leases-per-client",
            "3",
            "--max-envs-per-client",
            "10",
        ],
    );
    let greedy = server.connect();
    let mut held: Vec<_> = (0..3)
        .map(|_| attach_null(&greedy, 2, serde_json::json!({}), AutoresetMode::Disabled))
        .collect();
    let refusal = |result: Result<echogym_client::Lease, ControlCallError>| match result {
        Err(ControlCallError::Refused { kind, message }) => {
            assert_eq!(kind, echogym_protocol::ControlErrorKind::CapacityExceeded);
            message
        }
        Err(other) => panic!("expected a capacity refusal, got {other}"),
        Ok(_) => panic!("attach beyond the client's quota accepted"),
    };
    let null = |num_envs| AttachOptions {
        env_id: "echogym/Null-v0".into(),
        num_envs,
        config: serde_json::Map::new(),
        autoreset_mode: AutoresetMode::Disabled,
    };
    let message = refusal(greedy.attach(&null(1)));
    assert!(message.contains("max_leases_per_client"), "{message}");
    held.pop();
    let message = refusal(greedy.attach(&null(7)));
    assert!(message.contains("max_envs_per_client"), "{message}");
    held.push(greedy.attach(&null(4)).expect("within the quota"));

    // Another client still gets its share.
    let polite = server.connect();
    let mut lease = attach_null(&polite, 2, serde_json::json!({}), AutoresetMode::Disabled);
    lease.reset(None, None).expect("reset");
    // `status` names each lease's owner process.
    let now = status(&polite);
    assert_eq!(now.leases.len(), 4);
    assert!(
        now.leases
            .iter()
            .all(|l| l.client_pid == Some(std::process::id())),
        "{:?}",
        now.leases
    );
    drop((lease, held, polite, greedy));
}

#[test]
fn shared_memory_is_budgeted_per_client_and_per_server() {
    // A Null env with 4,096 float32 observations: 16 KiB per env per sample, so 64 envs
    // preallocate ≈ 6 MiB over their six observation samples.
    let server = TestServer::start_in(
        "isolation-shm",
        common::fresh_location(),
        &[
            "--max-shm-bytes-per-client",
            &(8u64 << 20).to_string(),
            "--max-shm-bytes",
            &(14u64 << 20).to_string(),
        ],
    );
    let wide = |num_envs| AttachOptions {
        env_id: "echogym/Null-v0".into(),
        num_envs,
        config: serde_json::json!({"obs_size": 4096})
            .as_object()
            .cloned()
            .unwrap(),
        autoreset_mode: AutoresetMode::Disabled,
    };
    let refusal = |result: Result<echogym_client::Lease, ControlCallError>| match result {
        Err(ControlCallError::Refused { kind, message }) => {
            assert_eq!(kind, echogym_protocol::ControlErrorKind::CapacityExceeded);
            message
        }
        Err(other) => panic!("expected a capacity refusal, got {other}"),
        Ok(_) => panic!("attach beyond the shared-memory budget accepted"),
    };
    let first = server.connect();
    let mut held = first.attach(&wide(64)).expect("within the budget");
    held.reset(None, None).expect("reset");
    let message = refusal(first.attach(&wide(32)));
    assert!(message.contains("max_shm_bytes_per_client"), "{message}");
    // Another client gets its own budget, until the server's is spent.
    let second = server.connect();
    let mut other = second.attach(&wide(64)).expect("its own budget");
    other.reset(None, None).expect("reset");
    let third = server.connect();
    let message = refusal(third.attach(&wide(64)));
    assert!(message.contains("server's max_shm_bytes of"), "{message}");
    // Small leases still fit, and the refused ones left nothing behind.
    let mut small = attach_null(&third, 2, serde_json::json!({}), AutoresetMode::Disabled);
    small.reset(None, None).expect("reset");
    assert_eq!(status(&third).leases.len(), 3);
    drop((small, other, held, third, second, first));
}

#[test]
fn only_the_attaching_client_can_detach_a_lease() {
    let server = TestServer::start_in("isolation-owner", common::fresh_location(), &[]);
    let owner = server.connect();
    let mut lease = attach_null(&owner, 2, serde_json::json!({}), AutoresetMode::Disabled);
    lease.reset(None, None).expect("reset");
    let lease_id = status(&owner).leases[0].lease_id;

    // Another client (same user) naming the lease, with its own node id or none.
    let intruder = server.connect();
    for node in [intruder.node_id().to_string(), String::new()] {
        let request = ControlRequest::Detach {
            lease_id,
            client_node_id: node,
        };
        match intruder.request(&request) {
            Err(ControlCallError::Refused { kind, message }) => {
                assert_eq!(kind, echogym_protocol::ControlErrorKind::NotOwner);
                assert!(message.contains(&lease_id.to_string()), "{message}");
            }
            other => panic!("a stranger's detach was not refused: {other:?}"),
        }
    }
    // The owner's lease is untouched and still steps; its own detach works.
    lease.reset(None, None).expect("the lease survived");
    assert_eq!(status(&owner).leases.len(), 1);
    lease.close();
    assert!(status(&owner).leases.is_empty());
}

#[test]
fn an_oversized_control_request_is_refused_unparsed() {
    let server = TestServer::start_in("isolation-big-request", common::fresh_location(), &[]);
    let connection = server.connect();
    let mut config = serde_json::Map::new();
    config.insert("pad".into(), serde_json::Value::String("x".repeat(2 << 20)));
    let request = ControlRequest::Attach(echogym_protocol::AttachRequest {
        env_id: "echogym/Null-v0".into(),
        num_envs: 1,
        config,
        autoreset_mode: AutoresetMode::Disabled,
        client_node_id: connection.node_id().to_string(),
        client_label: String::new(),
    });
    match connection.request(&request) {
        Err(ControlCallError::Refused { kind, message }) => {
            assert_eq!(kind, echogym_protocol::ControlErrorKind::InvalidRequest);
            assert!(message.contains("bytes refused"), "{message}");
        }
        other => panic!("a 2 MiB request was not refused: {other:?}"),
    }
    // The server serves on.
    let mut lease = attach_null(
        &connection,
        1,
        serde_json::json!({}),
        AutoresetMode::Disabled,
    );
    lease.reset(None, None).expect("reset");
}

/// Control replies the server preallocates (`CONTROL_RESPONSES` in `server/src/transport/reply.rs`).
const CONTROL_RESPONSES: usize = 64;

/// A raw iceoryx2 control client of a server (none of echogym's client code): it sends
/// any bytes as a request, with a correct header.
struct RawControl {
    control: echogym_protocol::services::ControlService<iceoryx2::prelude::ipc_threadsafe::Service>,
    wake: iceoryx2::port::notifier::Notifier<iceoryx2::prelude::ipc_threadsafe::Service>,
    _node: iceoryx2::node::Node<iceoryx2::prelude::ipc_threadsafe::Service>,
}

type RawClient = iceoryx2::port::client::Client<
    iceoryx2::prelude::ipc_threadsafe::Service,
    [u8],
    echogym_protocol::ControlHeader,
    [u8],
    echogym_protocol::ControlHeader,
>;
type RawPending = iceoryx2::pending_response::PendingResponse<
    iceoryx2::prelude::ipc_threadsafe::Service,
    [u8],
    echogym_protocol::ControlHeader,
    [u8],
    echogym_protocol::ControlHeader,
>;

impl RawControl {
    fn open(server: &TestServer) -> Self {
        use echogym_protocol::ServiceNames;
        use echogym_protocol::services::{Access, MAX_CLIENTS, control_service, event_service};
        use iceoryx2::prelude::*;
        let names = ServiceNames::new(&server.name).unwrap();
        let config = server.location.iceoryx_config().unwrap();
        let node = NodeBuilder::new()
            .config(&config)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc_threadsafe::Service>()
            .unwrap();
        let control = control_service(&node, &names.control(), Access::Open).unwrap();
        let wake = event_service(&node, &names.wake(), MAX_CLIENTS, Access::Open).unwrap();
        let wake = wake.notifier_builder().create().unwrap();
        Self {
            control,
            wake,
            _node: node,
        }
    }

    /// A client port of its own.
    fn client(&self) -> RawClient {
        use iceoryx2::prelude::*;
        self.control
            .client_builder()
            .initial_max_slice_len(4096)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .unwrap()
    }

    /// Send `bytes` as a request through `client` and wake the server.
    fn send(&self, client: &RawClient, bytes: &[u8]) -> RawPending {
        let mut request = client.loan_slice_uninit(bytes.len()).unwrap();
        *request.user_header_mut() = echogym_protocol::ControlHeader {
            protocol_version: echogym_protocol::PROTOCOL_VERSION,
            payload_len: bytes.len() as u32,
        };
        let pending = request.write_from_slice(bytes).send().unwrap();
        self.wake.notify().unwrap();
        pending
    }
}

/// The reply to `pending`, calling `meanwhile` while it is not in (at most 30 s).
fn raw_reply(pending: &RawPending, what: &str, mut meanwhile: impl FnMut()) -> ControlReply {
    let started = Instant::now();
    loop {
        if let Some(response) = pending.receive().unwrap() {
            let len = (response.user_header().payload_len as usize).min(response.payload().len());
            return serde_json::from_slice(&response.payload()[..len])
                .unwrap_or_else(|e| panic!("{what}: an unparsable reply: {e}"));
        }
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "{what}: no reply in 30 s"
        );
        meanwhile();
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn clients_that_never_take_their_replies_do_not_block_the_others() {
    // More raw clients than the server has reply samples send a request each and never
    // take the reply (stopped or malicious processes). The server lives; the requests
    // that find no free reply sample are answered as soon as the stuck clients go away.
    // (With iceoryx2's growable reply segment and fewer slots, the server panicked here.)
    let mut server = TestServer::start_in("isolation-stuck", common::fresh_location(), &[]);
    let raw = RawControl::open(&server);
    let text = serde_json::to_vec(&ControlRequest::Status).unwrap();
    let mut stuck = Vec::new();
    for _ in 0..3 * CONTROL_RESPONSES {
        let client = raw.client();
        let pending = raw.send(&client, &text);
        stuck.push((client, pending)); // never received
    }
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        server.child.as_mut().unwrap().try_wait().unwrap().is_none(),
        "the server died"
    );
    // A well-behaved client's request waits for a free reply sample ...
    let asking = {
        let options = server.options();
        std::thread::spawn(move || {
            let connection = Connection::connect(&options).expect("connect");
            let started = Instant::now();
            assert!(status(&connection).leases.is_empty());
            started.elapsed()
        })
    };
    std::thread::sleep(Duration::from_millis(500));
    // ... which the stuck clients free when they go away.
    drop(stuck);
    let waited = asking.join().expect("the status request was answered");
    assert!(waited < Duration::from_secs(10), "{waited:?}");
    // Every reply sample is usable again.
    let connection = server.connect();
    for _ in 0..2 * CONTROL_RESPONSES {
        status(&connection);
    }
    drop(raw);
}

#[test]
fn clients_going_away_do_not_stall_a_bystander() {
    // 20 clients connect, ask for the status and go away while a bystander steps. Each
    // disconnection made the server sweep its reply bookkeeping on the dispatcher: one
    // flag per reply slot, per channel, per possible segment (18 M flags with iceoryx2's
    // defaults for 512 clients: 125–180 ms on a 2-core VM), a stall of every lease after
    // every client that left; now a few hundred flags.
    let server = TestServer::start_in("isolation-disconnect", common::fresh_location(), &[]);
    let connection = server.connect();
    let mut bystander = reset_bystander(&connection);
    let done = Arc::new(AtomicBool::new(false));
    let churn = {
        let (options, done) = (server.options(), done.clone());
        std::thread::spawn(move || {
            for _ in 0..20 {
                let client = Connection::connect(&options).expect("connect");
                status(&client);
                drop(client);
                std::thread::sleep(Duration::from_millis(50));
            }
            done.store(true, Ordering::SeqCst);
        })
    };
    let mut latencies = Vec::new();
    while !done.load(Ordering::SeqCst) {
        let started = Instant::now();
        bystander.step(&[0.0; 7], None).expect("step");
        latencies.push(started.elapsed());
        std::thread::sleep(Duration::from_micros(500));
    }
    churn.join().expect("churn");
    latencies.sort();
    let slow = latencies
        .iter()
        .filter(|&&l| l > Duration::from_millis(50))
        .count();
    eprintln!(
        "bystander: {} steps beside 20 disconnections, {slow} over 50 ms, slowest {:?}",
        latencies.len(),
        latencies.last().copied().unwrap_or_default()
    );
    // Generous for a loaded machine (a stall per disconnection would be ≈ 20).
    assert!(slow < 5, "{slow} bystander steps over 50 ms");
}

/// Median step latency of a medium lease (4 `Null-v0` envs burning 150 µs each: above
/// the dispatcher's 100 µs inline budget) while two slow leases (`Faulty-v0`, 200 ms a
/// step) keep both pool workers busy; `extra` are the server's flags.
fn medium_beside_big(name: &str, extra: &[&str]) -> Duration {
    let mut flags = vec!["--fault-injection"];
    flags.extend_from_slice(extra);
    let server = TestServer::start_in(name, common::fresh_location(), &flags);
    let connection = server.connect();
    let mut medium = attach_null(
        &connection,
        4,
        serde_json::json!({"step_cost_us": 150.0}),
        AutoresetMode::SameStep,
    );
    medium.reset(None, None).expect("reset");
    for _ in 0..5 {
        medium.step(&[0.0; 28], None).expect("step"); // its cost is measured
    }
    let stop = Arc::new(AtomicBool::new(false));
    let slow: Vec<_> = (0..2)
        .map(|index| {
            let (options, stop) = (server.options(), stop.clone());
            std::thread::spawn(move || {
                let connection = Connection::connect(&options).expect("connect");
                let mut lease = slow_lease(
                    &connection,
                    serde_json::json!({"stall_ms": 200, "env_index": index}),
                );
                while !stop.load(Ordering::SeqCst) {
                    lease.step(&[0.0], None).expect("slow step");
                }
            })
        })
        .collect();
    std::thread::sleep(Duration::from_millis(500)); // both slow leases step
    let mut latencies: Vec<Duration> = (0..20)
        .map(|_| {
            let started = Instant::now();
            medium.step(&[0.0; 28], None).expect("step");
            let elapsed = started.elapsed();
            std::thread::sleep(Duration::from_millis(10));
            elapsed
        })
        .collect();
    stop.store(true, Ordering::SeqCst);
    for thread in slow {
        thread.join().expect("slow client");
    }
    latencies.sort();
    latencies[latencies.len() / 2]
}

#[test]
fn a_medium_exchange_does_not_queue_behind_big_ones() {
    // Before the medium lane, the medium exchange queued on the pool behind the slow
    // ones (median ≈ 100–200 ms); on the lane it takes about its own cost. (With
    // `--lane-budget-us 0`, the old routing, this fails: checked by hand.)
    let median = medium_beside_big("isolation-medium", &[]);
    eprintln!("medium lease beside two 200 ms exchanges: median step {median:?}");
    // Generous for a loaded machine: its own cost is 0.6 ms.
    assert!(median < Duration::from_millis(50), "median {median:?}");
}

#[test]
fn every_corpus_control_request_gets_a_typed_answer_and_the_server_serves_on() {
    // The corpus's raw control requests (tests/data/fuzz_corpus/control_*.bin: hostile
    // env counts, malformed, truncated, deeply nested, invalid UTF-8, ...) sent by a raw
    // iceoryx2 client, each with a correct header: each gets a reply that parses, and a
    // refusal where the request is not a valid one; a bystander steps throughout.
    let server = TestServer::start_in("isolation-corpus", common::fresh_location(), &[]);
    let connection = server.connect();
    let mut bystander = reset_bystander(&connection);
    let raw = RawControl::open(&server);
    let client = raw.client();
    let files = common::corpus("control_");
    assert!(files.len() >= 10, "the corpus is missing");
    for (name, bytes) in &files {
        let pending = raw.send(&client, bytes);
        let reply = raw_reply(&pending, name, || {
            bystander
                .step(&[0.0; 7], None)
                .expect("the bystander steps");
        });
        let valid = serde_json::from_slice::<ControlRequest>(bytes).is_ok();
        eprintln!(
            "{name}: {}",
            serde_json::to_string(&reply)
                .unwrap_or_default()
                .chars()
                .take(160)
                .collect::<String>()
        );
        match &reply {
            ControlReply::Error(e) => {
                assert!(!e.message.is_empty(), "{name}: an empty refusal");
                // A refusal quotes at most a screenful of the request.
                assert!(
                    e.message.len() < 4096,
                    "{name}: a refusal of {} bytes",
                    e.message.len()
                );
            }
            other => assert!(valid, "{name}: an invalid request was answered {other:?}"),
        }
        if name.starts_with("control_attach_65536") {
            // Beyond the client's quota on its own: refused naming the quota, not the
            // server's limit.
            let text = serde_json::to_string(&reply).unwrap_or_default();
            assert!(text.contains("max_envs_per_client"), "{text}");
        }
    }
    // An op name of 500 kB (serde quotes an unknown variant) is not echoed back whole.
    let huge = format!("{{\"op\": \"{}\"}}", "x".repeat(500_000));
    let pending = raw.send(&client, huge.as_bytes());
    match raw_reply(&pending, "a 500 kB op", || {}) {
        ControlReply::Error(e) => assert!(e.message.len() < 4096, "{} bytes", e.message.len()),
        other => panic!("an unknown op was answered {other:?}"),
    }
    // The server serves on: the bystander steps, a status answers, nothing was leased.
    bystander
        .step(&[0.0; 7], None)
        .expect("the bystander steps");
    assert_eq!(status(&connection).leases.len(), 1);
    drop((client, raw));
}
