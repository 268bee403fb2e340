//! The step/reset exchange, end to end over real shared memory: data integrity with many
//! client processes attaching, stepping and detaching at once; every bad input gets a
//! typed error, changes nothing and leaves the server serving others; same-step and
//! disabled autoreset; seeded determinism; parallel stepping of expensive batches.

mod common;

use std::time::Duration;

use common::*;
use echogym_client::{ConnectOptions, Connection, ControlCallError, LeaseError};
use echogym_protocol::{
    AttachRequest, AutoresetMode, ControlErrorKind, ControlReply, ControlRequest,
};
use serde_json::json;

/// Step `lease` (Null env, action size 7) `steps` times checking that every observation
/// echoes its own action and counts steps; `tag` makes actions unique per caller.
fn step_and_verify(lease: &mut echogym_client::Lease, steps: usize, tag: f32) {
    let k = lease.num_envs();
    for step in 1..=steps {
        let actions: Vec<f32> = (0..k * 7)
            .map(|i| ((tag * 1000.0 + step as f32 * 10.0 + i as f32) % 1000.0) / 1000.0)
            .collect();
        let payload = lease.step(&actions, None).unwrap().to_vec();
        for env in 0..k {
            let obs = null_obs(lease, &payload, env);
            assert_eq!(obs[0], step as f32, "step counter of env {env}");
            assert_eq!(
                &obs[1..8],
                &actions[env * 7..env * 7 + 7],
                "echo of env {env}"
            );
        }
    }
}

/// Child process body: rounds of attach → reset → step/verify → detach.
#[test]
#[ignore = "run as a child process by the exchange tests"]
fn child_integrity_rounds() {
    let Ok(name) = std::env::var("EG_CHILD_SERVER") else {
        return;
    };
    let tag: f32 = std::env::var("EG_CHILD_TAG").unwrap().parse().unwrap();
    let options = ConnectOptions {
        name,
        location: echogym_protocol::IpcLocation {
            prefix: std::env::var("EG_CHILD_PREFIX").unwrap(),
            root: std::env::var("EG_CHILD_ROOT").unwrap().into(),
        },
        ..ConnectOptions::default()
    };
    let connection = Connection::connect(&options).unwrap();
    for round in 0..4 {
        let k = 1 + (tag as usize + round) % 8;
        let mut lease = attach_null(
            &connection,
            k,
            json!({"max_episode_steps": null}),
            AutoresetMode::Disabled,
        );
        lease.reset(None, None).unwrap();
        step_and_verify(&mut lease, 150, tag + round as f32);
        lease.close();
    }
}

