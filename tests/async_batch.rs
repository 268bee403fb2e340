//! Asynchronous groups (`AsyncBatch`), end to end over real shared memory: the first
//! groups ready come back with the right env ids, every action reaches its env, a group
//! is never sent twice, and misuse is refused naming the env without sending anything.

mod common;

use common::*;
use echogym_client::{AttachOptions, LeaseError};
use echogym_protocol::AutoresetMode;
use serde_json::json;

fn null_options(num_envs: usize) -> AttachOptions {
    AttachOptions {
        env_id: "echogym/Null-v0".into(),
        num_envs,
        config: json!({"max_episode_steps": null})
            .as_object()
            .cloned()
            .unwrap(),
        autoreset_mode: AutoresetMode::Disabled,
    }
}

#[test]
fn first_ready_groups_carry_their_envs_actions_and_step_counts() {
    let server = TestServer::start("async-groups");
    let connection = server.connect();
    let (n, group) = (8, 2);
    let mut batch = connection.attach_async(&null_options(n), group).unwrap();
    assert_eq!((batch.num_envs(), batch.num_groups()), (n, n / group));
    let all: Vec<usize> = (0..n).collect();
    batch.send_reset(&all, None).unwrap();
    let mut steps = vec![0f32; n];
    let mut last = vec![[0f32; 7]; n];
    let mut received = 0;
    for round in 0..400 {
        let groups = batch.recv(4).unwrap();
        assert_eq!(
            groups.len(),
            2,
            "recv(4) hands out exactly two groups of two"
        );
        let mut ids = Vec::new();
        let mut actions = Vec::new();
        for &g in &groups {
            let payload = batch.lease(g).current().unwrap().to_vec();
            for (slot, env) in batch.env_ids(g).enumerate() {
                let obs = null_obs(batch.lease(g), &payload, slot);
                assert_eq!(
                    obs[0], steps[env],
                    "step count of env {env} (round {round})"
                );
                assert_eq!(obs[1..8], last[env], "echo of env {env} (round {round})");
                let action: [f32; 7] =
                    std::array::from_fn(|i| ((env * 7 + i + round) % 97) as f32 / 97.0);
                last[env] = action;
                steps[env] += 1.0;
                ids.push(env);
                actions.extend_from_slice(&action);
            }
            received += group;
        }
        // Ids in reverse order: rows follow `ids`, not the groups' slot order.
        let rows: Vec<[f32; 7]> = actions.chunks(7).map(|c| c.try_into().unwrap()).collect();
        let ids_rev: Vec<usize> = ids.iter().rev().copied().collect();
        let actions_rev: Vec<f32> = rows.iter().rev().flatten().copied().collect();
        batch.send_step(&actions_rev, &ids_rev).unwrap();
    }
    assert_eq!(received, 400 * 4);
    // Everything still in flight comes back.
    while batch.pending_envs() > 0 {
        batch.recv(n).unwrap();
    }
    assert!(matches!(batch.recv(1), Err(LeaseError::Async(_))));
    batch.close();
}

#[test]
fn misuse_is_refused_naming_the_env_and_sends_nothing() {
    let server = TestServer::start("async-misuse");
    let connection = server.connect();
    let mut batch = connection.attach_async(&null_options(4), 2).unwrap();
    assert!(connection.attach_async(&null_options(4), 3).is_err());
    batch.send_reset(&[0, 1, 2, 3], None).unwrap();
    let first = batch.recv(2).unwrap()[0];
    let ids: Vec<usize> = batch.env_ids(first).collect();
    let other: Vec<usize> = batch.env_ids(1 - first).collect();
    let refused = |r: Result<(), LeaseError>| match r {
        Err(LeaseError::Async(message)) => message,
        other => panic!("expected a refusal, got {other:?}"),
    };
    let half = refused(batch.send_step(&[0.0; 7], &ids[..1]));
    assert!(
        half.contains(&format!("env {} is sent without env {}", ids[0], ids[1])),
        "{half}"
    );
    let pending = refused(batch.send_step(&[0.0; 14], &other));
    assert!(pending.contains(&format!("env {}", other[0])), "{pending}");
    let twice = refused(batch.send_step(&[0.0; 21], &[ids[0], ids[1], ids[0]]));
    assert!(twice.contains("given twice"), "{twice}");
    assert!(matches!(
        batch.send_step(&[0.0; 7], &ids),
        Err(LeaseError::ActionShape { .. })
    ));
    // A non-finite action is the server's refusal, named in the batch's numbering.
    let mut actions = vec![0.0f32; 14];
    actions[7 + 3] = f32::NAN;
    batch.send_step(&actions, &ids).unwrap();
    let (mut refusal, mut reset) = (false, false);
    while !(refusal && reset) {
        match batch.recv(2) {
            Ok(groups) => {
                assert_eq!(groups, vec![1 - first], "the other group's reset");
                reset = true;
            }
            Err(LeaseError::NonFiniteAction { env, element }) => {
                assert_eq!((env, element), (ids[1], 3));
                refusal = true;
            }
            other => panic!("expected NonFiniteAction or the reset, got {other:?}"),
        }
    }
    // The refused group is usable again.
    batch.send_step(&[0.0; 14], &ids).unwrap();
    assert_eq!(batch.recv(2).unwrap(), vec![first]);
    batch.close();
}
