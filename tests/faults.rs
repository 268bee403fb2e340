//! No env fault reaches the daemon: panics injected in construction, reset, step and
//! drop (`echogym/Faulty-v0`, registered by `serve --fault-injection`) end in a typed
//! error (construction) or in that env alone being flagged `env_error`, truncated and
//! needing a reset while the other envs of its batch step on (reset, step), while a
//! bystander keeps stepping and the server still stops cleanly. Real server process,
//! real clients.

mod common;

use common::{TestServer, attach_null, fresh_location};
use echogym_client::{AttachOptions, Connection, ControlCallError, Lease, LeaseError};
use echogym_protocol::{
    AutoresetMode, ControlErrorKind, ControlReply, ControlRequest, ENV_ERROR_KEY, ResetFlag,
    ServerStatus,
};

fn faulty(
    connection: &Connection,
    num_envs: usize,
    config: serde_json::Value,
) -> Result<Lease, ControlCallError> {
    faulty_in(connection, num_envs, config, AutoresetMode::Disabled)
}

fn faulty_in(
    connection: &Connection,
    num_envs: usize,
    config: serde_json::Value,
    autoreset_mode: AutoresetMode,
) -> Result<Lease, ControlCallError> {
    connection.attach(&AttachOptions {
        env_id: "echogym/Faulty-v0".into(),
        num_envs,
        config: config.as_object().cloned().unwrap_or_default(),
        autoreset_mode,
    })
}

/// The info row of env `env` in `payload` (`final`: the `final_info` block).
fn info_row(lease: &Lease, payload: &[u8], env: usize, last: bool) -> Vec<f32> {
    let layout = lease.layout();
    let block = if last {
        layout.obs.final_info.expect("same-step layout")
    } else {
        layout.obs.info
    };
    let start = block + env * layout.info_len * 4;
    bytemuck::cast_slice::<u8, f32>(&payload[start..start + layout.info_len * 4]).to_vec()
}

/// The `env_error` value of env `env` in `payload`'s info (or `final_info`).
fn env_error(lease: &Lease, payload: &[u8], env: usize, last: bool) -> f32 {
    let key = lease
        .spec()
        .info_keys
        .iter()
        .position(|k| k == ENV_ERROR_KEY)
        .expect("every spec carries env_error");
    info_row(lease, payload, env, last)[key]
}

/// The `Faulty-v0` observation `[step in episode, env index]` of env `env` in the
/// `final_obs` block.
fn final_obs(lease: &Lease, payload: &[u8], env: usize) -> Vec<f32> {
    let layout = lease.layout();
    let start = layout.obs.final_obs.expect("same-step layout") + env * layout.obs_record_bytes;
    bytemuck::cast_slice::<u8, f32>(&payload[start..start + 8]).to_vec()
}

fn server_status(connection: &Connection) -> ServerStatus {
    match connection.request(&ControlRequest::Status).expect("status") {
        ControlReply::Status(status) => status,
        other => panic!("{other:?}"),
    }
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

    // reset: env 1 of 2 panics in reset; the reset returns env 0 and flags env 1,
    // which still needs a reset; the lease lives.
    let mut lease = faulty(
        &connection,
        2,
        serde_json::json!({"panic_in": "reset", "env_index": next + 1}),
    )
    .expect("attach");
    next += 2;
    let payload = lease.reset(None, None).expect("reset").to_vec();
    assert_eq!(lease.failed_envs(&payload), vec![1]);
    assert_eq!(
        common::null_obs(&lease, &payload, 0),
        vec![0.0, (next - 2) as f32]
    );
    assert_eq!(common::null_obs(&lease, &payload, 1), vec![0.0, 0.0]);
    match lease.step(&[0.0; 2], None) {
        Err(LeaseError::NeedsReset { env }) => assert_eq!(env, 1),
        other => panic!("expected NeedsReset of env 1, got {other:?}"),
    }
    bystander_steps(&mut bystander, 0.2);
    drop(lease);

    // step: env 0 panics at its 3rd step; the step returns the others.
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
    let payload = lease.step(&[0.0; 3], None).expect("step 3").to_vec();
    assert_eq!(lease.failed_envs(&payload), vec![0]);
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
    let status = server_status(&connection);
    assert_eq!(status.env_errors, 2, "one failed reset, one failed step");
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
    // The server lives and serves others while the stalled step still runs (its
    // exchange is on the worker pool, not on the dispatcher).
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
    assert_eq!(lease.spec().info_keys, ["physics_error", ENV_ERROR_KEY]);
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
            let info = info_row(&lease, &payload, env, false);
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
    let status = server_status(&connection);
    assert_eq!(status.physics_errors, 1);
    assert_eq!(status.leases[0].physics_errors, 1);
    assert_eq!(status.env_errors, 0);
}