#[test]
fn many_processes_interleaved_keep_every_observation_intact() {
    let server = TestServer::start("crowd");
    let children: Vec<_> = (0..8)
        .map(|i| {
            spawn_self(
                "child_integrity_rounds",
                &[
                    ("EG_CHILD_SERVER", server.name.clone()),
                    ("EG_CHILD_PREFIX", server.location.prefix.clone()),
                    ("EG_CHILD_ROOT", server.location.root.display().to_string()),
                    ("EG_CHILD_TAG", i.to_string()),
                ],
            )
        })
        .collect();
    let connection = server.connect();
    let mut mine = attach_null(
        &connection,
        16,
        json!({"max_episode_steps": null}),
        AutoresetMode::Disabled,
    );
    mine.reset(None, None).unwrap();
    step_and_verify(&mut mine, 300, 42.0);
    for child in children {
        let output = child.wait_with_output().unwrap();
        assert!(
            output.status.success(),
            "child failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    mine.close();
    match connection.request(&ControlRequest::Status).unwrap() {
        ControlReply::Status(status) => {
            assert!(
                status.leases.is_empty(),
                "leaked leases: {:?}",
                status.leases
            );
            assert!(status.env_steps >= 16 * 300);
        }
        other => panic!("{other:?}"),
    }
}

fn refused_kind(
    result: Result<impl std::fmt::Debug, ControlCallError>,
) -> (ControlErrorKind, String) {
    match result {
        Err(ControlCallError::Refused { kind, message }) => (kind, message),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn bad_inputs_get_typed_errors_and_lose_nothing() {
    let server = TestServer::start("strict");
    let connection = server.connect();
    let mut bystander = attach_null(&connection, 2, json!({}), AutoresetMode::SameStep);
    bystander.reset(None, None).unwrap();

    // Control-plane refusals.
    let attach = |env_id: &str, num_envs: usize, config: serde_json::Value| {
        connection.attach(&echogym_client::AttachOptions {
            env_id: env_id.into(),
            num_envs,
            config: config.as_object().cloned().unwrap(),
            autoreset_mode: AutoresetMode::Disabled,
        })
    };
    let (kind, message) = refused_kind(attach("echogym/Nope-v9", 1, json!({})));
    assert_eq!(kind, ControlErrorKind::UnknownEnv);
    assert!(
        message.contains("echogym/Null-v0"),
        "lists known ids: {message}"
    );
    let (kind, message) = refused_kind(attach("echogym/Null-v0", 1, json!({"obs_sise": 3})));
    assert_eq!(kind, ControlErrorKind::InvalidConfig);
    assert!(message.contains("obs_sise"), "{message}");
    let (kind, message) = refused_kind(attach("echogym/Null-v0", 1, json!({"obs_size": 0})));
    assert_eq!(kind, ControlErrorKind::InvalidConfig);
    assert!(message.contains("`obs_size`"), "{message}");
    let (kind, _) = refused_kind(attach("echogym/Null-v0", 0, json!({})));
    assert_eq!(kind, ControlErrorKind::InvalidRequest);
    let (kind, message) =
        refused_kind(connection.request_with_version(999, &ControlRequest::Status));
    assert_eq!(kind, ControlErrorKind::VersionMismatch);
    assert!(message.contains("999"), "{message}");
    let (kind, _) = refused_kind(connection.request(&ControlRequest::Detach {
        lease_id: 12345,
        client_node_id: connection.node_id().to_string(),
    }));
    assert_eq!(kind, ControlErrorKind::UnknownLease);
    let bad_node = ControlRequest::Attach(AttachRequest {
        env_id: "echogym/Null-v0".into(),
        num_envs: 1,
        config: Default::default(),
        autoreset_mode: AutoresetMode::Disabled,
        client_node_id: "not-a-node".into(),
        client_label: String::new(),
    });
    assert_eq!(
        refused_kind(connection.request(&bad_node)).0,
        ControlErrorKind::InvalidRequest
    );

    // Step-path refusals: each leaves the lease usable and its envs untouched.
    let mut lease = attach_null(&connection, 3, json!({}), AutoresetMode::Disabled);
    assert_eq!(
        lease.step(&[0.0; 21], None).unwrap_err(),
        LeaseError::NeedsReset { env: 0 }
    );
    lease.reset(None, None).unwrap();
    lease.step(&[0.1; 21], None).unwrap();
    assert!(matches!(
        lease.step(&[0.0; 20], None).unwrap_err(),
        LeaseError::ActionShape {
            got: 20,
            expected: 21,
            ..
        }
    ));
    let mut nan = vec![0.2; 21];
    nan[7 + 3] = f32::NAN;
    assert_eq!(
        lease.step(&nan, None).unwrap_err(),
        LeaseError::NonFiniteAction { env: 1, element: 3 }
    );
    let mut inf = vec![0.2; 21];
    inf[20] = f32::INFINITY;
    assert_eq!(
        lease.step(&inf, None).unwrap_err(),
        LeaseError::NonFiniteAction { env: 2, element: 6 }
    );
    let payload = lease.step(&[0.4; 21], None).unwrap().to_vec();
    for env in 0..3 {
        assert_eq!(
            null_obs(&lease, &payload, env)[0],
            2.0,
            "refused steps did not count"
        );
    }
    // Out-of-range actions are clipped to the bounds, not refused.
    let payload = lease.step(&[5.0; 21], None).unwrap().to_vec();
    assert_eq!(null_obs(&lease, &payload, 0)[1], 1.0);
    assert!(matches!(
        lease.reset(Some(&[true]), None).unwrap_err(),
        LeaseError::BadReset(_)
    ));

    bystander
        .step(&[0.9; 14], None)
        .expect("the other lease is unaffected");
    lease.close();
    assert_eq!(
        lease.step(&[0.0; 21], None).unwrap_err(),
        LeaseError::Closed
    );
}

#[test]
fn same_step_autoreset_reports_the_final_observation() {
    let server = TestServer::start("samestep");
    let mut lease = attach_null(
        &server.connect(),
        2,
        json!({"max_episode_steps": 3}),
        AutoresetMode::SameStep,
    );
    lease.reset(None, None).unwrap();
    lease.step(&[0.0; 14], None).unwrap();
    lease.step(&[0.0; 14], None).unwrap();
    let payload = lease.step(&[0.5; 14], None).unwrap().to_vec();
    let layout = lease.layout().clone();
    assert_eq!(
        &payload[layout.obs.truncated..layout.obs.truncated + 2],
        &[1, 1]
    );
    assert_eq!(
        &payload[layout.obs.terminated..layout.obs.terminated + 2],
        &[0, 0]
    );
    assert_eq!(
        null_obs(&lease, &payload, 0)[0],
        0.0,
        "new episode already started"
    );
    let final_obs = layout.obs.final_obs.unwrap();
    let final_counter: f32 = bytemuck::cast_slice(&payload[final_obs..final_obs + 4])[0];
    assert_eq!(final_counter, 3.0);
    let final_info = layout.obs.final_info.unwrap();
    let final_step: f32 = bytemuck::cast_slice(&payload[final_info..final_info + 4])[0];
    assert_eq!(final_step, 3.0);
    // Episodes continue without a client reset.
    let payload = lease.step(&[0.5; 14], None).unwrap().to_vec();
    assert_eq!(null_obs(&lease, &payload, 1)[0], 1.0);
}

#[test]
fn disabled_autoreset_needs_partial_resets() {
    let server = TestServer::start("partial");
    let mut lease = attach_null(
        &server.connect(),
        3,
        json!({"max_episode_steps": 2}),
        AutoresetMode::Disabled,
    );
    lease.reset(None, None).unwrap();
    lease.step(&[0.0; 21], None).unwrap();
    lease.step(&[0.0; 21], None).unwrap();
    assert_eq!(
        lease.step(&[0.0; 21], None).unwrap_err(),
        LeaseError::NeedsReset { env: 0 }
    );
    let payload = lease
        .reset(Some(&[true, false, true]), None)
        .unwrap()
        .to_vec();
    assert_eq!(
        null_obs(&lease, &payload, 1)[0],
        2.0,
        "env left alone reports its state"
    );
    assert_eq!(null_obs(&lease, &payload, 0)[0], 0.0);
    assert_eq!(
        lease.step(&[0.0; 21], None).unwrap_err(),
        LeaseError::NeedsReset { env: 1 }
    );
    lease.reset(Some(&[false, true, false]), None).unwrap();
    lease.step(&[0.0; 21], None).unwrap();
}

#[test]
fn seeded_resets_are_deterministic() {
    let server = TestServer::start("seeds");
    let connection = server.connect();
    let run = |seeds: [Option<u64>; 2]| {
        let mut lease = attach_null(&connection, 2, json!({}), AutoresetMode::Disabled);
        lease.reset(None, Some(&seeds)).unwrap();
        let mut draws = Vec::new();
        for _ in 0..5 {
            let payload = lease.step(&[0.0; 14], None).unwrap().to_vec();
            draws.push((
                null_obs(&lease, &payload, 0)[63],
                null_obs(&lease, &payload, 1)[63],
            ));
        }
        draws
    };
    assert_eq!(run([Some(1), Some(2)]), run([Some(1), Some(2)]));
    assert_ne!(run([Some(1), Some(2)]), run([Some(3), Some(2)]));
}

#[test]
fn expensive_batches_step_in_parallel_and_stay_intact() {
    let server = TestServer::start("busy");
    let mut lease = attach_null(
        &server.connect(),
        8,
        json!({"step_cost_us": 300.0, "max_episode_steps": null}),
        AutoresetMode::Disabled,
    );
    lease.reset(None, None).unwrap();
    step_and_verify(&mut lease, 30, 7.0);
    std::thread::sleep(Duration::from_millis(1));
}
