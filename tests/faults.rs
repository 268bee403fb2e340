//! No env fault reaches the daemon: panics injected in construction, reset, step and
//! drop (`echogym/Faulty-v0`, registered by `serve --fault-injection`) end in a typed
//! error for the client concerned, while a bystander keeps stepping and the server
//! still stops cleanly. Real server process, real clients.

mod common;

use common::{TestServer, attach_null, fresh_location};
use echogym_client::{AttachOptions, Connection, ControlCallError, Lease, LeaseError};
use echogym_protocol::{AutoresetMode, ControlErrorKind, ControlReply, ControlRequest};

fn faulty(
    connection: &Connection,
    num_envs: usize,
    config: serde_json::Value,
) -> Result<Lease, ControlCallError> {
    connection.attach(&AttachOptions {
        env_id: "echogym/Faulty-v0".into(),
        num_envs,
        config: config.as_object().cloned().unwrap_or_default(),
        autoreset_mode: AutoresetMode::Disabled,
    })
}

/// The bystander's lease still steps and echoes its action.
fn bystander_steps(lease: &mut Lease, tag: f32) {
    let payload = lease
        .step(&[tag; 7], None)
        .expect("bystander step")
        .to_vec();
    let obs = common::null_obs(lease, &payload, 0);
    assert_eq!(obs[1], tag, "{obs:?}");
}

#[test]
fn panics_in_make_reset_step_and_drop_are_contained() {
    let mut server = TestServer::start_in("faults", fresh_location(), &["--fault-injection"]);
    let connection = server.connect();
    let mut bystander = attach_null(
        &connection,
        1,
        serde_json::json!({}),
        AutoresetMode::Disabled,
    );
    bystander.reset(None, None).expect("bystander reset");
    // Faulty envs are numbered over the server's life: `next` is the next one's index.
    let mut next = 0usize;

    // make: the third env of four panics while being built.
    match faulty(
        &connection,
        4,
        serde_json::json!({"panic_in": "make", "env_index": next + 2}),
    ) {
        Err(ControlCallError::Refused { kind, message }) => {
            assert_eq!(kind, ControlErrorKind::Internal);
            assert!(message.contains("env 2 of the batch panicked"), "{message}");
        }
        Err(other) => panic!("expected a refusal, got {other}"),
        Ok(_) => panic!("a batch whose construction panicked was attached"),
    }
    next += 3;
    bystander_steps(&mut bystander, 0.1);

    // reset: env 1 of 2 panics in reset; the reset reports it and the lease lives.
    let mut lease = faulty(
        &connection,
        2,
        serde_json::json!({"panic_in": "reset", "env_index": next + 1}),
    )
    .expect("attach");
    next += 2;
    match lease.reset(None, None) {
        Err(LeaseError::EnvFailure { env }) => assert_eq!(env, 1),
        other => panic!("expected EnvFailure of env 1, got {other:?}"),
    }
    bystander_steps(&mut bystander, 0.2);
    drop(lease);

    // step: env 0 panics at its 3rd step.
    let mut lease = faulty(
        &connection,
        3,
        serde_json::json!({"panic_in": "step", "env_index": next, "at_step": 3}),
    )
    .expect("attach");
    next += 3;
    lease.reset(None, None).expect("reset");
    lease.step(&[0.0; 3], None).expect("step 1");
    lease.step(&[0.0; 3], None).expect("step 2");
    match lease.step(&[0.0; 3], None) {
        Err(LeaseError::EnvFailure { env }) => assert_eq!(env, 0),
        other => panic!("expected EnvFailure of env 0, got {other:?}"),
    }
    bystander_steps(&mut bystander, 0.3);
    drop(lease);

    // drop: env 1 panics while being dropped, on detach.
    let mut lease = faulty(
        &connection,
        2,
        serde_json::json!({"panic_in": "drop", "env_index": next + 1}),
    )
    .expect("attach");
    lease.reset(None, None).expect("reset");
    lease.close();
    drop(lease);
    bystander_steps(&mut bystander, 0.4);
    let status = connection.request(&ControlRequest::Status).expect("status");
    let ControlReply::Status(status) = status else {
        panic!("unexpected {status:?}")
    };
    assert_eq!(
        status.leases.len(),
        1,
        "the detached lease is gone, the bystander's held"
    );

    // And once more at shutdown: a lease whose env panics in drop is held at SIGTERM.
    let mut held = faulty(
        &connection,
        1,
        serde_json::json!({"panic_in": "drop", "env_index": next + 2}),
    )
    .expect("attach");
    held.reset(None, None).expect("reset");
    server.signal("TERM");
    assert_eq!(
        server.wait(),
        Some(0),
        "the server exits 0 despite the panicking drop"
    );
    assert!(matches!(
        held.step(&[0.0], None),
        Err(LeaseError::ServerStopped)
    ));
    drop((held, bystander, connection));
    common::assert_clean_and_remove(&server.location);
}