/// Steps `1..=steps` of a 5-env `Faulty-v0` batch (autoreset disabled), env 2 of which
/// panics at step 3: every step returns, the other envs advance, env 2 is flagged.
fn step_through_a_failure(lease: &mut Lease) {
    let (k, failing) = (5, 2);
    for step in 1..=3u64 {
        let payload = lease
            .step(&[0.25; 5], None)
            .expect("the step returns")
            .to_vec();
        let layout = lease.layout().clone();
        let failed = step == 3;
        assert_eq!(
            lease.failed_envs(&payload),
            if failed { vec![failing] } else { vec![] },
            "step {step}"
        );
        for env in 0..k {
            let obs = common::null_obs(lease, &payload, env);
            let truncated = payload[layout.obs.truncated + env];
            let flag = env_error(lease, &payload, env, false);
            if failed && env == failing {
                assert_eq!(obs, vec![0.0, 0.0], "a failed env's observation is zeroed");
                assert_eq!((truncated, flag), (1, 1.0), "flagged and truncated");
            } else {
                assert_eq!(obs, vec![step as f32, env as f32], "env {env} step {step}");
                assert_eq!((truncated, flag), (0, 0.0), "env {env} step {step}");
            }
        }
    }
}

#[test]
fn one_env_failing_in_a_batch_fails_alone() {
    let server = TestServer::start_in("faults-partial", fresh_location(), &["--fault-injection"]);
    let connection = server.connect();
    let (k, failing) = (5usize, 2usize);
    let mut lease = faulty(
        &connection,
        k,
        serde_json::json!({"panic_in": "step", "env_index": failing, "at_step": 3}),
    )
    .expect("attach");
    lease.reset(None, None).expect("reset");
    step_through_a_failure(&mut lease);

    // The failed env must be reset before it steps again; the others are untouched.
    match lease.step(&[0.0; 5], None) {
        Err(LeaseError::NeedsReset { env }) => assert_eq!(env, failing),
        other => panic!("expected NeedsReset for env {failing}, got {other:?}"),
    }
    // Reset it within a step: it restarts, the others advance, and the lease steps on.
    let mut flags = vec![ResetFlag::Keep as u8; k];
    flags[failing] = ResetFlag::Reset as u8;
    let payload = lease.step(&[0.0; 5], Some(&flags)).expect("step").to_vec();
    assert!(lease.failed_envs(&payload).is_empty());
    for env in 0..k {
        let want = if env == failing { 0.0 } else { 4.0 };
        assert_eq!(
            common::null_obs(&lease, &payload, env),
            vec![want, env as f32]
        );
    }
    for step in 1..=2u64 {
        let payload = lease.step(&[0.0; 5], None).expect("step").to_vec();
        for env in 0..k {
            let want = if env == failing { step } else { 4 + step };
            assert_eq!(
                common::null_obs(&lease, &payload, env),
                vec![want as f32, env as f32]
            );
        }
    }
    let status = server_status(&connection);
    assert_eq!(status.env_errors, 1);
    assert_eq!(status.leases[0].env_errors, 1);
    let cli = server.cli(&["status", "--name", &server.name]);
    let text = String::from_utf8_lossy(&cli.stdout);
    assert!(text.contains("1 env errors"), "{text}");
}

#[test]
fn a_failed_env_is_reset_in_the_same_step_with_same_step_autoreset() {
    let server = TestServer::start_in("faults-autoreset", fresh_location(), &["--fault-injection"]);
    let connection = server.connect();
    let (k, failing) = (4usize, 1usize);
    let mut lease = faulty_in(
        &connection,
        k,
        serde_json::json!({"panic_in": "step", "env_index": failing, "at_step": 2}),
        AutoresetMode::SameStep,
    )
    .expect("attach");
    lease.reset(None, None).expect("reset");
    lease.step(&[0.0; 4], None).expect("step 1");
    let payload = lease.step(&[0.0; 4], None).expect("step 2").to_vec();
    let layout = lease.layout().clone();
    assert_eq!(lease.failed_envs(&payload), vec![failing]);
    for env in 0..k {
        let truncated = payload[layout.obs.truncated + env];
        if env == failing {
            // Restarted at once; the failed step's (zeroed) row is the final one.
            assert_eq!(
                common::null_obs(&lease, &payload, env),
                vec![0.0, env as f32]
            );
            assert_eq!(final_obs(&lease, &payload, env), vec![0.0, 0.0]);
            assert_eq!(env_error(&lease, &payload, env, true), 1.0);
            assert_eq!(truncated, 1);
        } else {
            assert_eq!(
                common::null_obs(&lease, &payload, env),
                vec![2.0, env as f32]
            );
            assert_eq!(
                (truncated, env_error(&lease, &payload, env, false)),
                (0, 0.0)
            );
        }
    }
    // No reset asked for: the lease steps on, the failed env one step into its new episode.
    let payload = lease.step(&[0.0; 4], None).expect("step 3").to_vec();
    assert!(lease.failed_envs(&payload).is_empty());
    assert_eq!(
        common::null_obs(&lease, &payload, failing),
        vec![1.0, failing as f32]
    );
    assert_eq!(common::null_obs(&lease, &payload, 0), vec![3.0, 0.0]);
}