#[test]
fn a_step_past_its_deadline_ends_in_a_typed_error() {
    let server = TestServer::start_in("deadline", fresh_location(), &["--fault-injection"]);
    let impatient = Connection::connect(&echogym_client::ConnectOptions {
        step_timeout: std::time::Duration::from_millis(300),
        ..server.options()
    })
    .expect("connect");
    let mut lease = faulty(&impatient, 1, serde_json::json!({"stall_ms": 2000})).expect("attach");
    lease.reset(None, None).expect("reset");
    let started = std::time::Instant::now();
    match lease.step(&[0.0], None) {
        Err(LeaseError::Timeout(_)) => {}
        other => panic!("expected a timeout, got {other:?}"),
    }
    assert!(started.elapsed() < std::time::Duration::from_secs(1));
    assert!(matches!(
        lease.step(&[0.0], None),
        Err(LeaseError::Timeout(_))
    ));
    // The server lives and serves others once the stalled step is over (a slow batch
    // still delays other leases' exchanges while it runs: exchanges are not yet
    // dispatched asynchronously).
    let other = server.connect();
    let mut bystander = attach_null(&other, 1, serde_json::json!({}), AutoresetMode::Disabled);
    bystander.reset(None, None).expect("reset");
    bystander_steps(&mut bystander, 0.5);
    drop((lease, bystander, other, impatient));
}

#[test]
fn a_non_finite_step_is_truncated_flagged_and_counted() {
    let server = TestServer::start_in("faults-nan", fresh_location(), &["--fault-injection"]);
    let connection = server.connect();
    // Two envs; the second (index 1 over the server's life) blows up at step 3.
    let mut lease = faulty(
        &connection,
        2,
        serde_json::json!({"env_index": 1, "nan_at_step": 3}),
    )
    .expect("attach");
    assert_eq!(lease.spec().info_keys, vec!["physics_error".to_owned()]);
    lease.reset(None, None).expect("reset");
    for step in 1..=3u64 {
        let payload = lease.step(&[0.0, 0.0], None).expect("step").to_vec();
        let layout = lease.layout().clone();
        for env in 0..2 {
            let obs = common::null_obs(&lease, &payload, env);
            assert!(
                obs.iter().all(|v| v.is_finite()),
                "NaN reached the client: {obs:?}"
            );
            let truncated = payload[layout.obs.truncated + env] != 0;
            let info: &[f32] = bytemuck::cast_slice(
                &payload[layout.obs.info + env * 4..layout.obs.info + env * 4 + 4],
            );
            let blew_up = env == 1 && step == 3;
            assert_eq!(truncated, blew_up, "env {env} step {step}");
            assert_eq!(
                info[0],
                if blew_up { 1.0 } else { 0.0 },
                "env {env} step {step}"
            );
            if blew_up {
                // The other observation values are kept; only the NaN is zeroed.
                assert_eq!(obs, vec![0.0, 1.0]);
            }
        }
    }
    // The blown-up env must be reset before it steps again; the other is untouched.
    match lease.step(&[0.0, 0.0], None) {
        Err(LeaseError::NeedsReset { env }) => assert_eq!(env, 1),
        other => panic!("expected NeedsReset for env 1, got {other:?}"),
    }
    let status = match connection.request(&ControlRequest::Status).expect("status") {
        ControlReply::Status(status) => status,
        other => panic!("{other:?}"),
    };
    assert_eq!(status.physics_errors, 1);
    assert_eq!(status.leases[0].physics_errors, 1);
}
